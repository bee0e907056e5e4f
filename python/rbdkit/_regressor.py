"""Inertial-parameter regressors on rbdkit.RBD: the dynamics as linear maps
of the inertial parameters π = model.inertial_parameters() (10·nb,), per body
in body order [m, m·c_x, m·c_y, m·c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]
with I about the body-frame origin in body axes (Pinocchio's dynamic
parameters; docs/conventions.md). Analytic and exact, in the C++ core.

inverse_dynamics_regressor, kinetic_energy_regressor and
potential_energy_regressor are registered operations
(include/rbdkit/ops/registry.hpp), bound by rbdkit.RBD itself; the methods
below are the others.
"""

from . import _core
from ._checks import Batch, check_scalar

GRAVITY = -9.81


class RegressorMixin:
    """The regressors that are not registered operations; mixed into rbdkit.RBD."""

    def inverse_dynamics_regressor_gradient(self, q, qd, qdd=None, gravity=GRAVITY):
        """dY_dx (2·nv, nv, 10·nb): dY_dx[c] = ∂Y/∂x_c for x = [q (tangent
        step through integrate); qd], so dY_dx[c] @ π is column c of
        inverse_dynamics_gradient(q, qd, qdd). O(10·n·d²) after one forward pass."""
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        ia = None if qdd is None else self._v(b, qdd, "qdd")
        g = check_scalar(gravity, "gravity")
        dY = b.out(2 * self.nv, self.nv, 10 * self.nb)
        _core.inverse_dynamics_regressor_gradient(self._m, b.get(iq), b.get(iv), None if ia is None else b.get(ia),
                                                  g, dY)
        return b.ret(dY)

    def forward_dynamics_parameter_gradient(self, q, qd, u, gravity=GRAVITY):
        """∂qdd/∂π (nv, 10·nb) of qdd = forward_dynamics(q, qd, u): -M⁻¹ Y
        with Y evaluated at that qdd."""
        b = Batch()
        iq, iv, iu = self._q(b, q), self._v(b, qd, "qd"), self._v(b, u, "u")
        g = check_scalar(gravity, "gravity")
        out = b.out(self.nv, 10 * self.nb)
        _core.forward_dynamics_parameter_gradient(self._m, b.get(iq), b.get(iv), b.get(iu), g, out)
        return b.ret(out)
