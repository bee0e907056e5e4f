"""The trajectory optimiser (rbdkit.solve_trajectory) and `rbdkit demo`.

- the default task (iiwa14 reach, 100 knots, rk4) converges to within 1 mm of
  its target with every joint position, velocity and torque limit respected;
- its controls, replayed through an independent rollout (Pinocchio's ABA,
  RK4 at dt/10, zero-order hold) reach the same end state (q within 1e-5 rad,
  qd within 1e-4 rad/s, the tool point within 1e-5 m of the solver's: the
  solver's own rk4 truncation at dt = 0.01 s is ~2e-6 rad), and within 1 mm of the target;
- the derivatives are the handle's: a counting rbdkit.Handle sees one batched
  plant_step_gradient of the N knots per differentiated iterate and the
  result is the C++ path's bit for bit; no finite differences anywhere;
- DDP (step Hessians), every integrator scheme, warm starts, tighter limits,
  the Atlas whole-body task, the CLI's figure and record, and bad input.
The Riccati gains against the brute-force LQR optimum: tests/cpp/test_solver.cpp.
"""

import json
import warnings

import numpy as np
import pytest

import rbdkit
from rbdkit import cli, demo

pin = pytest.importorskip("pinocchio")


@pytest.fixture(scope="module")
def iiwa():
    return rbdkit.robots.load("iiwa")


def reach(model, **kw):
    setup = demo.reach_task(model)
    x0 = setup.pop("x0")
    setup.update(kw)
    horizon, dt = setup.pop("horizon", 100), setup.pop("dt", 0.01)
    integrator = setup.pop("integrator_type", "rk4")
    return setup, rbdkit.solve_trajectory(model, x0, horizon, dt, integrator, **setup)


@pytest.fixture(scope="module")
def default_solution(iiwa):
    return reach(iiwa)


@pytest.fixture(scope="module")
def engine_solution(iiwa):
    # derivatives from the batch engine (an rbdkit.Handle's, in C++). The
    # default's come from the per-sample functions: equal to rounding (the
    # engine has its own sin and cos), and a barrier-schedule decision on the
    # way may flip on that rounding, so the engine runs are compared with this one
    return reach(iiwa, handle=rbdkit.Handle(iiwa, algorithms=["integrator_gradient"], threads=1))[1]


def test_engine_and_default_derivatives_solve_alike(default_solution, engine_solution):
    _, ref = default_solution
    res = engine_solution
    assert res.converged and ref.converged
    np.testing.assert_allclose(res.U, ref.U, rtol=0, atol=1e-9 * np.abs(ref.U).max())
    # the same iterates up to at most one extra step where the stall test flips on rounding
    assert abs(res.iterations - ref.iterations) <= 1


def test_default_task_converges_within_limits(iiwa, default_solution):
    setup, res = default_solution
    assert res.converged, res.status
    P = demo.ee_positions(iiwa, res.X, None, setup["ee_offset"])
    assert np.linalg.norm(P[-1] - setup["ee_target"]) < 1e-3
    # every limit respected along the whole trajectory, checked here independently of the solver
    q, qd = res.X[:, :7], res.X[:, 7:]
    assert np.all(q > iiwa.lower) and np.all(q < iiwa.upper)
    assert np.all(np.abs(qd) < iiwa.velocity_limit)
    assert np.all(np.abs(res.U) < iiwa.effort_limit)
    assert demo.max_limit_violation(iiwa, res.X, res.U) == 0.0
    assert res.violation == 0.0
    # from rest, and at rest again at the end
    assert np.all(res.X[0, 7:] == 0) and np.abs(res.X[-1, 7:]).max() < 0.05
    # the log: the initial rollout then one record per iteration, the merit non-increasing at a fixed mu
    assert len(res.log) == res.iterations + 1
    for a, b in zip(res.log, res.log[1:]):
        if a["mu"] == b["mu"]:
            assert b["merit"] <= a["merit"] + 1e-12
    assert res.log[-1]["mu"] == pytest.approx(1e-7)


def rk4_pinocchio(pm, pd, q, v, u, h):
    f = lambda q, v: pin.aba(pm, pd, q, v, u)
    k1q, k1v = v, f(q, v)
    k2q, k2v = v + h / 2 * k1v, f(pin.integrate(pm, q, h / 2 * k1q), v + h / 2 * k1v)
    k3q, k3v = v + h / 2 * k2v, f(pin.integrate(pm, q, h / 2 * k2q), v + h / 2 * k2v)
    k4q, k4v = v + h * k3v, f(pin.integrate(pm, q, h * k3q), v + h * k3v)
    return (pin.integrate(pm, q, h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)),
            v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v))


def test_replay_through_pinocchio_reaches_the_same_end_state(iiwa, default_solution):
    setup, res = default_solution
    pm = pin.buildModelFromUrdf(rbdkit.robots.path("iiwa"))
    assert [n for n in pm.names[1:]] == iiwa.joint_names
    pd = pm.createData()
    dt, sub = 0.01, 10
    q, v = res.X[0, :7].copy(), res.X[0, 7:].copy()
    for k in range(res.U.shape[0]):
        for _ in range(sub):  # zero-order hold on u, RK4 at dt/10
            q, v = rk4_pinocchio(pm, pd, q, v, res.U[k], dt / sub)
    # rk4 at dt against rk4 at dt/10: the O(dt⁴) truncation of the solver's own steps (~2e-6 rad here)
    assert np.abs(q - res.X[-1, :7]).max() < 1e-5
    assert np.abs(v - res.X[-1, 7:]).max() < 1e-4
    # the tool point of the replay against the solver's (Pinocchio kinematics)
    pin.forwardKinematics(pm, pd, q)
    M = pd.oMi[7]
    p = M.translation + M.rotation @ setup["ee_offset"]
    P = demo.ee_positions(iiwa, res.X, None, setup["ee_offset"])
    assert np.linalg.norm(p - P[-1]) < 1e-5
    assert np.linalg.norm(p - setup["ee_target"]) < 1e-3


class CountingHandle:
    """an rbdkit.Handle that records every derivative call the solver makes"""

    def __init__(self, model, **kw):
        self.h = rbdkit.Handle(model, **kw)
        self.model, self.calls = model, []

    def has(self, op):
        return self.h.has(op)

    def plant_step_gradient(self, X, U, dt, integrator_type, **kw):
        self.calls.append(("plant_step_gradient", X.shape, U.shape))
        return self.h.plant_step_gradient(X, U, dt, integrator_type, **kw)

    def plant_step_hessian(self, X, U, dt, integrator_type, **kw):
        self.calls.append(("plant_step_hessian", X.shape, U.shape))
        return self.h.plant_step_hessian(X, U, dt, integrator_type, **kw)


def test_derivatives_come_from_the_handle(iiwa, engine_solution):
    ref = engine_solution
    h = CountingHandle(iiwa, algorithms=["integrator_gradient"])
    _, res = reach(iiwa, handle=h)
    N = 100
    grads = [c for c in h.calls if c[0] == "plant_step_gradient"]
    assert len(grads) == len(h.calls) >= 1
    # one batched call of all N knots per differentiated iterate, nothing else
    assert all(c[1] == (N, 14) and c[2] == (N, 7) for c in grads)
    assert res.derivative_knots == N * len(grads) == ref.derivative_knots
    assert len(grads) <= res.iterations
    # the same derivatives as the C++ handle's batch engine: the same iterates
    np.testing.assert_allclose(res.U, ref.U, rtol=0, atol=1e-9 * np.abs(ref.U).max())
    assert res.iterations == ref.iterations


def test_an_rbdkit_handle_stays_in_cpp(iiwa, engine_solution):
    # an rbdkit.Handle (float64) gives its threads to the solver's C++ handle:
    # no derivative goes through Python, and the iterates are the C++ handle's
    # (its engine is bit-identical whatever the thread count)
    ref = engine_solution
    h = rbdkit.Handle(iiwa, algorithms=["integrator_gradient"], threads=2)

    def boom(*a, **k):
        raise AssertionError("the solver called the Python handle")

    h.plant_step_gradient = boom
    _, res = reach(iiwa, handle=h)
    np.testing.assert_allclose(res.U, ref.U, rtol=0, atol=1e-9 * np.abs(ref.U).max())
    assert res.iterations == ref.iterations and res.derivative_knots == ref.derivative_knots


def test_the_handle_derivatives_are_used(iiwa):
    """a handle returning wrong derivatives changes what the solver does"""
    class Wrong(CountingHandle):
        def plant_step_gradient(self, X, U, dt, integrator_type, **kw):
            AB = super().plant_step_gradient(X, U, dt, integrator_type, **kw)
            AB[:, :, 14:] *= -1  # flip B
            return AB
    _, res = reach(iiwa, handle=Wrong(iiwa, algorithms=["integrator_gradient"]), max_iterations=5)
    # the flipped model predicts a decrease the rollout never shows: every step is rejected
    assert all(r["step"] == 0 for r in res.log[1:])


def test_float32_handle_still_converges(iiwa):
    h = rbdkit.Handle(iiwa, algorithms=["integrator_gradient"], dtype="float32", threads=1)
    setup, res = reach(iiwa, handle=h, horizon=50, dt=0.02)
    P = demo.ee_positions(iiwa, res.X, None, setup["ee_offset"])
    assert np.linalg.norm(P[-1] - setup["ee_target"]) < 1e-3


def test_ddp_converges_and_calls_the_step_hessian(iiwa):
    h = CountingHandle(iiwa, algorithms=["integrator_gradient", "plant_step_hessian"])
    setup, res = reach(iiwa, horizon=30, dt=0.03, ddp=True, handle=h)
    assert res.converged, res.status
    hess = [c for c in h.calls if c[0] == "plant_step_hessian"]
    grads = [c for c in h.calls if c[0] == "plant_step_gradient"]
    assert len(hess) == len(grads) >= 1 and all(c[1] == (30, 14) for c in hess)
    P = demo.ee_positions(iiwa, res.X, None, setup["ee_offset"])
    assert np.linalg.norm(P[-1] - setup["ee_target"]) < 1e-3
    # the C++ path (plant_step_hessian of rbd::Handle) gives the same
    _, res2 = reach(iiwa, horizon=30, dt=0.03, ddp=True)
    np.testing.assert_allclose(res2.U, res.U, atol=1e-9)


@pytest.mark.parametrize("scheme", ["euler", "semi_implicit_euler", "midpoint", "trapezoidal",
                                    "constant_acceleration"])
def test_every_integrator(iiwa, scheme):
    setup, res = reach(iiwa, horizon=40, dt=0.025, integrator_type=scheme)
    P = demo.ee_positions(iiwa, res.X, None, setup["ee_offset"])
    assert np.linalg.norm(P[-1] - setup["ee_target"]) < 1e-3, res.status
    # the trajectory is the scheme's own rollout
    rbd = rbdkit.RBD(iiwa)
    Xn = rbd.plant_step(res.X[:-1], res.U, 0.025, scheme)
    np.testing.assert_allclose(Xn, res.X[1:], atol=1e-12)


def test_tight_limits_are_respected(iiwa):
    """torque and velocity limits that bind: the iterates stay inside them"""
    u_lim, v_lim = np.full(7, 80.0), np.full(7, 1.2)
    setup, res = reach(iiwa, horizon=60, dt=0.02, u_limit=u_lim, v_limit=v_lim)
    assert res.converged, res.status
    assert np.abs(res.U).max() < 80 and np.abs(res.X[:, 7:]).max() < 1.2
    assert np.abs(res.X[:, 7:]).max() > 0.8 * 1.2 or np.abs(res.U).max() > 0.8 * 80  # a limit is active
    P = demo.ee_positions(iiwa, res.X, None, setup["ee_offset"])
    assert np.linalg.norm(P[-1] - setup["ee_target"]) < 2e-3


def test_warm_start(iiwa, default_solution):
    setup, ref = default_solution
    x0 = ref.X[0]
    kw = {k: v for k, v in setup.items()}
    # the optimum warm-started (controls, states, gains and the final barrier parameter) is already converged
    res = rbdkit.solve_trajectory(iiwa, x0, 100, 0.01, "rk4", U_init=ref.U, X_init=ref.X, K_init=ref.K,
                                  mu_init=ref.mu, **kw)
    np.testing.assert_allclose(res.X[0], x0)
    assert res.converged and res.iterations <= 3
    assert res.log[0]["cost"] == pytest.approx(ref.cost, rel=1e-9)
    # MPC: shift by 5 knots from a perturbed state, closed-loop first rollout
    x1 = ref.X[5] + np.r_[np.zeros(7), 0.05 * np.ones(7)]
    U = np.r_[ref.U[5:], np.repeat(ref.U[-1:], 5, axis=0)]
    X = np.r_[ref.X[5:], np.repeat(ref.X[-1:], 5, axis=0)]
    K = np.r_[ref.K[5:], np.repeat(ref.K[-1:], 5, axis=0)]
    cold = rbdkit.solve_trajectory(iiwa, x1, 100, 0.01, "rk4", **kw)
    warm = rbdkit.solve_trajectory(iiwa, x1, 100, 0.01, "rk4", U_init=U, X_init=X, K_init=K, mu_init=1e-5, **kw)
    assert warm.converged and warm.iterations < cold.iterations
    assert warm.cost == pytest.approx(cold.cost, rel=1e-3)


def test_atlas_whole_body_reach_with_com_cost(tmp_path):
    with open(tmp_path / "log", "w") as log:
        rec = demo.run(task="atlas_reach", out=None, stream=log)
    s = rec["summary"]
    assert s["converged"], s["status"]
    assert s["final_ee_error_m"] < 1e-3
    assert s["max_limit_violation"] == 0.0
    model = demo.load_robot("atlas")
    X = np.array(rec["X"])
    com = rbdkit.RBD(model).com(X[:, :model.nq])
    assert np.abs(com[:, :2] - com[0, :2]).max() < 0.02  # the CoM stays over the pelvis


def test_cli_demo_writes_figure_and_record(tmp_path, capsys):
    out = tmp_path / "o"
    rc = cli.main(["demo", "--horizon", "40", "--dt", "0.025", "--out", str(out)])
    text = capsys.readouterr().out
    assert rc == 0
    assert "final end-effector error" in text and "per knot point" in text
    assert (out / "demo.png").stat().st_size > 10000
    rec = json.loads((out / "demo.json").read_text())
    assert rec["summary"]["final_ee_error_m"] < 1e-3 and rec["summary"]["converged"]
    assert len(rec["log"]) == rec["summary"]["iterations"] + 1
    assert {"cost", "violation", "step", "time"} <= set(rec["log"][1])
    assert np.array(rec["U"]).shape == (40, 7)


def test_cli_demo_threads_and_dtype(tmp_path, capsys):
    rc = cli.main(["demo", "--horizon", "30", "--dt", "0.03", "--threads", "1", "--dtype", "float32",
                   "--integrator", "midpoint", "--no-png", "--out", str(tmp_path)])
    assert rc == 0
    rec = json.loads((tmp_path / "demo.json").read_text())
    assert rec["dtype"] == "float32" and rec["threads"] == 1 and rec["integrator"] == "midpoint"


# ---- bad input

@pytest.mark.parametrize("argv, needle", [
    (["--task", "juggle"], "invalid choice"),
    (["--robot", "r2d2"], "robot: unknown robot 'r2d2'"),
    (["--horizon", "-5"], "--horizon: expected a positive number"),
    (["--dt", "0"], "--dt: expected a positive"),
    (["--target", "1,2"], "--target: expected x,y,z"),
    (["--target", "3,0,0.5"], "out of reach"),
    (["--integrator", "leapfrog"], "integrator_type"),
    (["--dtype", "float16"], "invalid choice"),
])
def test_cli_demo_bad_arguments(tmp_path, capsys, argv, needle):
    try:
        rc = cli.main(["demo", "--out", str(tmp_path), *argv])
    except SystemExit as e:  # argparse's own errors
        rc = e.code
    err = capsys.readouterr().err
    assert rc == 2
    assert needle in err


def test_bad_input(iiwa):
    x0 = np.r_[demo.IIWA_START, np.zeros(7)]
    t = demo.IIWA_TARGET
    solve = lambda **kw: rbdkit.solve_trajectory(iiwa, **{**dict(x0=x0, horizon=10, dt=0.01, ee_target=t), **kw})
    cases = [
        (dict(horizon=-3), ValueError, "horizon: expected an integer >= 1"),
        (dict(horizon=2.5), TypeError, "horizon: expected an integer"),
        (dict(dt=-0.1), ValueError, "dt: expected a positive"),
        (dict(x0=np.zeros(13)), ValueError, "x0: expected shape (14,)"),
        (dict(x0=np.r_[np.full(7, np.nan), np.zeros(7)]), ValueError, "x0: expected finite"),
        (dict(ee_target=[1.0, 2.0]), ValueError, "ee_target: expected shape (3,)"),
        (dict(ee_target=[2.0, 0.0, 1.0]), ValueError, "ee_target: out of reach"),
        (dict(ee_frame="no_such_link"), ValueError, "ee_frame"),
        (dict(Q=np.ones(7)), ValueError, "Q: expected shape (14,)"),
        (dict(R=-1.0), ValueError, "R: expected non-negative"),
        (dict(U_init=np.zeros((9, 7))), ValueError, "U_init: expected shape (10, 7)"),
        (dict(U_init=np.zeros((10, 7)), X_init=np.zeros((10, 14))), ValueError, "X_init: expected shape (11, 14)"),
        (dict(K_init=np.zeros((10, 7, 14))), ValueError, "K_init: needs X_init"),
        (dict(U_init=np.full((10, 7), 301.0) * (np.arange(7) == 0)), ValueError, "joint limits"),  # > 300 N·m
        (dict(x0=np.r_[3.0, demo.IIWA_START[1:], np.zeros(7)]), ValueError, "joint limits"),
        (dict(integrator_type="leapfrog"), ValueError, "integrator_type"),
        (dict(limits=("position", "acceleration")), ValueError, "limits: expected a subset"),
        (dict(mu_factor=2.0), ValueError, "mu_factor"),
        (dict(tolerance=1e-3), TypeError, "unknown option 'tolerance'"),
        (dict(max_iterations=-1), ValueError, "max_iterations"),
        (dict(handle=object()), TypeError, "handle: expected an rbdkit.Handle"),
        (dict(handle=rbdkit.Handle(iiwa, algorithms=["crba"])), ValueError, "add 'integrator_gradient'"),
        (dict(handle=rbdkit.Handle(iiwa, algorithms=["integrator_gradient"]), ddp=True), ValueError,
         "add 'plant_step_hessian'"),
        (dict(callback=3), TypeError, "callback: expected a callable"),
    ]
    for kw, exc, needle in cases:
        with pytest.raises(exc) as e:
            solve(**kw)
        assert needle in str(e.value), (kw, str(e.value))
    with pytest.raises(TypeError, match="model: expected an rbdkit.Model"):
        rbdkit.solve_trajectory("iiwa", x0, 10, 0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        hyq = rbdkit.robots.load("hyq", floating_base=True)
    with pytest.raises(ValueError, match="handle: its model has nq=19"):
        rbdkit.solve_trajectory(iiwa, x0, 10, 0.01, handle=rbdkit.Handle(hyq))


def test_floating_base_state_arithmetic():
    """HyQ with a free-flyer: the solver's state differences go through
    difference/integrate (quaternions stay unit, the rollout is plant_step's)"""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        hyq = rbdkit.robots.load("hyq", floating_base=True)
    rbd = rbdkit.RBD(hyq)
    q0 = hyq.neutral()
    q0[2] = 1.0
    x0 = np.r_[q0, np.zeros(hyq.nv)]
    # the reference: the base 5 cm higher and turned by 0.1 rad about a tilted axis, so the tangent
    # cost goes through the quaternion's difference (the warm start holds x0 against gravity: at
    # x_ref = x0 the cost is zero from the start, or rounding noise)
    d = np.zeros(hyq.nv)
    d[2], d[3:6] = 0.05, 0.1 * np.array([0.6, 0.0, 0.8])
    x_ref = np.r_[rbd.integrate(q0, d), np.zeros(hyq.nv)]
    res = rbdkit.solve_trajectory(hyq, x0, 15, 0.02, "rk4", x_ref=x_ref, Q=np.r_[np.full(18, 1.0), np.full(18, 0.1)],
                                  Q_terminal=np.r_[np.full(18, 10.0), np.ones(18)], R=np.full(18, 1e-4),
                                  limits=(), max_iterations=15)
    assert res.log[-1]["cost"] < 0.5 * res.log[0]["cost"]
    quat = res.X[:, 3:7]
    np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(rbd.plant_step(res.X[:-1], res.U, 0.02, "rk4"), res.X[1:], atol=1e-12)
