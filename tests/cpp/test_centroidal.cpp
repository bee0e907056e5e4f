// Energy, Coriolis and centroidal algorithms against central finite
// differences in the tangent space and against identities, on every bundled
// robot and joint-type test model (fixed and floating). Pinocchio
// equivalence is in tests/python/test_centroidal.py; this suite also runs
// under the sanitizers.
#include <gtest/gtest.h>

#include "test_models.hpp"

#include <cmath>
#include <random>
#include <stdexcept>

#include "rbdkit/algorithms/centroidal.hpp"
#include "rbdkit/algorithms/energy.hpp"
#include "rbdkit/batch/centroidal_api.hpp"

using namespace rbd;

namespace {
using rbd_test::all_cases;
using rbd_test::max_rel_err;
using rbd_test::ModelCase;


class Centroidal : public ::testing::TestWithParam<ModelCase> {
 protected:
  void SetUp() override {
    model = Model::from_urdf_file(GetParam().path, GetParam().floating);
    buf.reset(new WorkspaceBuffer(model));
    mv = model.view();
    nq = model.nq, nv = model.nv;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> U(-1, 1);
    std::vector<double> q0 = model.neutral(), d(nv);
    for (auto& x : d) x = 2 * U(rng);
    q.resize(nq), qd.resize(nv), qdd.resize(nv);
    integrate(mv, q0.data(), d.data(), q.data());
    for (int k = 0; k < nv; ++k) qd[k] = 2 * U(rng), qdd[k] = 3 * U(rng);
  }
  Workspace<double>& w() { return buf->get(); }

  // (f(q ⊕ h e_k) - f(q ⊕ -h e_k)) / 2h into column k of an (n x nv) matrix
  template <typename F> std::vector<double> fd_tangent(int n, F f, double h = 1e-5) {
    std::vector<double> out(n * nv), e(nv, 0.0), qp(nq), a(n), b(n);
    for (int k = 0; k < nv; ++k) {
      e[k] = h;
      integrate(mv, q.data(), e.data(), qp.data());
      f(qp.data(), a.data());
      e[k] = -h;
      integrate(mv, q.data(), e.data(), qp.data());
      f(qp.data(), b.data());
      e[k] = 0;
      for (int r = 0; r < n; ++r) out[r * nv + k] = (a[r] - b[r]) / (2 * h);
    }
    return out;
  }

  Model model;
  std::unique_ptr<WorkspaceBuffer> buf;
  ModelView<double> mv{};
  int nq = 0, nv = 0;
  std::vector<double> q, qd, qdd;
};
}  // namespace

TEST_P(Centroidal, CoriolisIdentities) {
  std::vector<double> C(nv * nv), g(nv), c(nv), zero(nv, 0.0);
  coriolis_matrix(mv, w(), q.data(), qd.data(), C.data());
  // C qd + g = nonlinear effects
  rnea(mv, w(), q.data(), zero.data(), static_cast<const double*>(nullptr), static_cast<const double*>(nullptr),
       -9.81, g.data());
  rnea(mv, w(), q.data(), qd.data(), static_cast<const double*>(nullptr), static_cast<const double*>(nullptr), -9.81,
       c.data());
  std::vector<double> Cqd_g(nv);
  for (int r = 0; r < nv; ++r) {
    Cqd_g[r] = g[r];
    for (int k = 0; k < nv; ++k) Cqd_g[r] += C[r * nv + k] * qd[k];
  }
  EXPECT_LT(max_rel_err(Cqd_g, c), 1e-12);
  // Ṁ = C + Cᵀ (Ṁ - 2C skew-symmetric), Ṁ by central differences along qd
  const double h = 1e-5;
  std::vector<double> step(nv), qp(nq), Mp(nv * nv), Mm(nv * nv), Mdot(nv * nv), CCt(nv * nv);
  for (int k = 0; k < nv; ++k) step[k] = h * qd[k];
  integrate(mv, q.data(), step.data(), qp.data());
  crba(mv, w(), qp.data(), Mp.data());
  for (int k = 0; k < nv; ++k) step[k] = -h * qd[k];
  integrate(mv, q.data(), step.data(), qp.data());
  crba(mv, w(), qp.data(), Mm.data());
  for (int r = 0; r < nv; ++r)
    for (int k = 0; k < nv; ++k) {
      Mdot[r * nv + k] = (Mp[r * nv + k] - Mm[r * nv + k]) / (2 * h);
      CCt[r * nv + k] = C[r * nv + k] + C[k * nv + r];
    }
  EXPECT_LT(max_rel_err(CCt, Mdot), 1e-6);
}

TEST_P(Centroidal, KineticEnergyIsHalfQdMQd) {
  std::vector<double> M(nv * nv);
  crba(mv, w(), q.data(), M.data());
  double ref = 0;
  for (int r = 0; r < nv; ++r)
    for (int k = 0; k < nv; ++k) ref += 0.5 * qd[r] * M[r * nv + k] * qd[k];
  EXPECT_NEAR(kinetic_energy(mv, w(), q.data(), qd.data()), ref, 1e-12 * std::max(1.0, std::fabs(ref)));
}

TEST_P(Centroidal, JacobianComByFiniteDifferences) {
  std::vector<double> J(3 * nv), com(3), com2(3);
  ASSERT_TRUE(jacobian_com(mv, w(), q.data(), J.data(), com.data()));
  ASSERT_TRUE(center_of_mass(mv, w(), q.data(), com2.data()));
  EXPECT_LT(max_rel_err(com, com2), 1e-12);
  auto fd = fd_tangent(3, [&](const double* x, double* o) { ASSERT_TRUE(center_of_mass(mv, w(), x, o)); });
  EXPECT_LT(max_rel_err(J, fd), 1e-6);
}

TEST_P(Centroidal, DccrbaByFiniteDifferencesAndTimeVariation) {
  std::vector<double> A(6 * nv), A2(6 * nv), h(6), dA(6 * nv * nv), Adot(6 * nv), h2(6);
  ASSERT_TRUE(ccrba(mv, w(), q.data(), qd.data(), A.data(), h.data()));
  ASSERT_TRUE(dccrba(mv, w(), q.data(), A2.data(), dA.data()));
  EXPECT_LT(max_rel_err(A2, A), 1e-12);
  auto fd = fd_tangent(6 * nv, [&](const double* x, double* o) {
    ASSERT_TRUE(ccrba(mv, w(), x, static_cast<const double*>(nullptr), o, static_cast<double*>(nullptr)));
  });
  EXPECT_LT(max_rel_err(dA, fd), 1e-6);
  // Ȧ = Σ_k dA[:, :, k] qd_k, and its h output equals ccrba's
  ASSERT_TRUE(cmm_time_variation(mv, w(), q.data(), qd.data(), A2.data(), Adot.data(), h2.data()));
  std::vector<double> contracted(6 * nv, 0.0);
  for (int rj = 0; rj < 6 * nv; ++rj)
    for (int k = 0; k < nv; ++k) contracted[rj] += dA[rj * nv + k] * qd[k];
  EXPECT_LT(max_rel_err(Adot, contracted), 1e-12);
  EXPECT_LT(max_rel_err(A2, A), 1e-12);
  EXPECT_LT(max_rel_err(h2, h), 1e-12);
}

TEST_P(Centroidal, MomentumRateIsAQddPlusAdotQd) {
  std::vector<double> A(6 * nv), Adot(6 * nv), h(6), h1(6), hdot(6), hd(6), hdot_ref(6, 0.0);
  ASSERT_TRUE(cmm_time_variation(mv, w(), q.data(), qd.data(), A.data(), Adot.data(), h.data()));
  ASSERT_TRUE(centroidal_momentum(mv, w(), q.data(), qd.data(), h1.data()));
  EXPECT_LT(max_rel_err(h1, h), 1e-12);
  ASSERT_TRUE(centroidal_momentum_time_variation(mv, w(), q.data(), qd.data(), qdd.data(), hdot.data(), hd.data()));
  EXPECT_LT(max_rel_err(hd, h), 1e-12);
  for (int r = 0; r < 6; ++r)
    for (int k = 0; k < nv; ++k) hdot_ref[r] += A[r * nv + k] * qdd[k] + Adot[r * nv + k] * qd[k];
  EXPECT_LT(max_rel_err(hdot, hdot_ref), 1e-12);
}

TEST_P(Centroidal, DynamicsDerivativesByFiniteDifferences) {
  std::vector<double> dh_dq(6 * nv), dhdot_dq(6 * nv), dhdot_dv(6 * nv), dhdot_da(6 * nv), A(6 * nv), h(6);
  ASSERT_TRUE(centroidal_dynamics_derivatives(mv, w(), q.data(), qd.data(), qdd.data(), dh_dq.data(),
                                              dhdot_dq.data(), dhdot_dv.data(), dhdot_da.data()));
  ASSERT_TRUE(ccrba(mv, w(), q.data(), qd.data(), A.data(), h.data()));
  EXPECT_LT(max_rel_err(dhdot_da, A), 1e-12);
  auto fd_h = fd_tangent(6, [&](const double* x, double* o) {
    ASSERT_TRUE(centroidal_momentum(mv, w(), x, qd.data(), o));
  });
  EXPECT_LT(max_rel_err(dh_dq, fd_h), 1e-6);
  auto fd_hdot = fd_tangent(6, [&](const double* x, double* o) {
    ASSERT_TRUE(centroidal_momentum_time_variation(mv, w(), x, qd.data(), qdd.data(), o));
  });
  EXPECT_LT(max_rel_err(dhdot_dq, fd_hdot), 1e-6);
  // qd: ḣ is quadratic in qd, so central differences are exact up to rounding
  std::vector<double> fd_v(6 * nv), vp = qd, a(6), b(6);
  for (int k = 0; k < nv; ++k) {
    vp[k] = qd[k] + 1e-4;
    ASSERT_TRUE(centroidal_momentum_time_variation(mv, w(), q.data(), vp.data(), qdd.data(), a.data()));
    vp[k] = qd[k] - 1e-4;
    ASSERT_TRUE(centroidal_momentum_time_variation(mv, w(), q.data(), vp.data(), qdd.data(), b.data()));
    vp[k] = qd[k];
    for (int r = 0; r < 6; ++r) fd_v[r * nv + k] = (a[r] - b[r]) / 2e-4;
  }
  EXPECT_LT(max_rel_err(dhdot_dv, fd_v), 1e-6);
}

TEST_P(Centroidal, BatchedHostApiChecksInputs) {
  std::vector<double> out(6 * nv * nv), bad = q;
  bad[0] = std::nan("");
  EXPECT_THROW(batch::dccrba(model, 1, bad.data(), out.data()), std::invalid_argument);
  std::vector<double> badv = qd;
  badv[nv - 1] = INFINITY;
  EXPECT_THROW(batch::ccrba(model, 1, q.data(), badv.data(), out.data(), out.data() + 6 * nv), std::invalid_argument);
  EXPECT_THROW(batch::dccrba_fd(model, 1, q.data(), 0.0, out.data()), std::invalid_argument);
  EXPECT_THROW(batch::potential_energy(model, 1, q.data(), NAN, out.data()), std::invalid_argument);
  // the analytic derivative agrees with the finite-difference cross-check of the host layer
  std::vector<double> dA(6 * nv * nv), dA_fd(6 * nv * nv);
  batch::dccrba(model, 1, q.data(), dA.data());
  batch::dccrba_fd(model, 1, q.data(), 1e-5, dA_fd.data());
  EXPECT_LT(max_rel_err(dA, dA_fd), 1e-6);
}

INSTANTIATE_TEST_SUITE_P(Models, Centroidal, ::testing::ValuesIn(all_cases()), rbd_test::case_name);

TEST(CentroidalHostApi, MasslessRobotHasNoCenterOfMass) {
  const Model m = Model::from_urdf_string(
      "<robot name='ghost'><link name='a'/><link name='b'/><joint name='j' type='revolute'><parent link='a'/>"
      "<child link='b'/><axis xyz='0 0 1'/></joint></robot>");
  std::vector<double> q(1, 0.0), qd(1, 1.0), out(64);
  EXPECT_THROW(batch::center_of_mass(m, 1, q.data(), out.data()), std::runtime_error);
  EXPECT_THROW(batch::ccrba(m, 1, q.data(), qd.data(), out.data(), out.data() + 6), std::runtime_error);
  batch::kinetic_energy(m, 1, q.data(), qd.data(), out.data());
  EXPECT_EQ(out[0], 0.0);
}
