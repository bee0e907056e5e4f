"""The MuJoCo output convention (output_convention="mujoco") on rbdkit.RBD.

With output_convention="mujoco" the integrators, the plant step and the
costs take and return states in MuJoCo's qpos/qvel layout and frames, and
their derivatives are along MuJoCo's retraction (mj_integratePos), as
mjd_transitionFD's A and B:

  free joint   qpos [p (3), quaternion w x y z], qvel [ṗ (3, world); ω (3, body)],
               generalized force [f (world); τ (body)], acceleration d/dt qvel
  ball joint   quaternion w x y z, ω body frame
  ⊕            position additive (world), quaternion r ⊗ exp(δθ) (body frame), others additive

A model without free or ball joints is unchanged. Default: "pinocchio"
(quaternions x y z w, v = [v_lin; ω] in the body frame, ⊕ = integrate).
See include/rbdkit/algorithms/mujoco_convention.hpp.
"""

from . import _core
from ._checks import Batch

CONVENTIONS = ("pinocchio", "mujoco")


def convention_code(name):
    """"pinocchio" -> 0, "mujoco" -> 1; anything else raises naming output_convention"""
    if not isinstance(name, str):
        raise TypeError(f"output_convention: expected a string ('pinocchio' or 'mujoco'), got {type(name).__name__}")
    return _core.convention_from_name(name)


class MujocoMixin:
    """Conversions between the conventions and MuJoCo's ⊕ / ⊖; mixed into rbdkit.RBD."""

    def _state_map(self, x, fn):
        nx = self.nq + self.nv
        b = Batch()
        ix = b.add(x, "x", (nx,), ("nq+nv",))
        out = b.out(nx)
        fn(self._m, b.get(ix), out)
        return b.ret(out)

    def state_to_mujoco(self, x):
        """x = [q; qd] (nq + nv,) in our convention -> [qpos; qvel] in MuJoCo's."""
        return self._state_map(x, _core.state_to_mujoco)

    def state_from_mujoco(self, x):
        """[qpos; qvel] (nq + nv,) in MuJoCo's convention -> x = [q; qd] in ours."""
        return self._state_map(x, _core.state_from_mujoco)

    def _force_map(self, qpos, u, fn):
        b = Batch()
        iq, iu = self._q(b, qpos, "qpos"), self._v(b, u, "u")
        out = b.out(self.nv)
        fn(self._m, b.get(iq), b.get(iu), out)
        return b.ret(out)

    def force_to_mujoco(self, qpos, u):
        """generalized force u (nv,) in our frames -> MuJoCo's (qfrc) at qpos (nq,, MuJoCo layout)."""
        return self._force_map(qpos, u, _core.force_to_mujoco)

    def force_from_mujoco(self, qpos, u):
        """generalized force u (nv,) in MuJoCo's frames (qfrc) at qpos -> ours."""
        return self._force_map(qpos, u, _core.force_from_mujoco)

    def mujoco_integrate(self, qpos, v):
        """MuJoCo's qpos ⊕ v (mj_integratePos with a unit step): (nq,)."""
        b = Batch()
        iq, iv = self._q(b, qpos, "qpos"), self._v(b, v, "v")
        out = b.out(self.nq)
        _core.mujoco_integrate(self._m, b.get(iq), b.get(iv), out)
        return b.ret(out)

    def mujoco_difference(self, qpos0, qpos1):
        """MuJoCo's qpos1 ⊖ qpos0 (mj_differentiatePos with a unit step): (nv,)."""
        b = Batch()
        i0, i1 = self._q(b, qpos0, "qpos0"), self._q(b, qpos1, "qpos1")
        out = b.out(self.nv)
        _core.mujoco_difference(self._m, b.get(i0), b.get(i1), out)
        return b.ret(out)
