// Algorithm identities on the bundled robots (fixed and floating base):
// ABA = M⁻¹(tau - c), M·M⁻¹ = I, RNEA(q, qd, ABA(τ)) = τ, integrate/difference.
// Pinocchio equivalence is in tests/python.
#include <gtest/gtest.h>

#include <random>

#include <Eigen/Dense>

#include "rbdkit/dynamics.hpp"

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
