"""First-order dynamics derivatives on rbdkit.RBD (analytical, O(n·d)),
and the per-pass helpers that let an accelerator port be checked pass by pass.

Derivatives are in the tangent space: a configuration column k is the
derivative along q ← integrate(q, δ·e_k), so every derivative has NV columns
per configuration, floating bases and spherical joints included.
"""

from . import _core
from ._checks import Batch, check_scalar

GRAVITY = -9.81


class DerivativesMixin:
    """Dynamics gradients; mixed into rbdkit.RBD."""

    def _cols(self, b, x, name):
        return b.add(x, name, (self.nb, 6, 6), ("nb", "6", "6"))

    # ---- per-pass helpers
    def inverse_dynamics_fpass(self, q, qd, qdd=None, gravity=GRAVITY, f_ext=None):
        """RNEA forward pass: per body (nb, 6), body frame: velocity v,
        acceleration a (with the fictitious gravity acceleration -g) and the
        net body force f = I a + v ×* I v - f_ext."""
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        ia = None if qdd is None else self._v(b, qdd, "qdd")
        ifx = self._fext(b, f_ext)
        g = check_scalar(gravity, "gravity")
        v, a, f = b.out(self.nb, 6), b.out(self.nb, 6), b.out(self.nb, 6)
        _core.inverse_dynamics_fpass(self._m, b.get(iq), b.get(iv), None if ia is None else b.get(ia),
                                     None if ifx is None else b.get(ifx), g, v, a, f)
        return b.ret(v), b.ret(a), b.ret(f)

    def inverse_dynamics_bpass(self, q, f):
        """RNEA backward pass from net body forces f (nb, 6): (c (nv,), joint
        forces (nb, 6)). inverse_dynamics_bpass(q, fpass(...)[2]) = inverse_dynamics."""
        b = Batch()
        iq, i_f = self._q(b, q), b.add(f, "f", (self.nb, 6), ("nb", "6"))
        tau, fo = b.out(self.nv), b.out(self.nb, 6)
        _core.inverse_dynamics_bpass(self._m, b.get(iq), b.get(i_f), tau, fo)
        return b.ret(tau), b.ret(fo)

    def minv_bpass(self, q):
        """Backward pass of the direct M⁻¹: the rows of each joint over its
        subtree's columns (nv, nv; zeros elsewhere). Models without mimic joints."""
        b = Batch()
        iq = self._q(b, q)
        out = b.out(self.nv, self.nv)
        _core.minv_bpass(self._m, b.get(iq), out)
        return b.ret(out)

    def minv_fpass(self, q, minv_b):
        """Forward pass of the direct M⁻¹ from minv_bpass's result: the upper
        triangle of M⁻¹ (nv, nv)."""
        b = Batch()
        iq, im = self._q(b, q), b.add(minv_b, "minv_b", (self.nv, self.nv), ("nv", "nv"))
        out = b.out(self.nv, self.nv)
        _core.minv_fpass(self._m, b.get(iq), b.get(im), out)
        return b.ret(out)

    def _grad_fpass(self, q, qd, qdd, gravity, wrt):
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        ia = None if qdd is None else self._v(b, qdd, "qdd")
        g = check_scalar(gravity, "gravity")
        o1, o2 = b.out(self.nb, 6, 6), b.out(self.nb, 6, 6)
        _core.inverse_dynamics_gradient_fpass(self._m, b.get(iq), b.get(iv), None if ia is None else b.get(ia), g,
                                              wrt, o1, o2)
        return b.ret(o1), b.ret(o2)

    def inverse_dynamics_gradient_fpass_dq(self, q, qd, qdd=None, gravity=GRAVITY):
        """Forward pass of ∂ID/∂q: per body (nb, 6, 6), [b, :, a] the world-frame
        column of DoF a of body b's joint: (dV_dq = v_λ × s, dA_dq = a_λ × s + v_λ × dV_dq)."""
        return self._grad_fpass(q, qd, qdd, gravity, 0)

    def inverse_dynamics_gradient_fpass_dqd(self, q, qd, qdd=None, gravity=GRAVITY):
        """Forward pass of ∂ID/∂qd: per body (nb, 6, 6): (S = s, the world-frame
        motion subspace, dA_dqd = v × s + v_λ × s)."""
        return self._grad_fpass(q, qd, qdd, gravity, 1)

    def _grad_bpass(self, q, qd, qdd, in1, in2, names, gravity, wrt):
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        ia = None if qdd is None else self._v(b, qdd, "qdd")
        i1, i2 = self._cols(b, in1, names[0]), self._cols(b, in2, names[1])
        g = check_scalar(gravity, "gravity")
        out = b.out(self.nv, self.nv)
        _core.inverse_dynamics_gradient_bpass(self._m, b.get(iq), b.get(iv), None if ia is None else b.get(ia), g,
                                              wrt, b.get(i1), b.get(i2), out)
        return b.ret(out)

    def inverse_dynamics_gradient_bpass_dq(self, q, qd, qdd, dV_dq, dA_dq, gravity=GRAVITY):
        """Backward pass of ∂ID/∂q from the forward pass's columns: ∂c/∂q (nv, nv)."""
        return self._grad_bpass(q, qd, qdd, dV_dq, dA_dq, ("dV_dq", "dA_dq"), gravity, 0)

    def inverse_dynamics_gradient_bpass_dqd(self, q, qd, qdd, S, dA_dqd, gravity=GRAVITY):
        """Backward pass of ∂ID/∂qd from the forward pass's columns: ∂c/∂qd (nv, nv)."""
        return self._grad_bpass(q, qd, qdd, S, dA_dqd, ("S", "dA_dqd"), gravity, 1)
