// The step Hessian (plant/integrator_hessian.hpp) against an exact
// reference: the step run in nested dual numbers Dual<Dual<double>> through
// integrator_step and the convention's ⊕ / ⊖ gives ∂²ψ/∂z_j∂z_k (and ∂ψ/∂z)
// to rounding, for every scheme on every bundled robot and joint-type test
// model, fixed and floating (the floating base spinning fast), in both
// conventions: Pinocchio's (integrate, difference) and MuJoCo's (MujocoStep:
// mj_integrate, mj_difference, MuJoCo's qpos/qvel). Without free or ball
// joints the two conventions give bit-identical results. Central finite
// differences on every model: tests/python/test_step_hessian.py.
#include <gtest/gtest.h>

#include "test_models.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/batch/integrators_api.hpp"
#include "rbdkit/plant/integrator_hessian.hpp"

using namespace rbd;

namespace {
using rbd_test::all_cases;
using rbd_test::ModelCase;
using D1 = Dual<double>;
using D2 = Dual<D1>;

class StepHessian : public ::testing::TestWithParam<ModelCase> {};

// the nested-dual check of every scheme in one convention (the state in its coordinates)
void check_against_nested_duals(const Model& m, int conv) {
  const ModelView<double> mv = m.view();
  const int nq = m.nq, nv = m.nv, N = 3 * nv;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> q(nq), v(nv), u(nv), d(nv);
  const std::vector<double> q0 = m.neutral();
  for (auto& x : d) x = U(rng);
  integrate(mv, q0.data(), d.data(), q.data());
  for (int k = 0; k < nv; ++k) v[k] = 2 * U(rng), u[k] = 10 * U(rng);
  // a floating base spinning fast: the retraction's curvature matters
  if (m.floating_base) v[3] = 6, v[4] = -4, v[5] = 5;
  if (conv == kMujocoConvention) configuration_to_mujoco(mv, q.data(), q.data());
  const double dt = 0.02, g = -9.81;

  // the model and a workspace in nested dual numbers
  const std::vector<BodyDesc<D2>> bodies = m.bodies_as<D2>();
  const ModelView<D2> mdd = {m.nb(), nq, nv, m.general_path() ? 1 : 0, bodies.data()};
  WorkspaceBufferT<D2> wdd(m);
  WorkspaceBuffer wd(m);
  std::vector<D2> qd(nq), vd(nv), ud(nv), dq(nv), qp(nq), xn(nq + nv), qn_ref(nq), psi(nv),
      sdd(integrator_scratch_values(nq, nv));
  std::vector<double> xh(nq + nv), AB(2L * nv * N), H(2L * nv * N * N),
      scratch(integrator_hessian_scratch_values(nq, nv));
  // the convention's ⊕ and ⊖
  auto retract = [&](const D2* a, const D2* b, D2* out) {
    if (conv == kMujocoConvention) mj_integrate(mdd, a, b, out);
    else integrate(mdd, a, b, out);
  };
  auto diff = [&](const D2* a, const D2* b, D2* out) {
    if (conv == kMujocoConvention) mj_difference(mdd, a, b, out);
    else difference(mdd, a, b, out);
  };

  // (j, k) pairs: diagonal and mixed, across the q, v and u blocks
  std::vector<std::pair<int, int>> pairs;
  for (int t = 0; t < 12; ++t) pairs.push_back({static_cast<int>(rng() % N), static_cast<int>(rng() % N)});
  for (int j : {0, 3, 5}) pairs.push_back({std::min(j, nv - 1), std::min(j + 1, nv - 1)});
  // inside the floating base (or the first joints): rotation-rotation, translation-rotation, q-v, q-u
  for (auto [j, k] : {std::pair<int, int>{4, 4}, {1, 5}, {3, 5}, {0, 4}, {3, nv + 3}, {nv + 3, nv + 5}, {4, nv + 1},
                      {5, 2 * nv + 1}, {4, 2 * nv + 2}})
    pairs.push_back({std::min(j, N - 1), std::min(k, N - 1)});
  pairs.push_back({0, nv});
  pairs.push_back({nv - 1, 2 * nv});
  for (int type = kEuler; type <= kConstantAcceleration; ++type) {
    SCOPED_TRACE("integrator " + std::to_string(type) + (conv == kMujocoConvention ? ", mujoco" : ", pinocchio"));
    ASSERT_TRUE(integrator_hessian(mv, wd.get(), type, q.data(), v.data(), u.data(), dt, g, xh.data(),
                                   xh.data() + nq, AB.data(), H.data(), scratch.data(), conv));
    for (int k = 0; k < nq; ++k) qn_ref[k] = D2(D1(xh[k]));
    double scale = 1;
    for (double h : H) scale = std::max(scale, std::fabs(h));
    double err = 0, err1 = 0;
    for (const auto& jk : pairs) {
      // z = ε₁ e_j + ε₂ e_k (plain ints: a lambda may not capture a structured binding before C++20)
      const int j = jk.first, k = jk.second;
      auto seed = [&](int c) { return D2(D1(0.0, c == j ? 1.0 : 0.0), D1(c == k ? 1.0 : 0.0)); };
      for (int c = 0; c < nv; ++c) dq[c] = seed(c);
      for (int c = 0; c < nq; ++c) qd[c] = D2(D1(q[c]));
      retract(qd.data(), dq.data(), qp.data());
      for (int c = 0; c < nv; ++c) vd[c] = D2(D1(v[c])) + seed(nv + c), ud[c] = D2(D1(u[c])) + seed(2 * nv + c);
      ASSERT_TRUE(integrator_step(mdd, wdd.get(), type, qp.data(), vd.data(), ud.data(),
                                  static_cast<const D2*>(nullptr), D2(D1(dt)), D2(D1(g)), xn.data(),
                                  xn.data() + nq, sdd.data(), conv));
      diff(qn_ref.data(), xn.data(), psi.data());
      for (int i = 0; i < 2 * nv; ++i) {
        const D2 p = i < nv ? psi[i] : xn[nq + i - nv];
        err = std::max(err, std::fabs(p.d.d - H[(static_cast<long>(i) * N + j) * N + k]));
        err1 = std::max(err1, std::fabs(p.v.d - AB[i * N + j]));
        err1 = std::max(err1, std::fabs(p.d.v - AB[i * N + k]));
      }
    }
    EXPECT_LT(err / scale, 1e-9);
    EXPECT_LT(err1, 1e-9);
    // the value and AB are the step and integrator_gradient in the same convention
    std::vector<double> xg(nq + nv), ABg(2L * nv * N), s1(integrator_gradient_scratch_values(nq, nv));
    ASSERT_TRUE(integrator_gradient(mv, wd.get(), type, q.data(), v.data(), u.data(),
                                    static_cast<const double*>(nullptr), dt, g, xg.data(), xg.data() + nq, ABg.data(),
                                    s1.data(), conv));
    EXPECT_LT(rbd_test::max_rel_err(AB, ABg), 1e-12);
    EXPECT_LT(rbd_test::max_rel_err(xh, xg), 1e-14);
    // symmetric in (j, k)
    double asym = 0;
    for (int i = 0; i < 2 * nv; ++i)
      for (int a = 0; a < N; ++a)
        for (int b = 0; b < a; ++b)
          asym = std::max(asym, std::fabs(H[(static_cast<long>(i) * N + a) * N + b] -
                                          H[(static_cast<long>(i) * N + b) * N + a]));
    EXPECT_EQ(asym, 0.0);
  }
}

TEST_P(StepHessian, MatchesNestedDualNumbersThroughTheStep) {
  check_against_nested_duals(Model::from_urdf_file(GetParam().path, GetParam().floating), kPinocchioConvention);
}

TEST_P(StepHessian, MatchesNestedDualNumbersThroughTheMujocoStep) {
  check_against_nested_duals(Model::from_urdf_file(GetParam().path, GetParam().floating), kMujocoConvention);
}

INSTANTIATE_TEST_SUITE_P(Models, StepHessian, ::testing::ValuesIn(all_cases()), rbd_test::case_name);

TEST(StepHessianConventions, BitIdenticalWithoutFreeOrBallJoints) {
  int checked = 0;
  for (const ModelCase& c : all_cases()) {
    const Model m = Model::from_urdf_file(c.path, c.floating);
    const ModelView<double> mv = m.view();
    bool quaternions = false;
    for (int i = 0; i < m.nb(); ++i)
      quaternions = quaternions || mv.body[i].type == kFree || mv.body[i].type == kSpherical;
    if (quaternions) continue;  // the conventions differ there (checked above against nested duals)
    SCOPED_TRACE(c.path);
    ++checked;
    const int nq = m.nq, nv = m.nv, N = 3 * nv;
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> U(-1, 1);
    std::vector<double> q(nq), v(nv), u(nv), scratch(integrator_hessian_scratch_values(nq, nv));
    for (int k = 0; k < nq; ++k) q[k] = U(rng);
    for (int k = 0; k < nv; ++k) v[k] = 2 * U(rng), u[k] = 10 * U(rng);
    WorkspaceBuffer wd(m);
    for (int type = kEuler; type <= kConstantAcceleration; ++type) {
      std::vector<double> out[2];
      for (int conv : {kPinocchioConvention, kMujocoConvention}) {
        std::vector<double>& o = out[conv];
        o.assign(nq + nv + 2L * nv * N + 2L * nv * N * N, -1.0);
        ASSERT_TRUE(integrator_hessian(mv, wd.get(), type, q.data(), v.data(), u.data(), 0.02, -9.81, o.data(),
                                       o.data() + nq, o.data() + nq + nv, o.data() + nq + nv + 2L * nv * N,
                                       scratch.data(), conv));
      }
      EXPECT_EQ(std::memcmp(out[0].data(), out[1].data(), out[0].size() * sizeof(double)), 0)
          << "integrator " << type;
    }
  }
  EXPECT_GE(checked, 5);
}

}  // namespace
