// ModelBuilder: a model written in code equals the URDF reader's model of the
// same robot bit for bit (bodies, limits, frames, dynamics), and each bad
// input is an std::invalid_argument that names it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/batch/derivatives_api.hpp"
#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/parsers/builder.hpp"

using namespace rbd;

namespace {

// a floating arm: revolute, a fixed tool link (merged), prismatic with limits,
// continuous, inertial origins with rotations
const char* kUrdf = R"(<robot name="arm">
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
    <origin xyz="0.1 0 0.3" rpy="0.3 -0.2 0.5"/><axis xyz="0 1 1"/>
    <limit lower="-2" upper="2.5" velocity="3" effort="40"/></joint>
  <joint name="mount" type="fixed"><parent link="upper"/><child link="tool"/>
    <origin xyz="0 0.05 0.4" rpy="0.2 0 0"/></joint>
  <joint name="slide" type="prismatic"><parent link="upper"/><child link="carriage"/>
    <origin xyz="0 0 0.45"/><axis xyz="1 0 0"/><limit lower="-0.1" upper="0.2" velocity="1" effort="100"/></joint>
  <joint name="wrist" type="continuous"><parent link="carriage"/><child link="hand"/>
    <origin xyz="0 0.2 0" rpy="0 0 1.2"/><axis xyz="0 0 1"/></joint>
</robot>)";

// the rotation of URDF rpy (fixed axes): Rz Ry Rx
Mat3<double> rpy(double r, double p, double y) {
  return axis_angle(Vec3<double>{0, 0, 1}, y) * axis_angle(Vec3<double>{0, 1, 0}, p) *
         axis_angle(Vec3<double>{1, 0, 0}, r);
}

// a URDF <inertial>: mass, origin (c, R) and the inertia about c in the origin's axes
Inertia<double> inertial(double m, const Vec3<double>& c, const Mat3<double>& R, const Mat3<double>& Ic) {
  return rigid_inertia(m, c, R * Ic * transpose(R));
}
Mat3<double> sym(double ixx, double ixy, double ixz, double iyy, double iyz, double izz) {
  return {{ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz}};
}

Model arm_in_code() {
  const Transform<double> I = Transform<double>::identity();
  ModelBuilder b("arm");
  JointSpec root;
  root.name = "root_joint";
  root.type = "free";
  const int base = b.add_body(-1, root, "base");
  b.add_frame("root_joint", "joint", base, I);
  b.add_frame("base", "link", base, I);
  b.add_inertia(base, inertial(3, {0.01, 0.02, -0.03}, rpy(0.1, 0.2, 0.3), sym(0.05, 0.001, -0.002, 0.04, 0.003, 0.03)),
                I);
  JointSpec sh;
  sh.name = "shoulder";
  sh.type = "revolute";
  sh.X_parent_joint = {rpy(0.3, -0.2, 0.5), {0.1, 0, 0.3}};
  sh.axis = {0, 1, 1};
  sh.lower = -2, sh.upper = 2.5, sh.velocity = 3, sh.effort = 40;
  const int upper = b.add_body(base, sh, "upper");
  b.add_frame("shoulder", "joint", upper, I);
  b.add_frame("upper", "link", upper, I);
  b.add_inertia(upper, inertial(1.5, {0, 0, 0.2}, Mat3<double>::identity(), sym(0.02, 0, 0, 0.02, 0, 0.004)), I);
  const Transform<double> X_upper_tool = {rpy(0.2, 0, 0), {0, 0.05, 0.4}};
  b.add_frame("mount", "joint", upper, X_upper_tool);
  b.add_frame("tool", "link", upper, X_upper_tool);
  b.add_inertia(upper, inertial(0.3, {0.05, 0, 0}, rpy(0, 0.4, 0), sym(0.001, 0, 0, 0.002, 0, 0.0025)), X_upper_tool);
  JointSpec sl;
  sl.name = "slide";
  sl.type = "prismatic";
  sl.X_parent_joint = {Mat3<double>::identity(), {0, 0, 0.45}};
  sl.axis = {1, 0, 0};
  sl.lower = -0.1, sl.upper = 0.2, sl.velocity = 1, sl.effort = 100;
  const int carriage = b.add_body(upper, sl, "carriage");
  b.add_frame("slide", "joint", carriage, I);
  b.add_frame("carriage", "link", carriage, I);
  b.add_inertia(carriage, inertial(0.8, {0, 0.1, 0}, Mat3<double>::identity(), sym(0.003, 0, 0, 0.002, 0, 0.003)), I);
  JointSpec wr;
  wr.name = "wrist";
  wr.type = "continuous";
  wr.X_parent_joint = {rpy(0, 0, 1.2), {0, 0.2, 0}};
  wr.axis = {0, 0, 1};
  const int hand = b.add_body(carriage, wr, "hand");
  b.add_frame("wrist", "joint", hand, I);
  b.add_frame("hand", "link", hand, I);
  b.add_inertia(hand, inertial(0.4, {0, 0, 0.05}, Mat3<double>::identity(), sym(0.001, 0, 0, 0.001, 0, 0.0005)), I);
  return b.build();
}

void expect_same_bits(const Mat3<double>& a, const Mat3<double>& b) {
  for (int k = 0; k < 9; ++k) EXPECT_EQ(a.m[k], b.m[k]) << k;
}
void expect_same_bits(const Vec3<double>& a, const Vec3<double>& b) {
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.y, b.y);
  EXPECT_EQ(a.z, b.z);
}

// the message of `fn`'s std::invalid_argument, "" if it throws none
template <typename Fn> std::string error_of(Fn&& fn) {
  try {
    fn();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Builder, CodeEqualsUrdfBitForBit) {
  const Model u = Model::from_urdf_string(kUrdf, true);
  const Model c = arm_in_code();
  ASSERT_EQ(c.nq, u.nq);
  ASSERT_EQ(c.nv, u.nv);
  ASSERT_EQ(c.nb(), u.nb());
  EXPECT_EQ(c.body_names, u.body_names);
  EXPECT_EQ(c.joint_names(), u.joint_names());
  EXPECT_EQ(c.lower, u.lower);
  EXPECT_EQ(c.upper, u.upper);
  EXPECT_EQ(c.velocity_limit, u.velocity_limit);
  EXPECT_EQ(c.effort_limit, u.effort_limit);
  EXPECT_EQ(c.floating_base, u.floating_base);
  for (int i = 0; i < c.nb(); ++i) {
    const BodyDesc<double>&a = c.bodies[i], &b = u.bodies[i];
    EXPECT_EQ(a.parent, b.parent);
    EXPECT_EQ(a.type, b.type);
    EXPECT_EQ(a.q_idx, b.q_idx);
    EXPECT_EQ(a.v_idx, b.v_idx);
    expect_same_bits(a.axis, b.axis);
    expect_same_bits(a.X_tree.R, b.X_tree.R);
    expect_same_bits(a.X_tree.p, b.X_tree.p);
    EXPECT_EQ(a.I.m, b.I.m);
    expect_same_bits(a.I.h, b.I.h);
    expect_same_bits(a.I.I, b.I.I);
  }
  for (const std::string name : {"base", "tool", "mount", "hand", "wrist"}) {
    const FrameInfo &a = c.frames[c.frame_index(name)], &b = u.frames[u.frame_index(name)];
    EXPECT_EQ(a.body, b.body) << name;
    EXPECT_EQ(a.kind, b.kind) << name;
    expect_same_bits(a.X_body_frame.R, b.X_body_frame.R);
    expect_same_bits(a.X_body_frame.p, b.X_body_frame.p);
  }
  // the dynamics, bit for bit
  Dynamics dc(c), du(u);
  Eigen::VectorXd dq(c.nv), qd(c.nv), qdd(c.nv);
  for (int k = 0; k < c.nv; ++k) dq[k] = 0.3 * k - 0.7, qd[k] = 0.5 - 0.2 * k, qdd[k] = std::sin(k + 1.0);
  const std::vector<double> q0 = c.neutral();
  const Eigen::VectorXd q = dc.integrate(Eigen::Map<const Eigen::VectorXd>(q0.data(), c.nq), dq);
  EXPECT_EQ(dc.crba(q), du.crba(q));
  EXPECT_EQ(dc.inverse_dynamics(q, qd, qdd), du.inverse_dynamics(q, qd, qdd));
}

TEST(Builder, BadInputNamesIt) {
  const Transform<double> I = Transform<double>::identity();
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  JointSpec j;
  j.name = "j";
  j.type = "revolute";
  auto with = [&](auto change) {
    JointSpec s = j;
    change(s);
    return s;
  };
  ModelBuilder b;
  const int a = b.add_body(-1, j, "a");
  EXPECT_NE(error_of([&] { b.add_body(5, with([](JointSpec& s) { s.name = "k"; }), "x"); }).find("parent body 5"),
            std::string::npos);
  EXPECT_NE(error_of([&] { b.add_body(a, j, "x"); }).find("a joint named 'j' already exists"), std::string::npos);
  EXPECT_NE(error_of([&] { b.add_body(a, with([](JointSpec& s) { s.name = "k"; }), "a"); })
                .find("a body named 'a' already exists"),
            std::string::npos);
  EXPECT_NE(error_of([&] { b.add_body(a, with([](JointSpec& s) { s.name = "k", s.type = "hinge"; }), "x"); })
                .find("type 'hinge'"),
            std::string::npos);
  EXPECT_NE(error_of([&] { b.add_body(a, with([](JointSpec& s) { s.name = "k", s.axis = {0, 0, 0}; }), "x"); })
                .find("zero axis"),
            std::string::npos);
  EXPECT_NE(error_of([&] { b.add_body(a, with([](JointSpec& s) { s.name = "k", s.X_parent_joint.p.x = nan; }), "x"); })
                .find("placement"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              b.add_body(a, with([](JointSpec& s) { s.name = "k", s.X_parent_joint.R(0, 0) = 2; }), "x");
            }).find("not orthonormal"),
            std::string::npos);
  EXPECT_NE(error_of([&] { b.add_body(a, with([](JointSpec& s) { s.name = ""; }), "x"); }).find("no name"),
            std::string::npos);
  EXPECT_NE(error_of([&] { b.add_body(a, with([](JointSpec& s) { s.name = "k", s.lower = nan; }), "x"); })
                .find("NaN limit"),
            std::string::npos);
  EXPECT_NE(error_of([&] { b.add_inertia(a, rigid_inertia(-1, {0, 0, 0}, Mat3<double>::zero()), I); })
                .find("negative mass"),
            std::string::npos);
  EXPECT_NE(error_of([&] { b.add_inertia(3, rigid_inertia(1, {0, 0, 0}, Mat3<double>::zero()), I); })
                .find("body 3 does not exist"),
            std::string::npos);
  EXPECT_NE(error_of([&] { b.add_frame("f", "site", 7, I); }).find("body 7 does not exist"), std::string::npos);
  EXPECT_NE(error_of([&] { b.add_frame("", "site", a, I); }).find("no name"), std::string::npos);
  // mimic errors surface in build()
  ModelBuilder c;
  c.add_body(-1, j, "a");
  c.add_mimic("j", "nowhere");
  EXPECT_NE(error_of([&] { c.build(); }).find("'nowhere' is not a joint"), std::string::npos);
}

// found by fuzzing: a refused add_inertia leaves the body as it was, and mimic
// couplings whose (flattened) multiplier or offset would overflow are refused
TEST(Builder, RefusedInputLeavesNoTrace) {
  ModelBuilder b("t");
  JointSpec j;
  j.name = "j1";
  j.type = "revolute";
  const int body = b.add_body(-1, j, "a", rigid_inertia(1.0, {0, 0, 0}, Mat3<double>::identity()));
  Inertia<double> heavy = Inertia<double>::zero();
  heavy.m = 9e14;  // accepted alone, refused once merged with the next one
  b.add_inertia(body, heavy, Transform<double>::identity());
  EXPECT_NE(error_of([&] { b.add_inertia(body, heavy, Transform<double>::identity()); }).find("(merged)"),
            std::string::npos);
  const Model m = b.build();
  EXPECT_EQ(m.bodies[0].I.m, 1.0 + 9e14);
}

TEST(Builder, MimicMultipliersAndOffsetsAreBounded) {
  auto chain = [](double mult, double offset) {
    ModelBuilder b("t");
    int parent = -1;
    for (const char* name : {"drive", "f1", "f2"}) {
      JointSpec j;
      j.name = name;
      j.type = "revolute";
      parent = b.add_body(parent, j, std::string(name) + "_link", rigid_inertia(1.0, {0, 0, 0}, Mat3<double>::identity()));
    }
    b.add_mimic("f1", "drive", mult, offset);
    b.add_mimic("f2", "f1", mult, offset);
    return b;
  };
  EXPECT_NE(error_of([&] { chain(1e200, 0); }).find("add_mimic: joint 'f1' has multiplier 1e+200"), std::string::npos);
  EXPECT_NE(error_of([&] { chain(1, 1e300); }).find("offset 1e+300"), std::string::npos);
  // each within the bound, the flattened chain beyond it
  EXPECT_NE(error_of([&] { chain(1e7, 0).build(); }).find("mimic joint 'f2' follows 'drive' through a chain"),
            std::string::npos);
  const Model m = chain(-2, 0.5).build();
  EXPECT_EQ(m.joints[2].mimic_of, "drive");
  EXPECT_EQ(m.joints[2].multiplier, 4.0);   // q_f2 = -2 q_f1 + 0.5 = 4 q_drive - 1 + 0.5
  EXPECT_EQ(m.joints[2].offset, -0.5);
}

// a reflection is not a placement, and the algorithms read inertias as symmetric
TEST(Builder, ReflectionsAndAsymmetricInertiasAreRefused) {
  ModelBuilder b("t");
  JointSpec j;
  j.name = "j1";
  j.type = "revolute";
  j.X_parent_joint.R = Mat3<double>::identity();
  j.X_parent_joint.R(2, 2) = -1;  // orthonormal, det = -1
  EXPECT_NE(error_of([&] { b.add_body(-1, j, "a"); }).find("is a reflection"), std::string::npos);
  j.X_parent_joint = Transform<double>::identity();
  Inertia<double> I = rigid_inertia(1.0, {0, 0, 0}, Mat3<double>::identity());
  I.I(0, 1) = 0.1;  // I(1, 0) stays 0
  EXPECT_NE(error_of([&] { b.add_body(-1, j, "a", I); }).find("not symmetric"), std::string::npos);
  EXPECT_EQ(b.nb(), 0);
}

// a long mimic chain (each joint follows the one before) resolves in one pass:
// joint k follows joint 0 with multiplier (-1)^k and offset 0.001·(k mod 2)
TEST(Builder, LongMimicChainsResolveToTheirRoot) {
  ModelBuilder b("t");
  const int n = 20000;
  int parent = -1;
  for (int k = 0; k < n; ++k) {
    JointSpec j;
    j.name = "j" + std::to_string(k);
    j.type = "revolute";
    parent = b.add_body(parent, j, "l" + std::to_string(k), rigid_inertia(1.0, {0, 0, 0}, Mat3<double>::identity()));
  }
  for (int k = n - 1; k >= 1; --k) b.add_mimic("j" + std::to_string(k), "j" + std::to_string(k - 1), -1.0, 0.001);
  const Model m = b.build();
  EXPECT_EQ(m.nv, 1);
  for (int k = 1; k < n; ++k) {
    ASSERT_EQ(m.joints[k].mimic_of, "j0") << k;
    ASSERT_EQ(m.joints[k].multiplier, k % 2 ? -1.0 : 1.0) << k;
    ASSERT_NEAR(m.joints[k].offset, k % 2 ? 0.001 : 0.0, 1e-15) << k;
  }
}

// a model whose bodies were not added depth-first (both hips, then both knees) takes the general
// paths (world-frame CRBA, M⁻¹ through M's factor) and computes what the same robot added
// depth-first does, coordinate by coordinate; the direct inverse's passes refuse it by name
TEST(ModelBuilder, BodiesAddedBreadthFirstGiveTheSameDynamics) {
  auto build = [](bool depth_first) {
    ModelBuilder b;
    JointSpec root;
    root.name = "root";
    root.type = "free";
    const int base = b.add_body(-1, root, "base", rigid_inertia(4.0, {0.02, -0.01, 0.03}, Mat3<double>{{0.1, 0.01, 0, 0.01, 0.2, 0.02, 0, 0.02, 0.15}}));
    auto leg = [&](const std::string& side, int parent, int level) {
      JointSpec j;
      j.name = side + (level == 0 ? "_hip" : "_knee");
      j.type = "revolute";
      j.axis = level == 0 ? Vec3<double>{1, 0, 0} : Vec3<double>{0, 0.6, 0.8};
      j.X_parent_joint.p = {level == 0 ? 0.2 : 0.0, side == "l" ? 0.15 : -0.15, level == 0 ? 0.0 : -0.4};
      return b.add_body(parent, j, side + std::to_string(level),
                        rigid_inertia(1.0 + level, {0.01, 0.0, -0.2}, Mat3<double>{{0.02, 0, 0, 0, 0.02, 0, 0, 0, 0.004}}));
    };
    if (depth_first) {
      leg("r", leg("r", base, 0), 1);
      leg("l", leg("l", base, 0), 1);
    } else {
      const int r = leg("r", base, 0), l = leg("l", base, 0);
      leg("r", r, 1);
      leg("l", l, 1);
    }
    return b.build();
  };
  const Model df = build(true), bf = build(false);
  EXPECT_FALSE(df.general_path());
  EXPECT_TRUE(bf.general_path());
  EXPECT_FALSE(bf.has_mimic());
  ASSERT_EQ(df.nv, bf.nv);
  // v index of each of df's coordinates in bf (by joint name)
  std::vector<int> perm(df.nv), qperm(df.nq);
  for (const JointInfo& j : df.joints) {
    const JointInfo& k = bf.joints[bf.joint_index(j.name)];
    const int nv = df.bodies[df.joint_index(j.name)].nv, nq = df.bodies[df.joint_index(j.name)].nq;
    for (int a = 0; a < nv; ++a) perm[j.v_idx + a] = k.v_idx + a;
    for (int a = 0; a < nq; ++a) qperm[j.q_idx + a] = k.q_idx + a;
  }
  Eigen::VectorXd q(df.nq), qb(df.nq), qd(df.nv), qdb(df.nv), tau(df.nv), taub(df.nv);
  const std::vector<double> q0 = df.neutral();
  for (int k = 0; k < df.nq; ++k) q[k] = q0[k] + 0.3 * std::sin(1.0 + k);
  q.segment(3, 4).normalize();
  for (int k = 0; k < df.nv; ++k) qd[k] = std::cos(2.0 + k), tau[k] = 3 * std::sin(0.5 * k);
  for (int k = 0; k < df.nq; ++k) qb[qperm[k]] = q[k];
  for (int k = 0; k < df.nv; ++k) qdb[perm[k]] = qd[k], taub[perm[k]] = tau[k];
  Dynamics a(df), b(bf);
  const Eigen::MatrixXd M = a.crba(q), Mb = b.crba(qb), Mi = a.minv(q), Mib = b.minv(qb);
  const Eigen::VectorXd qdd = a.aba(q, qd, tau), qddb = b.aba(qb, qdb, taub);
  for (int r = 0; r < df.nv; ++r) {
    EXPECT_NEAR(qdd[r], qddb[perm[r]], 1e-13 * std::max(1.0, std::abs(qdd[r])));
    for (int c = 0; c < df.nv; ++c) {
      EXPECT_NEAR(M(r, c), Mb(perm[r], perm[c]), 1e-13) << r << ", " << c;
      EXPECT_NEAR(Mi(r, c), Mib(perm[r], perm[c]), 1e-11) << r << ", " << c;
    }
  }
  // ∇FD through the general path's Cholesky factor
  WorkspaceBuffer wa(df), wb(bf);
  std::vector<double> x(df.nv), xb(df.nv), A(df.nv * df.nv), B(A.size()), Ab(A.size()), Bb(A.size());
  ASSERT_TRUE(aba_derivatives(df.view(), wa.get(), q.data(), qd.data(), tau.data(), static_cast<const double*>(nullptr),
                              -9.81, x.data(), A.data(), B.data()));
  ASSERT_TRUE(aba_derivatives(bf.view(), wb.get(), qb.data(), qdb.data(), taub.data(),
                              static_cast<const double*>(nullptr), -9.81, xb.data(), Ab.data(), Bb.data()));
  const int n = df.nv;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      EXPECT_NEAR(A[r * n + c], Ab[perm[r] * n + perm[c]], 1e-10) << r << ", " << c;
      EXPECT_NEAR(B[r * n + c], Bb[perm[r] * n + perm[c]], 1e-10) << r << ", " << c;
    }
  EXPECT_NE(error_of([&] { batch::minv_bpass(bf, 1, qb.data(), Ab.data()); }).find("bodies added depth-first"),
            std::string::npos);
}
