"""Models from MuJoCo: Model.from_mujoco(mjModel) and Model.from_mjcf(path).

MuJoCo's compiler has already resolved defaults, includes, orientations and
the inertias it infers from geoms and meshes; this reads the compiled
mujoco.MjModel and builds the same tree through rbdkit.ModelBuilder.

  - bodies are read in MuJoCo's order, so q follows qpos and v follows qvel
    (a qvel index names the same DoF in both); the state and force maps are
    RBD.state_from_mujoco / state_to_mujoco / force_*_mujoco and
    Model.mujoco_velocity_map (the output convention, docs/conventions.md)
  - hinge -> revolute, slide -> prismatic, ball -> spherical, free -> free;
    a joint turns about (or slides along) its axis through its anchor
    jnt_pos; a hinge or slide `ref` is folded into the placement, so q = qpos
  - a body with several joints is a chain of massless bodies named
    "<body>/<joint>", the last (named after the MuJoCo body) carrying the
    inertia; MuJoCo applies the joints in order, each in the frame the
    previous ones left: X = X_body0 Π_k T(p_k) J_k(q_k) T(-p_k) (its
    compiler allows only slides after a ball joint, and a free joint only
    alone on a child of the world)
  - a body without joints is welded to its parent (inertia merged)
  - frames: each MuJoCo body (kind "body"), joint ("joint": the joint frame
    at its anchor, moved by the joint) and site ("site") by name; unnamed
    ones get "body<i>", "<body>_joint<k>", "site<i>"
What MuJoCo adds beyond rigid-body dynamics (armature, damping, friction
loss, springs, gravity compensation, equality constraints, tendons,
actuators, contacts, flexes, plugins, fluid forces) is not imported; the
model warns about each kind it finds. Hinge and slide ranges become the
position limits (lower, upper), not constraint forces. Gravity: rbdkit's is along z (gravity=
mj.opt.gravity[2] in the RBD calls); a model whose gravity has x or y parts
gets a warning.
"""

import contextlib
import os

import numpy as np

from ._builder import ModelBuilder, rotation_from_quat

# mjtJoint
_FREE, _BALL, _SLIDE, _HINGE = 0, 1, 2, 3
_TYPES = {_FREE: "free", _BALL: "spherical", _SLIDE: "prismatic", _HINGE: "revolute"}


def _mujoco():
    try:
        import mujoco
    except ImportError as e:  # the package is optional
        raise ImportError("Model.from_mujoco / from_mjcf need the mujoco package (pip install mujoco)") from e
    return mujoco


def _quat_wxyz_to_R(q):
    """the rotation of MuJoCo's quaternion (w, x, y, z)"""
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return rotation_from_quat((x, y, z, w))


def _axis_angle(u, t):
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + np.sin(t) * K + (1 - np.cos(t)) * (K @ K)


class _X:
    """a rigid transform (R, p): x_parent = R x_child + p"""

    def __init__(self, R=None, p=None):
        self.R = np.eye(3) if R is None else np.asarray(R, dtype=np.float64)
        self.p = np.zeros(3) if p is None else np.asarray(p, dtype=np.float64)

    def __mul__(self, o):
        return _X(self.R @ o.R, self.R @ o.p + self.p)

    def pair(self):
        return (self.R, self.p)


@contextlib.contextmanager
def _naming(where):
    """a builder error names the MuJoCo body (and joint) it came from"""
    try:
        yield
    except ValueError as e:
        raise ValueError(f"mjmodel: {where}: {e}") from e


def _unique(name, taken):
    n, k = name, 1
    while n in taken:
        n, k = f"{name}_{k}", k + 1
    taken.add(n)
    return n


def _warn_unmodelled(mujoco, m, b):
    """one warning per kind of MuJoCo feature that the rigid-body model leaves out"""
    def note(count, what):
        if count:
            b.add_warning(f"{what} not imported (rbdkit models rigid-body dynamics only)")

    note(int(np.count_nonzero(m.dof_armature)), f"armature on {np.count_nonzero(m.dof_armature)} DoF:")
    note(int(np.count_nonzero(m.dof_damping)), f"damping on {np.count_nonzero(m.dof_damping)} DoF:")
    note(int(np.count_nonzero(m.dof_frictionloss)), f"friction loss on {np.count_nonzero(m.dof_frictionloss)} DoF:")
    note(int(np.count_nonzero(m.jnt_stiffness)), f"springs (stiffness) on {np.count_nonzero(m.jnt_stiffness)} joints:")
    note(int(np.count_nonzero(m.body_gravcomp)), f"gravity compensation on {np.count_nonzero(m.body_gravcomp)} bodies:")
    note(m.neq, f"{m.neq} equality constraints:")
    note(m.ntendon, f"{m.ntendon} tendons:")
    note(m.nu, f"{m.nu} actuators (their gains, ranges and transmissions):")
    collide = int(np.count_nonzero((m.geom_contype != 0) | (m.geom_conaffinity != 0)))
    note(collide, f"contacts ({collide} colliding geoms):")
    limited = [i for i in range(m.njnt) if m.jnt_limited[i] and m.jnt_type[i] == _BALL]
    note(len(limited), f"cone limits of {len(limited)} ball joints:")
    mocap = int(np.count_nonzero(m.body_mocapid >= 0))
    note(mocap, f"{mocap} mocap bodies (welded at their model pose here):")
    note(m.nflex, f"{m.nflex} flexes (deformable elements):")
    note(m.nplugin, f"{m.nplugin} plugins:")
    fluid = m.opt.density > 0 or m.opt.viscosity > 0 or np.any(m.opt.wind != 0)
    note(fluid, f"fluid forces (density {m.opt.density}, viscosity {m.opt.viscosity}):")
    g = np.asarray(m.opt.gravity, dtype=np.float64)
    if m.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY):
        b.add_warning("the model disables gravity; pass gravity=0 to match it")
    elif g[0] != 0 or g[1] != 0:
        b.add_warning(f"the model's gravity {g.tolist()} has x or y parts; rbdkit's gravity is along z "
                      f"(pass gravity={g[2]} for its z part)")


def from_mujoco(m, _stacklevel=4):
    """rbdkit.Model of a compiled mujoco.MjModel (see the module docstring);
    its warnings point _stacklevel frames up from ModelBuilder.build"""
    mujoco = _mujoco()
    if not isinstance(m, mujoco.MjModel):
        raise TypeError(f"mjmodel: expected a compiled mujoco.MjModel, got {type(m).__name__}")
    names = bytes(m.names)
    name = names[:names.index(b"\0")].decode() or "mujoco"
    b = ModelBuilder(name)
    # MuJoCo's own names are kept; generated ones avoid them
    taken_bodies = {m.body(i).name for i in range(m.nbody)} - {""}
    taken_joints = {m.joint(j).name for j in range(m.njnt)} - {""}
    taken_frames = set(taken_bodies)

    rbd_body = np.full(m.nbody, -1, dtype=int)
    X_rbd_mj = [_X() for _ in range(m.nbody)]
    for i in range(1, m.nbody):
        bname = m.body(i).name or _unique(f"body{i}", taken_bodies)
        taken_frames.add(bname)
        parent = int(m.body_parentid[i])
        # the body frame before its joints, in the rbdkit body of the parent
        X = X_rbd_mj[parent] * _X(_quat_wxyz_to_R(m.body_quat[i]), m.body_pos[i])
        body = rbd_body[parent]
        nj, j0 = int(m.body_jntnum[i]), int(m.body_jntadr[i])
        for k in range(nj):
            j = j0 + k
            jtype = int(m.jnt_type[j])
            if jtype not in _TYPES:
                raise ValueError(f"mjmodel: joint {j} of body '{bname}' has type {jtype}, expected hinge, slide, "
                                 "ball or free")
            jname = m.joint(j).name or _unique(f"{bname}_joint{k}", taken_joints)
            last = k == nj - 1
            bn = bname if last else _unique(f"{bname}/{jname}", taken_bodies)
            if jtype == _FREE:
                # MuJoCo places a free body (the only joint of a child of the
                # world) by qpos alone: body_pos is its qpos0
                X_joint = _X()
            else:
                anchor = np.asarray(m.jnt_pos[j], dtype=np.float64)
                X_joint = X * _X(None, anchor)
                # hinge / slide move by qpos - qpos0 (the joint's ref): fold -ref into the placement
                ref = float(m.qpos0[m.jnt_qposadr[j]]) if jtype in (_HINGE, _SLIDE) else 0.0
                u = np.asarray(m.jnt_axis[j], dtype=np.float64)
                if ref != 0 and jtype == _HINGE:
                    X_joint = X_joint * _X(_axis_angle(u / np.linalg.norm(u), -ref))
                elif ref != 0:
                    X_joint = X_joint * _X(None, -ref * u / np.linalg.norm(u))
            lower = upper = None
            if jtype in (_HINGE, _SLIDE) and m.jnt_limited[j]:
                lower, upper = (float(x) for x in m.jnt_range[j])
            kw = {} if lower is None else {"lower": lower, "upper": upper}
            with _naming(f"body '{bname}', joint '{jname}'"):
                body = b.add_body(int(body), jname, _TYPES[jtype], bn, axis=m.jnt_axis[j]
                                  if jtype in (_HINGE, _SLIDE) else (0.0, 0.0, 1.0), placement=X_joint.pair(), **kw)
            if jname not in taken_frames:  # a body of the same name keeps the name
                b.add_frame(jname, body, kind="joint")
                taken_frames.add(jname)
            # the next joint (or the MuJoCo body) is the joint frame moved back from the anchor
            X = _X() if jtype == _FREE else _X(None, -np.asarray(m.jnt_pos[j], dtype=np.float64))
        rbd_body[i] = body
        X_rbd_mj[i] = X
        b.add_frame(bname, int(body), placement=X.pair(), kind="body")
        # the body's inertia: principal moments in the inertial frame (ipos, iquat)
        mass = float(m.body_mass[i])
        if mass > 0 or np.any(m.body_inertia[i] != 0):
            X_inertial = X * _X(_quat_wxyz_to_R(m.body_iquat[i]), m.body_ipos[i])
            with _naming(f"body '{bname}'"):
                b.add_inertia(int(body), mass, inertia=np.asarray(m.body_inertia[i], dtype=np.float64),
                              placement=X_inertial.pair())
    for s in range(m.nsite):
        i = int(m.site_bodyid[s])
        sname = _unique(m.site(s).name or f"site{s}", taken_frames)
        X = X_rbd_mj[i] * _X(_quat_wxyz_to_R(m.site_quat[s]), m.site_pos[s])
        b.add_frame(sname, int(rbd_body[i]), placement=X.pair(), kind="site")
    _warn_unmodelled(mujoco, m, b)
    model = b.build(_stacklevel)
    # q follows qpos and v follows qvel: check the layout against MuJoCo's
    for j in range(m.njnt):
        info = model.joints[j]  # one rbdkit body per MuJoCo joint, in the same order
        if info["q_index"] != m.jnt_qposadr[j] or info["v_index"] != m.jnt_dofadr[j]:
            raise RuntimeError(f"from_mujoco: joint {j} is at q {info['q_index']}, v {info['v_index']}; "
                               f"MuJoCo has qpos {m.jnt_qposadr[j]}, qvel {m.jnt_dofadr[j]}")
    if model.nq != m.nq or model.nv != m.nv:
        raise RuntimeError(f"from_mujoco: nq, nv = {model.nq}, {model.nv}; MuJoCo has {m.nq}, {m.nv}")
    return model


def from_mjcf(path, _stacklevel=5):
    """compile an MJCF file with MuJoCo, then from_mujoco"""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path: expected a file path (str or os.PathLike), got {type(path).__name__}")
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"path: no MJCF file at '{path}'")
    mujoco = _mujoco()
    return from_mujoco(mujoco.MjModel.from_xml_path(path), _stacklevel)
