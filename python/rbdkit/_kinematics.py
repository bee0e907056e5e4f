"""Kinematics methods of rbdkit.RBD: placements, frame Jacobians and their
time variation, end-effector poses with their first and second derivatives,
and the operational-space inertia.

Shapes (each result gains a leading batch axis B when q is batched):

  forward_kinematics(q)                     R (nb, 3, 3), p (nb, 3): X_world_body
  frame_placement(q, frame_name)            R (3, 3), p (3,): X_world_frame
  frame_jacobian(q, frame_name, rf)         (6, nv), rows [linear; angular]
  frame_jacobian_dot(q, qd, frame_name, rf) (6, nv)
  end_effector_pose(q, ...)                 (n_ee, 6)
  end_effector_pose_gradient(q, ...)        (n_ee, 6, nv)
  end_effector_pose_hessian(q, ...)         (n_ee, 6, nv, nv)
  osc_inertia(q, ...)                       (n_ee, 6, 6)

Reference frames (Pinocchio's getFrameJacobian semantics): "LOCAL" — the
frame's spatial velocity in its own axes; "WORLD" — the spatial velocity at
the world origin in world axes; "LOCAL_WORLD_ALIGNED" — the velocity of the
frame's origin and the angular velocity, in world axes.

End-effector pose: [x, y, z, roll, pitch, yaw], the world position of the
tool point (an offset in the end-effector body's frame, default zero) and the
roll-pitch-yaw angles of the body's orientation in the URDF convention
R = Rz(yaw) Ry(pitch) Rx(roll), pitch in [-π/2, π/2], roll and yaw in
(-π, π]. At pitch = ±π/2 (gimbal lock) only roll ∓ yaw is defined (the
returned angles still rebuild R) and the rpy rows of the derivatives are
singular.
Derivatives are with respect to tangent perturbations q ⊕ δ (δ of width nv,
the configuration moved through rbd.integrate):

  gradient[e, r, k]   = ∂pose[e, r] / ∂δ_k
  hessian[e, r, j, k] = ∂gradient[e, r, k] / ∂δ_j   (the gradient evaluated at q ⊕ δ)

The Hessian is what central differences of the gradient through integrate
give. It is symmetric in (j, k) for 1-DoF joints, but not within a
free-flyer or spherical joint, whose tangent directions do not commute.
"""

import numpy as np

from . import _core
from ._checks import Batch, as_real_array


class KinematicsMixin:
    """end_effector_pose_hessian, by dual numbers (see the module doc for
    shapes and conventions). The other kinematics operations are registered
    operations (include/rbdkit/ops/registry.hpp), bound by rbdkit.RBD itself."""

    # ---- argument helpers
    def _ee_bodies(self, ee_joint_names, name="ee_joint_names"):
        """body indices of the end effectors: the leaf bodies by default"""
        if ee_joint_names is None:
            if self.nb == 0:
                raise ValueError(f"{name}: the model has no joints (nq = 0), so it has no end effector")
            return list(_core.leaf_bodies(self._m))
        if isinstance(ee_joint_names, str):
            ee_joint_names = [ee_joint_names]
        if not isinstance(ee_joint_names, (list, tuple)):
            raise TypeError(f"{name}: expected a list of joint names (str), got {type(ee_joint_names).__name__}")
        for n in ee_joint_names:
            if not isinstance(n, str):
                raise TypeError(f"{name}: expected joint names (str), got an entry of type {type(n).__name__}")
        return list(_core.end_effector_bodies(self._m, list(ee_joint_names)))

    def _ee_offsets(self, b, offsets, n_ee, name):
        """offsets (3,), (n_ee, 3) or (B, n_ee, 3) -> Batch index, None for zero"""
        if offsets is None:
            return None
        a = as_real_array(offsets, name)
        ok = a.shape in ((3,), (n_ee, 3)) or (a.ndim == 3 and a.shape[1:] == (n_ee, 3))
        if not ok:
            raise ValueError(f"{name}: expected shape (3,), (n_ee, 3) or (B, n_ee, 3) with n_ee={n_ee}, "
                             f"got shape {a.shape}")
        if a.shape == (3,):
            a = np.broadcast_to(a, (n_ee, 3))
        return b.add(a, name, (n_ee, 3), ("n_ee", "3"))

    def _ee_call(self, fn, q, ee_joint_names, offsets, offsets_name, out_shape, *extra):
        bodies = self._ee_bodies(ee_joint_names)
        b = Batch()
        iq = self._q(b, q)
        io = self._ee_offsets(b, offsets, len(bodies), offsets_name)
        out = b.out(len(bodies), *out_shape)
        fn(self._m, b.get(iq), bodies, None if io is None else b.get(io), offsets_name, *extra, out)
        return b.ret(out)

    # ---- end effectors
    def end_effector_pose_hessian(self, q, offsets=None, ee_joint_names=None):
        """Hessian (n_ee, 6, nv, nv) of end_effector_pose, H[e, r, j, k] =
        ∂gradient[e, r, k]/∂δ_j, by forward-mode dual numbers through the
        analytic gradient (exact; one pass per tangent direction). Not
        symmetric within free-flyer and spherical joints (see the module doc).
        Note the argument order: offsets before ee_joint_names."""
        return self._ee_call(_core.end_effector_pose_hessian, q, ee_joint_names, offsets, "offsets",
                             (6, self.nv, self.nv))
