"""Time integrators on rbdkit.RBD: one step x⁺ = f(x, u) of the forward
dynamics and its tangent-space Jacobian [A | B].

integrator_type: euler, semi_implicit_euler, midpoint, rk4, trapezoidal
(explicit two-stage Heun) or constant_acceleration; see
include/rbdkit/algorithms/integrators.hpp for the schemes.
output_convention: "pinocchio" (default) or "mujoco" (MuJoCo's qpos/qvel,
frames and retraction for q, qd, u, x⁺, [A | B] and the step Hessian; see _mujoco.py).
"""

import numpy as np

from . import _core
from ._checks import MAX_TIME_STEP, Batch, check_scalar, check_values
from ._mujoco import convention_code

GRAVITY = -9.81
INTEGRATORS = ("euler", "semi_implicit_euler", "midpoint", "rk4", "trapezoidal", "constant_acceleration")


def integrator_code(name):
    if not isinstance(name, str):
        raise TypeError(f"integrator_type: expected a string, got {type(name).__name__}")
    return _core.integrator_from_name(name)


def check_dt(dt):
    """0 < dt <= MAX_TIME_STEP (s; a larger step overflows the state)"""
    dt = check_scalar(dt, "dt")
    if not 0 < dt <= MAX_TIME_STEP:
        raise ValueError(f"dt: expected a positive time step of at most {MAX_TIME_STEP:g} s, got {dt:g}")
    return dt


class IntegratorsMixin:
    """One-step integration and its Jacobian; mixed into rbdkit.RBD."""

    # ---- the plant layer's state form, x = [q; qd]
    def plant_step_hessian(self, x, u, dt, integrator_type="euler", gravity=GRAVITY, output_convention="pinocchio"):
        """H (2·nv, 3·nv, 3·nv): the second-order sensitivity of plant_step.

        With z = [δq; δqd; δu] (3·nv), the input q = q0 ⊕ δq, qd = qd0 + δqd,
        u = u0 + δu, and the output read in the chart at the nominal output,
        ψ(z) = [q⁺(z) ⊖ q⁺(0); qd⁺(z) - qd⁺(0)], H[i, j, k] = ∂²ψ_i/∂z_j∂z_k
        (symmetric in j, k), so that x⁺(z) = x⁺(0) ⊕ (AB z + ½ H[z, z] + O(|z|³))
        with AB = plant_step_gradient (same convention). ⊕ / ⊖: integrate /
        difference, or with output_convention="mujoco" MuJoCo's mj_integratePos
        / mj_differentiatePos with x, u in MuJoCo's qpos/qvel layout and frames
        (the second derivatives of the map plant_step(..., output_convention=
        "mujoco") computes, in the tangent of plant_step_gradient's). Every
        integrator_type; batched: (B, 2·nv, 3·nv, 3·nv). No f_ext argument
        (the second-order forward dynamics take no external forces).
        """
        t = integrator_code(integrator_type)
        cv = convention_code(output_convention)
        dt, g = check_dt(dt), check_scalar(gravity, "gravity")
        nq, nv = self.nq, self.nv
        b = Batch()
        ix, iu = b.add(x, "x", (nq + nv,), ("nq+nv",)), self._v(b, u, "u")
        X = check_values(b.get(ix), "x", batched=b.batched)
        xn, AB, H = b.out(nq + nv), b.out(2 * nv, 3 * nv), b.out(2 * nv, 3 * nv, 3 * nv)
        _core.plant_step_hessian(self._m, np.ascontiguousarray(X[:, :nq]), np.ascontiguousarray(X[:, nq:]), b.get(iu),
                                 dt, g, t, xn, AB, H, cv)
        return b.ret(H)
