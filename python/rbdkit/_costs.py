"""The plant layer's costs and log barriers on rbdkit.RBD.

Every cost returns (value, gradient, Hessian); barriers return (value,
gradient, Hessian diagonal). Weights are diagonal, given as vectors; all
arguments take a leading batch axis. NX = nq + nv.

  quadratic_state_cost(x, x_des, Q)          Q (NX,):  grad (NX,), H (NX, NX), exact, ambient coordinates
  quadratic_state_cost_tangent(x, x_des, Q)  Q (2nv,): e = [difference(q_des, q); qd - qd_des],
                                             grad Jᵀ Q e (2nv,), Gauss–Newton H = Jᵀ Q J (2nv, 2nv)
  quadratic_input_cost(u, u_des, R)          R (nv,):  grad (nv,), H (nv, nv), exact
  ee_pos_cost(q, p_des, W)                   first end effector (or ee_joint_name), W (3,):
                                             grad (NX,), Gauss–Newton H (NX, NX); tangent δq in
                                             entries [0, nv), velocity entries [nq, NX) zero, the
                                             extra quaternion entries [nv, nq) zero
  com_cost(q, p_des, W)                      the same for the centre of mass
  momentum_cost(q, qd, h_des, W)             r = A(q)·qd - h_des, W (6,): grad (2nv,),
                                             Gauss–Newton H (2nv, 2nv), J = [(∂A/∂q)·qd | A]
  joint_{position,velocity,torque}_barrier(x, lower, upper, mu)
                                             -mu Σ [log(x - lower) + log(upper - x)], infinite
                                             bounds add nothing; outside the open interval the
                                             value is +inf and that coordinate's derivatives NaN

output_convention="mujoco" (every cost and barrier; default "pinocchio"): x,
q, qd in MuJoCo's qpos/qvel layout and frames (_mujoco.py); the tangent
error and the tangent blocks of the derivatives are along MuJoCo's ⊖ / ⊕;
momentum_cost converts qd to body frames inside r and keeps that
conversion's configuration dependence in J. The quadratic costs and the
barriers act on the given vectors coordinate by coordinate, so there only the
layout of the bounds and targets changes.
"""

import numpy as np

from . import _core
from ._checks import Batch, check_scalar
from ._mujoco import convention_code


class CostsMixin:
    """Costs and barriers; mixed into rbdkit.RBD."""

    def _quadratic(self, x, x_des, W, n, dim, names):
        b = Batch()
        ix = b.add(x, names[0], (n,), (dim,))
        idd = b.add(x_des, names[1], (n,), (dim,))
        iw = b.add(W, names[2], (n,), (dim,))
        v, g, H = b.out(), b.out(n), b.out(n, n)
        _core.quadratic_cost(b.get(ix), b.get(idd), b.get(iw), v, g, H, *names)
        return b.ret(v), b.ret(g), b.ret(H)

    def quadratic_state_cost(self, x, x_des, Q, output_convention="pinocchio"):
        """½ Σ Q (x - x_des)² on x = [q; qd] (NX,): (value, grad (NX,), H (NX, NX))."""
        convention_code(output_convention)
        return self._quadratic(x, x_des, Q, self.nq + self.nv, "nq+nv", ("x", "x_des", "Q"))

    def quadratic_input_cost(self, u, u_des, R, output_convention="pinocchio"):
        """½ Σ R (u - u_des)²: (value, grad (nv,), H (nv, nv))."""
        convention_code(output_convention)
        return self._quadratic(u, u_des, R, self.nv, "nv", ("u", "u_des", "R"))

    def quadratic_state_cost_tangent(self, x, x_des, Q, output_convention="pinocchio"):
        """½ eᵀ diag(Q) e with the log-map error e = [difference(q_des, q);
        qd - qd_des]: (value, grad (2nv,), Gauss–Newton H (2nv, 2nv))."""
        cv = convention_code(output_convention)
        nx, n2 = self.nq + self.nv, 2 * self.nv
        b = Batch()
        ix = b.add(x, "x", (nx,), ("nq+nv",))
        idd = b.add(x_des, "x_des", (nx,), ("nq+nv",))
        iq = b.add(Q, "Q", (n2,), ("2nv",))
        v, g, H = b.out(), b.out(n2), b.out(n2, n2)
        _core.quadratic_state_cost_tangent(self._m, b.get(ix), b.get(idd), b.get(iq), v, g, H, cv)
        return b.ret(v), b.ret(g), b.ret(H)

    def ee_pos_cost(self, q, p_des, W, ee_joint_name=None, ee_offset=None, output_convention="pinocchio"):
        """½ Σ W (p_ee(q) - p_des)² for the first end effector (the first
        leaf body) or the named joint's body, tool point ee_offset (3,) in its
        frame: (value, grad (NX,), Gauss–Newton H (NX, NX))."""
        cv = convention_code(output_convention)
        bodies = self._ee_bodies(None if ee_joint_name is None else [ee_joint_name], "ee_joint_name")
        off = None
        if ee_offset is not None:
            off = np.ascontiguousarray(self._ee_point(ee_offset), dtype=np.float64)
        nx = self.nq + self.nv
        b = Batch()
        iq = self._q(b, q)
        ip = b.add(p_des, "p_des", (3,), ("3",))
        iw = b.add(W, "W", (3,), ("3",))
        v, g, H = b.out(), b.out(nx), b.out(nx, nx)
        _core.ee_pos_cost(self._m, b.get(iq), b.get(ip), b.get(iw), bodies[0], off, v, g, H, cv)
        return b.ret(v), b.ret(g), b.ret(H)

    def com_cost(self, q, p_des, W, output_convention="pinocchio"):
        """½ Σ W (com(q) - p_des)²: (value, grad (NX,), Gauss–Newton H (NX, NX)),
        tangent blocks embedded as in ee_pos_cost."""
        cv = convention_code(output_convention)
        nx = self.nq + self.nv
        b = Batch()
        iq = self._q(b, q)
        ip = b.add(p_des, "p_des", (3,), ("3",))
        iw = b.add(W, "W", (3,), ("3",))
        v, g, H = b.out(), b.out(nx), b.out(nx, nx)
        _core.com_cost(self._m, b.get(iq), b.get(ip), b.get(iw), v, g, H, cv)
        return b.ret(v), b.ret(g), b.ret(H)

    def momentum_cost(self, q, qd, h_des, W, output_convention="pinocchio"):
        """½ Σ W r² with r = A(q)·qd - h_des (6,): (value, grad Jᵀ W r (2nv,),
        Gauss–Newton H = Jᵀ W J (2nv, 2nv)) in tangent [δq | δqd] coordinates,
        J = [(∂A/∂q)·qd | A] from dccrba (the full residual Jacobian: the
        configuration dependence is kept, only the residual curvature is dropped)."""
        cv = convention_code(output_convention)
        n2 = 2 * self.nv
        b = Batch()
        iq, iv = self._q(b, q), self._v(b, qd, "qd")
        ih = b.add(h_des, "h_des", (6,), ("6",))
        iw = b.add(W, "W", (6,), ("6",))
        v, g, H = b.out(), b.out(n2), b.out(n2, n2)
        _core.momentum_cost(self._m, b.get(iq), b.get(iv), b.get(ih), b.get(iw), v, g, H, cv)
        return b.ret(v), b.ret(g), b.ret(H)

    def _ee_point(self, offset):
        from ._checks import as_real_array, check_values
        a = as_real_array(offset, "ee_offset")
        if a.shape != (3,):
            raise ValueError(f"ee_offset: expected shape (3,), got shape {a.shape}")
        return check_values(a, "ee_offset")

    def _barrier(self, x, lower, upper, mu, n, dim, name):
        mu = check_scalar(mu, "mu")
        b = Batch()
        ix = b.add(x, name, (n,), (dim,))
        il = b.add(lower, "lower", (n,), (dim,))
        iu = b.add(upper, "upper", (n,), (dim,))
        lo, hi = b.get(il), b.get(iu)
        if np.any(np.isnan(lo)) or np.any(np.isnan(hi)):
            raise ValueError("lower, upper: expected numbers or ±inf, got NaN")
        v, g, h = b.out(), b.out(n), b.out(n)
        _core.log_barrier(b.get(ix), lo, hi, mu, v, g, h, name)
        return b.ret(v), b.ret(g), b.ret(h)

    def joint_position_barrier(self, q, lower, upper, mu, output_convention="pinocchio"):
        """Log barrier on q (nq,) with bounds (nq,) in the same layout: (value, grad (nq,),
        Hessian diagonal (nq,))."""
        convention_code(output_convention)
        return self._barrier(q, lower, upper, mu, self.nq, "nq", "q")

    def joint_velocity_barrier(self, qd, lower, upper, mu, output_convention="pinocchio"):
        """Log barrier on qd (nv,) with bounds (nv,): (value, grad (nv,), Hessian diagonal (nv,))."""
        convention_code(output_convention)
        return self._barrier(qd, lower, upper, mu, self.nv, "nv", "qd")

    def joint_torque_barrier(self, u, lower, upper, mu, output_convention="pinocchio"):
        """Log barrier on u (nv,) with bounds (nv,): (value, grad (nv,), Hessian diagonal (nv,))."""
        convention_code(output_convention)
        return self._barrier(u, lower, upper, mu, self.nv, "nv", "u")
