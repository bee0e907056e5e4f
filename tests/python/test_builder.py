"""rbdkit.ModelBuilder: a model written in Python equals Pinocchio's model of
the same robot written as URDF (mass matrix and inverse dynamics at random
states, 1e-10), equals rbdkit's own URDF reading of it bit for bit, and each
bad argument raises an error that names it."""

import warnings

import numpy as np
import pinocchio as pin
import pytest

import rbdkit

# a floating arm: revolute (tilted axis), a fixed tool link, prismatic, revolute
URDF = """<robot name="arm">
  <link name="base"><inertial><origin xyz="0.01 0.02 -0.03" rpy="0.1 0.2 0.3"/><mass value="3"/>
    <inertia ixx="0.05" ixy="0.001" ixz="-0.002" iyy="0.04" iyz="0.003" izz="0.03"/></inertial></link>
  <link name="upper"><inertial><origin xyz="0 0 0.2"/><mass value="1.5"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.004"/></inertial></link>
  <link name="tool"><inertial><origin xyz="0.05 0 0" rpy="0 0.4 0"/><mass value="0.3"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.0025"/></inertial></link>
  <link name="carriage"><inertial><origin xyz="0 0.1 0"/><mass value="0.8"/>
    <inertia ixx="0.003" ixy="0" ixz="0" iyy="0.002" iyz="0" izz="0.003"/></inertial></link>
  <link name="hand"><inertial><origin xyz="0 0 0.05"/><mass value="0.4"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.0005"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0.1 0 0.3" rpy="0.3 -0.2 0.5"/><axis xyz="0 0.6 0.8"/>
    <limit lower="-2" upper="2.5" velocity="3" effort="40"/></joint>
  <joint name="mount" type="fixed"><parent link="upper"/><child link="tool"/>
    <origin xyz="0 0.05 0.4" rpy="0.2 0 0"/></joint>
  <joint name="slide" type="prismatic"><parent link="upper"/><child link="carriage"/>
    <origin xyz="0 0 0.45"/><axis xyz="1 0 0"/><limit lower="-0.1" upper="0.2" velocity="1" effort="100"/></joint>
  <joint name="wrist" type="revolute"><parent link="carriage"/><child link="hand"/>
    <origin xyz="0 0.2 0" rpy="0 0 1.2"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="5" effort="10"/></joint>
</robot>"""


def rpy_R(r, p, y):
    return rbdkit._builder.rotation_from_rpy((r, p, y))


def inertial(R, Ic):
    """a URDF <inertial> rotation: the inertia about the com in link axes"""
    return R @ np.asarray(Ic) @ R.T


def arm_in_code():
    b = rbdkit.ModelBuilder("arm")
    base = b.add_body(None, "root_joint", "free", "base", mass=3, com=(0.01, 0.02, -0.03),
                      inertia=inertial(rpy_R(0.1, 0.2, 0.3), [[0.05, 0.001, -0.002], [0.001, 0.04, 0.003],
                                                              [-0.002, 0.003, 0.03]]))
    upper = b.add_body(base, "shoulder", "revolute", "upper", axis=(0, 0.6, 0.8),
                       placement=((0.3, -0.2, 0.5), (0.1, 0, 0.3)), mass=1.5, com=(0, 0, 0.2),
                       inertia=[0.02, 0.02, 0.004], lower=-2, upper=2.5, velocity=3, effort=40)
    X_tool = (rpy_R(0.2, 0, 0), (0, 0.05, 0.4))
    b.add_frame("tool", "upper", placement=X_tool, kind="link")
    b.add_inertia("upper", 0.3, com=(0.05, 0, 0), inertia=inertial(rpy_R(0, 0.4, 0), np.diag([0.001, 0.002, 0.0025])),
                  placement=X_tool)
    carriage = b.add_body(upper, "slide", "prismatic", "carriage", axis=(1, 0, 0), placement=(np.eye(3), (0, 0, 0.45)),
                          mass=0.8, com=(0, 0.1, 0), inertia=np.diag([0.003, 0.002, 0.003]), lower=-0.1, upper=0.2,
                          velocity=1, effort=100)
    b.add_body(carriage, "wrist", "revolute", "hand", placement=((0, 0, 1.2), (0, 0.2, 0)), mass=0.4,
               com=(0, 0, 0.05), inertia=np.diag([0.001, 0.001, 0.0005]), lower=-3, upper=3, velocity=5, effort=10)
    return b.build()


def test_built_model_matches_pinocchio():
    model = arm_in_code()
    rbd = rbdkit.RBD(model)
    pm = pin.buildModelFromXML(URDF, pin.JointModelFreeFlyer())
    pd = pm.createData()
    assert [pm.names[i] for i in range(2, pm.njoints)] == ["shoulder", "slide", "wrist"]
    rng = np.random.default_rng(1)
    for _ in range(5):
        q = model.random_configuration(rng)
        v, a = rng.uniform(-2, 2, model.nv), rng.uniform(-3, 3, model.nv)
        M = pin.crba(pm, pd, q)
        M = np.triu(M) + np.triu(M, 1).T
        assert np.max(np.abs(rbd.crba(q) - M)) < 1e-10
        tau = pin.rnea(pm, pd, q, v, a)
        assert np.max(np.abs(rbd.inverse_dynamics(q, v, a, gravity=-9.81)[0] - tau)) < 1e-10
        pin.framesForwardKinematics(pm, pd, q)
        R, p = rbd.frame_placement(q, "tool")
        oMf = pd.oMf[pm.getFrameId("tool")]
        assert np.max(np.abs(R - oMf.rotation)) < 1e-12 and np.max(np.abs(p - oMf.translation)) < 1e-12


def test_built_model_equals_urdf_reading():
    a, u = arm_in_code(), rbdkit.Model.from_urdf_string(URDF, floating_base=True)
    assert a.joint_names == u.joint_names and a.body_names == u.body_names
    np.testing.assert_allclose(a.inertial_parameters(), u.inertial_parameters(), rtol=0, atol=1e-15)
    assert np.array_equal(a.lower, u.lower) and np.array_equal(a.upper, u.upper)
    assert np.array_equal(a.velocity_limit, u.velocity_limit) and np.array_equal(a.effort_limit, u.effort_limit)
    q = a.random_configuration(3)
    np.testing.assert_allclose(rbdkit.RBD(a).crba(q), rbdkit.RBD(u).crba(q), rtol=0, atol=1e-14)


def test_placement_forms_agree():
    """rpy, quaternion (x, y, z, w), 3x3 and 4x4 describe the same placement"""
    R = rpy_R(0.3, -0.2, 0.5)
    w = np.sqrt(1 + np.trace(R)) / 2
    quat = np.array([(R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w), w])
    H = np.eye(4)
    H[:3, :3], H[:3, 3] = R, (1, 2, 3)
    placements = []
    for pl in [((0.3, -0.2, 0.5), (1, 2, 3)), (quat, (1, 2, 3)), (R, [1, 2, 3]), H]:
        b = rbdkit.ModelBuilder()
        b.add_body(None, "j", "revolute", "a", placement=pl, mass=1, inertia=[1, 1, 1])
        b.add_frame("f", "a")
        placements.append(rbdkit.RBD(b.build()).frame_placement(np.zeros(1), "f"))
    for Rk, pk in placements:
        np.testing.assert_allclose(Rk, R, atol=1e-15)
        np.testing.assert_allclose(pk, [1, 2, 3], atol=0)


def test_mimic_and_warning():
    b = rbdkit.ModelBuilder("m")
    a = b.add_body(None, "a", "revolute", "A", mass=1, inertia=[1, 1, 1])
    b.add_body(a, "b", "revolute", "B", mass=1, inertia=[1, 1, 1], placement=(np.eye(3), (1, 0, 0)))
    b.add_mimic("b", "a", 2.0, 0.5)
    b.add_warning("hand-written")
    with pytest.warns(UserWarning, match="hand-written"):
        m = b.build()
    assert m.nv == 1 and m.joint("b")["mimic_of"] == "a" and m.joint("b")["multiplier"] == 2.0
    assert b.nb == 0  # left empty


@pytest.mark.parametrize("kwargs, exc, match", [
    (dict(parent="nowhere"), ValueError, "parent: no body named 'nowhere'"),
    (dict(parent=7), ValueError, "parent: body 7 does not exist"),
    (dict(parent=1.5), TypeError, "parent"),
    (dict(joint_type="hinge"), ValueError, "joint_type"),
    (dict(joint_type="fixed"), ValueError, "add_inertia and add_frame"),
    (dict(joint_name=3), TypeError, "joint_name"),
    (dict(body_name=None), TypeError, "body_name"),
    (dict(axis=(0, 0, 0)), ValueError, "axis"),
    (dict(axis=(0, 1)), ValueError, r"axis: expected shape \(3,\)"),
    (dict(axis=(0, np.nan, 1)), ValueError, "axis: expected finite"),
    (dict(placement=((0, 0, 0, 2), (0, 0, 0))), ValueError, "quaternion"),
    (dict(placement=(np.ones((3, 3)), (0, 0, 0))), ValueError, "placement rotation: expected a rotation matrix"),
    (dict(placement=(np.diag([1, 1, -1]), (0, 0, 0))), ValueError, "det"),
    (dict(placement=((0, 0, 0), (0, 0))), ValueError, "placement translation"),
    (dict(placement="up"), TypeError, "placement"),
    (dict(mass=-1), ValueError, "mass: expected a mass >= 0"),
    (dict(mass="1"), TypeError, "mass"),
    (dict(com=(0, 0)), ValueError, "com"),
    (dict(inertia=[[1, 2, 0], [0, 1, 0], [0, 0, 1]]), ValueError, "symmetric"),
    (dict(inertia=[-1, 1, 1]), ValueError, "negative principal moment"),
    (dict(inertia=[1, 1, 3]), ValueError, "triangle inequality"),
    (dict(lower=1, upper=0), ValueError, "lower limit 1.0 > upper limit 0.0"),
    (dict(lower=np.nan), ValueError, "lower"),
    (dict(joint_type="continuous", lower=-1, upper=1), ValueError, "no position limits"),
    (dict(velocity=0), ValueError, "velocity"),
    (dict(effort=-1), ValueError, "effort"),
    (dict(joint_name="a"), ValueError, "a joint named 'a' already exists"),
    (dict(body_name="A"), ValueError, "a body named 'A' already exists"),
])
def test_bad_add_body(kwargs, exc, match):
    b = rbdkit.ModelBuilder()
    b.add_body(None, "a", "revolute", "A", mass=1, inertia=[1, 1, 1])
    args = dict(parent=None, joint_name="j", joint_type="revolute", body_name="B")
    args.update(kwargs)
    parent = args.pop("parent")
    with pytest.raises(exc, match=match):
        b.add_body(parent, args.pop("joint_name"), args.pop("joint_type"), args.pop("body_name"), **args)


def test_bad_other_calls():
    b = rbdkit.ModelBuilder()
    b.add_body(None, "a", "revolute", "A")
    with pytest.raises(ValueError, match="body: no body named 'X'"):
        b.add_inertia("X", 1.0)
    with pytest.raises(ValueError, match="added mass"):
        b.add_inertia("A", -1.0)
    with pytest.raises(TypeError, match="name"):
        b.add_frame("", "A")
    with pytest.raises(ValueError, match="body: body 4 does not exist"):
        b.add_frame("f", 4)
    with pytest.raises(TypeError, match="target"):
        b.add_mimic("a", None)
    with pytest.raises(ValueError, match="multiplier"):
        b.add_mimic("a", "a", np.inf)
    with pytest.raises(ValueError, match="name: no body named 'Z'"):
        b.body_index("Z")
    with pytest.raises(TypeError, match="name"):
        rbdkit.ModelBuilder(3)
    b.add_mimic("a", "nowhere")
    with pytest.raises(ValueError, match="'nowhere' is not a joint"):
        b.build()
