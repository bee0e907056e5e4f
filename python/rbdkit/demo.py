"""rbdkit demo: trajectory optimisation on the plant layer (rbdkit.solve_trajectory).

Tasks
    reach        (default) the arm (bundled iiwa14, or --robot NAME|URDF) moves its
                 end effector from rest to a target and stops there, within the
                 joint position, velocity and torque limits of its URDF
    atlas_reach  Atlas, fixed base: the left hand reaches a target in front of the
                 robot with the whole body (back, arms, legs), a centre-of-mass
                 cost holding the CoM over the pelvis, within Atlas's limits

Prints one line per iteration (cost, constraint violation, step size, time), a
summary (final end-effector error, iterations, time per iteration, time per
knot point of the derivatives), and writes demo.png (joint trajectories,
torques, end-effector path against the target, cost per iteration) and
demo.json (settings, per-iteration log, summary, trajectory) to --out.
"""

import json
import os
import platform
import sys

import numpy as np

from . import robots
from ._model import Model
from ._rbd import RBD
from ._solver import ee_body_and_offset, solve_trajectory

TASKS = ("reach", "atlas_reach")

# iiwa14 start pose (rest) and target (m, world frame); tool point 5 cm past the flange
IIWA_START = np.array([0.0, 0.6, 0.0, -1.2, 0.0, 0.9, 0.0])
IIWA_TARGET = np.array([0.4, 0.4, 0.8])
IIWA_TOOL = np.array([0.0, 0.0, 0.05])


def load_robot(name, floating_base=False):
    """a bundled robot by name or a URDF by path; a clear error otherwise"""
    if not isinstance(name, str):
        raise TypeError(f"robot: expected a bundled robot name or a URDF path, got {type(name).__name__}")
    if os.path.isfile(name):
        return Model.from_urdf(name, floating_base=floating_base)
    if name not in robots.names():
        raise ValueError(f"robot: unknown robot '{name}'; expected one of {', '.join(robots.names())} "
                         f"or the path of a URDF file")
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Atlas's published inertias (docs/conventions.md)
        return robots.load(name, floating_base=floating_base)


def _inside_limits(model, q, margin=0.1):
    """q moved inside the position limits (by a margin of their span)"""
    q = q.copy()
    lo, hi = model.lower, model.upper
    for i in range(model.nq):
        if np.isfinite(lo[i]) and np.isfinite(hi[i]):
            m = margin * (hi[i] - lo[i])
            q[i] = np.clip(q[i], lo[i] + m, hi[i] - m)
    return q


def reach_task(model, target=None):
    """start state, end-effector tool point and target, weights of the arm reach"""
    nv = model.nv
    if model.name.startswith("iiwa") and model.nq == 7:
        q0, off = IIWA_START.copy(), IIWA_TOOL
        default_target = IIWA_TARGET
    else:
        q0, off = _inside_limits(model, model.neutral()), np.zeros(3)
        # a reachable default: the tool point at a configuration 0.4 rad away
        rbd = RBD(model)
        body, tool = ee_body_and_offset(model, None, off)
        q1 = _inside_limits(model, q0 + 0.4)
        names = [j["name"] for j in model.joints if j["body"] == body]
        default_target = rbd.end_effector_pose(q1, names or None, tool)[0, :3]
    return dict(x0=np.concatenate([q0, np.zeros(nv)]), ee_offset=off,
                ee_target=default_target if target is None else np.asarray(target, float),
                W_ee=1.0, W_ee_terminal=1e5, Q=np.r_[np.full(nv, 1e-2), np.full(nv, 1e-1)],
                Q_terminal=np.r_[np.zeros(nv), np.full(nv, 10.0)], R=np.full(nv, 1e-4))


# Atlas: arms down, slightly bent (inside the 30 N·m torque limits at rest)
ATLAS_START = {"l_arm_shx": -1.3, "r_arm_shx": 1.3, "l_arm_elx": 0.3, "r_arm_elx": -0.3,
               "l_leg_kny": 0.3, "r_leg_kny": 0.3, "l_leg_hpy": -0.15, "r_leg_hpy": -0.15,
               "l_leg_aky": -0.15, "r_leg_aky": -0.15}
ATLAS_TARGET = np.array([0.35, 0.45, -0.05])


def atlas_task(model, target=None):
    nv = model.nv
    names = model.joint_names
    q0 = model.neutral()
    for n, v in ATLAS_START.items():
        if n in names:
            q0[model.joint(n)["q_index"]] = v
    rbd = RBD(model)
    com0 = rbd.com(q0)
    return dict(x0=np.concatenate([q0, np.zeros(nv)]), ee_frame="l_hand", ee_offset=np.zeros(3),
                ee_target=ATLAS_TARGET if target is None else np.asarray(target, float),
                W_ee=1.0, W_ee_terminal=1e4, Q=np.r_[np.full(nv, 1e-1), np.full(nv, 1e-1)],
                Q_terminal=np.r_[np.zeros(nv), np.full(nv, 10.0)], R=np.full(nv, 1e-3),
                com_target=com0, W_com=np.array([100.0, 100.0, 0.0]), W_com_terminal=np.array([1e3, 1e3, 0.0]))


def ee_positions(model, X, ee_frame, ee_offset):
    """tool-point positions (N+1, 3) along a trajectory"""
    rbd = RBD(model)
    body, tool = ee_body_and_offset(model, ee_frame, ee_offset)
    names = [j["name"] for j in model.joints if j["body"] == body]
    return rbd.end_effector_pose(np.ascontiguousarray(X[:, :model.nq]), names, tool)[:, 0, :3]


def max_limit_violation(model, X, U):
    """max over the trajectory of the joint position, velocity and torque limit violations (≥ 0)"""
    q, qd = X[:, :model.nq], X[:, model.nq:]
    with np.errstate(invalid="ignore"):
        v = [np.max(model.lower - q), np.max(q - model.upper), np.max(np.abs(qd) - model.velocity_limit),
             np.max(np.abs(U) - model.effort_limit)]
    return float(max(0.0, *[x for x in v if np.isfinite(x)]))


def run(task="reach", robot=None, horizon=None, dt=None, integrator="rk4", target=None, threads=None,
        dtype="float64", ddp=False, max_iterations=200, out="rbdkit_demo", png=True, stream=None):
    """Solve a built-in task, print progress and a summary, write demo.png and demo.json
    into `out` (None: write nothing). Returns the record (a dict)."""
    if task not in TASKS:
        raise ValueError(f"task: unknown task {task!r}; expected one of {', '.join(TASKS)}")
    if task == "atlas_reach":
        if robot not in (None, "atlas"):
            raise ValueError("robot: the atlas_reach task runs on the bundled atlas; leave --robot out")
        model = load_robot("atlas")
        setup = atlas_task(model, target)
        horizon, dt = horizon or 50, dt or 0.03
    else:
        model = load_robot(robot or "iiwa")
        setup = reach_task(model, target)
        horizon, dt = horizon or 100, dt or 0.01
    if target is not None:
        t = np.asarray(target, dtype=float)
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise ValueError(f"target: expected three finite numbers x,y,z (m), got {target!r}")
    handle = None
    if threads is not None or dtype != "float64":
        from ._handle import Handle
        algos = ["integrator_gradient"] + (["plant_step_hessian"] if ddp else [])
        handle = Handle(model, algorithms=algos, dtype=dtype, threads=threads)

    stream = sys.stdout if stream is None else stream
    p = lambda *a: print(*a, file=stream, flush=True)
    p(f"rbdkit demo — {task}: {model.name} (nq={model.nq}, nv={model.nv}), {horizon} knots × dt {dt} s, "
      f"{integrator}, {'DDP' if ddp else 'iLQR'}")
    p(f"  target {np.round(setup['ee_target'], 4).tolist()} m"
      + (f", CoM held at {np.round(setup['com_target'][:2], 3).tolist()} (x, y)" if "com_target" in setup else "")
      + ("" if handle is None else f"; derivatives by rbdkit.Handle(dtype={dtype}, threads={handle.threads})"))
    p(f"  {'iter':>4s} {'cost':>12s} {'violation':>10s} {'step':>7s} {'reg':>8s} {'mu':>8s} {'|Qu|':>9s} "
      f"{'time':>9s}")

    def progress(r):
        p(f"  {r['iteration']:4d} {r['cost']:12.6g} {r['violation']:10.3g} {r['step']:7.4f} {r['reg']:8.1e} "
          f"{r['mu']:8.1e} {r['grad_norm']:9.2e} {r['time'] * 1e3:7.2f}ms")

    res = solve_trajectory(model, setup.pop("x0"), horizon, dt, integrator, ddp=ddp, max_iterations=max_iterations,
                           handle=handle, callback=progress, **setup)
    ee_frame, ee_off = setup.get("ee_frame"), setup.get("ee_offset")
    P = ee_positions(model, res.X, ee_frame, ee_off)
    err = float(np.linalg.norm(P[-1] - setup["ee_target"]))
    viol = max_limit_violation(model, res.X, res.U)
    it_times = [r["time"] for r in res.log[1:]]
    summary = dict(status=res.status, converged=bool(res.converged), iterations=res.iterations,
                   final_ee_error_m=err, max_limit_violation=viol, final_cost=res.cost,
                   total_time_s=res.time, time_per_iteration_s=float(np.mean(it_times)) if it_times else 0.0,
                   derivatives_time_s=res.derivatives_time,
                   derivatives_time_per_knot_s=res.derivatives_time / max(res.derivative_knots, 1),
                   final_speed_max=float(np.abs(res.X[-1, model.nq:]).max()))
    p("summary")
    p(f"  status {res.status} after {res.iterations} iterations; final end-effector error "
      f"{err * 1e3:.3f} mm; max limit violation {viol:.3g}")
    p(f"  time {res.time:.3f} s: {summary['time_per_iteration_s'] * 1e3:.2f} ms per iteration, derivatives "
      f"{summary['derivatives_time_per_knot_s'] * 1e6:.2f} µs per knot point "
      f"({res.derivative_knots} knot points differentiated)")
    p(f"  torques within ±{np.max(model.effort_limit):g}: peak |u| {np.abs(res.U).max():.2f} N·m; "
      f"peak |qd| {np.abs(res.X[:, model.nq:]).max():.3f} rad/s (limit {np.max(model.velocity_limit):g})")
    record = dict(task=task, robot=model.name, nq=model.nq, nv=model.nv, horizon=horizon, dt=dt,
                  integrator=integrator, ddp=bool(ddp), dtype=dtype, threads=None if handle is None else handle.threads,
                  derivatives="rbdkit.Handle (Python)" if handle is not None else "rbd::Handle (C++)",
                  target=np.asarray(setup["ee_target"]).tolist(), machine=platform.platform(),
                  summary=summary, log=res.log, X=res.X.tolist(), U=res.U.tolist(), ee_path=P.tolist())
    if out is not None:
        os.makedirs(out, exist_ok=True)
        with open(os.path.join(out, "demo.json"), "w") as f:
            json.dump(record, f, indent=1)
        written = [os.path.join(out, "demo.json")]
        if png:
            written.append(figure(model, res, P, setup, dt, os.path.join(out, "demo.png")))
        p("wrote " + ", ".join(written))
    return record


def figure(model, res, P, setup, dt, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    N = res.U.shape[0]
    t = np.arange(N + 1) * dt
    fig = plt.figure(figsize=(13, 9))
    ax = fig.add_subplot(2, 2, 1)
    ax.plot(t, res.X[:, :model.nq])
    ax.set(title="joint positions", xlabel="t (s)", ylabel="q (rad)")
    ax = fig.add_subplot(2, 2, 2)
    ax.step(t[:-1], res.U, where="post")
    lim = np.max(model.effort_limit)
    if np.isfinite(lim) and lim < 5 * np.abs(res.U).max():
        for s in (-1, 1):
            ax.axhline(s * lim, color="k", ls="--", lw=0.8)
    ax.set(title="joint torques", xlabel="t (s)", ylabel="u (N·m)")
    ax = fig.add_subplot(2, 2, 3, projection="3d")
    ax.plot(P[:, 0], P[:, 1], P[:, 2], label="end effector")
    ax.scatter(*P[0], color="g", label="start")
    ax.scatter(*setup["ee_target"], color="r", marker="x", s=60, label="target")
    ax.set(title="end-effector path", xlabel="x (m)", ylabel="y (m)", zlabel="z (m)")
    ax.legend()
    ax = fig.add_subplot(2, 2, 4)
    it = [r["iteration"] for r in res.log]
    ax.semilogy(it, [r["cost"] for r in res.log], "o-", ms=3)
    ax.set(title="cost per iteration", xlabel="iteration", ylabel="cost (without barriers)")
    fig.suptitle(f"rbdkit demo: {model.name}, {N} knots, status {res.status}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def add_arguments(parser):
    parser.add_argument("--task", default="reach", choices=TASKS, help="built-in task (default: reach)")
    parser.add_argument("--robot", help="reach: bundled robot name or URDF path (default: iiwa)")
    parser.add_argument("--horizon", type=int, help="knot points (default: 100 reach, 50 atlas_reach)")
    parser.add_argument("--dt", type=float, help="time step in s (default: 0.01 reach, 0.03 atlas_reach)")
    parser.add_argument("--integrator", default="rk4", help="euler, semi_implicit_euler, midpoint, rk4 (default), "
                                                            "trapezoidal, constant_acceleration")
    parser.add_argument("--target", help="end-effector target x,y,z in m (world frame)")
    parser.add_argument("--threads", type=int, help="derivatives through an rbdkit.Handle with this many threads")
    parser.add_argument("--dtype", default="float64", choices=("float64", "float32"),
                        help="precision of the derivatives (float32: through an rbdkit.Handle)")
    parser.add_argument("--ddp", action="store_true", help="full DDP (step Hessians) instead of iLQR")
    parser.add_argument("--max-iterations", type=int, default=200)
    parser.add_argument("--out", default="rbdkit_demo", help="output folder (default ./rbdkit_demo)")
    parser.add_argument("--no-png", action="store_true", help="skip the figure")


def main_from_args(args):
    target = None
    if args.target is not None:
        try:
            target = [float(v) for v in args.target.split(",")]
        except ValueError:
            raise ValueError(f"--target: expected x,y,z in metres, got {args.target!r}") from None
        if len(target) != 3:
            raise ValueError(f"--target: expected x,y,z in metres, got {args.target!r}")
    if args.horizon is not None and args.horizon < 1:
        raise ValueError(f"--horizon: expected a positive number of knot points, got {args.horizon}")
    if args.dt is not None and not args.dt > 0:
        raise ValueError(f"--dt: expected a positive time step, got {args.dt}")
    rec = run(task=args.task, robot=args.robot, horizon=args.horizon, dt=args.dt, integrator=args.integrator,
              target=target, threads=args.threads, dtype=args.dtype, ddp=args.ddp,
              max_iterations=args.max_iterations, out=args.out, png=not args.no_png)
    return 0 if rec["summary"]["converged"] else 1
