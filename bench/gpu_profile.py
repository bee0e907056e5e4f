"""One operation's resident call on the CUDA backend, for a profiler: a
warm-up call, then the call to profile (issue 17: where a target is missed,
say why from a profile).

    ncu -k regex:op_kernel --launch-skip 1 --launch-count 1 \\
        --section SpeedOfLight --section Occupancy --section LaunchStats \\
        python3 bench/gpu_profile.py --op forward_dynamics_gradient --B 256 --dtype float32
    nsys profile python3 bench/gpu_profile.py --calls 100

--work forces the work memory (RBDKIT_CUDA_WORK: auto, global, shared;
docs/cuda.md). Inputs are PyTorch CUDA tensors, as bench/gpu.py's resident
column.
"""

import argparse
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import numpy as np  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robot", default="iiwa", help="a bundled robot; suffix _floating for a free base")
    ap.add_argument("--op", default="forward_dynamics_gradient", help="an operation of bench/gpu.py's list")
    ap.add_argument("--B", type=int, default=256)
    ap.add_argument("--dtype", default="float32", choices=("float32", "float64"))
    ap.add_argument("--work", default="auto", choices=("auto", "global", "shared"))
    ap.add_argument("--calls", type=int, default=1, help="calls after the warm-up")
    a = ap.parse_args()
    import rbdkit
    from gpu import arguments, device_module

    dev = device_module("torch")
    if dev is None:
        ap.error("no CUDA device for PyTorch: this script profiles device arrays")
    name = a.robot.removesuffix("_floating")
    model = rbdkit.robots.load(name, floating_base=a.robot.endswith("_floating"))
    os.environ["RBDKIT_CUDA_WORK"] = a.work
    h = rbdkit.Handle(model, backend="cuda", dtype=a.dtype)
    args, kw = arguments(h, a.op, a.B, np.random.default_rng(0))
    dargs = tuple(dev[1](x) for x in args)
    f = getattr(h, a.op)
    f(*dargs, **kw)
    dev[2]()
    t0 = time.perf_counter()
    for _ in range(a.calls):
        f(*dargs, **kw)
    dev[2]()
    dt = (time.perf_counter() - t0) / a.calls
    print(f"{a.robot} {a.op} B={a.B} {a.dtype} work={a.work}: {dt * 1e6:.1f} µs per call, "
          f"{dt * 1e6 / a.B:.3f} µs per knot point")
    return 0


if __name__ == "__main__":
    sys.exit(main())
