"""The URDF reader's rules seen from Python, with Pinocchio as the reference:
what is accepted with a warning (surfaced as a UserWarning) and what is an
error; mimic=False (Pinocchio's default); generated names that never take a
name of the file. The structural rules are also tested in C++
(tests/cpp/test_urdf.cpp, run under AddressSanitizer by test.sh)."""

import os

import numpy as np
import pytest

import rbdkit
from pinref import URDF_DIR, Reference, compare_dynamics


def link(name, mass=1.0, inertia="0.01 0 0 0.02 0 0.03", xyz="0.05 -0.02 0.1"):
    ixx, ixy, ixz, iyy, iyz, izz = inertia.split()
    return (f'<link name="{name}"><inertial><origin xyz="{xyz}" rpy="0.1 0.2 0.3"/><mass value="{mass}"/>'
            f'<inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" izz="{izz}"/></inertial></link>')


def joint(name, type, parent, child, extra=""):
    return f'<joint name="{name}" type="{type}"><parent link="{parent}"/><child link="{child}"/>{extra}</joint>'


def robot(body):
    return f'<robot name="t">{body}</robot>'


def test_zero_axis_on_a_fixed_joint_loads_on_a_moving_joint_fails():
    m = rbdkit.Model.from_urdf_string(robot(link("base") + link("a") + joint("f", "fixed", "base", "a",
                                                                             '<axis xyz="0 0 0"/>')))
    assert m.nv == 0 and "f" in m.frame_names
    with pytest.raises(ValueError, match="joint 'r' has a zero axis"):
        rbdkit.Model.from_urdf_string(robot(link("base") + link("a") + joint("r", "revolute", "base", "a",
                                                                             '<axis xyz="0 0 0"/>')))


def test_rounding_negative_moment_warns_clearly_negative_fails():
    xml = robot(link("base") + link("a", inertia="0.01 0 0 -1e-17 0 0.01") + joint("j", "continuous", "base", "a"))
    with pytest.warns(UserWarning, match="link 'a' has a negative principal moment of inertia iyy.*rounding"):
        m = rbdkit.Model.from_urdf_string(xml)
    assert m.nv == 1
    with pytest.raises(ValueError, match="link 'a' has a negative principal moment of inertia iyy=-0.1"):
        rbdkit.Model.from_urdf_string(xml.replace("-1e-17", "-0.1"))


def test_missing_mimic_target_warns_and_keeps_a_coordinate():
    xml = robot(link("base") + link("a") + link("b") + joint("j", "continuous", "base", "a") +
                joint("k", "continuous", "a", "b", '<mimic joint="nope"/>'))
    with pytest.warns(UserWarning, match="joint 'k' mimics joint 'nope', which is not defined"):
        m = rbdkit.Model.from_urdf_string(xml)
    assert m.nv == 2 and m.joint("k")["mimic_of"] is None and m.joint("k")["v_index"] == 1


def test_lower_above_upper_warns_and_keeps_the_numbers():
    xml = robot(link("base") + link("a") + joint("j", "revolute", "base", "a",
                                                 '<limit lower="0.5" upper="-0.25" effort="3" velocity="2"/>'))
    with pytest.warns(UserWarning, match="joint 'j' has lower limit 0.5 > upper limit -0.25"):
        m = rbdkit.Model.from_urdf_string(xml)
    assert m.lower.tolist() == [0.5] and m.upper.tolist() == [-0.25]


@pytest.mark.parametrize("floating", [False, True])
def test_mimic_false_equals_pinocchios_default_model(floating):
    path = os.path.join(URDF_DIR, "mimic.urdf")
    ref = Reference(path, floating, mimic=False)
    m = ref.model
    # one coordinate per moving joint, as in Pinocchio's model: G is a permutation
    assert not m.has_mimic and m.nv == ref.pin.nv == 7 + 6 * floating
    assert sorted(ref.G.sum(axis=0).tolist()) == [1.0] * m.nv and set(ref.G.ravel().tolist()) == {0.0, 1.0}
    assert m.lower[m.joint("finger_r_joint")["q_index"]] == -0.05  # the mimic's own limits kept
    compare_dynamics(ref, "mimic.urdf, mimic=False")
    # the default still folds the couplings, and agrees with Pinocchio through G
    folded = Reference(path, floating)
    assert folded.model.has_mimic and folded.model.nv == 4 + 6 * floating
    compare_dynamics(folded, "mimic.urdf, mimic=True")


def _clash_robot(hinge):
    """a revolute joint named `hinge` under the root, with its limits, and a mimic of it"""
    return robot(
        link("base", 2.0, "0.1 0 0 0.2 0 0.3") + link("a", 1.5, "0.05 0.01 0 0.04 0 0.03") +
        link("b", 0.7, "0.02 0 0.001 0.03 0 0.01") +
        joint(hinge, "revolute", "base", "a", '<origin xyz="0.1 0.2 0.3" rpy="0.3 -0.2 0.1"/><axis xyz="0 1 0"/>'
              '<limit lower="-0.5" upper="0.5" effort="3" velocity="2"/>') +
        joint("m", "revolute", "a", "b", '<origin xyz="0.3 0 0.1"/><axis xyz="1 0 0"/>'
              f'<limit lower="-1" upper="1" effort="4" velocity="5"/><mimic joint="{hinge}" multiplier="2" '
              'offset="0.1"/>'))


@pytest.mark.parametrize("mimic", [True, False])
def test_user_joint_named_root_joint_with_floating_base(tmp_path, mimic):
    path = tmp_path / "clash.urdf"
    path.write_text(_clash_robot("root_joint"))
    with pytest.warns(UserWarning, match="free-flyer added by floating_base is named 'root_joint_1'"):
        ref = Reference(str(path), True, mimic=mimic)
    m = ref.model
    assert [j["name"] for j in m.joints] == ["root_joint_1", "root_joint", "m"]
    assert m.joints[0]["type"] == "free" and m.joints[1]["type"] == "revolute"
    assert m.nq == 8 + (not mimic) and m.nv == 7 + (not mimic)
    assert (m.joint("m")["mimic_of"] == "root_joint") == mimic
    # the free-flyer has no limits; the user's joint keeps its own
    assert np.all(np.isinf(m.lower[:7])) and np.all(np.isinf(m.upper[:7])) and np.all(np.isinf(m.velocity_limit[:6]))
    assert m.lower[7] == -0.5 and m.upper[7] == 0.5 and m.velocity_limit[6] == 2.0
    # Pinocchio's model, its free-flyer named root_joint_1 too
    assert ref.pin.names[1] == "root_joint_1" and ref.pin.names[2] == "root_joint"
    compare_dynamics(ref, f"root_joint clash, mimic={mimic}")


def test_planar_sub_joint_names_never_take_a_user_name():
    xml = robot(link("base") + link("a") + link("b") + link("c") +
                joint("p", "planar", "base", "a", '<axis xyz="0 0 1"/>') +
                joint("p_x", "revolute", "a", "b", '<axis xyz="0 1 0"/><mimic joint="q" multiplier="2"/>'
                      '<limit lower="-1" upper="1" effort="3" velocity="2"/>') +
                joint("q", "continuous", "b", "c"))
    m = rbdkit.Model.from_urdf_string(xml)
    names = [j["name"] for j in m.joints]
    assert names == ["p_x_1", "p_y", "p_rot", "p_x", "q"]
    # the user's p_x is the mimic, never the planar joint's x translation
    assert m.joint("p_x_1")["type"] == "prismatic" and m.joint("p_x_1")["mimic_of"] is None
    assert m.joint("p_x")["type"] == "revolute" and m.joint("p_x")["mimic_of"] == "q"
    assert m.nv == 4
