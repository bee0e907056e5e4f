"""rbdkit.Model: a robot read from URDF or MuJoCo, or built in code."""

import os
import warnings

import numpy as np

from . import _core
from ._checks import as_real_array


def _flags(**flags):
    """the values of boolean options, in order; a TypeError names any that is
    not a bool (a numpy bool counts; "no", 1 or an array do not)"""
    out = []
    for name, value in flags.items():
        if not isinstance(value, (bool, np.bool_)):
            raise TypeError(f"{name}: expected True or False, got {value!r} ({type(value).__name__})")
        out.append(bool(value))
    return out


class Model:
    """A robot model: bodies, joints, frames and limits, read from URDF
    (from_urdf), from MuJoCo (from_mujoco, from_mjcf) or built in code
    (rbdkit.ModelBuilder).

    Attributes
      nq, nv        configuration and velocity widths
      nb            moving bodies (fixed links are merged into them)
      joint_names   joints owning velocity coordinates, in velocity order
      frame_names   every link and joint, fixed ones included
      joints        per body: dict(name, type, body, q_index, v_index, nq, nv,
                    mimic_of, multiplier, offset)
      lower, upper  (nq,) position limits; velocity_limit, effort_limit (nv,)
    """

    def __init__(self, core, _stacklevel=3):
        if not isinstance(core, _core.Model):
            raise TypeError("Model: build one with Model.from_urdf(path) or rbdkit.robots.load(name)")
        self._core = core
        for w in core.warnings:  # shown at the caller's line (_stacklevel frames up from here)
            warnings.warn(f"{core.name or 'URDF'}: {w}", UserWarning, stacklevel=_stacklevel)

    @classmethod
    def from_urdf(cls, path, floating_base=False, strict=False, mimic=True):
        """Read a URDF file. floating_base adds a free-flyer root joint
        'root_joint' (q = [x, y, z, qx, qy, qz, qw, ...]); strict makes a
        physically impossible link inertia (a negative principal moment, the
        triangle inequality broken) an error instead of a warning; mimic=True
        folds each <mimic> joint into its target's coordinate, mimic=False
        makes it an independent coordinate (Pinocchio's default)."""
        if not isinstance(path, (str, os.PathLike)):
            raise TypeError(f"path: expected a file path (str or os.PathLike), got {type(path).__name__}")
        path = os.fspath(path)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"path: no URDF file at '{path}'")
        flags = _flags(floating_base=floating_base, strict=strict, mimic=mimic)
        return cls(_core.Model.from_urdf_file(path, *flags))

    @classmethod
    def from_urdf_string(cls, xml, floating_base=False, strict=False, mimic=True):
        """Read a URDF document given as a string (options as from_urdf)."""
        if not isinstance(xml, str):
            raise TypeError(f"xml: expected the URDF text as str, got {type(xml).__name__}")
        flags = _flags(floating_base=floating_base, strict=strict, mimic=mimic)
        return cls(_core.Model.from_urdf_string(xml, *flags))

    @classmethod
    def from_mujoco(cls, mjmodel):
        """The rigid-body tree of a compiled mujoco.MjModel (MuJoCo has
        resolved defaults, includes and inferred inertias). q follows qpos and
        v follows qvel (a qvel index names the same DoF); convert states with
        RBD.state_from_mujoco / state_to_mujoco (free joints: qvel = T v, see
        Model.mujoco_velocity_map). What is not rigid-body dynamics (armature,
        damping, springs, equality constraints, tendons, actuators, contacts)
        is left out with a warning. Gravity: pass gravity=mjmodel.opt.gravity[2]."""
        from ._mujoco_import import from_mujoco
        return from_mujoco(mjmodel, _stacklevel=5)

    @classmethod
    def from_mjcf(cls, path):
        """Compile an MJCF file with the mujoco package, then from_mujoco."""
        from ._mujoco_import import from_mjcf
        return from_mjcf(path, _stacklevel=6)

    # ---- sizes and names
    name = property(lambda self: self._core.name)
    nq = property(lambda self: self._core.nq)
    nv = property(lambda self: self._core.nv)
    nb = property(lambda self: self._core.nb)
    floating_base = property(lambda self: self._core.floating_base)
    has_mimic = property(lambda self: self._core.has_mimic)
    joint_names = property(lambda self: list(self._core.joint_names))
    frame_names = property(lambda self: list(self._core.frame_names))
    body_names = property(lambda self: list(self._core.body_names))
    body_parents = property(lambda self: list(self._core.body_parents))
    joints = property(lambda self: list(self._core.joints))
    lower = property(lambda self: np.array(self._core.lower))
    upper = property(lambda self: np.array(self._core.upper))
    velocity_limit = property(lambda self: np.array(self._core.velocity_limit))
    effort_limit = property(lambda self: np.array(self._core.effort_limit))

    def frame(self, name):
        """(body index or -1 for the world, kind, R (3, 3), p (3,)): the
        placement of a named frame in its body's frame"""
        if not isinstance(name, str):
            raise TypeError(f"name: expected a frame name (str), got {type(name).__name__}")
        body, kind, R, p = self._core.frame_placement(self._core.frame_index(name))
        return body, kind, np.array(R).reshape(3, 3), np.array(p)

    def joint(self, name):
        """the joints entry of a named joint"""
        if not isinstance(name, str):
            raise TypeError(f"name: expected a joint name (str), got {type(name).__name__}")
        return self._core.joints[self._core.joint_index(name)]

    def neutral(self):
        """the neutral configuration (nq,): zero joints, identity quaternions"""
        return np.array(self._core.neutral())

    def inertial_parameters(self):
        """π (10·nb,): per body, in body order (body_names), [m, m·c_x, m·c_y,
        m·c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz] with I the rotational
        inertia about the body-frame origin in body axes (Pinocchio's dynamic
        parameters); fixed links merged into a body are included in it"""
        return np.array(self._core.inertial_parameters())

    def with_inertial_parameters(self, pi):
        """a new Model with the inertial parameters pi (10·nb,) (this one is
        unchanged). ValueError, naming the link, for non-finite values and,
        on every body whose 10 values differ from this model's, a physically
        inconsistent inertia: negative mass, zero mass with a non-zero first
        moment, a rotational inertia about the centre of mass that is not
        positive semi-definite or breaks the triangle inequalities. Bodies
        passed back unchanged keep their values as read from the URDF."""
        a = as_real_array(pi, "pi")
        n = 10 * self.nb
        if a.shape != (n,):
            raise ValueError(f"pi: expected shape ({n},) with 10*nb={n}, got shape {a.shape}")
        new = object.__new__(Model)  # no second round of the reader's warnings
        new._core = self._core.with_inertial_parameters(a.tolist())
        return new

    def mujoco_velocity_map(self, qpos):
        """T (nv, nv) with qvel = T v at one configuration qpos (nq,) in
        MuJoCo's layout (quaternions w x y z): on each free joint the linear
        block is the joint's rotation R (ṗ = R v_lin), identity elsewhere
        (docs/conventions.md, MuJoCo models in). T is orthogonal: v = Tᵀ
        qvel, qfrc = T u, M = Tᵀ M_mj T."""
        q = as_real_array(qpos, "qpos")
        if q.shape != (self.nq,):
            raise ValueError(f"qpos: expected one configuration of shape ({self.nq},), got shape {q.shape}")
        # row k: T e_k (force_to_mujoco is u -> T u; qpos broadcast over the rows)
        to_mujoco = _core.OpHandle(self._core, [], 0, "float64").op("force_to_mujoco", False)
        return to_mujoco(q, np.eye(self.nv)).T.copy()

    def random_configuration(self, rng=None, scale=1.0):
        """a random configuration: neutral ⊕ uniform(-scale, scale) tangent
        step (joint limits are not applied)"""
        rng = np.random.default_rng(rng)
        q = np.empty(self.nq)
        _core.integrate(self._core, self.neutral()[None], rng.uniform(-scale, scale, (1, self.nv)), q[None])
        return q

    def summary(self):
        """a short text description"""
        types = {}
        for j in self.joints:
            t = j["type"] + (" (mimic)" if j["mimic_of"] else "")
            types[t] = types.get(t, 0) + 1
        jt = ", ".join(f"{n} {t}" for t, n in sorted(types.items()))
        base = "floating base" if self.floating_base else "fixed base"
        return (f"robot {self.name!r}: {self.nb} bodies, nq={self.nq}, nv={self.nv}, {base}\n"
                f"  joints: {jt}\n  frames: {len(self.frame_names)}")

    def __repr__(self):
        return f"<rbdkit.Model {self.name!r} nq={self.nq} nv={self.nv} nb={self.nb}>"
