"""rbdkit.ModelBuilder: a robot model written in code.

    b = rbdkit.ModelBuilder("arm")
    upper = b.add_body(None, "shoulder", "revolute", "upper_arm", axis=(0, 0, 1),
                       placement=((0, 0, 0), (0, 0, 0.3)),       # (rpy, p) in the parent
                       mass=2.0, com=(0, 0, 0.2), inertia=np.diag([0.02, 0.02, 0.004]),
                       lower=-2.9, upper=2.9)
    b.add_frame("tool", upper, placement=(np.eye(3), (0, 0, 0.4)))
    model = b.build()                                          # an rbdkit.Model

Bodies are added under their parents (None: the world) through a joint; the
order of add_body is the coordinate order of the model. A placement is
(rotation, translation): the rotation a 3x3 matrix, a roll-pitch-yaw triple
(fixed axes x, y, z as URDF: R = Rz(yaw) Ry(pitch) Rx(roll)) or a unit
quaternion (x, y, z, w) (rbdkit's order); or a 4x4 homogeneous matrix; None
is the identity. Inertias: mass, centre of mass in the body frame and the
rotational inertia about the centre of mass in body axes (3x3, or (3,) for a
diagonal one). A fixed link is rigidly attached with add_inertia and add_frame.
"""

import math
import numbers

import numpy as np

from . import _core
from ._model import Model

JOINT_TYPES = ("revolute", "continuous", "prismatic", "helical", "spherical", "free")
_INF = math.inf


def _real(x, name):
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (numbers.Real, np.floating, np.integer)):
        raise TypeError(f"{name}: expected a real number, got {x!r} ({type(x).__name__})")
    return float(x)


def _finite(x, name):
    x = _real(x, name)
    if not math.isfinite(x):
        raise ValueError(f"{name}: expected a finite number, got {x}")
    return x


def _array(x, name, shapes):
    """x as a finite float64 array of one of the shapes"""
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected an array of real numbers of shape "
                        f"{' or '.join(map(str, shapes))}, got {x!r}") from None
    if a.shape not in shapes:
        raise ValueError(f"{name}: expected shape {' or '.join(map(str, shapes))}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite values, got {a.tolist()}")
    return a


def rotation_from_rpy(rpy):
    """R = Rz(yaw) Ry(pitch) Rx(roll) (fixed axes, as URDF)"""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def rotation_from_quat(q):
    """the rotation of a unit quaternion (x, y, z, w)"""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def placement_arrays(placement, name="placement"):
    """(R (3, 3), p (3,)) of a placement given as None, (rotation, translation)
    or a 4x4 homogeneous matrix; ValueError/TypeError naming `name`"""
    if placement is None:
        return np.eye(3), np.zeros(3)
    if isinstance(placement, np.ndarray) and placement.shape == (4, 4):
        T = _array(placement, name, [(4, 4)])
        if not np.allclose(T[3], [0, 0, 0, 1], rtol=0, atol=1e-12):
            raise ValueError(f"{name}: a 4x4 placement must end with the row (0, 0, 0, 1), got {T[3].tolist()}")
        R, p = T[:3, :3], T[:3, 3]
    else:
        if not isinstance(placement, (tuple, list)) or len(placement) != 2:
            raise TypeError(f"{name}: expected (rotation, translation), a 4x4 matrix or None, got {placement!r}")
        rot = _array(placement[0], f"{name} rotation", [(3, 3), (3,), (4,)])
        p = _array(placement[1], f"{name} translation", [(3,)])
        if rot.shape == (3,):
            R = rotation_from_rpy(rot)
        elif rot.shape == (4,):
            n = np.linalg.norm(rot)
            if abs(n - 1) > 1e-6:
                raise ValueError(f"{name} rotation: a quaternion (x, y, z, w) must have norm 1, got norm {n:.9g}")
            R = rotation_from_quat(rot / n)
        else:
            R = rot
    err = np.max(np.abs(R.T @ R - np.eye(3)))
    if err > 1e-9 or np.linalg.det(R) < 0:
        raise ValueError(f"{name} rotation: expected a rotation matrix (orthonormal, det +1), got "
                         f"|RᵀR - 1| = {err:.3g}, det = {np.linalg.det(R):.6g}")
    return R, p


def inertia_arrays(mass, com, inertia, name):
    """(mass, com (3,), I_com (3, 3)) checked: mass >= 0, I_com symmetric and
    physically possible (principal moments >= 0, triangle inequality)"""
    m = _finite(mass, f"{name} mass")
    if m < 0:
        raise ValueError(f"{name} mass: expected a mass >= 0, got {m}")
    c = _array(com, f"{name} com", [(3,)])
    if inertia is None:
        I = np.zeros((3, 3))
    else:
        I = _array(inertia, f"{name} inertia", [(3, 3), (3,)])
        if I.shape == (3,):
            I = np.diag(I)
    scale = max(1e-300, np.max(np.abs(I)))
    if np.max(np.abs(I - I.T)) > 1e-12 * scale:
        raise ValueError(f"{name} inertia: expected a symmetric 3x3 matrix, got {I.tolist()}")
    I = 0.5 * (I + I.T)
    ev = np.linalg.eigvalsh(I)
    if ev[0] < -1e-12 * scale:
        raise ValueError(f"{name} inertia: the rotational inertia has a negative principal moment "
                         f"(principal moments {ev.tolist()}); expected a positive semi-definite matrix")
    if ev[2] > ev[0] + ev[1] + 1e-10 * scale:
        raise ValueError(f"{name} inertia: principal moments {ev.tolist()} break the triangle inequality "
                         "(the largest exceeds the sum of the other two); no rigid body has this inertia")
    return m, c, I


def _flat(a):
    return np.ascontiguousarray(a, dtype=np.float64).ravel().tolist()


class ModelBuilder:
    """A Model built in code: add_body, add_inertia, add_frame, add_mimic, then
    build(). See the module docstring for the argument forms."""

    def __init__(self, name=""):
        if not isinstance(name, str):
            raise TypeError(f"name: expected the robot name (str), got {type(name).__name__}")
        self._b = _core.ModelBuilder(name)

    @property
    def nb(self):
        """the bodies added so far"""
        return self._b.nb

    def body_index(self, name):
        """the index of a body by name; ValueError if there is none"""
        if not isinstance(name, str):
            raise TypeError(f"name: expected a body name (str), got {type(name).__name__}")
        i = self._b.body_index(name)
        if i < 0:
            raise ValueError(f"name: no body named {name!r}")
        return i

    def _body(self, body, name, world=True):
        """-1 (the world) for None, the index of a body named or numbered"""
        if body is None and world:
            return -1
        if isinstance(body, str):
            i = self._b.body_index(body)
            if i < 0:
                raise ValueError(f"{name}: no body named {body!r} (add it first; None is the world)")
            return i
        if isinstance(body, (bool, np.bool_)) or not isinstance(body, (numbers.Integral, np.integer)):
            raise TypeError(f"{name}: expected a body index, a body name or None (the world), got {body!r}")
        if not -1 <= body < self.nb:
            raise ValueError(f"{name}: body {body} does not exist (expected -1 or None for the world, "
                             f"or 0..{self.nb - 1})")
        return int(body)

    def add_body(self, parent, joint_name, joint_type, body_name, *, axis=(0.0, 0.0, 1.0), placement=None,
                 mass=0.0, com=(0.0, 0.0, 0.0), inertia=None, lower=-_INF, upper=_INF, velocity=_INF,
                 effort=_INF, pitch=0.0):
        """Add body `body_name` under `parent` (index, name or None for the
        world) through joint `joint_name` of `joint_type` (revolute,
        continuous, prismatic, helical, spherical, free). placement: the joint
        frame in the parent's frame; the body frame is the joint frame moved
        by the joint. axis: the direction of a 1-DoF joint in the joint frame.
        mass, com, inertia: the body's own inertia (com in the body frame,
        inertia about the com in body axes). lower/upper: position limits of
        a revolute, prismatic or helical joint (lower > upper is an error
        here; the URDF reader keeps such a file's numbers with a warning, as
        Pinocchio does); velocity/effort: limits on
        each DoF. pitch: metres per radian of a helical joint. Returns the
        body index."""
        for n, s in (("joint_name", joint_name), ("joint_type", joint_type), ("body_name", body_name)):
            if not isinstance(s, str):
                raise TypeError(f"{n}: expected a str, got {type(s).__name__}")
        if joint_type not in JOINT_TYPES:
            hint = " (a fixed link: add_inertia and add_frame on the parent)" if joint_type == "fixed" else ""
            raise ValueError(f"joint_type: expected one of {', '.join(JOINT_TYPES)}, got {joint_type!r}{hint}")
        p_index = self._body(parent, "parent")
        ax = _array(axis, "axis", [(3,)])
        if joint_type not in ("spherical", "free") and not np.any(ax != 0):
            raise ValueError(f"axis: joint {joint_name!r} ({joint_type}) needs a non-zero axis, got {ax.tolist()}")
        R, p = placement_arrays(placement)
        m, c, I = inertia_arrays(mass, com, inertia, "body")
        lo, hi = _real(lower, "lower"), _real(upper, "upper")
        vel, eff = _real(velocity, "velocity"), _real(effort, "effort")
        for n, x in (("lower", lo), ("upper", hi), ("velocity", vel), ("effort", eff)):
            if math.isnan(x):
                raise ValueError(f"{n}: expected a number or ±inf, got nan")
        if lo > hi:
            raise ValueError(f"lower, upper: joint {joint_name!r} has lower limit {lo} > upper limit {hi}")
        if joint_type in ("continuous", "spherical", "free") and (math.isfinite(lo) or math.isfinite(hi)):
            raise ValueError(f"lower, upper: a {joint_type} joint has no position limits, got [{lo}, {hi}]")
        for n, x in (("velocity", vel), ("effort", eff)):
            if not x > 0:
                raise ValueError(f"{n}: expected a limit > 0 (inf: none), got {x}")
        pitch = _finite(pitch, "pitch")
        return self._b.add_body(p_index, joint_name, joint_type, body_name, _flat(R), _flat(p), _flat(ax), pitch,
                                lo, hi, vel, eff, m, _flat(c), _flat(I))

    def add_inertia(self, body, mass, com=(0.0, 0.0, 0.0), inertia=None, placement=None):
        """Rigidly attach a mass to `body` (index or name; None, the world,
        drops it): com and inertia (about the com) in a frame placed at
        `placement` in the body's frame."""
        b = self._body(body, "body")
        R, p = placement_arrays(placement)
        m, c, I = inertia_arrays(mass, com, inertia, "added")
        self._b.add_inertia(b, m, _flat(c), _flat(I), _flat(R), _flat(p))

    def add_frame(self, name, body, placement=None, kind="frame"):
        """A named frame fixed to `body` (index, name or None for the world)
        at `placement` in the body's frame; kind is a word of the caller's
        ("site", "tool", ...)."""
        if not isinstance(name, str) or not name:
            raise TypeError(f"name: expected a non-empty frame name (str), got {name!r}")
        if not isinstance(kind, str):
            raise TypeError(f"kind: expected a str, got {type(kind).__name__}")
        b = self._body(body, "body")
        R, p = placement_arrays(placement)
        self._b.add_frame(name, kind, b, _flat(R), _flat(p))

    def add_mimic(self, joint, target, multiplier=1.0, offset=0.0):
        """Joint `joint` follows `target`: q_joint = multiplier·q_target +
        offset (both 1-DoF joints; checked in build())."""
        for n, s in (("joint", joint), ("target", target)):
            if not isinstance(s, str):
                raise TypeError(f"{n}: expected a joint name (str), got {type(s).__name__}")
        self._b.add_mimic(joint, target, _finite(multiplier, "multiplier"), _finite(offset, "offset"))

    def add_warning(self, text):
        """a note the built model carries (shown as a UserWarning on build)"""
        if not isinstance(text, str):
            raise TypeError(f"text: expected a str, got {type(text).__name__}")
        self._b.add_warning(text)

    def build(self, _stacklevel=3):
        """The rbdkit.Model. The builder is left empty."""
        return Model(self._b.build(), _stacklevel)
