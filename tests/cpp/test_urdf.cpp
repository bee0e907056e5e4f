// URDF reader: bundled robots load with the expected sizes; every joint type,
// fixed-joint merging, mimic resolution and each malformed input.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "rbdkit/model.hpp"

using rbd::Model;

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
std::string error_of(const std::string& xml, bool floating = false) {
  try {
    Model::from_urdf_string(xml, floating);
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
