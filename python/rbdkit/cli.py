"""The rbdkit command.

    rbdkit                      report on the bundled iiwa14 (the main job)
    rbdkit report [--robot NAME|PATH] [--floating-base]
    rbdkit robots               list the bundled robots
"""

import argparse
import os
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


def main(argv=None):
    parser = argparse.ArgumentParser(prog="rbdkit", description="rigid-body dynamics for robots")
    sub = parser.add_subparsers(dest="cmd")
    r = sub.add_parser("report", help="dynamics report on a robot (the default command)")
    r.add_argument("--robot", default="iiwa", help="bundled robot name or URDF path (default: iiwa)")
    r.add_argument("--floating-base", action="store_true", help="add a free-flyer root joint")
    r.add_argument("--seed", type=int, default=0)
    sub.add_parser("robots", help="list the bundled robots")
    args = parser.parse_args(argv)
    try:
        if args.cmd == "robots":
            for n in robots.names():
                m = robots.load(n)
                print(f"{n:8s} nq={m.nq:3d} nv={m.nv:3d}  {robots.path(n)}")
            return 0
        if args.cmd is None:
            return report()
        return report(args.robot, args.floating_base, args.seed)
    except (ValueError, TypeError, FileNotFoundError) as e:
        print(f"rbdkit: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
