"""Energy, Coriolis and centroidal methods of rbdkit.RBD.

Shapes (each result gains a leading batch axis B when an argument is batched):

  kinetic_energy(q, qd), potential_energy(q), mechanical_energy(q, qd)   scalar
  coriolis_matrix(q, qd)                          C (nv, nv)
  com(q)                                          (3,)
  jacobian_com(q)                                 (3, nv)
  ccrba(q, qd)                                    A (6, nv), h (6,)
  centroidal_momentum(q, qd)                      h (6,)
  dccrba(q), dccrba_fd(q)                         dA (6, nv, nv)
  cmm_time_variation(q, qd), …_fd(q, qd)          Ȧ (6, nv)
  centroidal_momentum_time_variation(q, qd, qdd)  ḣ (6,)
  centroidal_dynamics_derivatives(q, qd, qdd)     4 x (6, nv)

Centroidal quantities are [linear; angular] about the centre of mass in
world-aligned axes (Pinocchio's data.Ag, data.hg): h = A·qd is the robot's
linear momentum and its angular momentum about the centre of mass. ḣ is the
rate of change of h; gravity is not in it (ḣ = Σ external wrenches + weight).
Configuration derivatives are tangent-space: index k is the step
q ← integrate(q, δ·e_k). dA[r, j, k] = ∂A[r, j]/∂δ_k, so Ȧ = dA @ qd.
Fixed-base robots: the world-fixed root link is not part of the robot (its
mass is not counted), as in Pinocchio.
"""

import numpy as np

from . import _core
from ._checks import Batch, check_scalar

GRAVITY = -9.81
FD_STEP = 1e-5


def _check_eps(eps):
    eps = check_scalar(eps, "eps")
    if eps <= 0:
        raise ValueError(f"eps: expected a positive finite-difference step, got {eps}")
    return eps


class CentroidalMixin:
    """Energy, Coriolis and centroidal methods of RBD (see the module doc)."""

    # ---- energy
    def kinetic_energy(self, q, qd):
        """T = ½ qdᵀ M(q) qd (a float; (B,) for a batch)."""
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        out = b.out()
        _core.kinetic_energy(self._m, b.get(iq), b.get(iv), out)
        return b.ret(out)

    def potential_energy(self, q, gravity=GRAVITY):
        """V = -Σ m_i g·c_i with g = (0, 0, gravity): the potential energy of
        the bodies' mass in the world, zero at z = 0 (a float; (B,) for a batch)."""
        b = Batch()
        iq = self._q(b, q)
        g = check_scalar(gravity, "gravity")
        out = b.out()
        _core.potential_energy(self._m, b.get(iq), g, out)
        return b.ret(out)

    def mechanical_energy(self, q, qd, gravity=GRAVITY):
        """T + V (a float; (B,) for a batch)."""
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        g = check_scalar(gravity, "gravity")
        out = b.out()
        _core.mechanical_energy(self._m, b.get(iq), b.get(iv), g, out)
        return b.ret(out)

    def coriolis_matrix(self, q, qd):
        """Coriolis matrix C (nv, nv) of Pinocchio's computeCoriolisMatrix: the
        Christoffel-consistent factorisation, with C·qd + g = nonlinear_effects
        and Ṁ - 2C skew-symmetric."""
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        C = b.out(self.nv, self.nv)
        _core.coriolis_matrix(self._m, b.get(iq), b.get(iv), C)
        return b.ret(C)

    # ---- centre of mass
    def com(self, q):
        """Centre of mass (3,) in the world frame."""
        b = Batch()
        iq = self._q(b, q)
        c = b.out(3)
        _core.center_of_mass(self._m, b.get(iq), c)
        return b.ret(c)

    def jacobian_com(self, q):
        """Jacobian of the centre of mass (3, nv): ċ = J_com·qd; also ∂c/∂δ
        along tangent steps. Equal to A[:3] / total mass."""
        b = Batch()
        iq = self._q(b, q)
        J = b.out(3, self.nv)
        _core.jacobian_com(self._m, b.get(iq), J)
        return b.ret(J)

    # ---- centroidal momentum
    def ccrba(self, q, qd):
        """Centroidal momentum matrix and momentum (A (6, nv), h (6,)), h = A·qd,
        by the composite rigid-body algorithm (Pinocchio's ccrba: data.Ag, data.hg)."""
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        A, h = b.out(6, self.nv), b.out(6)
        _core.ccrba(self._m, b.get(iq), b.get(iv), A, h)
        return b.ret(A), b.ret(h)

    def centroidal_momentum(self, q, qd):
        """Centroidal momentum h (6,) = A·qd, in one O(n) pass (no A)."""
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        h = b.out(6)
        _core.centroidal_momentum(self._m, b.get(iq), b.get(iv), h)
        return b.ret(h)

    def dccrba(self, q):
        """Analytic configuration derivative of A: dA (6, nv, nv) with
        dA[r, j, k] = ∂A[r, j]/∂δ_k along the tangent step q ← integrate(q, δ·e_k)."""
        b = Batch()
        iq = self._q(b, q)
        dA = b.out(6, self.nv, self.nv)
        _core.dccrba(self._m, b.get(iq), dA)
        return b.ret(dA)

    def dccrba_fd(self, q, eps=FD_STEP):
        """dccrba by central finite differences of ccrba through integrate
        (step eps): a cross-check of the analytic dccrba, not for production."""
        eps = _check_eps(eps)
        b = Batch()
        iq = self._q(b, q)
        dA = b.out(6, self.nv, self.nv)
        _core.dccrba_fd(self._m, b.get(iq), eps, dA)
        return b.ret(dA)

    def cmm_time_variation(self, q, qd):
        """Ȧ (6, nv) = Σ_k dA[:, :, k]·qd_k, the time variation of A along qd, in
        O(n) (Pinocchio's computeCentroidalMapTimeVariation: data.dAg)."""
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        Adot = b.out(6, self.nv)
        _core.cmm_time_variation(self._m, b.get(iq), b.get(iv), Adot)
        return b.ret(Adot)

    def cmm_time_variation_fd(self, q, qd, eps=FD_STEP):
        """cmm_time_variation from dccrba_fd (finite differences): a cross-check only."""
        eps = _check_eps(eps)
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        Adot = b.out(6, self.nv)
        _core.cmm_time_variation_fd(self._m, b.get(iq), b.get(iv), eps, Adot)
        return b.ret(Adot)

    def centroidal_momentum_time_variation(self, q, qd, qdd):
        """ḣ (6,) = A·qdd + Ȧ·qd, the rate of the centroidal momentum (gravity
        not included), in one O(n) pass (Pinocchio's
        computeCentroidalMomentumTimeVariation: data.dhg)."""
        b = Batch()
        iq, iv, ia = self._q(b, q), self._v(b, qd, "qd"), self._v(b, qdd, "qdd")
        hdot = b.out(6)
        _core.centroidal_momentum_time_variation(self._m, b.get(iq), b.get(iv), b.get(ia), hdot)
        return b.ret(hdot)

    def centroidal_dynamics_derivatives(self, q, qd, qdd):
        """(dh_dq, dhdot_dq, dhdot_dv, dhdot_da), each (6, nv), in O(n)
        (Pinocchio's computeCentroidalDynamicsDerivatives): dh_dq = ∂h/∂δ at
        fixed qd (the true tangent derivative of ccrba's h, the moving centre
        of mass included), dhdot_dq = ∂ḣ/∂δ, dhdot_dv = ∂ḣ/∂qd, dhdot_da =
        ∂ḣ/∂qdd = A."""
        b = Batch()
        iq, iv, ia = self._q(b, q), self._v(b, qd, "qd"), self._v(b, qdd, "qdd")
        outs = [b.out(6, self.nv) for _ in range(4)]
        _core.centroidal_dynamics_derivatives(self._m, b.get(iq), b.get(iv), b.get(ia), *outs)
        return tuple(b.ret(o) for o in outs)
