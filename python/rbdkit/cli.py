"""The rbdkit command.

    rbdkit                      the demo (the main job): iiwa14 reaches a target, optimised by iLQR
    rbdkit demo [--task reach|atlas_reach] [--robot NAME|PATH] [--horizon N] [--dt S]
                [--integrator rk4] [--target x,y,z] [--threads T] [--dtype float64|float32]
                [--ddp] [--out DIR]    trajectory optimisation: progress, summary, PNG, JSON
    rbdkit report [--robot NAME|PATH] [--floating-base]
                                dynamics report (model summary, RNEA/CRBA/ABA, times)
    rbdkit robots               list the bundled robots
    rbdkit bench [--robots iiwa,hyq] [--ops rnea,aba] [--batch 0,64] [--threads 1,2] [--quick]
                 [--out DIR] [--json FILE] [-- Google Benchmark flags]
                                rbdkit vs Pinocchio per knot point (bench/run.sh of the
                                source checkout), table + CSV + JSON + PNG
"""

import argparse
import os
import subprocess
import sys

import numpy as np

from . import robots
from ._model import Model
from ._rbd import RBD


def _load(name, floating_base):
    if os.path.isfile(name):
        return Model.from_urdf(name, floating_base=floating_base)
    return robots.load(name, floating_base=floating_base)


def _fmt_vec(x, width=8, prec=3):
    return "[" + " ".join(f"{v:{width}.{prec}f}" for v in x) + "]"


def _fmt_time(s):
    return f"{s * 1e9:8.0f} ns" if s < 1e-6 else f"{s * 1e6:8.2f} µs"


def report(robot="iiwa", floating_base=False, seed=0, out=sys.stdout):
    """Model summary, then inverse dynamics, mass matrix and forward dynamics
    at a sample state with their per-call times."""
    model = _load(robot, floating_base)
    rbd = RBD(model)
    rng = np.random.default_rng(seed)
    # a sample state: joints inside their limits where they have them
    q = model.random_configuration(rng, scale=1.0)
    for j in model.joints:
        if j["nq"] == 1 and j["type"] in ("revolute", "prismatic", "helical"):
            lo, hi = model.lower[j["q_index"]], model.upper[j["q_index"]]
            if np.isfinite(lo) and np.isfinite(hi):
                q[j["q_index"]] = rng.uniform(lo, hi) * 0.8
    qd = rng.uniform(-1, 1, model.nv)
    qdd = rng.uniform(-1, 1, model.nv)

    p = lambda *a: print(*a, file=out)
    p("rbdkit — rigid-body dynamics report")
    p("=" * 72)
    p(model.summary())
    p(f"  joint order (velocity coordinates): {', '.join(model.joint_names)}")
    p("")
    p("sample state (seed %d)" % seed)
    p(f"  q   = {_fmt_vec(q)}")
    p(f"  qd  = {_fmt_vec(qd)}")
    p(f"  qdd = {_fmt_vec(qdd)}")
    p("")
    tau = rbd.inverse_dynamics(q, qd, qdd)[0]
    g = rbd.generalized_gravity(q)
    M = rbd.crba(q)
    Minv = rbd.minv(q)
    qdd_aba = rbd.aba(q, qd, tau)
    qdd_fd = rbd.forward_dynamics(q, qd, tau)
    p("inverse dynamics (RNEA)")
    p(f"  tau = {_fmt_vec(tau)}  N·m / N")
    p(f"  g(q)= {_fmt_vec(g)}")
    p("mass matrix (CRBA)")
    p(f"  diag(M) = {_fmt_vec(np.diag(M), prec=4)}")
    ev = np.linalg.eigvalsh(M)
    p(f"  eigenvalues in [{ev[0]:.4g}, {ev[-1]:.4g}], condition number {ev[-1] / ev[0]:.3g}")
    p(f"  |M·Minv - I|max = {np.abs(M @ Minv - np.eye(model.nv)).max():.2e}")
    p("forward dynamics of tau (should give back qdd)")
    p(f"  ABA        |qdd - qdd_in|max = {np.abs(qdd_aba - qdd).max():.2e}")
    p(f"  Minv(τ-c)  |qdd - qdd_in|max = {np.abs(qdd_fd - qdd).max():.2e}")
    p("")
    p("time per call (C++, one core, best of 5)")
    for op, label in (("inverse_dynamics", "inverse dynamics (RNEA)"), ("crba", "mass matrix (CRBA)"),
                      ("minv", "inverse mass matrix (Minv)"), ("aba", "forward dynamics (ABA)"),
                      ("forward_dynamics", "forward dynamics (Minv·(τ-c))")):
        p(f"  {label:32s} {_fmt_time(rbd.time_per_call(op, q, qd, tau))}")
    return 0


# the benchmark scripts, first found wins: the batched benchmark's, then the
# single-call one's (both build in build/bench and take Google Benchmark flags)
BENCH_SCRIPTS = ("bench/run_batch.sh", "bench/run.sh")


def source_dir():
    """the source checkout holding bench/run.sh: $RBDKIT_SOURCE_DIR, the one
    this package was built from (_build_info.py, written by CMake), or the
    tree this module sits in (python/rbdkit/); None when none has it"""
    candidates = [os.environ.get("RBDKIT_SOURCE_DIR")]
    try:
        from . import _build_info
        candidates.append(_build_info.SOURCE_DIR)
    except ImportError:
        pass
    candidates.append(os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir))
    for c in candidates:
        if c and os.path.isfile(os.path.join(c, "bench", "run.sh")):
            return os.path.abspath(c)
    return None


def _csv_list(text, name, choices=None, kind=str, minimum=None):
    items = [t.strip() for t in text.split(",") if t.strip()]
    if not items:
        raise ValueError(f"--{name}: expected a comma-separated list, got {text!r}")
    out = []
    for t in items:
        if kind is int:
            if not t.isdigit() or (minimum is not None and int(t) < minimum):
                raise ValueError(f"--{name}: expected integers >= {minimum}, got {t!r}")
            out.append(int(t))
        else:
            if choices and t not in choices:
                raise ValueError(f"--{name}: unknown {name[:-1] if name.endswith('s') else name} {t!r}; "
                                 f"expected some of {', '.join(choices)}")
            out.append(t)
    return out


def bench_filter(robots=None, ops=None, batch=None, threads=None):
    """the --benchmark_filter regex selecting <impl>/<robot>/<op>/<dtype>/B<B>/T<threads>"""
    alt = lambda xs, any_: "(" + "|".join(str(x) for x in xs) + ")" if xs else any_
    return (f"^(rbdkit|pinocchio)/{alt(robots, '[^/]+')}/{alt(ops, '[^/]+')}/(f64|f32)/"
            f"B{alt(batch, '[0-9]+')}/T{alt(threads, '[0-9]+')}(/|$)")


def bench(args, extra):
    """rbdkit bench: run bench/run.sh (or read --json) and report"""
    from . import benchreport
    out = os.path.abspath(args.out)
    if args.json:
        if not os.path.isfile(args.json):
            raise FileNotFoundError(f"--json: no file at '{args.json}'")
        benchreport.report(args.json, out, png=not args.no_png)
        return 0
    robots_ = _csv_list(args.robots, "robots", benchreport.ROBOTS) if args.robots else None
    ops = _csv_list(args.ops, "ops", benchreport.OPS) if args.ops else None
    batch = _csv_list(args.batch, "batch", kind=int, minimum=0) if args.batch else None
    threads = _csv_list(args.threads, "threads", kind=int, minimum=1) if args.threads else None
    src = source_dir()
    if src is None:
        raise FileNotFoundError("rbdkit bench needs the rbdkit source checkout (bench/run.sh): set "
                                "RBDKIT_SOURCE_DIR to it, or pip install rbdkit from a checkout")
    os.makedirs(out, exist_ok=True)
    raw = os.path.join(out, "benchmark.json")
    env = dict(os.environ, BENCH_JSON=raw, BENCH_REPORT="0", PYTHON=os.environ.get("PYTHON", sys.executable))
    if args.quick:
        env.update(REPS=env.get("REPS", "1"), MIN_TIME=env.get("MIN_TIME", "0.05"))
    script = next(os.path.join(src, s) for s in BENCH_SCRIPTS if os.path.isfile(os.path.join(src, s)))
    # the last --benchmark_out wins: ours, whatever the script sets
    cmd = ["bash", script, f"--benchmark_filter={bench_filter(robots_, ops, batch, threads)}", *extra,
           f"--benchmark_out={raw}", "--benchmark_out_format=json"]
    print("rbdkit bench: " + " ".join(cmd), flush=True)
    rc = subprocess.run(cmd, env=env).returncode
    if rc != 0:
        print(f"rbdkit: error: {os.path.relpath(script, src)} failed (exit status {rc})", file=sys.stderr)
        return rc
    if not os.path.isfile(raw):
        raise FileNotFoundError(f"{os.path.relpath(script, src)} wrote no results at '{raw}'")
    benchreport.report(raw, out, png=not args.no_png)
    return 0


def generate(args):
    """`rbdkit generate`: the header of a robot file or a bundled robot"""
    from ._codegen import generate as write
    robot = args.robot
    if os.path.isfile(robot):
        if robot.lower().endswith(".xml"):
            if args.floating_base:
                raise ValueError("--floating-base: a MuJoCo model says itself whether its root is free")
            model = Model.from_mjcf(robot)
        else:
            model = Model.from_urdf(robot, floating_base=args.floating_base)
    elif robot in robots.names():
        model = robots.load(robot, floating_base=args.floating_base)
    else:
        raise FileNotFoundError(f"robot: '{robot}' is neither a file nor a bundled robot ({', '.join(robots.names())})")
    write(model, args.name, args.output, source=os.path.basename(robot), runtime_inertias=args.runtime_inertias)
    print(f"wrote {args.output}: struct rbdkit_generated::{args.name}, nq={model.nq} nv={model.nv} nb={model.nb}")
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(prog="rbdkit", description="rigid-body dynamics for robots")
    sub = parser.add_subparsers(dest="cmd")
    from . import demo
    d = sub.add_parser("demo", help="trajectory optimisation demo (the default command): progress, summary, "
                                    "PNG, JSON", description=demo.__doc__.split("\n\n")[0])
    demo.add_arguments(d)
    r = sub.add_parser("report", help="dynamics report on a robot")
    r.add_argument("--robot", default="iiwa", help="bundled robot name or URDF path (default: iiwa)")
    r.add_argument("--floating-base", action="store_true", help="add a free-flyer root joint")
    r.add_argument("--seed", type=int, default=0)
    sub.add_parser("robots", help="list the bundled robots")
    g = sub.add_parser("generate", help="write a robot as a C++ header of per-robot functions",
                       description="Writes ROBOT (a URDF, a MuJoCo XML or a bundled robot's name) as one C++ header: "
                                   "the model as constants and per-robot inverse_dynamics, aba, crba, minv, their "
                                   "gradients and integrator_gradient over rbdkit's header-only algorithms "
                                   "(docs/generated-code.md). Compile it with -I \"$(python3 -c 'import rbdkit; "
                                   "print(rbdkit.include_dir())')\".")
    g.add_argument("robot", help="URDF (.urdf), MuJoCo model (.xml) or bundled robot name")
    g.add_argument("--floating-base", action="store_true", help="add a free-flyer root joint (URDF)")
    g.add_argument("--name", required=True, help="the struct's name (a C++ identifier)")
    g.add_argument("--runtime-inertias", action="store_true",
                   help="the inertias as an argument (pi, 10 per body, first in every function) for identification")
    g.add_argument("-o", "--output", required=True, help="the header to write (NAME.hpp)")
    bp = sub.add_parser("bench", help="rbdkit vs Pinocchio per knot point: table, CSV, JSON, PNG",
                        description="Runs bench/run_batch.sh (else bench/run.sh) of the source checkout (extra "
                                    "Google Benchmark flags after --) and reports ns per knot point with the "
                                    "rbdkit/Pinocchio ratio.")
    bp.add_argument("--robots", help="comma-separated: iiwa, hyq, atlas, hyq_floating, atlas_floating (default all)")
    bp.add_argument("--ops", help="comma-separated: rnea, crba, minv, aba, rnea_derivatives, aba_derivatives, "
                                  "integrator_rk4, integrator_gradient_rk4 (default all)")
    bp.add_argument("--batch", help="comma-separated batch sizes, 0 = single call (default all: 0,1,16,64,256,1024)")
    bp.add_argument("--threads", help="comma-separated thread counts (default all: 1,2)")
    bp.add_argument("--quick", action="store_true", help="one short repetition per benchmark (REPS=1, MIN_TIME=0.05)")
    bp.add_argument("--out", default="rbdkit-bench", help="output folder (default ./rbdkit-bench)")
    bp.add_argument("--json", help="report this Google Benchmark JSON instead of running the benchmark")
    bp.add_argument("--no-png", action="store_true", help="skip the figure")
    if argv is None:
        argv = sys.argv[1:]
    extra = []
    if "--" in argv:
        k = argv.index("--")
        argv, extra = argv[:k], argv[k + 1:]
    args = parser.parse_args(argv)
    try:
        if args.cmd == "robots":
            for n in robots.names():
                m = robots.load(n)
                print(f"{n:8s} nq={m.nq:3d} nv={m.nv:3d}  {robots.path(n)}")
            return 0
        if args.cmd == "bench":
            return bench(args, extra)
        if args.cmd == "generate":
            return generate(args)
        if args.cmd is None:
            return demo.main_from_args(parser.parse_args(["demo"]))
        if args.cmd == "demo":
            return demo.main_from_args(args)
        return report(args.robot, args.floating_base, args.seed)
    except (ValueError, TypeError, FileNotFoundError) as e:
        print(f"rbdkit: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
