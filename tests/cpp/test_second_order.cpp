// Second-order derivatives (IDSVA-SO, FDSVA-SO) against central finite
// differences of the first-order derivatives in the tangent space, the two
// IDSVA-SO recursions against each other, and the symmetries, on every
// bundled robot and joint-type test model (fixed and floating). Pinocchio
// equivalence: tests/pinocchio_so; this suite also runs under the sanitizers.
#include <gtest/gtest.h>

#include "test_models.hpp"

#include <algorithm>
#include <random>

#include "rbdkit/algorithms/fdsva_so.hpp"
#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/batch/second_order_api.hpp"

using namespace rbd;

namespace {
using rbd_test::all_cases;
using rbd_test::max_rel_err;
using rbd_test::ModelCase;

class SecondOrder : public ::testing::TestWithParam<ModelCase> {};


using Tensor = std::vector<double>;  // nv x nv x nv, [i][j][k]

struct State {
  std::vector<double> q, qd, qdd, u;
};

State random_state(const Model& m, unsigned seed) {
  const ModelView<double> mv = m.view();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1, 1);
  State s;
  std::vector<double> q0 = m.neutral(), d(m.nv);
  for (auto& x : d) x = 2 * U(rng);
  s.q.resize(m.nq);
  integrate(mv, q0.data(), d.data(), s.q.data());
  for (int k = 0; k < m.nv; ++k) s.qd.push_back(2 * U(rng)), s.qdd.push_back(U(rng)), s.u.push_back(10 * U(rng));
  return s;
}

// central differences of a matrix-valued f (nv x nv), stored as
// T[i][j][k] = ∂f_ij/∂x_k. wrt 0: q through integrate, the five-point stencil
// (error O(h⁴)) with h = 1e-3, large enough that the rounding of the
// first-order results (amplified by M⁻¹ in forward dynamics) stays well below
// the tolerance; wrt 1: qd, the three-point stencil with h = 0.1 (every f here
// is quadratic or linear in qd, so it is exact up to rounding at any step).
template <typename F> Tensor fd_matrix(const Model& m, const State& s, int wrt, F f) {
  const ModelView<double> mv = m.view();
  const int nv = m.nv;
  Tensor T(static_cast<size_t>(nv) * nv * nv);
  std::vector<double> out(nv * nv), acc(nv * nv), qp(m.nq), vp = s.qd, e(nv, 0.0);
  const double h = wrt == 0 ? 1e-3 : 0.1;
  // (step multiple, weight): f'(x) ≈ Σ weight f(x + step h) / h
  const double w5[4][2] = {{1, 8.0 / 12}, {-1, -8.0 / 12}, {2, -1.0 / 12}, {-2, 1.0 / 12}};
  const double w3[2][2] = {{1, 0.5}, {-1, -0.5}};
  const int n_pts = wrt == 0 ? 4 : 2;
  for (int k = 0; k < nv; ++k) {
    std::fill(acc.begin(), acc.end(), 0.0);
    for (int p = 0; p < n_pts; ++p) {
      const double step = wrt == 0 ? w5[p][0] : w3[p][0], weight = wrt == 0 ? w5[p][1] : w3[p][1];
      if (wrt == 0) {
        e[k] = step * h;
        integrate(mv, s.q.data(), e.data(), qp.data());
        e[k] = 0;
        f(qp.data(), s.qd.data(), out.data());
      } else {
        vp[k] = s.qd[k] + step * h;
        f(s.q.data(), vp.data(), out.data());
        vp[k] = s.qd[k];
      }
      for (int i = 0; i < nv * nv; ++i) acc[i] += weight * out[i];
    }
    for (int i = 0; i < nv * nv; ++i) T[static_cast<size_t>(i) * nv + k] = acc[i] / h;
  }
  return T;
}

// T[i][j][k] -> T[i][k][j]
Tensor swap_jk(const Tensor& T, int nv) {
  Tensor O(T.size());
  for (int i = 0; i < nv; ++i)
    for (int j = 0; j < nv; ++j)
      for (int k = 0; k < nv; ++k) O[(i * nv + k) * nv + j] = T[(i * nv + j) * nv + k];
  return O;
}
}  // namespace

TEST_P(SecondOrder, IdsvaSoMatchesFiniteDifferencesAndVariantsAgree) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nv = m.nv;
  const size_t n3 = static_cast<size_t>(nv) * nv * nv;
  const State s = random_state(m, 11);
  const double g = -9.81;

  Tensor W[4], Bf[4];
  for (int t = 0; t < 4; ++t) W[t].resize(n3), Bf[t].resize(n3);
  idsva_so_world_frame(mv, w, s.q.data(), s.qd.data(), s.qdd.data(), g, W[0].data(), W[1].data(), W[2].data(),
                       W[3].data());
  idsva_so_body_frame(mv, w, s.q.data(), s.qd.data(), s.qdd.data(), g, Bf[0].data(), Bf[1].data(), Bf[2].data(),
                      Bf[3].data());
  for (int t = 0; t < 4; ++t) EXPECT_LT(max_rel_err(Bf[t], W[t]), 1e-10) << "tensor " << t;

  std::vector<double> tmp(nv * nv);
  auto dtau_dq = [&](const double* q, const double* v, double* out) {
    rnea_derivatives(mv, w, q, v, s.qdd.data(), static_cast<const double*>(nullptr), g, out, tmp.data());
  };
  auto dtau_dv = [&](const double* q, const double* v, double* out) {
    rnea_derivatives(mv, w, q, v, s.qdd.data(), static_cast<const double*>(nullptr), g, tmp.data(), out);
  };
  auto mass = [&](const double* q, const double*, double* out) { crba(mv, w, q, out); };
  EXPECT_LT(max_rel_err(W[0], fd_matrix(m, s, 0, dtau_dq)), 1e-6) << "d2tau_dq2";
  EXPECT_LT(max_rel_err(W[1], fd_matrix(m, s, 1, dtau_dv)), 1e-6) << "d2tau_dqd2";
  EXPECT_LT(max_rel_err(W[2], fd_matrix(m, s, 1, dtau_dq)), 1e-6) << "d2tau_dqdqd (qd steps)";
  EXPECT_LT(max_rel_err(W[2], swap_jk(fd_matrix(m, s, 0, dtau_dv), nv)), 1e-6) << "d2tau_dqdqd (q steps)";
  EXPECT_LT(max_rel_err(W[3], fd_matrix(m, s, 0, mass)), 1e-6) << "dM_dq";

  // symmetric: d2tau_dqd2 in (j, k), dM_dq in (i, j)
  Tensor dMt(n3);
  for (int i = 0; i < nv; ++i)
    for (int j = 0; j < nv; ++j)
      for (int k = 0; k < nv; ++k) dMt[(j * nv + i) * nv + k] = W[3][(i * nv + j) * nv + k];
  EXPECT_LT(max_rel_err(W[1], swap_jk(W[1], nv)), 1e-13);
  EXPECT_LT(max_rel_err(W[3], dMt), 1e-13);

  // the batched host entry point: the dispatch picks one of the two
  Tensor H[4];
  for (int t = 0; t < 4; ++t) H[t].resize(n3);
  batch::idsva_so(m, 1, s.q.data(), s.qd.data(), s.qdd.data(), g, kSoAuto, H[0].data(), H[1].data(), H[2].data(),
                  H[3].data());
  for (int t = 0; t < 4; ++t) EXPECT_EQ(H[t], GetParam().floating ? W[t] : Bf[t]);
}

TEST_P(SecondOrder, FdsvaSoMatchesFiniteDifferences) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nv = m.nv;
  const size_t n3 = static_cast<size_t>(nv) * nv * nv;
  const State s = random_state(m, 12);
  const double g = -9.81;

  Tensor T[4];
  for (int t = 0; t < 4; ++t) T[t].resize(n3);
  std::vector<double> qdd(nv);
  ASSERT_TRUE(fdsva_so(mv, w, s.q.data(), s.qd.data(), s.u.data(), g, T[0].data(), T[1].data(), T[2].data(),
                       T[3].data(), qdd.data()));

  std::vector<double> acc(nv), tmp(nv * nv);
  auto dqdd_dq = [&](const double* q, const double* v, double* out) {
    ASSERT_TRUE(aba_derivatives(mv, w, q, v, s.u.data(), static_cast<const double*>(nullptr), g, acc.data(), out,
                                tmp.data()));
  };
  auto dqdd_dv = [&](const double* q, const double* v, double* out) {
    ASSERT_TRUE(aba_derivatives(mv, w, q, v, s.u.data(), static_cast<const double*>(nullptr), g, acc.data(),
                                tmp.data(), out));
  };
  auto minv_of = [&](const double* q, const double*, double* out) { ASSERT_TRUE(minv(mv, w, q, true, out)); };
  EXPECT_LT(max_rel_err(T[0], fd_matrix(m, s, 0, dqdd_dq)), 1e-6) << "d2qdd_dq2";
  EXPECT_LT(max_rel_err(T[1], fd_matrix(m, s, 1, dqdd_dv)), 1e-6) << "d2qdd_dqd2";
  EXPECT_LT(max_rel_err(T[2], fd_matrix(m, s, 1, dqdd_dq)), 1e-6) << "d2qdd_dqdqd";
  // ∂²qdd/∂q_j∂u_k = ∂(M⁻¹)_ik/∂q_j
  EXPECT_LT(max_rel_err(T[3], swap_jk(fd_matrix(m, s, 0, minv_of), nv)), 1e-6) << "d2qdd_dqdu";
}

TEST(SecondOrderApi, ChecksInputs) {
  const Model m = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", true);
  std::vector<double> q = m.neutral(), v(m.nv, 0.0), out(static_cast<size_t>(m.nv) * m.nv * m.nv);
  q[6] = 2.0;  // a non-unit quaternion
  EXPECT_THROW(batch::idsva_so(m, 1, q.data(), v.data(), v.data(), -9.81, kSoAuto, out.data(), out.data(),
                               out.data(), out.data()),
               std::invalid_argument);
  q = m.neutral();
  v[3] = std::nan("");
  EXPECT_THROW(batch::fdsva_so(m, 1, q.data(), v.data(), v.data(), -9.81, out.data(), out.data(), out.data(),
                               out.data()),
               std::invalid_argument);
  v[3] = 0;
  EXPECT_THROW(batch::idsva_so(m, 1, q.data(), v.data(), v.data(), -9.81, 7, out.data(), out.data(), out.data(),
                               out.data()),
               std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(Models, SecondOrder, ::testing::ValuesIn(all_cases()), rbd_test::case_name);
