"""rbdkit.RBD: the dynamics of one model, single samples or batches.

Shapes: q (nq,), qd/qdd/tau/u (nv,), per-body 6D quantities (nb, 6) in the
body frame as [linear; angular]; each may carry a leading batch axis B, and
unbatched arguments are broadcast against batched ones. Results carry the
batch axis when any argument did.
"""

import numpy as np

from . import _core
from ._centroidal import CentroidalMixin
from ._checks import Batch, check_choice, check_scalar, check_values
from ._costs import CostsMixin
from ._derivatives import DerivativesMixin
from ._integrators import IntegratorsMixin
from ._model import Model
from ._kinematics import KinematicsMixin
from ._mujoco import MujocoMixin
from ._regressor import RegressorMixin
from ._second_order import SecondOrderMixin

GRAVITY = -9.81


class RBD(DerivativesMixin, KinematicsMixin, IntegratorsMixin, CostsMixin, RegressorMixin,
          CentroidalMixin, SecondOrderMixin, MujocoMixin):
    """Rigid-body dynamics of a Model (see the module doc for shapes)."""

    def __init__(self, model):
        if not isinstance(model, Model):
            raise TypeError(f"model: expected an rbdkit.Model, got {type(model).__name__}")
        self.model = model
        self._m = model._core
        self.nq, self.nv, self.nb = model.nq, model.nv, model.nb

    # ---- argument helpers
    def _q(self, b, q, name="q"):
        return b.add(q, name, (self.nq,), ("nq",))

    def _v(self, b, v, name):
        return b.add(v, name, (self.nv,), ("nv",))

    def _fext(self, b, f_ext, name="f_ext"):
        if f_ext is None or (isinstance(f_ext, (list, tuple)) and len(f_ext) == 0):
            return None
        return b.add(f_ext, name, (self.nb, 6), ("nb", "6"))

    # ---- dynamics
    def inverse_dynamics(self, q, qd, qdd=None, gravity=GRAVITY, f_ext=None):
        """RNEA. Returns (c, v, a, f): joint forces c (nv,) = M qdd + C qd + g
        - Σ Jᵀ f_ext, and per body (nb, 6): velocity v, acceleration a (gravity
        not included) and the force f transmitted by its joint (body frame)."""
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        ia = None if qdd is None else self._v(b, qdd, "qdd")
        ifx = self._fext(b, f_ext)
        g = check_scalar(gravity, "gravity")
        tau, v, a, f = b.out(self.nv), b.out(self.nb, 6), b.out(self.nb, 6), b.out(self.nb, 6)
        _core.inverse_dynamics(self._m, b.get(iq), b.get(iv), None if ia is None else b.get(ia),
                               None if ifx is None else b.get(ifx), g, tau, v, a, f)
        return b.ret(tau), b.ret(v), b.ret(a), b.ret(f)

    def aba(self, q, qd, tau, f_ext=None, gravity=GRAVITY):
        """Forward dynamics by the articulated-body algorithm: qdd (nv,)."""
        b = Batch()
        iq, iv, it = self._q(b, q), self._v(b, qd, "qd"), self._v(b, tau, "tau")
        ifx = self._fext(b, f_ext)
        g = check_scalar(gravity, "gravity")
        qdd = b.out(self.nv)
        _core.aba(self._m, b.get(iq), b.get(iv), b.get(it), None if ifx is None else b.get(ifx), g, qdd)
        return b.ret(qdd)

    def forward_dynamics(self, q, qd, u, f_ext=None, gravity=GRAVITY):
        """Forward dynamics through the inverse mass matrix: M⁻¹ (u - c)."""
        b = Batch()
        iq, iv, it = self._q(b, q), self._v(b, qd, "qd"), self._v(b, u, "u")
        ifx = self._fext(b, f_ext)
        g = check_scalar(gravity, "gravity")
        qdd = b.out(self.nv)
        _core.forward_dynamics(self._m, b.get(iq), b.get(iv), b.get(it), None if ifx is None else b.get(ifx), g,
                               qdd)
        return b.ret(qdd)

    def crba(self, q):
        """Joint-space mass matrix M (nv, nv) by the composite rigid-body algorithm."""
        b = Batch()
        iq = self._q(b, q)
        M = b.out(self.nv, self.nv)
        _core.crba(self._m, b.get(iq), M)
        return b.ret(M)

    def minv(self, q, output_dense=True):
        """M⁻¹ (nv, nv) computed directly in O(n²) (not by factorising M).
        output_dense=False returns the upper triangle (zeros below)."""
        if not isinstance(output_dense, (bool, np.bool_)):
            raise TypeError(f"output_dense: expected a bool, got {type(output_dense).__name__}")
        b = Batch()
        iq = self._q(b, q)
        Mi = b.out(self.nv, self.nv)
        _core.minv(self._m, b.get(iq), bool(output_dense), Mi)
        return b.ret(Mi)

    def apply_external_forces(self, f_in, f_ext):
        """f_in - f_ext per body, both (nb, 6) in body frames: the net body
        forces once the external forces are taken away."""
        b = Batch()
        i1 = b.add(f_in, "f_in", (self.nb, 6), ("nb", "6"))
        i2 = b.add(f_ext, "f_ext", (self.nb, 6), ("nb", "6"))
        f1, f2 = b.get(i1), b.get(i2)
        for name, f in (("f_in", f1), ("f_ext", f2)):
            check_values(f, name)
        return b.ret(f1 - f2)

    def generalized_gravity(self, q, gravity=GRAVITY):
        """g(q) (nv,): the joint forces that hold the robot still."""
        b = Batch()
        iq = self._q(b, q)
        g = check_scalar(gravity, "gravity")
        tau = b.out(self.nv)
        _core.inverse_dynamics(self._m, b.get(iq), np.zeros((b.size, self.nv)), None, None, g, tau, None, None, None)
        return b.ret(tau)

    def nonlinear_effects(self, q, qd, gravity=GRAVITY):
        """c(q, qd) = C(q, qd) qd + g(q) (nv,)."""
        return self.inverse_dynamics(q, qd, None, gravity)[0]

    # ---- configuration space (Lie-group operations)
    def integrate(self, q, v):
        """q ⊕ v (nq,): SE(3) exponential on a free-flyer joint (twist in the
        local frame), SO(3) on spherical joints, q + v elsewhere."""
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, v, "v")
        out = b.out(self.nq)
        _core.integrate(self._m, b.get(iq), b.get(iv), out)
        return b.ret(out)

    def difference(self, q0, q1):
        """q1 ⊖ q0 (nv,): the tangent step v with integrate(q0, v) = q1."""
        b = Batch()
        i0, i1 = self._q(b, q0, "q0"), self._q(b, q1, "q1")
        out = b.out(self.nv)
        _core.difference(self._m, b.get(i0), b.get(i1), out)
        return b.ret(out)

    def dIntegrate(self, q, v, with_respect_to="q"):
        """Tangent Jacobian (nv, nv) of integrate(q, v) with respect to 'q' or 'v'."""
        arg = check_choice(with_respect_to, "with_respect_to", ("q", "v"))
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, v, "v")
        J = b.out(self.nv, self.nv)
        _core.dintegrate(self._m, b.get(iq), b.get(iv), arg, J)
        return b.ret(J)

    def dDifference(self, q0, q1, with_respect_to="to"):
        """Tangent Jacobian (nv, nv) of difference(q0, q1) with respect to
        'from' (q0) or 'to' (q1)."""
        arg = check_choice(with_respect_to, "with_respect_to", ("from", "to"))
        b = Batch()
        i0, i1 = self._q(b, q0, "q0"), self._q(b, q1, "q1")
        J = b.out(self.nv, self.nv)
        _core.ddifference(self._m, b.get(i0), b.get(i1), arg, J)
        return b.ret(J)

    def d2Integrate(self, q, v, arg1="v", arg2="v"):
        """Second derivative of integrate: H (nv, nv, nv) with
        H[i, j, k] = ∂ dIntegrate(q, v, arg1)[i, j] / ∂x_k, x = arg2 ('q':
        a tangent step through integrate(q, ·), 'v': v itself). Exact (dual
        numbers through the closed-form Jacobians)."""
        a1 = check_choice(arg1, "arg1", ("q", "v"))
        a2 = check_choice(arg2, "arg2", ("q", "v"))
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, v, "v")
        H = b.out(self.nv, self.nv, self.nv)
        _core.d2integrate(self._m, b.get(iq), b.get(iv), a1, a2, H)
        return b.ret(H)

    # ---- timing (for reports; benchmarks live in bench/)
    def time_per_call(self, op, q, qd, tau, iters=2000):
        """seconds per call of a core algorithm in C++ (best of 5 runs of
        `iters` calls); op: inverse_dynamics, crba, minv, aba, forward_dynamics"""
        ops = ("inverse_dynamics", "crba", "minv", "aba", "forward_dynamics")
        check_choice(op, "op", ops)
        if isinstance(iters, (bool, np.bool_)) or not isinstance(iters, (int, np.integer)) or iters < 1:
            raise ValueError(f"iters: expected a positive integer, got {iters!r}")
        b = Batch()
        iq, iv, it = self._q(b, q), self._v(b, qd, "qd"), self._v(b, tau, "tau")
        if b.batched:
            raise ValueError("time_per_call: expected one sample, not a batch")
        self.integrate(q, np.zeros(self.nv))  # checks q (finite, unit quaternions)
        for name, i in (("qd", iv), ("tau", it)):
            check_values(b.get(i), name)
        return _core.time_per_call(self._m, op, b.get(iq)[0], b.get(iv)[0], b.get(it)[0], int(iters))

    def __repr__(self):
        return f"<rbdkit.RBD of {self.model!r}>"
