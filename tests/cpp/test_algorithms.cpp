// Algorithm identities on the bundled robots (fixed and floating base):
// ABA = M⁻¹(tau - c), M·M⁻¹ = I, RNEA(q, qd, ABA(τ)) = τ, integrate/difference.
// Pinocchio equivalence is in tests/python.
#include <gtest/gtest.h>

#include <random>

#include <Eigen/Dense>

#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/batch/integrators_api.hpp"

using namespace rbd;

namespace {
struct Case {
  const char* robot;
  bool floating;
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.robot << (c.floating ? " floating" : " fixed"); }

class Identities : public ::testing::TestWithParam<Case> {};

Eigen::VectorXd random_q(const Model& m, std::mt19937& rng) {
  std::uniform_real_distribution<double> U(-1, 1);
  Eigen::VectorXd dq(m.nv);
  for (int k = 0; k < m.nv; ++k) dq[k] = U(rng);
  Dynamics d(m);
  const std::vector<double> q0 = m.neutral();
  return d.integrate(Eigen::Map<const Eigen::VectorXd>(q0.data(), m.nq), dq);
}
}  // namespace

TEST_P(Identities, Hold) {
  const Case c = GetParam();
  Dynamics d(Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/" + c.robot + ".urdf", c.floating));
  const Model& m = d.model();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd q = random_q(m, rng);
    Eigen::VectorXd qd(m.nv), tau(m.nv);
    for (int k = 0; k < m.nv; ++k) qd[k] = 3 * U(rng), tau[k] = 20 * U(rng);
    const Eigen::MatrixXd M = d.crba(q), Mi = d.minv(q);
    EXPECT_LT((M * Mi - Eigen::MatrixXd::Identity(m.nv, m.nv)).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LT((M - M.transpose()).cwiseAbs().maxCoeff(), 1e-12);
    const Eigen::VectorXd qdd = d.aba(q, qd, tau);
    const Eigen::VectorXd qdd2 = d.forward_dynamics(q, qd, tau);
    const Eigen::VectorXd qdd3 = M.ldlt().solve(tau - d.nonlinear_effects(q, qd));
    const double s = std::max(1.0, qdd.cwiseAbs().maxCoeff());
    EXPECT_LT((qdd - qdd2).cwiseAbs().maxCoeff(), 1e-9 * s);
    EXPECT_LT((qdd - qdd3).cwiseAbs().maxCoeff(), 1e-9 * s);
    EXPECT_LT((d.inverse_dynamics(q, qd, qdd) - tau).cwiseAbs().maxCoeff(), 1e-9 * 20);
    // difference inverts integrate
    const Eigen::VectorXd q1 = d.integrate(q, 0.3 * qd);
    EXPECT_LT((d.difference(q, q1) - 0.3 * qd).cwiseAbs().maxCoeff(), 1e-12);
  }
}

INSTANTIATE_TEST_SUITE_P(Robots, Identities,
                         ::testing::Values(Case{"iiwa", false}, Case{"iiwa", true}, Case{"hyq", false},
                                           Case{"hyq", true}, Case{"atlas", false}, Case{"atlas", true}),
                         [](const auto& info) {
                           return std::string(info.param.robot) + (info.param.floating ? "_floating" : "_fixed");
                         });

TEST(BadInput, ConfigurationsAreChecked) {
  Dynamics d(Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", true));
  Eigen::VectorXd q = Eigen::VectorXd::Zero(d.model().nq), v = Eigen::VectorXd::Zero(d.model().nv);
  // zero quaternion
  EXPECT_THROW(d.crba(q), std::invalid_argument);
  q[6] = 1;
  EXPECT_NO_THROW(d.crba(q));
  q[6] = 2;  // non-unit
  EXPECT_THROW(d.crba(q), std::invalid_argument);
  q[6] = 1;
  v[0] = NAN;
  EXPECT_THROW(d.nonlinear_effects(q, v), std::invalid_argument);
  EXPECT_THROW(d.crba(Eigen::VectorXd::Zero(3)), std::invalid_argument);
  try {
    q[3] = 0.5;
    d.crba(q);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("root_joint"), std::string::npos);
  }
}

// ---- a joint that moves no mass: every algorithm that inverts the mass
// matrix reports it, naming the joint, instead of returning NaN (1/0 = inf
// passed the old D > 0 test) or rounding noise
namespace {
// an arm link on 'arm_joint', and under the fixed world a camera on
// 'cam_joint' with inertia `cam` (about its origin, on the joint axis `axis`)
std::string singular_urdf(const char* cam_mass, const char* cam_inertia, const char* axis) {
  return std::string(R"(<robot name="r"><link name="base"/>
    <link name="arm"><inertial><mass value="2"/><origin xyz="0.3 0 0"/>
      <inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
    <joint name="arm_joint" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
      <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
    <link name="cam"><inertial><mass value=")") +
         cam_mass + R"("/>)" + cam_inertia + R"(</inertial></link>
    <joint name="cam_joint" type="revolute"><parent link="base"/><child link="cam"/><axis xyz=")" + axis +
         R"("/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint></robot>)";
}

template <typename F> std::string runtime_message(F f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "no exception";
}
}  // namespace

TEST(SingularMassMatrix, JointThatMovesNoMassIsNamed) {
  const char* zero = R"(<inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/>)";
  // a thin rod along (1, 1, 0)/√2 on the same axis: D = a(1 - |u|²), zero or rounding noise of a
  const char* rod = R"(<inertia ixx="0.0005" iyy="0.0005" izz="0.001" ixy="-0.0005" ixz="0" iyz="0"/>)";
  for (const std::string& xml : {singular_urdf("0", zero, "0 0 1"), singular_urdf("1", rod, "1 1 0")}) {
    Dynamics d(Model::from_urdf_string(xml));
    const Model& m = d.model();
    ASSERT_EQ(m.nv, 2);
    const Eigen::VectorXd q = Eigen::VectorXd::Constant(2, 0.3), v = Eigen::VectorXd::Constant(2, 0.1);
    // the mass matrix itself is fine to compute, and singular: a zero (or rounding-level) diagonal
    const Eigen::MatrixXd M = d.crba(q);
    const int cam = m.joints[0].name == "cam_joint" ? m.joints[0].v_idx : m.joints[1].v_idx;
    EXPECT_LE(std::fabs(M(cam, cam)), 1e-15);
    for (const std::string& msg :
         {runtime_message([&] { d.aba(q, v, v); }), runtime_message([&] { d.minv(q); }),
          runtime_message([&] { d.forward_dynamics(q, v, v); })}) {
      EXPECT_NE(msg.find("joint 'cam_joint' moves no mass"), std::string::npos) << msg;
      EXPECT_NE(msg.find("singular"), std::string::npos) << msg;
    }
    std::vector<double> x(m.nq + m.nv), AB(6 * m.nv * m.nv);
    EXPECT_NE(runtime_message([&] {
                batch::integrator(m, 1, q.data(), v.data(), v.data(), nullptr, 0.01, -9.81, kRK4, x.data());
              }).find("integrator: joint 'cam_joint' moves no mass"),
              std::string::npos);
    EXPECT_NE(runtime_message([&] {
                batch::integrator_gradient(m, 1, q.data(), v.data(), v.data(), nullptr, 0.01, -9.81, kEuler,
                                           x.data(), AB.data());
              }).find("'cam_joint'"),
              std::string::npos);
    // a batch names the sample
    std::vector<double> q3(3 * m.nq, 0.2), v3(3 * m.nv, 0.0), a3(3 * m.nv);
    EXPECT_NE(runtime_message([&] {
                batch::aba(m, 3, q3.data(), v3.data(), v3.data(), nullptr, -9.81, a3.data());
              }).find("moves no mass at sample 0"),
              std::string::npos);
  }
}

TEST(BadInput, HugeValuesAreRejected) {
  Dynamics d(Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf"));
  const int nv = d.model().nv;
  const Eigen::VectorXd z = Eigen::VectorXd::Zero(nv);
  auto message = [](auto f) -> std::string {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "no exception";
  };
  Eigen::VectorXd big = z;
  big[2] = 1e300;  // finite, but its square overflows
  EXPECT_NE(message([&] { d.aba(z, big, z); }).find("qd: expected values of magnitude at most"), std::string::npos);
  EXPECT_NE(message([&] { d.aba(z, z, big); }).find("tau:"), std::string::npos);
  EXPECT_NE(message([&] { d.inverse_dynamics(z, z, big); }).find("qdd:"), std::string::npos);
  // a revolute angle beyond kMaxAngle keeps no precision: named with its joint
  Eigen::VectorXd q = z;
  q[1] = 1e13;
  const std::string msg = message([&] { d.crba(q); });
  EXPECT_NE(msg.find("q: the angle of joint '"), std::string::npos) << msg;
  q[1] = 0.9 * kMaxAngle;
  EXPECT_NO_THROW(d.crba(q));
  EXPECT_NE(message([&] { d.aba(z, z, z, 1e200); }).find("gravity"), std::string::npos);
  // dt above kMaxTimeStep (1e300 used to overflow and blame the mass matrix)
  std::vector<double> x(d.model().nq + nv);
  EXPECT_NE(message([&] {
              batch::integrator(d.model(), 1, z.data(), z.data(), z.data(), nullptr, 1e300, -9.81, kEuler, x.data());
            }).find("dt: expected a positive finite time step of at most"),
            std::string::npos);
}
