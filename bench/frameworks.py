"""What a framework call costs on top of the NumPy handle's (issue 15, point 3):
one jitted rbdkit.jax call and one rbdkit.torch call against the same
operation through rbdkit.Handle, in the same run, on the same machine, at B
knot points on the CPU, or on a GPU (--device cuda).

    python3 bench/frameworks.py [--batch 16] [--robots iiwa hyq_floating] [--quick] [--device cuda]

--device cuda: every handle has backend="cuda" and every array lives on the GPU:
the NumPy handle is given PyTorch CUDA tensors (its device-array path), JAX
arrays are on JAX's GPU and the custom call runs on XLA's buffers, PyTorch
tensors are CUDA tensors. Each call returns when its kernels are done.

For each operation: µs per call of the NumPy handle, of the jitted JAX call
(inputs already JAX arrays; block_until_ready) and of the PyTorch call (CPU
tensors), and the differences; "forward_dynamics_grad" is a gradient
(reverse mode) of a scalar of the result against the NumPy handle computing
the Jacobians that gradient needs (a backward pass in PyTorch). The best of
several repeats.
"""

import argparse
import json
import time

import numpy as np

import rbdkit

OPS = ("inverse_dynamics", "forward_dynamics", "crba", "integrator_rk4", "forward_dynamics_grad")


def best_us(f, min_time, repeats):
    f()
    n = 1
    while True:  # calls per repeat: at least min_time seconds
        t = time.perf_counter()
        for _ in range(n):
            f()
        if time.perf_counter() - t >= min_time:
            break
        n *= 2
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        for _ in range(n):
            f()
        times.append((time.perf_counter() - t) / n)
    return 1e6 * min(times)


def torch_calls(torch, ht, X, device):
    """{op: PyTorch call} on the batch X, tensors on `device`"""
    q, qd, u = (torch.from_numpy(a).to(device) for a in X)
    ug = u.clone().requires_grad_()

    def grad():
        ug.grad = None
        (ht.forward_dynamics(q, qd, ug) ** 2).sum().backward()
    return {
        "inverse_dynamics": lambda: ht.inverse_dynamics(q, qd, u),
        "forward_dynamics": lambda: ht.forward_dynamics(q, qd, u),
        "crba": lambda: ht.crba(q),
        "integrator_rk4": lambda: ht.integrator(q, qd, u, 0.01, "rk4"),
        "forward_dynamics_grad": grad,
    }


def calls(jax, h, X, jax_device, device_array):
    """{op: (NumPy call, jitted JAX call)} on the batch X: JAX's arrays on jax_device, the NumPy
    handle's made by device_array (a NumPy array itself on the CPU)"""
    q, qd, u = (device_array(a) for a in X)
    jq, jqd, ju = (jax.device_put(a, jax_device) for a in X)
    n = h.numpy
    jit = jax.jit
    f_id, f_fd, f_m = jit(h.inverse_dynamics), jit(h.forward_dynamics), jit(h.crba)
    f_rk = jit(lambda q, qd, u: h.integrator(q, qd, u, 0.01, "rk4"))
    f_g = jit(jax.grad(lambda u: (h.forward_dynamics(jq, jqd, u) ** 2).sum()))
    return {
        "inverse_dynamics": (lambda: n.inverse_dynamics(q, qd, u), lambda: f_id(jq, jqd, ju).block_until_ready()),
        "forward_dynamics": (lambda: n.forward_dynamics(q, qd, u), lambda: f_fd(jq, jqd, ju).block_until_ready()),
        "crba": (lambda: n.crba(q), lambda: f_m(jq).block_until_ready()),
        "integrator_rk4": (lambda: n.integrator(q, qd, u, 0.01, "rk4"),
                           lambda: f_rk(jq, jqd, ju).block_until_ready()),
        # the gradient: one forward_dynamics_gradient call (with qdd and M⁻¹) against the same from NumPy
        "forward_dynamics_grad": (lambda: n.forward_dynamics_gradient(q, qd, u),
                                  lambda: f_g(ju).block_until_ready()),
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--batch", type=int, default=16)
    p.add_argument("--robots", nargs="+", default=["iiwa", "hyq_floating"])
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--quick", action="store_true", help="short loops: a smoke run")
    p.add_argument("--device", choices=("cpu", "cuda"), default="cpu",
                   help="cuda: backend='cuda' handles on GPU arrays (module doc)")
    p.add_argument("--out", help="write the rows as JSON here")
    o = p.parse_args(argv)
    try:
        import jax
        import torch
        import rbdkit.jax as rj
        import rbdkit.torch as rt
    except ImportError as e:
        raise SystemExit(f"frameworks: {e}")
    jax.config.update("jax_enable_x64", True)
    min_time, repeats = (0.01, 2) if o.quick else (0.2, 7)
    rows = []
    if o.device == "cuda":
        if jax.default_backend() != "gpu" or not torch.cuda.is_available():
            raise SystemExit("frameworks: --device cuda needs JAX and PyTorch with a GPU")
        jax_device, device_array = jax.devices("gpu")[0], lambda a: torch.from_numpy(a).cuda()
        where = f"GPU ({torch.cuda.get_device_name()})"
    else:
        jax_device, device_array, where = jax.devices("cpu")[0], lambda a: a, "CPU"
    print(f"B = {o.batch}, threads = {o.threads}, float64, {where}; µs per call (best of {repeats})")
    print(f"{'robot':14s} {'operation':22s} {'numpy':>8s} {'jax jit':>8s} {'+jax':>7s} {'torch':>8s} {'+torch':>7s}")
    for label in o.robots:
        name, floating = label.split("_")[0], label.endswith("_floating")
        m = rbdkit.robots.load(name, floating_base=floating)
        h = rj.Handle(m, threads=o.threads, backend=o.device)
        ht = rt.Handle(m, threads=o.threads, backend=o.device)
        rng = np.random.default_rng(0)
        X = (np.stack([m.random_configuration(rng) for _ in range(o.batch)]),
             rng.uniform(-1, 1, (o.batch, m.nv)), rng.uniform(-1, 1, (o.batch, m.nv)))
        tc = torch_calls(torch, ht, X, o.device)
        for op, (f_np, f_jax) in calls(jax, h, X, jax_device, device_array).items():
            t_np, t_jax, t_t = (best_us(f, min_time, repeats) for f in (f_np, f_jax, tc[op]))
            rows.append({"robot": label, "op": op, "numpy_us": t_np, "jax_us": t_jax, "jax_extra_us": t_jax - t_np,
                         "torch_us": t_t, "torch_extra_us": t_t - t_np})
            print(f"{label:14s} {op:22s} {t_np:8.1f} {t_jax:8.1f} {t_jax - t_np:+7.1f} {t_t:8.1f} {t_t - t_np:+7.1f}")
    if o.out:
        with open(o.out, "w") as f:
            json.dump({"batch": o.batch, "threads": o.threads, "device": where, "rows": rows}, f, indent=1)
    return rows


if __name__ == "__main__":
    main()
