"""Second-order dynamics derivatives on rbdkit.RBD (analytical IDSVA-SO
recursions and the FDSVA-SO relations, in the C++ core).

Every tensor is (nv, nv, nv) (with a leading batch axis B when an argument
is batched), index order [i, j, k]:

  d2tau_dq2[i, j, k]   = ∂/∂q_k (∂tau_i/∂q_j)
  d2tau_dqd2[i, j, k]  = ∂²tau_i / ∂qd_j ∂qd_k          (symmetric in j, k)
  d2tau_dqdqd[i, j, k] = ∂²tau_i / ∂q_j ∂qd_k
  dM_dq[i, j, k]       = ∂M_ij / ∂q_k
  d2qdd_dq2, d2qdd_dqd2, d2qdd_dqdqd: the same for qdd = forward_dynamics(q, qd, u)
  d2qdd_dqdu[i, j, k]  = ∂²qdd_i / ∂q_j ∂u_k

q derivatives are tangent-space: ∂/∂q_k is the derivative along
q <- integrate(q, δ e_k), and ∂tau/∂q_j is inverse_dynamics_gradient's
column j, so d2tau_dq2[:, :, k] is what central differences of that gradient
along integrate give. It is symmetric in (j, k) except inside a free-flyer or
spherical joint, whose tangent directions do not commute: there
d2tau_dq2[i, j, k] - d2tau_dq2[i, k, j] = ∂tau_i/∂q · [e_k, e_j] (the Lie
bracket of the two directions); its symmetric part is the Hessian of
δ ↦ tau(integrate(q, δ)) at δ = 0.
"""

from . import _core
from ._checks import Batch, check_scalar

GRAVITY = -9.81
_BODY, _WORLD, _AUTO = 0, 1, 2  # rbd::SecondOrderFrame


class SecondOrderMixin:
    """Second-order derivatives; mixed into rbdkit.RBD."""

    def _idsva_so(self, q, qd, qdd, gravity, frame):
        b = Batch()
        iq, iv, ia = self._q(b, q), self._v(b, qd, "qd"), self._v(b, qdd, "qdd")
        g = check_scalar(gravity, "gravity")
        n = self.nv
        out = [b.out(n, n, n) for _ in range(4)]
        _core.idsva_so(self._m, b.get(iq), b.get(iv), b.get(ia), g, frame, *out)
        return tuple(b.ret(o) for o in out)

    def idsva_so_body_frame(self, q, qd, qdd, gravity=GRAVITY):
        """(d2tau_dq2, d2tau_dqd2, d2tau_dqdqd, dM_dq), each (nv, nv, nv), of
        tau = inverse_dynamics(q, qd, qdd)[0], by the body-frame recursion
        (body-frame propagation, inertias and motion subspaces)."""
        return self._idsva_so(q, qd, qdd, gravity, _BODY)

    def idsva_so_world_frame(self, q, qd, qdd, gravity=GRAVITY):
        """The same tensors as idsva_so_body_frame by the world-frame recursion
        (world-frame propagation with gravity in the sweep; composites add
        without transforms). Equal to the body-frame variant to rounding."""
        return self._idsva_so(q, qd, qdd, gravity, _WORLD)

    def idsva_so(self, q, qd, qdd, gravity=GRAVITY):
        """(d2tau_dq2, d2tau_dqd2, d2tau_dqdqd, dM_dq): the body-frame variant
        for a fixed base, the world-frame one for a floating base."""
        return self._idsva_so(q, qd, qdd, gravity, _AUTO)

    def fdsva_so(self, q, qd, u, gravity=GRAVITY):
        """(d2qdd_dq2, d2qdd_dqd2, d2qdd_dqdqd, d2qdd_dqdu), each (nv, nv, nv),
        of qdd = forward_dynamics(q, qd, u): -M⁻¹ times the second-order
        inverse-dynamics terms plus the ∂M/∂q·∂qdd terms, at qdd = FD(q, qd, u)."""
        b = Batch()
        iq, iv, iu = self._q(b, q), self._v(b, qd, "qd"), self._v(b, u, "u")
        g = check_scalar(gravity, "gravity")
        n = self.nv
        out = [b.out(n, n, n) for _ in range(4)]
        _core.fdsva_so(self._m, b.get(iq), b.get(iv), b.get(iu), g, *out)
        return tuple(b.ret(o) for o in out)
