"""Time integrators: the scheme names and the time-step check the solver
uses. The steps, their gradients and the step Hessian are registered
operations (include/rbdkit/ops/registry.hpp), bound by rbdkit.RBD itself.

integrator_type: euler, semi_implicit_euler, midpoint, rk4, trapezoidal
(explicit two-stage Heun) or constant_acceleration; see
include/rbdkit/plant/integrators.hpp for the schemes.
output_convention: "pinocchio" (default) or "mujoco" (MuJoCo's qpos/qvel,
frames and retraction for q, qd, u, x⁺, [A | B] and the step Hessian; see
docs/conventions.md, "MuJoCo output convention").
"""

from ._checks import MAX_TIME_STEP, check_scalar

INTEGRATORS = ("euler", "semi_implicit_euler", "midpoint", "rk4", "trapezoidal", "constant_acceleration")


def check_dt(dt):
    """0 < dt <= MAX_TIME_STEP (s; a larger step overflows the state)"""
    dt = check_scalar(dt, "dt")
    if not 0 < dt <= MAX_TIME_STEP:
        raise ValueError(f"dt: expected a positive time step of at most {MAX_TIME_STEP:g} s, got {dt:g}")
    return dt
