"""Where one resident call's time goes at B = 1 on the CUDA backend (issue
17: a single call in <= 5 µs). Times, on the same GPU in the same run:
  - PyTorch's own floor: one small op and a synchronize, as a framework user
    sees any synchronous call;
  - the pieces of an rbdkit call outside the kernel: a tensor's
    __cuda_array_interface__, an output's allocation;
  - rbdkit calls on resident tensors (B = 1) and on NumPy arrays;
then traces a few calls with torch.profiler (CUDA runtime calls, CPU side),
which names the runtime calls a call makes and their cost.

    python3 bench/gpu_call_cost.py [--robot iiwa] [--dtype float32] [--no-trace]
"""

import argparse
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402


def per_call_us(f, n=2000, repeats=5):
    """µs per call of f(), best of `repeats` loops of n calls"""
    f()
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n):
            f()
        best = min(best, (time.perf_counter() - t0) / n)
    return best * 1e6


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robot", default="iiwa", help="a bundled robot; suffix _floating for a free base")
    ap.add_argument("--dtype", default="float32", choices=("float32", "float64"))
    ap.add_argument("--no-trace", action="store_true", help="skip the torch.profiler trace")
    a = ap.parse_args()
    import torch
    import rbdkit
    from gpu import arguments

    if not torch.cuda.is_available():
        ap.error("no CUDA device for PyTorch: this script times resident calls")
    name = a.robot.removesuffix("_floating")
    model = rbdkit.robots.load(name, floating_base=a.robot.endswith("_floating"))
    h = rbdkit.Handle(model, backend="cuda", dtype=a.dtype)
    rng = np.random.default_rng(0)
    host = {op: arguments(h, op, 1, rng) for op in ("inverse_dynamics", "forward_dynamics_gradient")}
    dev = {op: (tuple(torch.from_numpy(v).cuda() for v in args), kw) for op, (args, kw) in host.items()}
    x = dev["inverse_dynamics"][0][0]
    sync = torch.cuda.synchronize

    rows = [
        ("PyTorch: x + 1, then synchronize", lambda: (x + 1, sync())),
        ("PyTorch: torch.cuda.synchronize() alone", sync),
        ("PyTorch: torch.empty((1, nv)) on the GPU", lambda: torch.empty((1, h.nv), dtype=x.dtype, device=x.device)),
        ("a tensor's __cuda_array_interface__", lambda: x.__cuda_array_interface__),
    ]
    for op, (args, kw) in dev.items():
        f = getattr(h, op)
        rows.append((f"rbdkit {op}, B = 1, resident tensors", lambda f=f, args=args, kw=kw: f(*args, **kw)))
    for op, (args, kw) in host.items():
        args1 = tuple(np.ascontiguousarray(v[0]) for v in args)
        f = getattr(h, op)
        rows.append((f"rbdkit {op}, one sample, NumPy arrays", lambda f=f, args=args1, kw=kw: f(*args, **kw)))

    print(f"{torch.cuda.get_device_name()}, {a.robot}, {a.dtype}: µs per call, best of 5 loops of 2000")
    print("| call | µs |\n|---|---:|")
    for label, f in rows:
        print(f"| {label} | {per_call_us(f):.1f} |")

    if a.no_trace:
        return 0
    from torch.profiler import ProfilerActivity, profile
    args, kw = dev["inverse_dynamics"]
    f = h.inverse_dynamics
    with profile(activities=[ProfilerActivity.CPU, ProfilerActivity.CUDA]) as p:
        for _ in range(100):
            f(*args, **kw)
    print("\ntorch.profiler, 100 calls of inverse_dynamics at B = 1 (CPU-side times of the runtime calls):")
    print(p.key_averages().table(sort_by="self_cpu_time_total", row_limit=15))
    return 0


if __name__ == "__main__":
    sys.exit(main())
