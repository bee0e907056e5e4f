// Inertial-parameter regressors against rbdkit's own dynamics (tau = Y·π,
// ∂tau/∂x = dY_dx·π, ∂qdd/∂π = -M⁻¹Y, energies), and the checks of
// Model::with_inertial_parameters. Pinocchio equivalence is in
// tests/python/test_regressor.py.
#include <gtest/gtest.h>

#include "test_models.hpp"

#include <random>
#include <stdexcept>

#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/algorithms/regressor.hpp"
#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/batch/regressor_api.hpp"

using namespace rbd;

namespace {
using rbd_test::all_cases;
using rbd_test::max_rel_err;
using rbd_test::ModelCase;

class Regressor : public ::testing::TestWithParam<ModelCase> {};


// M x (nv x cols, row-major) for M (nv x nv)
std::vector<double> matmul(const std::vector<double>& M, const std::vector<double>& x, int nv, int cols) {
  std::vector<double> out(nv * cols, 0.0);
  for (int r = 0; r < nv; ++r)
    for (int k = 0; k < nv; ++k)
      for (int c = 0; c < cols; ++c) out[r * cols + c] += M[r * nv + k] * x[k * cols + c];
  return out;
}
}  // namespace

TEST_P(Regressor, IdentitiesWithTheDynamics) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nq = m.nq, nv = m.nv, np = 10 * m.nb();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> q0 = m.neutral(), d(nv), q(nq), qd(nv), qdd(nv), u(nv);
  for (auto& x : d) x = 2 * U(rng);
  integrate(mv, q0.data(), d.data(), q.data());
  for (int k = 0; k < nv; ++k) qd[k] = 2 * U(rng), qdd[k] = U(rng), u[k] = 10 * U(rng);
  const std::vector<double> pi = m.inertial_parameters();
  ASSERT_EQ(static_cast<int>(pi.size()), np);

  // tau = Y·π
  std::vector<double> Y(nv * np), tau(nv), Ypi(nv, 0.0);
  inverse_dynamics_regressor(mv, w, q.data(), qd.data(), qdd.data(), -9.81, Y.data());
  rnea(mv, w, q.data(), qd.data(), qdd.data(), static_cast<const double*>(nullptr), -9.81, tau.data());
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < np; ++c) Ypi[r] += Y[r * np + c] * pi[c];
  EXPECT_LT(max_rel_err(Ypi, tau), 1e-12);

  // dY_dx·π = [∂tau/∂q | ∂tau/∂qd], and the gradient pass's Y is the regressor
  std::vector<double> dY(2 * nv * nv * np), Y2(nv * np), Dq(nv * nv), Dv(nv * nv), dYpi(2 * nv * nv, 0.0),
      D(2 * nv * nv);
  inverse_dynamics_regressor_gradient(mv, w, q.data(), qd.data(), qdd.data(), -9.81, dY.data(), Y2.data());
  EXPECT_LT(max_rel_err(Y2, Y), 1e-14);
  rnea_derivatives(mv, w, q.data(), qd.data(), qdd.data(), static_cast<const double*>(nullptr), -9.81, Dq.data(),
                   Dv.data());
  for (int c = 0; c < 2 * nv; ++c)
    for (int r = 0; r < nv; ++r) {
      for (int p = 0; p < np; ++p) dYpi[c * nv + r] += dY[(static_cast<long>(c) * nv + r) * np + p] * pi[p];
      D[c * nv + r] = c < nv ? Dq[r * nv + c] : Dv[r * nv + c - nv];
    }
  EXPECT_LT(max_rel_err(dYpi, D), 1e-12);

  // ∂qdd/∂π: M·(∂qdd/∂π) = -Y at qdd = FD(q, qd, u)
  std::vector<double> G(nv * np), acc(nv), M(nv * nv), Yf(nv * np);
  ASSERT_TRUE(forward_dynamics_parameter_gradient(mv, w, q.data(), qd.data(), u.data(), -9.81, acc.data(), G.data()));
  inverse_dynamics_regressor(mv, w, q.data(), qd.data(), acc.data(), -9.81, Yf.data());
  crba(mv, w, q.data(), M.data());
  std::vector<double> MG = matmul(M, G, nv, np);
  for (auto& x : MG) x = -x;
  EXPECT_LT(max_rel_err(MG, Yf), 1e-9);

  // energies: y_T·π = ½ qdᵀ M qd; y_V·π changes by -Σ g·Δ(m c) along a step (checked against g(q) below)
  std::vector<double> yT(np), yV(np);
  kinetic_energy_regressor(mv, w, q.data(), qd.data(), yT.data());
  double T = 0, Tref = 0;
  for (int p = 0; p < np; ++p) T += yT[p] * pi[p];
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < nv; ++c) Tref += 0.5 * qd[r] * M[r * nv + c] * qd[c];
  EXPECT_NEAR(T, Tref, 1e-12 * std::max(1.0, std::fabs(Tref)));
  // ∂V/∂q along a tangent step = generalized gravity
  std::vector<double> g(nv), zero(nv, 0.0), e(nv, 0.0), qp(nq), qm(nq);
  rnea(mv, w, q.data(), zero.data(), static_cast<const double*>(nullptr), static_cast<const double*>(nullptr), -9.81,
       g.data());
  const double h = 1e-6;
  for (int k = 0; k < nv; ++k) {
    e.assign(nv, 0.0);
    e[k] = h;
    integrate(mv, q.data(), e.data(), qp.data());
    e[k] = -h;
    integrate(mv, q.data(), e.data(), qm.data());
    double Vp = 0, Vm = 0;
    potential_energy_regressor(mv, w, qp.data(), -9.81, yV.data());
    for (int p = 0; p < np; ++p) Vp += yV[p] * pi[p];
    potential_energy_regressor(mv, w, qm.data(), -9.81, yV.data());
    for (int p = 0; p < np; ++p) Vm += yV[p] * pi[p];
    EXPECT_NEAR((Vp - Vm) / (2 * h), g[k], 1e-6 * std::max(1.0, std::fabs(g[k]))) << "dof " << k;
  }
}

INSTANTIATE_TEST_SUITE_P(AllModels, Regressor, ::testing::ValuesIn(all_cases()));

TEST(InertialParameters, RoundTripIsExact) {
  const Model m = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/atlas.urdf", true);
  const Model m2 = m.with_inertial_parameters(m.inertial_parameters());  // inconsistent links unchanged: accepted
  ASSERT_EQ(m2.nb(), m.nb());
  for (int b = 0; b < m.nb(); ++b) {
    EXPECT_EQ(m2.bodies[b].I.m, m.bodies[b].I.m);
    for (int k = 0; k < 9; ++k) EXPECT_EQ(m2.bodies[b].I.I.m[k], m.bodies[b].I.I.m[k]);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(m2.bodies[b].I.h[k], m.bodies[b].I.h[k]);
  }
}

TEST(InertialParameters, ChecksNameTheLinkAndTheCondition) {
  const Model m = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf");
  const std::vector<double> pi = m.inertial_parameters();
  auto expect_error = [&](int body, std::vector<double> blk, const std::string& what) {
    std::vector<double> x = pi;
    std::copy(blk.begin(), blk.end(), x.begin() + 10 * body);
    try {
      (void)m.with_inertial_parameters(x);
      ADD_FAILURE() << "no error for " << what;
    } catch (const std::invalid_argument& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("link '" + m.body_names[body] + "'"), std::string::npos) << msg;
      EXPECT_NE(msg.find(what), std::string::npos) << msg;
    }
  };
  expect_error(2, {-1, 0, 0, 0, 1, 0, 1, 0, 0, 1}, "negative mass");
  expect_error(2, {0, 0.1, 0, 0, 0, 0, 0, 0, 0, 0}, "zero mass with a non-zero first moment");
  expect_error(4, {1, 0, 0, 0, 0.1, 0.5, 0.1, 0, 0, 0.1}, "not positive semi-definite");
  expect_error(4, {1, 0, 0, 0, 0.1, 0, 0.1, 0, 0, 0.3}, "triangle inequality");
  EXPECT_THROW((void)m.with_inertial_parameters(std::vector<double>(pi.size() - 1)), std::invalid_argument);
  std::vector<double> nan = pi;
  nan[5] = std::nan("");
  EXPECT_THROW((void)m.with_inertial_parameters(nan), std::invalid_argument);
  // a consistent change is applied, the original model is unchanged
  std::vector<double> x = pi;
  x[0] *= 2;
  const Model m2 = m.with_inertial_parameters(x);
  EXPECT_EQ(m2.inertial_parameters()[0], 2 * pi[0]);
  EXPECT_EQ(m.inertial_parameters()[0], pi[0]);
}

TEST(RegressorApi, BatchedEntryPointsCheckInputs) {
  const Model m = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", true);
  const int nv = m.nv, np = 10 * m.nb();
  std::vector<double> q = m.neutral(), qd(nv, 0.1), Y(nv * np), y(np);
  batch::inverse_dynamics_regressor(m, 1, q.data(), qd.data(), nullptr, -9.81, Y.data());
  batch::potential_energy_regressor(m, 1, q.data(), -9.81, y.data());
  q[6] = 2;  // quaternion w
  EXPECT_THROW(batch::inverse_dynamics_regressor(m, 1, q.data(), qd.data(), nullptr, -9.81, Y.data()),
               std::invalid_argument);
  q[6] = 1;
  qd[3] = std::nan("");
  EXPECT_THROW(batch::kinetic_energy_regressor(m, 1, q.data(), qd.data(), y.data()), std::invalid_argument);
}
