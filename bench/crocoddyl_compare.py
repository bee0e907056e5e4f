#!/usr/bin/env python3
"""rbdkit's iLQR against Crocoddyl's FDDP on the same iiwa14 reach (the task of
`rbdkit demo`): same horizon, dt, integrator, start, target, tool point and
cost terms and weights; time per iteration and to convergence side by side.

    python bench/crocoddyl_compare.py [--horizon 100] [--dt 0.01] [--out build/croc-compare] [--reps 3]

Crocoddyl (PyPI `crocoddyl`) is installed into its own virtual environment,
build/croc-venv (made here on the first run), because the libpinocchio its
wheel pulls in may differ from the `pin` the tests use; this script re-runs
itself inside that environment for the Crocoddyl half (--inner) and passes
the numbers back as JSON. rbdkit runs in the calling Python.

What matches and what cannot:
- cost: Σ_k ℓ(x_k, u_k)·dt + ℓ_N(x_N) with ℓ = ½‖x ⊖ x_ref‖²_Q + ½‖u − g(q0)‖²_R +
  ½ W‖p_tool − p*‖²; the same diagonal weights (Crocoddyl: ResidualModelState,
  ResidualModelControl, ResidualModelFrameTranslation with weighted-quadratic
  activations). Crocoddyl's RK4 action integrates the running cost over the
  four stages; rbdkit evaluates it at the knot: the optima differ slightly.
  Both are also run with the semi-implicit (symplectic) Euler step, where the
  two costs are the same.
- limits: the task's limits are inactive at its optimum; FDDP has no state
  limits, so rbdkit runs once without barriers (same problem) and once with
  its default joint position, velocity and torque barriers (its demo).
- stopping: each solver's own test (Crocoddyl: th_stop 1e-9 on its stopping
  criterion; rbdkit: relative cost decrease 1e-8 or ‖Qu‖∞ 1e-7 at the last μ).
- threads: both single-threaded (Crocoddyl's problem nthreads = 1).
"""

import argparse
import json
import os
import subprocess
import sys
import time
import venv

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
URDF = os.path.join(ROOT, "robots", "iiwa.urdf")

# the demo's task (python/rbdkit/demo.py): start, target, tool point, weights
Q0 = [0.0, 0.6, 0.0, -1.2, 0.0, 0.9, 0.0]
TARGET = [0.4, 0.4, 0.8]
TOOL = [0.0, 0.0, 0.05]
W_EE, W_EE_T = 1.0, 1e5
Q_RUN = [1e-2] * 7 + [1e-1] * 7
Q_TERM = [0.0] * 7 + [10.0] * 7
R_RUN = [1e-4] * 7
SCHEMES = {"rk4": "rk4", "semi_implicit_euler": "euler"}  # rbdkit name -> Crocoddyl integrated action


# ---------------------------------------------------------------- Crocoddyl (inside build/croc-venv)
def crocoddyl_solve(horizon, dt, scheme, reps):
    import crocoddyl
    import pinocchio as pin

    model = pin.buildModelFromUrdf(URDF)
    link7 = model.getFrameId("iiwa_link_7")
    placement = pin.SE3(np.eye(3), np.array(TOOL))
    try:
        frame = pin.Frame("tool", model.frames[link7].parentJoint, link7, placement, pin.FrameType.OP_FRAME)
    except TypeError:
        frame = pin.Frame("tool", model.frames[link7].parentJoint, placement, pin.FrameType.OP_FRAME)
    tool = model.addFrame(frame)
    data = model.createData()
    q0 = np.array(Q0)
    x0 = np.r_[q0, np.zeros(model.nv)]
    u_ref = pin.computeGeneralizedGravity(model, data, q0)
    state = crocoddyl.StateMultibody(model)
    act = crocoddyl.ActuationModelFull(state)

    def costs(terminal):
        c = crocoddyl.CostModelSum(state, act.nu)
        ee = crocoddyl.ResidualModelFrameTranslation(state, tool, np.array(TARGET), act.nu)
        c.addCost("ee", crocoddyl.CostModelResidual(
            state, crocoddyl.ActivationModelWeightedQuad(np.full(3, W_EE_T if terminal else W_EE)), ee), 1.0)
        xr = crocoddyl.ResidualModelState(state, x0, act.nu)
        c.addCost("x", crocoddyl.CostModelResidual(
            state, crocoddyl.ActivationModelWeightedQuad(np.array(Q_TERM if terminal else Q_RUN)), xr), 1.0)
        if not terminal:
            ur = crocoddyl.ResidualModelControl(state, u_ref)
            c.addCost("u", crocoddyl.CostModelResidual(
                state, crocoddyl.ActivationModelWeightedQuad(np.array(R_RUN)), ur), 1.0)
        return c

    def integrated(dam, h):
        if SCHEMES[scheme] == "rk4":
            return crocoddyl.IntegratedActionModelRK(dam, crocoddyl.RKType.four, h)
        return crocoddyl.IntegratedActionModelEuler(dam, h)

    run = integrated(crocoddyl.DifferentialActionModelFreeFwdDynamics(state, act, costs(False)), dt)
    term = integrated(crocoddyl.DifferentialActionModelFreeFwdDynamics(state, act, costs(True)), 0.0)
    problem = crocoddyl.ShootingProblem(x0, [run] * horizon, term)
    try:
        problem.nthreads = 1
    except AttributeError:
        pass
    best = None
    for _ in range(reps):
        solver = crocoddyl.SolverFDDP(problem)
        solver.th_stop = 1e-9
        us = [u_ref.copy() for _ in range(horizon)]
        xs = problem.rollout(us)
        log = []

        class Log(crocoddyl.CallbackAbstract):
            def __init__(self):
                crocoddyl.CallbackAbstract.__init__(self)

            def __call__(self, s):
                log.append(dict(iteration=s.iter + 1, cost=s.cost, step=s.stepLength, time=time.perf_counter()))
        cb = Log()  # kept alive while the solver holds it
        solver.setCallbacks([cb])
        t0 = time.perf_counter()
        solver.solve(xs, us, 500, True)
        total = time.perf_counter() - t0
        it = max(solver.iter, 1)
        # the per-iteration times without the Python callback's own cost: solve again without it
        solver2 = crocoddyl.SolverFDDP(problem)
        solver2.th_stop = 1e-9
        t0 = time.perf_counter()
        solver2.solve(xs, us, 500, True)
        total_nocb = time.perf_counter() - t0
        pdata = model.createData()
        pin.forwardKinematics(model, pdata, np.array(solver2.xs[-1])[:7])
        pin.updateFramePlacements(model, pdata)
        err = float(np.linalg.norm(pdata.oMf[tool].translation - np.array(TARGET)))
        r = dict(iterations=int(solver2.iter), time_s=total_nocb, time_per_iteration_s=total_nocb / max(solver2.iter, 1),
                 cost=float(solver2.cost), ee_error_m=err, U=np.array(solver2.us).tolist(),
                 log=[dict(iteration=l["iteration"], cost=l["cost"], step=l["step"]) for l in log],
                 crocoddyl=crocoddyl.__version__ if hasattr(crocoddyl, "__version__") else "?",
                 pinocchio=pin.__version__)
        if best is None or r["time_s"] < best["time_s"]:
            best = r
    return best


# ---------------------------------------------------------------- rbdkit (the calling Python)
def rbdkit_solve(horizon, dt, scheme, limits, reps):
    import rbdkit
    model = rbdkit.robots.load("iiwa")
    x0 = np.r_[Q0, np.zeros(7)]
    kw = dict(ee_target=TARGET, ee_offset=TOOL, W_ee=W_EE, W_ee_terminal=W_EE_T, Q=Q_RUN, Q_terminal=Q_TERM,
              R=R_RUN, limits=limits)
    best = None
    for _ in range(reps):
        res = rbdkit.solve_trajectory(model, x0, horizon, dt, scheme, **kw)
        if best is None or res.time < best.time:
            best = res
    rbd = rbdkit.RBD(model)
    p = rbd.end_effector_pose(best.X[-1, :7], None, np.array(TOOL))[0, :3]
    it = max(best.iterations, 1)
    return dict(iterations=best.iterations, status=best.status, time_s=best.time,
                time_per_iteration_s=float(np.mean([r["time"] for r in best.log[1:]])) if best.log[1:] else 0.0,
                derivatives_per_knot_s=best.derivatives_time / max(best.derivative_knots, 1),
                cost=best.cost, ee_error_m=float(np.linalg.norm(p - np.array(TARGET))),
                log=[dict(iteration=r["iteration"], cost=r["cost"], step=r["step"]) for r in best.log])


def rbdkit_cost_of(horizon, dt, scheme, U):
    """rbdkit's objective (no barriers) of a control sequence (Crocoddyl's), rolled out by rbdkit"""
    import rbdkit
    model = rbdkit.robots.load("iiwa")
    res = rbdkit.solve_trajectory(model, np.r_[Q0, np.zeros(7)], horizon, dt, scheme, ee_target=TARGET,
                                  ee_offset=TOOL, W_ee=W_EE, W_ee_terminal=W_EE_T, Q=Q_RUN, Q_terminal=Q_TERM,
                                  R=R_RUN, limits=(), U_init=np.array(U), max_iterations=0)
    return res.log[0]["cost"]


def croc_venv():
    path = os.path.join(ROOT, "build", "croc-venv")
    py = os.path.join(path, "bin", "python")
    if not os.path.isfile(py):
        print(f"making {path} (crocoddyl from PyPI) ...", flush=True)
        venv.create(path, with_pip=True)
    ok = subprocess.run([py, "-c", "import crocoddyl"], capture_output=True).returncode == 0
    if not ok:
        subprocess.run([py, "-m", "pip", "install", "-q", "crocoddyl", "numpy"], check=True)
    return py


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--horizon", type=int, default=100)
    ap.add_argument("--dt", type=float, default=0.01)
    ap.add_argument("--reps", type=int, default=3, help="repetitions; the fastest is reported")
    ap.add_argument("--out", default=os.path.join(ROOT, "build", "croc-compare"))
    ap.add_argument("--inner", help=argparse.SUPPRESS)  # scheme: run the Crocoddyl half here, JSON on stdout
    a = ap.parse_args()
    if a.inner:
        print(json.dumps(crocoddyl_solve(a.horizon, a.dt, a.inner, a.reps)))
        return 0
    py = croc_venv()
    rows, record = [], dict(horizon=a.horizon, dt=a.dt, task="iiwa14 reach (rbdkit demo)", results={})
    for scheme in SCHEMES:
        env = dict(os.environ, OMP_NUM_THREADS="1")
        out = subprocess.run([py, os.path.abspath(__file__), "--inner", scheme, "--horizon", str(a.horizon),
                              "--dt", str(a.dt), "--reps", str(a.reps)], capture_output=True, text=True, env=env)
        if out.returncode != 0:
            print(out.stderr, file=sys.stderr)
            return out.returncode
        croc = json.loads(out.stdout.strip().splitlines()[-1])
        croc["cost_in_rbdkit_terms"] = rbdkit_cost_of(a.horizon, a.dt, scheme, croc.pop("U"))
        ours = rbdkit_solve(a.horizon, a.dt, scheme, (), a.reps)
        ours_lim = rbdkit_solve(a.horizon, a.dt, scheme, ("position", "velocity", "torque"), a.reps)
        record["results"][scheme] = dict(crocoddyl_fddp=croc, rbdkit_ilqr=ours, rbdkit_ilqr_barriers=ours_lim)
        for name, r in (("Crocoddyl FDDP", croc), ("rbdkit iLQR", ours), ("rbdkit iLQR + limits", ours_lim)):
            rows.append((scheme, name, r["iterations"], r["time_per_iteration_s"] * 1e3, r["time_s"] * 1e3,
                         r.get("cost_in_rbdkit_terms", r["cost"]), r["ee_error_m"] * 1e3))
    print(f"\niiwa14 reach, N = {a.horizon}, dt = {a.dt} s, one thread, best of {a.reps}")
    print(f"{'integrator':20s} {'solver':22s} {'iters':>5s} {'ms/iter':>8s} {'ms total':>9s} {'cost':>10s} "
          f"{'EE err mm':>9s}")
    for s, n, it, per, tot, c, e in rows:
        print(f"{s:20s} {n:22s} {it:5d} {per:8.3f} {tot:9.2f} {c:10.6f} {e:9.4f}")
    print("cost: rbdkit's objective of each solution (Crocoddyl's controls rolled out by rbdkit; barriers excluded)")
    os.makedirs(a.out, exist_ok=True)
    record["table"] = [dict(integrator=s, solver=n, iterations=it, ms_per_iteration=per, ms_total=tot, cost=c,
                            ee_error_mm=e) for s, n, it, per, tot, c, e in rows]
    path = os.path.join(a.out, "crocoddyl_compare.json")
    with open(path, "w") as f:
        json.dump(record, f, indent=1)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
