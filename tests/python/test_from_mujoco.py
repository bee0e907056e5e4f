"""Model.from_mujoco / from_mjcf checked against MuJoCo itself.

For MJCF models written here (hinge, slide, ball and free joints; anchors
jnt_pos; refs; several joints in one body; several trees under the world;
welded bodies; inertias from geoms and meshes; sites) and for the MuJoCo
models gymnasium ships, at random states:
  - the mass matrix: rbdkit's crba equals Tᵀ M_mj T, with M_mj from
    mj_fullM (armature 0, set before mj_setConst) and T =
    mujoco_velocity_map (qvel = T v);
  - the bias forces: rbdkit's nonlinear_effects (gravity = opt.gravity z;
    x and y parts set to 0 on the MuJoCo side)
    equals Tᵀ (qfrc_bias + M_mj b), b = d/dt qvel at zero rbdkit
    acceleration (on a free joint R (ω × v_lin));
  - every body, site and joint frame equals MuJoCo's xpos/xmat,
    site_xpos/site_xmat and xanchor/xaxis;
all to 1e-9 relative. The state maps used are RBD.state_from_mujoco (qpos
quaternions w x y z, free-joint qvel [ṗ world; ω body]).
"""

import importlib.util
import os
import warnings

import mujoco
import numpy as np
import pytest

import rbdkit

TOL = 1e-9

ARM = """
<mujoco model="arm">
  <compiler angle="radian"/>
  <worldbody>
    <body name="base" pos="0.1 0 0.2" euler="0.1 0.2 0.3">
      <inertial pos="0.01 0 0.02" mass="2" fullinertia="0.02 0.03 0.025 0.001 -0.002 0.003"/>
      <joint name="j1" type="hinge" axis="0 0 1" pos="0 0.05 0" range="-2 2" limited="true"/>
      <body name="link1" pos="0 0 0.3" quat="0.9 0.1 0.3 0.2">
        <inertial pos="0 0.02 0.1" quat="0.8 0.2 0.1 0.3" mass="1.5" diaginertia="0.01 0.012 0.004"/>
        <joint name="j2" type="hinge" axis="0.3 1 0.2" pos="0.02 -0.01 0.03" ref="0.4"/>
        <body name="welded" pos="0.05 0 0.2" euler="0 0.5 0">
          <inertial pos="0.01 0.01 0" mass="0.7" diaginertia="0.002 0.003 0.004"/>
          <site name="tool" pos="0 0 0.1" euler="0.2 0 0"/>
          <body name="slider" pos="0 0.1 0">
            <inertial pos="0 0 0.05" mass="0.5" diaginertia="0.001 0.001 0.0005"/>
            <joint name="s1" type="slide" axis="1 0.5 0" pos="0.1 0 0" ref="0.1" range="-0.2 0.3"
                   limited="true"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

BALL = """
<mujoco model="ball">
  <worldbody>
    <body name="b1" pos="0 0 1">
      <joint name="ball1" type="ball" pos="0 0 0.1"/>
      <inertial pos="0.05 0.02 -0.2" quat="1 0.2 0 0.1" mass="1.2" diaginertia="0.03 0.02 0.015"/>
      <body name="b2" pos="0.1 0 -0.4" euler="0.3 0 0">
        <joint name="h2" axis="0 1 0" pos="0 0 0.05"/>
        <joint name="ball2" type="ball" pos="0.02 0 0"/>
        <inertial pos="0 0 -0.1" mass="0.8" diaginertia="0.01 0.01 0.003"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

# a free root with a hinge+hinge+slide body and a ball+slide body
FLOATING = """
<mujoco model="floating">
  <worldbody>
    <body name="torso" pos="0.3 -0.2 1.1" quat="0.9 0.1 0.2 0.3">
      <freejoint name="root"/>
      <inertial pos="0.02 0.01 -0.03" quat="0.9 0 0.3 0.1" mass="5" diaginertia="0.2 0.15 0.1"/>
      <body name="hip" pos="0.1 0.1 -0.2" euler="0.2 -0.1 0.3">
        <joint name="hx" axis="1 0 0" pos="0 0 0.05"/>
        <joint name="hy" axis="0 1 0.3" pos="0.01 0 0.04"/>
        <joint name="hs" type="slide" axis="0 0 1" pos="0 0.02 0"/>
        <inertial pos="0 0 -0.15" mass="1" diaginertia="0.02 0.02 0.004"/>
        <site name="hip_site" pos="0.01 0.02 0.03"/>
        <body name="shin" pos="0 0 -0.3">
          <joint name="kb" type="ball" pos="0 0 0.02"/>
          <joint name="ks" type="slide" axis="0.2 0 1"/>
          <inertial pos="0 0.01 -0.1" mass="0.6" diaginertia="0.01 0.01 0.002"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

# several trees: an arm on a table (welded to the world), a free ball, a free
# box and a mesh body; inertias from geoms and the mesh (no <inertial>)
SCENE = """
<mujoco model="scene">
  <asset><mesh name="tet" vertex="0 0 0  0.2 0 0  0 0.3 0  0 0 0.25"/></asset>
  <worldbody>
    <geom type="plane" size="1 1 0.1"/>
    <body name="table" pos="0.5 0 0.4">
      <geom type="box" size="0.3 0.3 0.02" mass="10"/>
      <body name="arm1" pos="0 0 0.05">
        <joint name="a1" axis="0 0 1"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.03"/>
        <body name="arm2" pos="0 0 0.3">
          <joint name="a2" axis="0 1 0"/>
          <geom type="box" size="0.02 0.02 0.15" pos="0 0 0.15" euler="0.1 0 0"/>
          <site name="ee" pos="0 0 0.3"/>
        </body>
      </body>
    </body>
    <body name="ball" pos="0 0.5 1">
      <freejoint/>
      <geom type="sphere" size="0.05" density="500"/>
    </body>
    <body name="box" pos="0 -0.5 1" euler="0.2 0.1 0">
      <freejoint name="box_free"/>
      <geom type="box" size="0.1 0.05 0.03" pos="0.02 0 0" euler="0 0 0.3"/>
      <geom type="cylinder" size="0.02 0.1" pos="0 0.05 0"/>
      <body name="lid" pos="0 0 0.05">
        <joint name="lid_hinge" axis="1 0 0" pos="0 -0.05 0"/>
        <geom type="box" size="0.1 0.05 0.005"/>
      </body>
    </body>
    <body name="tet" pos="0 0 0.5">
      <joint name="mh" axis="1 1 0" pos="0.05 0 0"/>
      <geom type="mesh" mesh="tet"/>
    </body>
  </worldbody>
</mujoco>
"""

WRITTEN = {"arm": ARM, "ball": BALL, "floating": FLOATING, "scene": SCENE}


def gymnasium_assets():
    """the MJCF files gymnasium ships (found without importing gymnasium)"""
    spec = importlib.util.find_spec("gymnasium")
    assert spec is not None, "gymnasium is needed (requirements-dev.txt): it ships the real MuJoCo models"
    return os.path.join(spec.submodule_search_locations[0], "envs", "mujoco", "assets")


REAL = ["ant", "half_cheetah", "hopper", "humanoid", "humanoidstandup", "inverted_double_pendulum",
        "inverted_pendulum", "pusher", "reacher", "swimmer", "walker2d"]


def rel_err(a, b):
    return np.max(np.abs(np.asarray(a) - np.asarray(b))) / max(1.0, np.max(np.abs(b)))


def load(mj):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the warnings are checked in test_warnings
        return rbdkit.Model.from_mujoco(mj)


def random_state(mj, rng):
    """a random (qpos, qvel) in MuJoCo's layout"""
    qpos = np.array(mj.qpos0, dtype=np.float64)
    qvel = rng.uniform(-2, 2, mj.nv)
    for j in range(mj.njnt):
        a, t = mj.jnt_qposadr[j], mj.jnt_type[j]
        if t == mujoco.mjtJoint.mjJNT_FREE:
            qpos[a:a + 3] = rng.uniform(-1, 1, 3)
            quat = rng.normal(size=4)
            qpos[a + 3:a + 7] = quat / np.linalg.norm(quat)
        elif t == mujoco.mjtJoint.mjJNT_BALL:
            quat = rng.normal(size=4)
            qpos[a:a + 4] = quat / np.linalg.norm(quat)
        else:
            qpos[a] = rng.uniform(-1.5, 1.5)
    return qpos, qvel


def mujoco_reference(mj, qpos, qvel):
    """(M_mj, qfrc_bias, data) at (qpos, qvel) with the armature set to 0"""
    d = mujoco.MjData(mj)
    d.qpos[:], d.qvel[:] = qpos, qvel
    mujoco.mj_forward(mj, d)
    M = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, d, M)
    return M, np.array(d.qfrc_bias), d


def qvel_rate(model, qpos, v):
    """b = d/dt qvel at zero rbdkit acceleration: R (ω × v_lin) on each free joint"""
    b = np.zeros(model.nv)
    for j in model.joints:
        if j["type"] == "free":
            o, a = j["v_index"], j["q_index"]
            w, x, y, z = qpos[a + 3:a + 7]
            R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                          [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                          [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
            b[o:o + 3] = R @ np.cross(v[o + 3:o + 6], v[o:o + 3])
    return b


def check_against_mujoco(mj, samples=3, seed=0):
    """the largest relative errors (mass matrix, bias, frames) over random states"""
    mj.dof_armature[:] = 0
    mj.opt.gravity[:2] = 0  # rbdkit's gravity is along z (inverted_double_pendulum has 1e-5 along x)
    mujoco.mj_setConst(mj, mujoco.MjData(mj))  # MuJoCo 4 caches the armature in constants
    model = load(mj)
    rbd = rbdkit.RBD(model)
    g = float(mj.opt.gravity[2])
    rng = np.random.default_rng(seed)
    errs = {"M": 0.0, "bias": 0.0, "frames": 0.0}
    for _ in range(samples):
        qpos, qvel = random_state(mj, rng)
        M_mj, bias_mj, d = mujoco_reference(mj, qpos, qvel)
        x = rbd.state_from_mujoco(np.concatenate([qpos, qvel]))
        q, v = x[:model.nq], x[model.nq:]
        T = model.mujoco_velocity_map(qpos)
        assert np.allclose(T @ v, qvel, rtol=0, atol=1e-12)
        errs["M"] = max(errs["M"], rel_err(rbd.crba(q), T.T @ M_mj @ T))
        nle_ref = T.T @ (bias_mj + M_mj @ qvel_rate(model, qpos, v))
        errs["bias"] = max(errs["bias"], rel_err(rbd.nonlinear_effects(q, v, gravity=g), nle_ref))
        # frames: bodies (xpos, xmat), sites, joint anchors and axes
        for i in range(1, mj.nbody):
            R, p = rbd.frame_placement(q, mj.body(i).name or f"body{i}")
            errs["frames"] = max(errs["frames"], rel_err(p, d.xpos[i]), rel_err(R, d.xmat[i].reshape(3, 3)))
        for s in range(mj.nsite):
            if mj.site(s).name:
                R, p = rbd.frame_placement(q, mj.site(s).name)
                errs["frames"] = max(errs["frames"], rel_err(p, d.site_xpos[s]),
                                     rel_err(R, d.site_xmat[s].reshape(3, 3)))
        for j in range(mj.njnt):
            name = model.joints[j]["name"]
            if name in model.frame_names and model.frame(name)[1] == "joint":
                R, p = rbd.frame_placement(q, name)
                if mj.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:  # MuJoCo's anchor: before the slide
                    a = mj.jnt_qposadr[j]
                    p = p - (qpos[a] - mj.qpos0[a]) * d.xaxis[j]
                errs["frames"] = max(errs["frames"], rel_err(p, d.xanchor[j]))
                if mj.jnt_type[j] in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
                    errs["frames"] = max(errs["frames"], rel_err(R @ mj.jnt_axis[j], d.xaxis[j]))
    return errs


@pytest.mark.parametrize("name", sorted(WRITTEN))
def test_written_models_match_mujoco(name):
    errs = check_against_mujoco(mujoco.MjModel.from_xml_string(WRITTEN[name]))
    assert max(errs.values()) < TOL, errs


@pytest.mark.parametrize("name", REAL)
def test_real_models_match_mujoco(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo logs compiler warnings (half_cheetah's settotalmass) to MUJOCO_LOG.TXT
    mj = mujoco.MjModel.from_xml_path(os.path.join(gymnasium_assets(), name + ".xml"))
    errs = check_against_mujoco(mj, samples=2)
    assert max(errs.values()) < TOL, errs


def test_layout_follows_mujoco():
    """q follows qpos and v follows qvel; names, types, limits and refs"""
    mj = mujoco.MjModel.from_xml_string(FLOATING)
    model = load(mj)
    assert (model.nq, model.nv) == (mj.nq, mj.nv)
    assert [j["name"] for j in model.joints] == ["root", "hx", "hy", "hs", "kb", "ks"]
    assert [j["type"] for j in model.joints] == ["free", "revolute", "revolute", "prismatic", "spherical",
                                                 "prismatic"]
    assert [j["v_index"] for j in model.joints] == list(mj.jnt_dofadr)
    assert [j["q_index"] for j in model.joints] == list(mj.jnt_qposadr)
    # the massless chain bodies, the last named after the MuJoCo body
    assert model.body_names == ["torso", "hip/hx", "hip/hy", "hip", "shin/kb", "shin"]
    assert model.floating_base
    arm = load(mujoco.MjModel.from_xml_string(ARM))
    assert arm.joint("j1")["nq"] == 1
    assert arm.lower.tolist() == [-2, -np.inf, -0.2] and arm.upper.tolist() == [2, np.inf, 0.3]
    assert arm.frame("tool")[1] == "site" and arm.frame("welded")[1] == "body"
    # the welded body is merged: three moving bodies for three joints
    assert arm.nb == 3


def test_refs_fold_into_placement():
    """a hinge or slide ref: rbdkit's q equals qpos, and at qpos0 the bodies sit as the MJCF places them"""
    mj = mujoco.MjModel.from_xml_string(ARM)
    assert mj.qpos0[1] == 0.4 and mj.qpos0[2] == 0.1
    rbd = rbdkit.RBD(load(mj))
    d = mujoco.MjData(mj)
    mujoco.mj_forward(mj, d)
    for i in range(1, mj.nbody):
        R, p = rbd.frame_placement(mj.qpos0, mj.body(i).name)
        assert rel_err(p, d.xpos[i]) < TOL and rel_err(R, d.xmat[i].reshape(3, 3)) < TOL


def test_from_mjcf_file(tmp_path):
    path = tmp_path / "arm.xml"
    path.write_text(ARM)
    a, b = rbdkit.Model.from_mjcf(path), load(mujoco.MjModel.from_xml_string(ARM))
    assert a.name == "arm" and a.body_names == b.body_names
    assert np.array_equal(a.inertial_parameters(), b.inertial_parameters())


def test_warnings_name_what_is_not_imported():
    mj = mujoco.MjModel.from_xml_path(os.path.join(gymnasium_assets(), "ant.xml"))
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        rbdkit.Model.from_mujoco(mj)
    text = "\n".join(str(x.message) for x in w)
    for what in ("armature", "damping", "actuators", "contacts"):
        assert what in text, (what, text)
    mj = mujoco.MjModel.from_xml_string("""
<mujoco><option gravity="1 0 -9.81"/><worldbody><body><joint name="h" stiffness="2"/>
<geom size="0.1" contype="0" conaffinity="0"/></body><body name="b2"><joint name="h2" range="0 1"/>
<geom size="0.1" contype="0" conaffinity="0"/></body><body name="b3"><joint name="h3" type="ball" range="0 1"/>
<geom size="0.1" contype="0" conaffinity="0"/></body></worldbody>
<tendon><fixed name="t"><joint joint="h" coef="1"/></fixed></tendon>
<equality><joint joint1="h" joint2="h2"/></equality></mujoco>""")
    with pytest.warns(UserWarning) as w:
        rbdkit.Model.from_mujoco(mj)
    text = "\n".join(str(x.message) for x in w)
    for what in ("springs", "tendons", "equality constraints", "cone limits", "gravity"):
        assert what in text, (what, text)
    assert "contacts" not in text
    assert all(x.filename == __file__ for x in w)  # shown at the caller's line
    mj = mujoco.MjModel.from_xml_string("""
<mujoco><option density="1.2" viscosity="0.1"><flag gravity="disable"/></option>
<worldbody><body><joint name="h"/><geom size="0.1" contype="0" conaffinity="0"/></body></worldbody></mujoco>""")
    with pytest.warns(UserWarning) as w:
        rbdkit.Model.from_mujoco(mj)
    text = "\n".join(str(x.message) for x in w)
    assert "fluid forces" in text and "disables gravity" in text, text


def test_warnings_point_at_the_caller(tmp_path):
    path = tmp_path / "ant.xml"
    path.write_text(open(os.path.join(gymnasium_assets(), "ant.xml")).read())
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        rbdkit.Model.from_mjcf(path)
    assert any("actuators" in str(x.message) for x in w)
    assert all(x.filename == __file__ for x in w)


def test_bad_input(monkeypatch):
    model = load(mujoco.MjModel.from_xml_string(FLOATING))
    rbd = rbdkit.RBD(model)
    qpos = rbd.state_to_mujoco(np.concatenate([model.neutral(), np.zeros(model.nv)]))[:model.nq]
    with pytest.raises(ValueError, match="qpos: expected one configuration"):
        model.mujoco_velocity_map(np.tile(qpos, (2, 1)))
    with pytest.raises(ValueError, match="qpos"):
        model.mujoco_velocity_map(np.zeros(3))
    with pytest.raises(ValueError, match="unit norm"):
        model.mujoco_velocity_map(np.zeros(model.nq))
    with pytest.raises(TypeError, match="mjmodel"):
        rbdkit.Model.from_mujoco("arm.xml")
    with pytest.raises(FileNotFoundError, match="path"):
        rbdkit.Model.from_mjcf("/no/such/file.xml")
    with pytest.raises(TypeError, match="path"):
        rbdkit.Model.from_mjcf(3)
    monkeypatch.setitem(__import__("sys").modules, "mujoco", None)  # mujoco stays optional
    with pytest.raises(ImportError, match="need the mujoco package"):
        rbdkit.Model.from_mujoco(object())


def test_builder_errors_name_the_mujoco_body():
    # MuJoCo's compiler accepts a mass above rbdkit's bound (1e15 kg); the
    # error names the body it came from
    xml = """<mujoco><worldbody><body name="heavy"><joint name="hinge" type="hinge"/>
             <inertial pos="0 0 0" mass="1e20" diaginertia="1 1 1"/></body></worldbody></mujoco>"""
    with pytest.raises(ValueError, match=r"^mjmodel: body 'heavy'"):
        rbdkit.Model.from_mujoco(mujoco.MjModel.from_xml_string(xml))
