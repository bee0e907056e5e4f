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
    """ee_pos_cost and the barriers; mixed into rbdkit.RBD. The other costs
    (quadratic_state_cost, quadratic_input_cost, quadratic_state_cost_tangent,
    com_cost, momentum_cost) are registered operations
    (include/rbdkit/ops/registry.hpp), bound by rbdkit.RBD itself."""

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
