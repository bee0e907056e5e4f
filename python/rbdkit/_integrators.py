"""Time integrators on rbdkit.RBD: one step x⁺ = f(x, u) of the forward
dynamics and its tangent-space Jacobian [A | B].

integrator_type: euler, semi_implicit_euler, midpoint, rk4, trapezoidal
(explicit two-stage Heun) or constant_acceleration; see
include/rbdkit/algorithms/integrators.hpp for the schemes.
output_convention: "pinocchio" (default) or "mujoco" (MuJoCo's qpos/qvel,
frames and retraction for q, qd, u, x⁺ and [A | B]; see _mujoco.py).
"""

from . import _core
from ._checks import Batch, check_scalar
from ._mujoco import convention_code

GRAVITY = -9.81
INTEGRATORS = ("euler", "semi_implicit_euler", "midpoint", "rk4", "trapezoidal", "constant_acceleration")


def integrator_code(name):
    if not isinstance(name, str):
        raise TypeError(f"integrator_type: expected a string, got {type(name).__name__}")
    return _core.integrator_from_name(name)


def check_dt(dt):
    dt = check_scalar(dt, "dt")
    if dt <= 0:
        raise ValueError(f"dt: expected a positive time step, got {dt}")
    return dt


class IntegratorsMixin:
    """One-step integration and its Jacobian; mixed into rbdkit.RBD."""

    def _step_args(self, b, q, qd, u, f_ext):
        return self._q(b, q), self._v(b, qd, "qd"), self._v(b, u, "u"), self._fext(b, f_ext)

    def integrator(self, q, qd, u, dt, integrator_type="euler", f_ext=None, gravity=GRAVITY,
                   output_convention="pinocchio"):
        """x⁺ = [q⁺; qd⁺] (nq + nv,) after one step of length dt with constant
        controls u and body-local external forces f_ext."""
        t = integrator_code(integrator_type)
        cv = convention_code(output_convention)
        dt, g = check_dt(dt), check_scalar(gravity, "gravity")
        b = Batch()
        iq, iv, iu, ifx = self._step_args(b, q, qd, u, f_ext)
        x = b.out(self.nq + self.nv)
        _core.integrator(self._m, b.get(iq), b.get(iv), b.get(iu), None if ifx is None else b.get(ifx), dt, g, t, x,
                         cv)
        return b.ret(x)

    def integrator_gradient(self, q, qd, u, dt, integrator_type="euler", f_ext=None, gravity=GRAVITY,
                            output_convention="pinocchio"):
        """[A | B] = ∂x⁺/∂(x, u) (2·nv, 3·nv) in the tangent space: rows
        [δq⁺; δqd⁺], columns [δq | δqd | δu] (δq through integrate, or
        MuJoCo's mj_integratePos with output_convention="mujoco")."""
        t = integrator_code(integrator_type)
        cv = convention_code(output_convention)
        dt, g = check_dt(dt), check_scalar(gravity, "gravity")
        b = Batch()
        iq, iv, iu, ifx = self._step_args(b, q, qd, u, f_ext)
        x, AB = b.out(self.nq + self.nv), b.out(2 * self.nv, 3 * self.nv)
        _core.integrator_gradient(self._m, b.get(iq), b.get(iv), b.get(iu), None if ifx is None else b.get(ifx), dt,
                                  g, t, x, AB, cv)
        return b.ret(AB)

    # ---- the plant layer's state form, x = [q; qd]
    def _split_state(self, x, name="x"):
        """(q, qd) views of x (nq + nv,) or (B, nq + nv)"""
        b = Batch()
        ix = b.add(x, name, (self.nq + self.nv,), ("nq+nv",))
        X = b.ret(b.get(ix))
        return X[..., :self.nq], X[..., self.nq:]

    def plant_step(self, x, u, dt, integrator_type="euler", f_ext=None, gravity=GRAVITY,
                   output_convention="pinocchio"):
        """x⁺ (nq + nv,) for x = [q; qd] (nq + nv,)."""
        q, qd = self._split_state(x)
        return self.integrator(q, qd, u, dt, integrator_type, f_ext, gravity, output_convention)

    def plant_step_gradient(self, x, u, dt, integrator_type="euler", f_ext=None, gravity=GRAVITY,
                            output_convention="pinocchio"):
        """[A | B] (2·nv, 3·nv) of plant_step, tangent space."""
        q, qd = self._split_state(x)
        return self.integrator_gradient(q, qd, u, dt, integrator_type, f_ext, gravity, output_convention)
