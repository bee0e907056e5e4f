"""Trajectory optimisation on the plant layer: iLQR (Gauss–Newton) or full
DDP, C++ core (include/rbdkit/solver/solver.hpp).

    import rbdkit
    model = rbdkit.robots.load("iiwa")
    x0 = np.concatenate([q0, np.zeros(model.nv)])
    res = rbdkit.solve_trajectory(model, x0, horizon=100, dt=0.01, integrator_type="rk4",
                                  ee_target=[0.5, 0.2, 0.6], W_ee_terminal=1e4, R=1e-3)
    res.X (N+1, nq+nv), res.U (N, nv), res.K (N, nv, 2nv), res.log, res.status

Problem (tangent state δx = x ⊖ x̄ = [difference(q̄, q); qd - q̄d], 2nv):
    minimise Σ_{k<N} ℓ(x_k, u_k)·dt + ℓ_N(x_N) + μ·barriers,  x_{k+1} = plant_step(x_k, u_k)
    ℓ   = ½‖x ⊖ x_ref‖²_Q + ½‖u - u_ref‖²_R + ½‖p_ee - ee_target‖²_W_ee + ½‖com - com_target‖²_W_com
    ℓ_N = the same with Q_terminal, W_ee_terminal, W_com_terminal and no input term
Joint position (q_1..q_N), velocity (qd_1..qd_N) and torque (u_0..u_{N-1})
limits (the model's URDF limits unless given) enter as log barriers whose
parameter μ falls from mu_init to mu_min by mu_factor each time the
iterations stall; the iterates stay strictly inside the limits.

Each iteration: one batched plant_step_gradient over the N knots (and one
plant_step_hessian with ddp=True), batched costs and barriers, a Riccati
backward pass with Levenberg–Marquardt regularisation of Quu, a forward
rollout with a backtracking line search on the actual cost. Derivatives come
from the C++ rbd::Handle, or from `handle` (an rbdkit.Handle: its thread
count, precision and batch engine) when one is given; rollouts and costs are
always float64 in C++.
"""

import numpy as np

from . import _core
from ._checks import as_real_array, check_choice, check_scalar, check_values
from ._integrators import INTEGRATORS, check_dt
from ._model import Model, _flags

GRAVITY = -9.81
LIMITS = ("position", "velocity", "torque")
OPTIONS = ("mu_init", "mu_min", "mu_factor", "reg_init", "reg_min", "reg_max", "reg_factor", "tol_cost",
           "tol_grad", "line_search_steps")


class TrajectoryResult:
    """X (N+1, nq+nv), U (N, nv), K (N, nv, 2nv) feedback gains on x ⊖ X_k,
    k (N, nv) feedforward, log (list of dicts: iteration, cost, merit,
    violation, step, reg, mu, grad_norm, expected, actual, time,
    derivatives_time; log[0] is the initial rollout), status ('converged',
    'max_iterations', 'stalled'), converged, iterations, cost, merit,
    violation, mu, time, derivatives_time, derivative_knots."""

    def __init__(self, d):
        self.__dict__.update(d)
        self.log = list(d["log"])

    def __repr__(self):
        return (f"<TrajectoryResult {self.status}: {self.iterations} iterations, cost {self.cost:.6g}, "
                f"violation {self.violation:.3g}, {self.time:.3f} s>")


def _vector(x, n, name, allow_scalar=True, nonneg=False):
    if x is None:
        return None
    a = as_real_array(x, name)
    if a.ndim == 0 and allow_scalar:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ValueError(f"{name}: expected shape ({n},){' or a scalar' if allow_scalar else ''}, got shape {a.shape}")
    if name not in ("q_lower", "q_upper", "v_limit", "u_limit"):  # limits may be infinite
        check_values(a, name)
    if nonneg and np.any(a < 0):
        raise ValueError(f"{name}: expected non-negative weights")
    return np.ascontiguousarray(a)


INT_MAX = 2**31 - 1  # the C++ options are int


def _int(x, name, minimum):
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, np.integer)):
        raise TypeError(f"{name}: expected an integer, got {type(x).__name__}")
    if x < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {x}")
    if x > INT_MAX:
        raise ValueError(f"{name}: expected an integer of at most {INT_MAX} (the C++ option is an int), got {x}")
    return int(x)


def ee_body_and_offset(model, ee_frame=None, ee_offset=None):
    """(body index, tool point in the body frame) of a named frame (link or
    joint; default: the first leaf body) with a tool offset in that frame"""
    off = np.zeros(3) if ee_offset is None else _vector(ee_offset, 3, "ee_offset", allow_scalar=False)
    if ee_frame is None:
        if model.nb == 0:
            raise ValueError("ee_frame: the model has no joints (nq = 0), so it has no end effector")
        return int(_core.leaf_bodies(model._core)[0]), off
    if not isinstance(ee_frame, str):
        raise TypeError(f"ee_frame: expected a frame name (str), got {type(ee_frame).__name__}")
    try:
        body, _, R, p = model.frame(ee_frame)
    except ValueError as e:
        raise ValueError(f"ee_frame: {e}") from None
    if body < 0:
        raise ValueError(f"ee_frame: '{ee_frame}' is attached to the world, not to a body")
    return int(body), R @ off + p


def solve_trajectory(model, x0, horizon, dt, integrator_type="rk4", *, gravity=GRAVITY,
                     ee_target=None, ee_frame=None, ee_offset=None, W_ee=0.0, W_ee_terminal=1e4,
                     x_ref=None, Q=None, Q_terminal=None, u_ref=None, R=None,
                     com_target=None, W_com=0.0, W_com_terminal=0.0,
                     limits=LIMITS, q_lower=None, q_upper=None, v_limit=None, u_limit=None,
                     U_init=None, X_init=None, K_init=None, ddp=False, max_iterations=200,
                     handle=None, callback=None, **options):
    """Optimise a trajectory of `horizon` knot points from x0 (nq+nv,) (module doc).

    ee_target (3,): end-effector position target (None: no end-effector cost) of
    ee_frame (a link or joint frame name; default the first leaf body) at the
    tool point ee_offset (3,) in that frame; W_ee, W_ee_terminal: weights
    (scalar or (3,)); x_ref (nq+nv,; default x0), Q, Q_terminal (2nv,): state
    regularisation in the tangent space; u_ref (nv,; default gravity
    compensation at x0), R (nv,); com_target (3,), W_com, W_com_terminal: CoM
    cost; limits: a subset of ('position', 'velocity', 'torque'); q_lower,
    q_upper (nq,), v_limit, u_limit (nv,): bounds replacing the model's.
    Warm start: U_init (N, nv), optionally X_init (N+1, nq+nv) and K_init
    (N, nv, 2nv) (closed-loop first rollout u = U + K (x ⊖ X)).
    ddp: add the step Hessian (plant_step_hessian) to the backward pass.
    handle: an rbdkit.Handle whose plant_step_gradient (and plant_step_hessian)
    supply the derivatives. callback(record) after every iteration.
    options: mu_init, mu_min, mu_factor, reg_init, reg_min, reg_max, reg_factor,
    tol_cost, tol_grad, line_search_steps (include/rbdkit/solver/solver.hpp).
    Returns a TrajectoryResult."""
    if not isinstance(model, Model):
        raise TypeError(f"model: expected an rbdkit.Model, got {type(model).__name__}")
    nq, nv = model.nq, model.nv
    N = _int(horizon, "horizon", 1)
    dt = check_dt(dt)
    check_choice(integrator_type, "integrator_type", INTEGRATORS)
    gravity = check_scalar(gravity, "gravity")
    x0 = _vector(x0, nq + nv, "x0", allow_scalar=False)
    if isinstance(limits, str):
        limits = (limits,)
    if not isinstance(limits, (list, tuple, set, frozenset)) or any(l not in LIMITS for l in limits):
        raise ValueError(f"limits: expected a subset of {LIMITS}, got {limits!r}")
    for k in options:
        if k not in OPTIONS:
            raise TypeError(f"solve_trajectory: unknown option '{k}'; expected one of {', '.join(OPTIONS)}")
    problem = dict(horizon=N, dt=dt, integrator=integrator_type, gravity=gravity, x0=x0,
                   x_ref=_vector(x_ref, nq + nv, "x_ref", allow_scalar=False),
                   Q=_vector(Q, 2 * nv, "Q", nonneg=True), Q_terminal=_vector(Q_terminal, 2 * nv, "Q_terminal", nonneg=True),
                   u_ref=_vector(u_ref, nv, "u_ref", allow_scalar=False), R=_vector(R, nv, "R", nonneg=True),
                   position_limits="position" in limits, velocity_limits="velocity" in limits,
                   torque_limits="torque" in limits,
                   q_lower=_vector(q_lower, nq, "q_lower"), q_upper=_vector(q_upper, nq, "q_upper"),
                   v_limit=_vector(v_limit, nv, "v_limit"), u_limit=_vector(u_limit, nv, "u_limit"))
    if ee_target is not None:
        body, off = ee_body_and_offset(model, ee_frame, ee_offset)
        problem.update(ee=True, ee_body=body, ee_offset=off,
                       ee_target=_vector(ee_target, 3, "ee_target", allow_scalar=False),
                       W_ee=_vector(W_ee, 3, "W_ee", nonneg=True),
                       W_ee_terminal=_vector(W_ee_terminal, 3, "W_ee_terminal", nonneg=True))
    elif ee_frame is not None or ee_offset is not None:
        raise ValueError("ee_frame, ee_offset: given without ee_target")
    if com_target is not None:
        problem.update(com=True, com_target=_vector(com_target, 3, "com_target", allow_scalar=False),
                       W_com=_vector(W_com, 3, "W_com", nonneg=True),
                       W_com_terminal=_vector(W_com_terminal, 3, "W_com_terminal", nonneg=True))
    problem = {k: v for k, v in problem.items() if v is not None}
    (ddp,) = _flags(ddp=ddp)
    opts = dict(max_iterations=_int(max_iterations, "max_iterations", 0), ddp=ddp)
    for k, v in options.items():
        opts[k] = _int(v, k, 1) if k == "line_search_steps" else check_scalar(v, k)

    # warm start
    def traj(a, shape, name):
        if a is None:
            return None
        a = as_real_array(a, name)
        if a.shape != shape:
            raise ValueError(f"{name}: expected shape {shape}, got shape {a.shape}")
        check_values(a, name)
        return np.ascontiguousarray(a)
    U_init = traj(U_init, (N, nv), "U_init")
    X_init = traj(X_init, (N + 1, nq + nv), "X_init")
    K_init = traj(K_init, (N, nv, 2 * nv), "K_init")
    if X_init is not None and U_init is None:
        raise ValueError("X_init: needs U_init (the controls of that trajectory)")
    if K_init is not None and X_init is None:
        raise ValueError("K_init: needs X_init (the trajectory the gains act around)")

    # derivatives from a Python handle
    grad = hess = None
    if handle is not None:
        from ._handle import Handle
        if not isinstance(handle, Handle) and not hasattr(handle, "plant_step_gradient"):
            raise TypeError(f"handle: expected an rbdkit.Handle, got {type(handle).__name__}")
        hm = getattr(handle, "model", None)
        if hm is not None and (hm.nq, hm.nv) != (nq, nv):
            raise ValueError(f"handle: its model has nq={hm.nq}, nv={hm.nv}; expected the solved model's "
                             f"nq={nq}, nv={nv}")
        if hasattr(handle, "has") and not handle.has("plant_step_gradient"):
            raise ValueError("handle: it was not built with plant_step_gradient; add 'integrator_gradient' "
                             "to its algorithms")
        if ddp and hasattr(handle, "has") and not handle.has("plant_step_hessian"):
            raise ValueError("handle: ddp=True needs plant_step_hessian; add 'plant_step_hessian' to its algorithms")
        if (isinstance(handle, Handle) and handle.dtype == np.float64
                and "plant_step_gradient" in handle.fast_operations()):
            # an rbdkit.Handle's derivatives are the C++ handle's: the solver
            # builds one with its threads (no round trip through Python)
            opts["threads"] = handle.threads
        else:
            grad = lambda X, U: np.ascontiguousarray(
                handle.plant_step_gradient(X, U, dt, integrator_type, gravity=gravity), dtype=np.float64)
            if ddp:
                hess = lambda X, U: np.ascontiguousarray(
                    handle.plant_step_hessian(X, U, dt, integrator_type, gravity=gravity), dtype=np.float64)
    if callback is not None and not callable(callback):
        raise TypeError(f"callback: expected a callable, got {type(callback).__name__}")
    d = _core.solve_trajectory(model._core, problem, opts, U_init, X_init, K_init, grad, hess, callback)
    return TrajectoryResult(d)
