"""Energy, Coriolis and centroidal methods of rbdkit.RBD.

Every one but the finite-difference cross-checks (dccrba_fd,
cmm_time_variation_fd) is a registered operation (include/rbdkit/ops/registry.hpp), bound by rbdkit.RBD itself;
the methods below are the others.

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

from . import _core
from ._checks import Batch, check_scalar

FD_STEP = 1e-5


def _check_eps(eps):
    eps = check_scalar(eps, "eps")
    if eps <= 0:
        raise ValueError(f"eps: expected a positive finite-difference step, got {eps}")
    return eps


class CentroidalMixin:
    """The centroidal methods of RBD that are not registered operations (see the module doc)."""

    # ---- the finite-difference cross-checks of dccrba and cmm_time_variation
    def dccrba_fd(self, q, eps=FD_STEP):
        """dccrba by central finite differences of ccrba through integrate
        (step eps): a cross-check of the analytic dccrba, not for production."""
        eps = _check_eps(eps)
        b = Batch()
        iq = self._q(b, q)
        dA = b.out(6, self.nv, self.nv)
        _core.dccrba_fd(self._m, b.get(iq), eps, dA)
        return b.ret(dA)

    def cmm_time_variation_fd(self, q, qd, eps=FD_STEP):
        """cmm_time_variation from dccrba_fd (finite differences): a cross-check only."""
        eps = _check_eps(eps)
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        Adot = b.out(6, self.nv)
        _core.cmm_time_variation_fd(self._m, b.get(iq), b.get(iv), eps, Adot)
        return b.ret(Adot)
