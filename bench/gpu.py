"""µs per knot point on the CUDA backend, beside the CPU engine at the same B
on the same machine (issue 14, scripts/gpu-check.sh).

For iiwa, HyQ and Atlas, fixed and floating; ID, M, M⁻¹, FD, ∇ID, ∇FD, the
rk4 step gradient and the Euler step Hessian; float32 and float64; B in
{1, 16, 64, 256, 1024, 4096, 16384}:
  resident   inputs already on the device (PyTorch or CuPy device arrays;
             "-" when neither is installed), outputs made there
  host       a call on NumPy arrays: copies in and out included
  cpu        the CPU engine (rbdkit.Handle(backend="cpu"), all cores)
With --work-memory: two more resident columns, each sample's work (workspace
and scratch) forced into global memory and into the block's shared memory
(RBDKIT_CUDA_WORK; the default, "auto", picks shared where it fits and the
batch runs in at most three waves there; docs/cuda.md).

With --ops, also the rk4 step's value, a state cost (tangent), the momentum
cost and the position barrier (not timed by default).

With --kernels: two more resident columns, the operations that have a team
kernel (ID, M, M⁻¹, FD, ∇ID, ∇FD, the step gradient and Hessian, the costs
and barriers: a block of threads per sample) forced to the sample-per-thread kernel and to the team kernel
(RBDKIT_CUDA_KERNEL; the default, "auto", picks by B per SM and by nv;
docs/cuda.md, "Team kernels"); "-" for the others.

With --specialize: one more resident column, a handle with specialize=True (the
CUDA backend's kernels compiled by nvcc on the robot's constants for ID, M⁻¹,
FD, ∇ID, ∇FD and the step gradient; docs/generated-code.md), and after the
table, per robot and dtype, the compilation's seconds and the largest
difference of its results from the generic kernels' (relative to each output's
scale); "-" for the operations it does not hold.

With --ilqr: one iLQR iteration's derivatives for K = 64 trajectories of
N = 100 knot points of the demo's iiwa reach (B = 6400 in one call each:
rk4 step gradients, state, input and end-effector costs), on the GPU
(resident) against the CPU engine (issue 17, point 3).

    python3 bench/gpu.py [--quick] [--robots R,..] [--ops OP,..] [--batches B,..] [--work-memory]
                         [--kernels] [--specialize] [--ilqr] [--out table.md]

In interpret mode (RBDKIT_CUDA_INTERPRET=1, no GPU) the same runs, slowly:
a smoke test of the script, not a measurement.
"""

import argparse
import os
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
import rbdkit  # noqa: E402

ROBOTS = (("iiwa", False), ("iiwa", True), ("hyq", False), ("hyq", True), ("atlas", False), ("atlas", True))
OPS = (("ID", "inverse_dynamics"), ("M", "crba"), ("M⁻¹", "minv"), ("FD", "forward_dynamics"),
       ("∇ID", "inverse_dynamics_gradient"), ("∇FD", "forward_dynamics_gradient"),
       ("rk4 ∇step", "integrator_gradient"), ("euler ∇²step", "plant_step_hessian"))
BATCHES = (1, 16, 64, 256, 1024, 4096, 16384)
# more operations with a team kernel, timed only when --ops names them (their per-SM rule has no GPU
# measurement yet): the rk4 step's value, a state cost (tangent), the momentum cost, the position barrier
EXTRA_OPS = (("rk4 step", "integrator"), ("state cost", "quadratic_state_cost_tangent"),
             ("momentum cost", "momentum_cost"), ("q barrier", "joint_position_barrier"))
# the operations with a team kernel (include/rbdkit/cuda/team_kernels.cuh; --kernels)
TEAM_OPS = ("inverse_dynamics", "crba", "minv", "forward_dynamics", "inverse_dynamics_gradient", "forward_dynamics_gradient",
            "integrator_gradient", "plant_step_hessian") + tuple(o[1] for o in EXTRA_OPS)
# the operations a CUDA instance holds (rbdkit/cuda/instance.cuh's Ops)
INSTANCE_OPS = ("inverse_dynamics", "minv", "forward_dynamics", "inverse_dynamics_gradient",
                "forward_dynamics_gradient", "integrator_gradient")


def device_module(choice="any"):
    """(name, to_device, synchronize) of PyTorch or CuPy on a GPU (choice: "any", "torch", "cupy",
    "none"), or None"""
    if choice in ("any", "torch"):
        try:
            import torch
            if torch.cuda.is_available():
                return "torch", (lambda a: torch.from_numpy(a).cuda()), torch.cuda.synchronize
        except ImportError:
            pass
    if choice in ("any", "cupy"):
        try:
            import cupy
            if cupy.cuda.runtime.getDeviceCount() > 0:
                return "cupy", cupy.asarray, cupy.cuda.runtime.deviceSynchronize
        except Exception:  # noqa: BLE001  no CuPy, or no device for it
            pass
    return None


def arguments(h, op, B, rng):
    """the call's positional arguments and keywords on B samples (NumPy, the handle's dtype)"""
    dt = h.dtype
    q = np.stack([h.rbd.integrate(h.model.neutral(), rng.uniform(-1, 1, h.nv)) for _ in range(B)]).astype(dt)
    qd = rng.uniform(-1, 1, (B, h.nv)).astype(dt)
    u = rng.uniform(-1, 1, (B, h.nv)).astype(dt)
    if op in ("crba", "minv"):
        return (q,), {}
    if op in ("integrator", "integrator_gradient"):
        return (q, qd, u), {"dt": 0.01, "integrator_type": "rk4"}
    if op == "plant_step_hessian":
        return (np.concatenate([q, qd], axis=1), u), {"dt": 0.01, "integrator_type": "euler"}
    if op == "quadratic_state_cost_tangent":
        x = np.concatenate([q, qd], axis=1)
        return (x, x[::-1].copy(), np.ones((B, 2 * h.nv), dt)), {}
    if op == "momentum_cost":
        return (q, qd, rng.uniform(-1, 1, (B, 6)).astype(dt), np.ones((B, 6), dt)), {}
    if op == "joint_position_barrier":
        return (q, np.full_like(q, -10), np.full_like(q, 10)), {"mu": 0.1}
    return (q, qd, u), {}


def per_call(f, args, kwargs, sync, budget):
    """seconds per call, best of repeats within `budget` seconds"""
    f(*args, **kwargs)
    sync()
    best, spent, n = np.inf, 0.0, 1
    while spent < budget:
        t0 = time.perf_counter()
        for _ in range(n):
            f(*args, **kwargs)
        sync()
        dt = time.perf_counter() - t0
        best, spent = min(best, dt / n), spent + dt
        n = min(n * 2, 64)
    return best


def scaled_difference(a, b):
    """the largest |a - b| over the outputs, each relative to its own scale (device arrays or NumPy)"""
    pairs = zip(a, b) if isinstance(a, tuple) else [(a, b)]
    worst = 0.0
    def host(v):  # a PyTorch tensor, a CuPy array or NumPy
        v = v.cpu() if hasattr(v, "cpu") else v.get() if hasattr(v, "get") else v
        return np.asarray(v, dtype=np.float64)

    for x, y in pairs:
        x, y = host(x), host(y)
        worst = max(worst, float(np.max(np.abs(x - y))) / max(1.0, float(np.max(np.abs(y)))))
    return worst


def nbytes(result):
    """bytes of an operation's result (an array or a tuple of arrays)"""
    return sum(np.asarray(r).nbytes for r in result) if isinstance(result, tuple) else np.asarray(result).nbytes


def cuda_handle(model, dtype, var, value):
    """a CUDA handle made with the environment variable var=value (the caller's value restored after)"""
    before = os.environ.get(var)
    os.environ[var] = value
    try:
        return rbdkit.Handle(model, backend="cuda", dtype=dtype)
    finally:
        if before is None:
            del os.environ[var]
        else:
            os.environ[var] = before


def ilqr_table(out, dev, budget, K=64, N=100):
    """one iLQR iteration's derivatives on K trajectories of N knots of iiwa: µs per iteration"""
    model = rbdkit.robots.load("iiwa")
    B, nq, nv = K * N, model.nq, model.nv
    out()
    out(f"iLQR derivatives, iiwa, K = {K} trajectories × N = {N} knots (B = {B}): rk4 step gradients, "
        "state, input and end-effector costs; µs per iteration")
    out()
    out("| dtype | GPU resident | CPU engine | cpu / resident |")
    out("|---|---:|---:|---:|")
    for dtype in ("float32", "float64"):
        rng = np.random.default_rng(1)
        cpu = rbdkit.Handle(model, backend="cpu", dtype=dtype)
        q = np.stack([cpu.rbd.integrate(model.neutral(), rng.uniform(-1, 1, nv)) for _ in range(B)]).astype(dtype)
        qd, u = (rng.uniform(-1, 1, (B, nv)).astype(dtype) for _ in range(2))
        x = np.concatenate([q, qd], axis=1)
        arrays = dict(q=q, qd=qd, u=u, x=x, x_des=np.zeros_like(x), Q=np.ones_like(x), u_des=np.zeros_like(u),
                      R=np.full_like(u, 1e-3), p_des=np.tile(np.array([0.5, 0.2, 0.6], dtype), (B, 1)),
                      W=np.full((B, 3), 1e4, dtype))

        def iteration(h, a):
            h.integrator_gradient(a["q"], a["qd"], a["u"], dt=0.01, integrator_type="rk4")
            h.quadratic_state_cost(a["x"], a["x_des"], a["Q"])
            h.quadratic_input_cost(a["u"], a["u_des"], a["R"])
            h.ee_pos_cost(a["q"], a["p_des"], a["W"])

        t_cpu = per_call(iteration, (cpu, arrays), {}, lambda: None, budget * 4) * 1e6
        res = "-"
        if dev:
            cu = rbdkit.Handle(model, backend="cuda", dtype=dtype)
            darrays = {k: dev[1](v) for k, v in arrays.items()}
            t_res = per_call(iteration, (cu, darrays), {}, dev[2], budget * 4) * 1e6
            res = f"{t_res:.0f}"
        out(f"| {dtype} | {res} | {t_cpu:.0f} | {'-' if res == '-' else f'{t_cpu / t_res:.1f}×'} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="iiwa and floating HyQ, B in {1, 256, 4096}")
    ap.add_argument("--out", help="also write the table (markdown) here")
    ap.add_argument("--budget", type=float, default=0.2, help="seconds per measurement")
    ap.add_argument("--max-gb", type=float, default=4.0,
                    help="skip a B whose inputs and outputs take more than this (GB): the Euler step Hessian "
                         "of floating Atlas is 6.7 MB per knot point")
    ap.add_argument("--batches", help="comma-separated batch sizes, e.g. 1,256,4096 (default: 1 to 16384)")
    ap.add_argument("--robots", help="comma-separated, e.g. atlas,atlas_floating (default: all six)")
    ap.add_argument("--ops", help="comma-separated operation names, e.g. forward_dynamics_gradient (default: all eight; "
                    "also integrator, momentum_cost, quadratic_state_cost_tangent, joint_position_barrier)")
    ap.add_argument("--arrays", default="any", choices=("any", "torch", "cupy", "none"),
                    help="the device arrays of the resident column")
    ap.add_argument("--kernels", action="store_true",
                    help="two more resident columns: the sample-per-thread and the team kernel, where an op has both")
    ap.add_argument("--specialize", action="store_true",
                    help="one more resident column: the robot's compiled CUDA instance (specialize=True)")
    ap.add_argument("--work-memory", action="store_true",
                    help="also time the resident call with the work in global and in shared memory")
    ap.add_argument("--ilqr", action="store_true",
                    help="also time one iLQR iteration's derivatives for 64 iiwa trajectories of 100 knots")
    ap.add_argument("--only-ilqr", action="store_true", help="the --ilqr table only")
    a = ap.parse_args()
    robots = ROBOTS[:1] + ROBOTS[3:4] if a.quick else ROBOTS
    if a.robots:
        known = {r[0] + ("_floating" if r[1] else ""): r for r in ROBOTS}
        unknown = [n for n in a.robots.split(",") if n not in known]
        if unknown:
            ap.error(f"--robots: unknown {', '.join(unknown)}; expected some of {', '.join(known)}")
        robots = [known[n] for n in a.robots.split(",")]
    batches = (1, 256, 4096) if a.quick else BATCHES
    if a.batches:
        try:
            batches = tuple(int(b) for b in a.batches.split(","))
        except ValueError:
            ap.error(f"--batches: expected comma-separated positive integers, got {a.batches!r}")
        if any(b <= 0 for b in batches):
            ap.error(f"--batches: expected positive batch sizes, got {a.batches!r}")
    ops = OPS
    if a.ops:
        known_ops = {o[1] for o in OPS + EXTRA_OPS}
        unknown = [n for n in a.ops.split(",") if n not in known_ops]
        if unknown:
            ap.error(f"--ops: unknown {', '.join(unknown)}; expected some of {', '.join(sorted(known_ops))}")
        ops = [o for o in OPS + EXTRA_OPS if o[1] in a.ops.split(",")]
    dev = device_module(a.arrays)
    warnings.filterwarnings("ignore", message=".*inertia.*")  # the bundled Atlas's published inertias
    nosync = lambda: None  # noqa: E731
    lines, notes, worst = [], [], {}  # (--specialize: the instances' compile times, their largest differences)

    def out(s=""):
        print(s, flush=True)
        lines.append(s)

    gpu = None
    for robot, floating in robots if not a.only_ilqr else ():
        model = rbdkit.robots.load(robot, floating_base=floating)
        for dtype in ("float32", "float64"):
            cu = rbdkit.Handle(model, backend="cuda", dtype=dtype)
            cpu = rbdkit.Handle(model, backend="cpu", dtype=dtype)
            forced = {}  # --work-memory, --kernels: handles with the work memory or the kernel forced
            for where in ("global", "shared") if a.work_memory and dev else ():
                forced[where] = cuda_handle(model, dtype, "RBDKIT_CUDA_WORK", where)
            for kernel in ("sample", "team") if a.kernels and dev else ():
                forced[kernel] = cuda_handle(model, dtype, "RBDKIT_CUDA_KERNEL", kernel)
            if a.specialize and dev:
                t0 = time.perf_counter()
                spec = rbdkit.Handle(model, backend="cuda", dtype=dtype, specialize=True)
                notes.append(f"{robot}{'_floating' if floating else ''} {dtype}: the instance in "
                             f"{time.perf_counter() - t0:.1f} s ({'in use' if spec.specialized else 'NOT in use'})")
                forced["specialized"] = spec if spec.specialized else None  # ("-" when it could not be made)
            if gpu is None:
                gpu = cu.device
                out(f"# rbdkit CUDA backend: µs per knot point on {gpu} "
                    f"(CPU engine: {cpu.threads} threads; device arrays: {dev[0] if dev else 'none'})")
                out()
                extra = [c for c, on in (("global", a.work_memory), ("shared", a.work_memory),
                                         ("sample kernel", a.kernels), ("team kernel", a.kernels),
                                         ("specialized", a.specialize)) if on]
                out("| robot | dtype | op | B | resident | host | cpu | cpu / resident |" +
                    "".join(f" {c} |" for c in extra))
                out("|---|---|---|---:|---:|---:|---:|---:|" + "---:|" * len(extra))
            for label, op in ops:
                args1, kw1 = arguments(cpu, op, 1, np.random.default_rng(0))
                per_sample = nbytes(getattr(cpu, op)(*args1, **kw1)) + sum(x.nbytes for x in args1)
                for B in batches:
                    name = robot + ("_floating" if floating else "")
                    if per_sample * B > a.max_gb * 1e9:
                        out(f"| {name} | {dtype} | {label} | {B} | - | - | - | over --max-gb "
                            f"({per_sample * B / 1e9:.1f} GB) |" + " - |" * len(extra))
                        continue
                    rng = np.random.default_rng(0)
                    args, kw = arguments(cu, op, B, rng)
                    host = per_call(getattr(cu, op), args, kw, nosync, a.budget) / B * 1e6
                    cpu_t = per_call(getattr(cpu, op), args, kw, nosync, a.budget) / B * 1e6
                    res = None
                    if dev:
                        dargs = tuple(dev[1](x) for x in args)
                        res = per_call(getattr(cu, op), dargs, kw, dev[2], a.budget) / B * 1e6
                    cols = ""
                    for where, h in forced.items():
                        if where in ("sample", "team") and op not in TEAM_OPS:
                            cols += " - |"  # (no team kernel: both columns would time the same kernel)
                            continue
                        if where == "specialized":
                            if h is None or op not in INSTANCE_OPS:
                                cols += " - |"
                                continue
                            worst[(name, dtype)] = max(worst.get((name, dtype), 0.0),
                                                       scaled_difference(getattr(h, op)(*dargs, **kw),
                                                                         getattr(cu, op)(*dargs, **kw)))
                        try:
                            t = per_call(getattr(h, op), dargs, kw, dev[2], a.budget) / B * 1e6
                            cols += f" {t:.3f} |"
                        except ValueError:  # a sample's work exceeds a block's shared memory
                            cols += " - |"
                    if extra and not forced:
                        cols = " - |" * len(extra)
                    out(f"| {name} | {dtype} | {label} | {B} | {'-' if res is None else f'{res:.3f}'} | "
                        f"{host:.3f} | {cpu_t:.3f} | {'-' if res is None else f'{cpu_t / res:.1f}×'} |{cols}")
    for line in notes:
        out(f"- {line}")
    for (name, dtype), d in worst.items():
        out(f"- {name} {dtype}: the instance's results differ from the generic kernels' by {d:.1e} at most "
            f"(relative to each output's scale)")
    if a.ilqr or a.only_ilqr:
        ilqr_table(out, dev, a.budget)
    if a.out:
        with open(a.out, "w") as f:
            f.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
