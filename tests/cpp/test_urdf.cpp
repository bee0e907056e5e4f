// URDF reader: bundled robots load with the expected sizes; every joint type,
// fixed-joint merging, mimic resolution and each malformed input; what real
// files need (accepted with a warning) and what stays an error; generated
// names that never collide; chains of any depth.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include <Eigen/Dense>

#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/parsers/model.hpp"

using rbd::Dynamics;
using rbd::Model;
using rbd::Mat3;
using rbd::Vec3;
using rbd::axis_angle;

namespace {
const std::string kRobots = RBDKIT_ROBOTS_DIR;

std::string link(const std::string& name, double mass = 1.0, const std::string& inertia = "1 0 0 1 0 1") {
  double i[6];
  sscanf(inertia.c_str(), "%lf %lf %lf %lf %lf %lf", &i[0], &i[1], &i[2], &i[3], &i[4], &i[5]);
  char buf[512];
  snprintf(buf, sizeof buf,
           "<link name=\"%s\"><inertial><mass value=\"%g\"/><inertia ixx=\"%g\" ixy=\"%g\" ixz=\"%g\" iyy=\"%g\" "
           "iyz=\"%g\" izz=\"%g\"/></inertial></link>",
           name.c_str(), mass, i[0], i[1], i[2], i[3], i[4], i[5]);
  return buf;
}
std::string joint(const std::string& name, const std::string& type, const std::string& parent,
                  const std::string& child, const std::string& extra = "") {
  return "<joint name=\"" + name + "\" type=\"" + type + "\"><parent link=\"" + parent + "\"/><child link=\"" +
         child + "\"/>" + extra + "</joint>";
}
std::string robot(const std::string& body) { return "<robot name=\"t\">" + body + "</robot>"; }

// the exception message of building `xml`, "" if it builds
std::string error_of(const std::string& xml, bool floating = false, bool mimic = true) {
  try {
    Model::from_urdf_string(xml, floating, false, mimic);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(Urdf, BundledRobotsHaveExpectedSizes) {
  const Model iiwa = Model::from_urdf_file(kRobots + "/iiwa.urdf");
  EXPECT_EQ(iiwa.nq, 7);
  EXPECT_EQ(iiwa.nv, 7);
  const Model hyq = Model::from_urdf_file(kRobots + "/hyq.urdf", true);
  EXPECT_EQ(hyq.nq, 19);
  EXPECT_EQ(hyq.nv, 18);
  EXPECT_EQ(hyq.joints[0].name, "root_joint");
  const Model atlas = Model::from_urdf_file(kRobots + "/atlas.urdf");
  EXPECT_EQ(atlas.nv, 30);
}

TEST(Urdf, DepthFirstInDocumentOrder) {
  // siblings keep document order (not alphabetical)
  const std::string xml = robot(link("base") + link("a") + link("b") + link("c") +
                                joint("zz", "continuous", "base", "a") + joint("aa", "continuous", "base", "b") +
                                joint("mm", "continuous", "a", "c"));
  const Model m = Model::from_urdf_string(xml);
  ASSERT_EQ(m.joint_names().size(), 3u);
  EXPECT_EQ(m.joint_names()[0], "zz");
  EXPECT_EQ(m.joint_names()[1], "mm");
  EXPECT_EQ(m.joint_names()[2], "aa");
}

TEST(Urdf, FixedJointsMergeInertiaAndKeepFrames) {
  // a 2 kg link fixed 1 m along x of a 1 kg link: one body of 3 kg, CoM at x = 2/3
  const std::string xml =
      robot(link("base") + link("a") + link("tool", 2.0) + joint("j", "revolute", "base", "a",
            "<limit lower=\"-1\" upper=\"1\" effort=\"5\" velocity=\"2\"/>") +
            joint("f", "fixed", "a", "tool", "<origin xyz=\"1 0 0\"/>"));
  const Model m = Model::from_urdf_string(xml);
  ASSERT_EQ(m.nb(), 1);
  EXPECT_DOUBLE_EQ(m.bodies[0].I.m, 3.0);
  EXPECT_DOUBLE_EQ(m.bodies[0].I.h.x, 2.0);
  const int f = m.frame_index("tool");
  EXPECT_EQ(m.frames[f].body, 0);
  EXPECT_DOUBLE_EQ(m.frames[f].X_body_frame.p.x, 1.0);
  EXPECT_DOUBLE_EQ(m.lower[0], -1.0);
  EXPECT_DOUBLE_EQ(m.upper[0], 1.0);
  EXPECT_DOUBLE_EQ(m.effort_limit[0], 5.0);
  EXPECT_DOUBLE_EQ(m.velocity_limit[0], 2.0);
}

// an rpy of quarter turns rounded (to double precision, or to 11 digits as HyQ's files) is read as the
// exact quarter turns, within 1e-10 of the file's rotation; one further off (π/2 to float32's 7
// digits, Atlas's) as written
TEST(Urdf, QuarterTurnPlacementsAreExact) {
  const auto placed = [](const std::string& rpy) {
    const Model m = Model::from_urdf_string(robot(link("base") + link("a", 1.0, "0.1 0 0 0.2 0 0.3") +
        joint("j", "continuous", "base", "a", "<origin xyz=\"0.1 0 0\" rpy=\"" + rpy + "\"/><axis xyz=\"0 0 1\"/>")));
    return m.bodies[0].X_tree.R;
  };
  const Mat3<double> exact = {{0, 0, 1, 1, 0, 0, 0, 1, 0}};  // Rz(π/2) Rx(π/2)
  for (const char* rpy : {"1.5707963267948966 0 1.5707963267948966", "1.57079632679 0 1.57079632679",
                          "1.570796326794897 -0.0 1.570796326794897"}) {
    const Mat3<double> R = placed(rpy);
    for (int k = 0; k < 9; ++k) EXPECT_EQ(R.m[k], exact.m[k]) << rpy << " entry " << k;
  }
  // not within 1e-10: the file's rotation, entries as axis_angle's
  const Mat3<double> R = placed("1.5708 0 0");
  const Mat3<double> ref = axis_angle(Vec3<double>{1, 0, 0}, 1.5708);
  for (int k = 0; k < 9; ++k) EXPECT_EQ(R.m[k], ref.m[k]) << "entry " << k;
  EXPECT_NE(R(1, 1), 0.0);
  // a general rotation is as written
  const Mat3<double> G = placed("0.3 -0.2 0.1");
  const Mat3<double> Gref = axis_angle(Vec3<double>{0, 0, 1}, 0.1) * axis_angle(Vec3<double>{0, 1, 0}, -0.2) *
                            axis_angle(Vec3<double>{1, 0, 0}, 0.3);
  for (int k = 0; k < 9; ++k) EXPECT_EQ(G.m[k], Gref.m[k]) << "entry " << k;
}

TEST(Urdf, JointTypesAndSizes) {
  const std::string xml = robot(
      link("base") + link("a") + link("b") + link("c") + link("d") + link("e") +
      joint("sph", "spherical", "base", "a") + joint("hel", "helical", "a", "b", "<axis xyz=\"0 0 2\" pitch=\"0.1\"/>") +
      joint("pla", "planar", "b", "c", "<axis xyz=\"0 0 1\"/>") + joint("pri", "prismatic", "c", "d",
      "<axis xyz=\"1 1 0\"/><limit lower=\"0\" upper=\"1\" effort=\"1\" velocity=\"1\"/>") +
      joint("fl", "floating", "d", "e"));
  const Model m = Model::from_urdf_string(xml);
  // spherical 4/3, helical 1/1, planar 3/3, prismatic 1/1, floating 7/6
  EXPECT_EQ(m.nq, 4 + 1 + 3 + 1 + 7);
  EXPECT_EQ(m.nv, 3 + 1 + 3 + 1 + 6);
  EXPECT_DOUBLE_EQ(m.bodies[1].pitch, 0.1);
  EXPECT_NEAR(m.bodies[1].axis.z, 1.0, 1e-15);  // axis normalised
  EXPECT_NEAR(m.bodies[5].axis.x, std::sqrt(0.5), 1e-15);
  EXPECT_EQ(m.joints[2].name, "pla_x");
  EXPECT_EQ(m.joints[4].name, "pla_rot");
}

TEST(Urdf, MimicChainsFlatten) {
  const std::string xml = robot(link("base") + link("a") + link("b") + link("c") +
                                joint("j", "continuous", "base", "a") +
                                joint("m1", "continuous", "a", "b", "<mimic joint=\"j\" multiplier=\"2\" offset=\"0.1\"/>") +
                                joint("m2", "continuous", "b", "c", "<mimic joint=\"m1\" multiplier=\"-3\" offset=\"0.5\"/>"));
  const Model m = Model::from_urdf_string(xml);
  EXPECT_EQ(m.nv, 1);
  EXPECT_EQ(m.joints[2].mimic_of, "j");
  // q_m2 = -3 (2 q + 0.1) + 0.5 = -6 q + 0.2
  EXPECT_DOUBLE_EQ(m.joints[2].multiplier, -6.0);
  EXPECT_NEAR(m.joints[2].offset, 0.2, 1e-15);
}

TEST(Urdf, MalformedInputsAreRejectedWithClearMessages) {
  const std::string two = link("base") + link("a");
  EXPECT_NE(error_of("<robot><link name=").find("malformed XML"), std::string::npos);
  EXPECT_NE(error_of("<notarobot/>").find("<robot>"), std::string::npos);
  EXPECT_NE(error_of(robot(two + joint("j", "wobbly", "base", "a"))).find("unknown type 'wobbly'"), std::string::npos);
  EXPECT_NE(error_of(robot(two + joint("j", "continuous", "nope", "a"))).find("parent link 'nope'"), std::string::npos);
  EXPECT_NE(error_of(robot(two + link("c"))).find("root links"), std::string::npos);
  EXPECT_NE(error_of(robot(two + link("c") + joint("j1", "continuous", "base", "a") +
                           joint("j2", "continuous", "a", "c") + joint("j3", "continuous", "c", "a")))
                .find("child of two joints"),
            std::string::npos);
  EXPECT_NE(error_of(robot(link("a") + link("b") + joint("j1", "continuous", "a", "b") +
                           joint("j2", "continuous", "b", "a")))
                .find("cycle"),
            std::string::npos);
  EXPECT_NE(error_of(robot(link("base") + link("a", -1.0) + joint("j", "continuous", "base", "a"))).find("negative mass"),
            std::string::npos);
  EXPECT_NE(error_of(robot(link("base") + link("a", 1.0, "1 0 0 -1 0 1") + joint("j", "continuous", "base", "a")))
                .find("negative principal moment of inertia iyy"),
            std::string::npos);
  EXPECT_NE(error_of(robot(two + link("b") + joint("j", "continuous", "base", "a", "<mimic joint=\"k\"/>") +
                           joint("k", "continuous", "a", "b", "<mimic joint=\"j\"/>")))
                .find("mimic joints form a cycle"),
            std::string::npos);
  EXPECT_NE(error_of(robot(two + joint("j", "continuous", "base", "a", "<origin xyz=\"1 2\"/>"))).find("3 numbers"),
            std::string::npos);
  EXPECT_THROW(Model::from_urdf_file("/nonexistent/robot.urdf"), std::invalid_argument);
}

TEST(Urdf, NonPsdInertiaWarnsOrFailsWhenStrict) {
  // positive moments but |ixy| too large: eigenvalues 1 ± 3 -> one negative
  const std::string xml = robot(link("base") + link("a", 1.0, "1 3 0 1 0 1") + joint("j", "continuous", "base", "a"));
  const Model m = Model::from_urdf_string(xml);
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_NE(m.warnings[0].find("link 'a'"), std::string::npos);
  EXPECT_THROW(Model::from_urdf_string(xml, false, true), std::invalid_argument);
}

TEST(Urdf, UnknownNamesAreRejected) {
  const Model m = Model::from_urdf_file(kRobots + "/iiwa.urdf");
  EXPECT_THROW(m.frame_index("iiwa_link_99"), std::invalid_argument);
  EXPECT_THROW(m.joint_index("nope"), std::invalid_argument);
  EXPECT_EQ(m.frames[m.frame_index("iiwa_link_7")].body, 6);
}

namespace {
bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }
// the warning of `m` that contains `part`, "" if none
std::string warning_with(const Model& m, const std::string& part) {
  for (const std::string& w : m.warnings)
    if (has(w, part)) return w;
  return "";
}
}  // namespace

TEST(UrdfReader, ZeroAxisOnlyMattersOnAMovingJoint) {
  // 17 files of example-robot-data write <axis xyz="0 0 0"/> on fixed joints
  const Model m = Model::from_urdf_string(
      robot(link("base") + link("a") + joint("f", "fixed", "base", "a", "<axis xyz=\"0 0 0\"/>")));
  EXPECT_EQ(m.nv, 0);
  EXPECT_TRUE(m.warnings.empty());
  for (const char* type : {"revolute", "continuous", "prismatic"}) {
    const std::string e =
        error_of(robot(link("base") + link("a") + joint("r", type, "base", "a", "<axis xyz=\"0 0 0\"/>")));
    EXPECT_TRUE(has(e, "joint 'r'") && has(e, "zero axis")) << type << ": " << e;
  }
}

TEST(UrdfReader, MomentsNegativeByRoundingWarnClearlyNegativeFail) {
  // -0.000000 in a file is about -1e-17: kept, with a warning naming the link and the moment
  for (const char* tiny : {"-1e-17", "-1e-9"}) {
    const Model m = Model::from_urdf_string(robot(link("base") + "<link name=\"a\"><inertial><mass value=\"1\"/>"
                                                  "<inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"" + tiny +
                                                  "\" iyz=\"0\" izz=\"0.01\"/></inertial></link>" +
                                                  joint("j", "continuous", "base", "a")));
    const std::string w = warning_with(m, "link 'a'");
    EXPECT_TRUE(has(w, "iyy") && has(w, "rounding")) << tiny << ": " << w;
    EXPECT_EQ(m.nv, 1);
  }
  // clearly negative: an error, whatever the scale of the others
  for (const char* neg : {"-0.1", "-1e-4"}) {
    const std::string e = error_of(robot(link("base") + "<link name=\"a\"><inertial><mass value=\"1\"/>"
                                         "<inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"" + neg +
                                         "\" iyz=\"0\" izz=\"0.01\"/></inertial></link>" +
                                         joint("j", "continuous", "base", "a")));
    EXPECT_TRUE(has(e, "link 'a'") && has(e, "negative principal moment of inertia iyy")) << neg << ": " << e;
  }
}

TEST(UrdfReader, MissingMimicTargetWarnsAndKeepsACoordinate) {
  const std::string xml = robot(link("base") + link("a") + link("b") + joint("j", "continuous", "base", "a") +
                                joint("k", "continuous", "a", "b", "<mimic joint=\"nope\" multiplier=\"2\"/>"));
  const Model m = Model::from_urdf_string(xml);
  EXPECT_EQ(m.nv, 2);
  EXPECT_TRUE(m.joints[1].mimic_of.empty());
  EXPECT_EQ(m.joints[1].v_idx, 1);
  EXPECT_TRUE(has(warning_with(m, "joint 'k'"), "'nope', which is not defined")) << m.warnings.size();
}

TEST(UrdfReader, MimicOnAFixedJointIsIgnored) {
  // talos' grippers: a fixed joint carrying a <mimic> (Pinocchio ignores it)
  const std::string xml = robot(link("base") + link("a") + link("b") + joint("j", "continuous", "base", "a") +
                                joint("f", "fixed", "a", "b", "<mimic joint=\"j\"/>"));
  const Model m = Model::from_urdf_string(xml);
  EXPECT_EQ(m.nv, 1);
  EXPECT_EQ(m.nb(), 1);
  EXPECT_TRUE(has(warning_with(m, "joint 'f'"), "ignored"));
}

TEST(UrdfReader, LowerAboveUpperWarnsAndKeepsTheNumbers) {
  const Model m = Model::from_urdf_string(robot(link("base") + link("a") + joint("j", "revolute", "base", "a",
      "<limit lower=\"0.5\" upper=\"-0.25\" effort=\"3\" velocity=\"2\"/>")));
  EXPECT_DOUBLE_EQ(m.lower[0], 0.5);
  EXPECT_DOUBLE_EQ(m.upper[0], -0.25);
  EXPECT_DOUBLE_EQ(m.effort_limit[0], 3.0);
  const std::string w = warning_with(m, "joint 'j'");
  EXPECT_TRUE(has(w, "lower limit 0.5 > upper limit -0.25")) << w;
}

TEST(UrdfReader, MimicFalseMakesIndependentCoordinates) {
  const std::string path = std::string(RBDKIT_TEST_URDF_DIR) + "/mimic.urdf";
  const Model folded = Model::from_urdf_file(path);
  const Model free = Model::from_urdf_file(path, false, false, false);
  EXPECT_EQ(folded.nv, 4);  // wrist, finger_l_joint, shoulder, wrist2
  EXPECT_EQ(free.nv, 7);    // one per moving joint
  EXPECT_EQ(free.nb(), folded.nb());
  for (const auto& j : free.joints) EXPECT_TRUE(j.mimic_of.empty()) << j.name;
  // the mimic's own limits are kept (a folded mimic has none)
  const auto& fr = free.joints[free.joint_index("finger_r_joint")];
  EXPECT_DOUBLE_EQ(free.lower[fr.q_idx], -0.05);
  // no mimic check at all: a mimic of a missing joint gives no warning
  const Model m = Model::from_urdf_string(robot(link("base") + link("a") +
      joint("k", "continuous", "base", "a", "<mimic joint=\"nope\"/>")), false, false, false);
  EXPECT_TRUE(m.warnings.empty());
}

namespace {
// a revolute joint named `hinge` under the root with its own limits, and a mimic of it
std::string clash_robot(const std::string& hinge) {
  return robot(link("base", 2.0, "0.1 0 0 0.2 0 0.3") + link("a", 1.5, "0.05 0.01 0 0.04 0 0.03") +
               link("b", 0.7, "0.02 0 0.001 0.03 0 0.01") +
               joint(hinge, "revolute", "base", "a",
                     "<origin xyz=\"0.1 0.2 0.3\" rpy=\"0.3 -0.2 0.1\"/><axis xyz=\"0 1 0\"/>"
                     "<limit lower=\"-0.5\" upper=\"0.5\" effort=\"3\" velocity=\"2\"/>") +
               joint("m", "revolute", "a", "b",
                     "<origin xyz=\"0.3 0 0.1\"/><axis xyz=\"1 0 0\"/>"
                     "<limit lower=\"-1\" upper=\"1\" effort=\"4\" velocity=\"5\"/>"
                     "<mimic joint=\"" + hinge + "\" multiplier=\"2\" offset=\"0.1\"/>"));
}
}  // namespace

TEST(UrdfReader, UserJointNamedRootJointWithFloatingBase) {
  // the free-flyer must not take the user's name, limits or mimic (this read past
  // the end of q before: ASan heap-buffer-overflow in quat_to_matrix)
  const Model m = Model::from_urdf_string(clash_robot("root_joint"), true);
  ASSERT_EQ(m.nb(), 3);
  EXPECT_EQ(m.joints[0].name, "root_joint_1");
  EXPECT_EQ(m.joints[0].type, "free");
  EXPECT_EQ(m.joints[1].name, "root_joint");
  EXPECT_EQ(m.nq, 8);
  EXPECT_EQ(m.nv, 7);
  EXPECT_EQ(m.joints[2].mimic_of, "root_joint");
  EXPECT_EQ(m.bodies[2].q_idx, 7);
  for (int k = 0; k < 7; ++k) {
    EXPECT_EQ(m.lower[k], -std::numeric_limits<double>::infinity());
    EXPECT_EQ(m.upper[k], std::numeric_limits<double>::infinity());
  }
  for (int k = 0; k < 6; ++k) EXPECT_EQ(m.velocity_limit[k], std::numeric_limits<double>::infinity());
  EXPECT_DOUBLE_EQ(m.lower[7], -0.5);
  EXPECT_DOUBLE_EQ(m.velocity_limit[6], 2.0);
  EXPECT_TRUE(has(warning_with(m, "root_joint_1"), "free-flyer"));
  // the same dynamics as the robot whose joint has another name (run under ASan by test.sh)
  Dynamics d(m), ref(Model::from_urdf_string(clash_robot("hinge"), true));
  ASSERT_EQ(ref.model().nq, 8);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  Eigen::VectorXd dq(7), qd(7), qdd(7), tau(7);
  for (int k = 0; k < 7; ++k) dq[k] = U(rng), qd[k] = U(rng), qdd[k] = U(rng), tau[k] = U(rng);
  const std::vector<double> q0 = m.neutral();
  const Eigen::VectorXd q = d.integrate(Eigen::Map<const Eigen::VectorXd>(q0.data(), 8), dq);
  EXPECT_EQ(d.inverse_dynamics(q, qd, qdd), ref.inverse_dynamics(q, qd, qdd));
  EXPECT_EQ(d.crba(q), ref.crba(q));
  EXPECT_EQ(d.aba(q, qd, tau), ref.aba(q, qd, tau));
}

TEST(UrdfReader, PlanarSubJointNamesNeverTakeAUserName) {
  // the user's joint p_x has a mimic: it must stay the user's revolute joint's,
  // never the planar joint's x sub-joint's
  const std::string xml = robot(
      link("base") + link("a") + link("b") + link("c") + joint("p", "planar", "base", "a", "<axis xyz=\"0 0 1\"/>") +
      joint("p_x", "revolute", "a", "b",
            "<axis xyz=\"0 1 0\"/><limit lower=\"-1\" upper=\"1\" effort=\"3\" velocity=\"2\"/>"
            "<mimic joint=\"q\" multiplier=\"2\"/>") +
      joint("q", "continuous", "b", "c") + link("p_y") + joint("f", "fixed", "c", "p_y"));
  const Model m = Model::from_urdf_string(xml);
  ASSERT_EQ(m.nb(), 5);
  EXPECT_EQ(m.joints[0].name, "p_x_1");  // "p_x" is the user's joint, "p_y" a user's link
  EXPECT_EQ(m.joints[1].name, "p_y_1");
  EXPECT_EQ(m.joints[2].name, "p_rot");
  EXPECT_EQ(m.joints[0].type, "prismatic");
  EXPECT_TRUE(m.joints[0].mimic_of.empty());
  EXPECT_EQ(m.joints[3].name, "p_x");
  EXPECT_EQ(m.joints[3].type, "revolute");
  EXPECT_EQ(m.joints[3].mimic_of, "q");
  EXPECT_EQ(m.nv, 4);  // x, y, rot and q
  // the names are unique among joints, bodies and frames of each kind
  for (size_t i = 0; i < m.joints.size(); ++i)
    for (size_t k = i + 1; k < m.joints.size(); ++k) EXPECT_NE(m.joints[i].name, m.joints[k].name);
  EXPECT_EQ(m.frames[m.frame_index("p")].body, 2);  // the planar joint's frame: on the rotating body
}

TEST(UrdfReader, HundredThousandLinkChainLoads) {
  // the reader walks with an explicit stack: the recursive one overflowed at ~10,500 links
  const int n = 100000;
  std::string xml = "<robot name=\"chain\"><link name=\"l0\"/>";
  xml.reserve(static_cast<size_t>(n) * 260);
  for (int k = 1; k <= n; ++k) {
    const std::string p = "l" + std::to_string(k - 1), c = "l" + std::to_string(k);
    xml += "<link name=\"" + c + "\"><inertial><mass value=\"0.01\"/><inertia ixx=\"1e-4\" ixy=\"0\" ixz=\"0\" "
           "iyy=\"1e-4\" iyz=\"0\" izz=\"1e-4\"/></inertial></link><joint name=\"j" + std::to_string(k) +
           "\" type=\"continuous\"><parent link=\"" + p + "\"/><child link=\"" + c +
           "\"/><origin xyz=\"0 0 0.01\"/><axis xyz=\"0 1 0\"/></joint>";
  }
  xml += "</robot>";
  const auto t0 = std::chrono::steady_clock::now();
  const Model m = Model::from_urdf_string(xml);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  RecordProperty("load_seconds", std::to_string(s));
  ASSERT_EQ(m.nb(), n);
  EXPECT_EQ(m.nv, n);
  EXPECT_EQ(m.bodies[n - 1].parent, n - 2);
  EXPECT_EQ(m.joints[n - 1].name, "j100000");
  EXPECT_EQ(m.frames[m.frame_index("l100000")].body, n - 1);
}
