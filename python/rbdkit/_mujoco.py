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
See include/rbdkit/plant/mujoco_convention.hpp. The conversions
between the conventions and MuJoCo's ⊕ / ⊖ (state_to_mujoco,
state_from_mujoco, force_to_mujoco, force_from_mujoco, mujoco_integrate,
mujoco_difference) are registered operations (include/rbdkit/ops/registry.hpp),
bound by rbdkit.RBD itself.
"""

from . import _core

CONVENTIONS = ("pinocchio", "mujoco")


def convention_code(name):
    """"pinocchio" -> 0, "mujoco" -> 1; anything else raises naming output_convention"""
    if not isinstance(name, str):
        raise TypeError(f"output_convention: expected a string ('pinocchio' or 'mujoco'), got {type(name).__name__}")
    return _core.convention_from_name(name)
