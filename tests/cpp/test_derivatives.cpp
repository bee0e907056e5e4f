// First-order derivatives against central finite differences in the tangent
// space, on every bundled robot and joint-type test model (fixed and
// floating). Pinocchio equivalence is in tests/python; this suite also runs
// under the sanitizers. Also: ∇FD's tree-sparse product against the dense one
// (bit for bit), the body-frame CRBA against the world-frame pass, the team
// forms against the serial passes (bit for bit, ∇FD on a free root to 1e-11),
// ∇FD's acceleration against ABA's, and M⁻¹ and the derivatives in a free
// root's frame (M M⁻¹ = 1, the world frame's results, the base's position not
// entering, bit for bit).
#include <gtest/gtest.h>

#include "test_models.hpp"

#include <cmath>
#include <cstring>
#include <functional>
#include <random>
#include <string>
#include <tuple>

#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/batch/dynamics.hpp"

using namespace rbd;

namespace {
using rbd_test::all_cases;
using rbd_test::max_rel_err;
using rbd_test::ModelCase;
using rbd_test::ReversedTeam;

class Derivatives : public ::testing::TestWithParam<ModelCase> {};

}  // namespace

TEST_P(Derivatives, MatchFiniteDifferences) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nq = m.nq, nv = m.nv, nb = m.nb();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> q0 = m.neutral(), d(nv), q(nq), qd(nv), qdd(nv), tau(nv), fext(6 * nb);
  for (auto& x : d) x = U(rng);
  integrate(mv, q0.data(), d.data(), q.data());
  for (int k = 0; k < nv; ++k) qd[k] = 2 * U(rng), qdd[k] = U(rng), tau[k] = 10 * U(rng);
  for (auto& x : fext) x = U(rng);

  // analytical
  std::vector<double> Dq(nv * nv), Dv(nv * nv), Fq(nv * nv), Fv(nv * nv), acc(nv);
  std::vector<double> dtau_df(nb * nv * 6), dqdd_df(nb * nv * 6);
  rnea_derivatives(mv, w, q.data(), qd.data(), qdd.data(), fext.data(), -9.81, Dq.data(), Dv.data());
  ASSERT_TRUE(aba_derivatives(mv, w, q.data(), qd.data(), tau.data(), fext.data(), -9.81, acc.data(), Fq.data(),
                              Fv.data()));
  ASSERT_TRUE(fext_derivatives(mv, w, q.data(), dtau_df.data(), dqdd_df.data()));

  // central differences: q along integrate, qd and f_ext directly
  const double h = 1e-5;
  std::vector<double> fdDq(nv * nv), fdDv(nv * nv), fdFq(nv * nv), fdFv(nv * nv), qp(nq), t1(nv), t2(nv);
  auto id = [&](const double* qq, const double* vv, const double* ff, double* out) {
    rnea(mv, w, qq, vv, qdd.data(), ff, -9.81, out);
  };
  auto fd = [&](const double* qq, const double* vv, const double* ff, double* out) {
    ASSERT_TRUE(aba(mv, w, qq, vv, tau.data(), ff, -9.81, out));
  };
  for (int k = 0; k < nv; ++k) {
    std::vector<double> e(nv, 0.0), vp = qd;
    for (auto [f, DQ, DV] : {std::tuple{0, &fdDq, &fdDv}, std::tuple{1, &fdFq, &fdFv}}) {
      auto call = f == 0 ? std::function<void(const double*, const double*, double*)>(
                               [&](const double* a, const double* b, double* o) { id(a, b, fext.data(), o); })
                         : [&](const double* a, const double* b, double* o) { fd(a, b, fext.data(), o); };
      e[k] = h;
      integrate(mv, q.data(), e.data(), qp.data());
      call(qp.data(), qd.data(), t1.data());
      e[k] = -h;
      integrate(mv, q.data(), e.data(), qp.data());
      call(qp.data(), qd.data(), t2.data());
      e[k] = 0;
      for (int r = 0; r < nv; ++r) (*DQ)[r * nv + k] = (t1[r] - t2[r]) / (2 * h);
      vp[k] = qd[k] + 1e-4;
      call(q.data(), vp.data(), t1.data());
      vp[k] = qd[k] - 1e-4;
      call(q.data(), vp.data(), t2.data());
      vp[k] = qd[k];
      for (int r = 0; r < nv; ++r) (*DV)[r * nv + k] = (t1[r] - t2[r]) / 2e-4;
    }
  }
  EXPECT_LT(max_rel_err(Dq, fdDq), 1e-6);
  EXPECT_LT(max_rel_err(Dv, fdDv), 1e-6);
  EXPECT_LT(max_rel_err(Fq, fdFq), 1e-6);
  EXPECT_LT(max_rel_err(Fv, fdFv), 1e-6);

  // f_ext: linear, so differences are exact up to rounding
  std::vector<double> fdT(nb * nv * 6), fdA(nb * nv * 6), fp = fext;
  for (int b = 0; b < nb; ++b)
    for (int c = 0; c < 6; ++c) {
      fp[6 * b + c] = fext[6 * b + c] + 1e-3;
      id(q.data(), qd.data(), fp.data(), t1.data());
      fp[6 * b + c] = fext[6 * b + c] - 1e-3;
      id(q.data(), qd.data(), fp.data(), t2.data());
      for (int r = 0; r < nv; ++r) fdT[(b * nv + r) * 6 + c] = (t1[r] - t2[r]) / 2e-3;
      fp[6 * b + c] = fext[6 * b + c] + 1e-3;
      fd(q.data(), qd.data(), fp.data(), t1.data());
      fp[6 * b + c] = fext[6 * b + c] - 1e-3;
      fd(q.data(), qd.data(), fp.data(), t2.data());
      fp[6 * b + c] = fext[6 * b + c];
      for (int r = 0; r < nv; ++r) fdA[(b * nv + r) * 6 + c] = (t1[r] - t2[r]) / 2e-3;
    }
  EXPECT_LT(max_rel_err(dtau_df, fdT), 1e-6);
  EXPECT_LT(max_rel_err(dqdd_df, fdA), 1e-6);
}

// -M⁻¹ ∂ID through the tree's sparsity (neg_minv_times_tree_sparse, both products over the union of
// their columns' rows) is the dense product's number, bit for bit: each entry the same sum in the same
// order without its zero terms. It is taken on the
// branched robots and not on a chain, where the dense blocked product is faster
TEST_P(Derivatives, TreeSparseProductIsTheDenseProduct) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  if (m.has_mimic()) {  // mimic models solve with M's Cholesky factor instead (MatchFiniteDifferences)
    EXPECT_FALSE(tree_sparse_product_pays(mv));
    return;
  }
  const int nq = m.nq, nv = m.nv;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> q0 = m.neutral(), d(nv), q(nq), qd(nv), tau(nv), qdd(nv);
  for (auto& x : d) x = U(rng);
  integrate(mv, q0.data(), d.data(), q.data());
  for (int k = 0; k < nv; ++k) qd[k] = 2 * U(rng), tau[k] = 10 * U(rng);
  std::vector<double> A(nv * nv), B(nv * nv), dq(nv * nv), dv(nv * nv), Mi(nv * nv), want_q(nv * nv), want_v(nv * nv);
  ASSERT_TRUE(aba_derivatives(mv, w, q.data(), qd.data(), tau.data(), static_cast<const double*>(nullptr), -9.81,
                              qdd.data(), A.data(), B.data()));
  std::copy_n(w.dense, nv * nv, Mi.data());
  rnea_derivatives(mv, w, q.data(), qd.data(), qdd.data(), static_cast<const double*>(nullptr), -9.81, dq.data(),
                   dv.data());
  neg_matmul(Mi.data(), dq.data(), nv, nv, want_q.data());
  neg_matmul(Mi.data(), dv.data(), nv, nv, want_v.data());
  EXPECT_EQ(std::memcmp(A.data(), want_q.data(), A.size() * sizeof(double)), 0);
  EXPECT_EQ(std::memcmp(B.data(), want_v.data(), B.size() * sizeof(double)), 0);
  // the sparse pass on its own, whatever the rule picks
  std::vector<double> Sq = dq, Sv = dv;
  neg_minv_times_tree_sparse(mv, w, Sq.data(), Sv.data());
  EXPECT_EQ(std::memcmp(Sq.data(), want_q.data(), Sq.size() * sizeof(double)), 0);
  EXPECT_EQ(std::memcmp(Sv.data(), want_v.data(), Sv.size() * sizeof(double)), 0);
  const std::string robot = GetParam().path.substr(GetParam().path.rfind('/') + 1);
  if (robot == "iiwa.urdf") EXPECT_FALSE(tree_sparse_product_pays(mv));
  if (robot == "hyq.urdf" || robot == "atlas.urdf") EXPECT_TRUE(tree_sparse_product_pays(mv));
}

// M by the body-frame CRBA (models without mimic joints) against the world-frame pass, on every
// joint type; and every entry written (no stale value survives in M); the upper triangle and the lower
// tree pattern alone against M
TEST_P(Derivatives, BodyFrameCrbaEqualsWorldFrameCrba) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nv = m.nv;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> q0 = m.neutral(), d(nv), q(m.nq);
  for (int trial = 0; trial < 3; ++trial) {
    for (auto& x : d) x = 2 * U(rng);
    integrate(mv, q0.data(), d.data(), q.data());
    std::vector<double> M(nv * nv, std::nan("")), Mw(nv * nv);
    crba(mv, w, q.data(), M.data());
    crba_world(mv, w, q.data(), Mw.data());
    EXPECT_LT(max_rel_err(M, Mw), 1e-13) << "trial " << trial;
    for (int r = 0; r < nv; ++r)
      for (int c = 0; c < nv; ++c) EXPECT_EQ(M[r * nv + c], M[c * nv + r]) << r << ", " << c;
    // the upper triangle alone (kMassUpper): M's upper entries bit for bit, exact zeros below
    std::vector<double> Mu(nv * nv, std::nan(""));
    crba<kMassUpper>(mv, w, q.data(), Mu.data());
    for (int r = 0; r < nv; ++r)
      for (int c = 0; c < nv; ++c)
        if (c >= r) EXPECT_EQ(Mu[r * nv + c], M[r * nv + c]) << r << ", " << c;
        else EXPECT_EQ(Mu[r * nv + c], 0.0) << r << ", " << c;
    // the lower tree pattern (mass_factor's input): M's entries of each DoF against itself and its
    // ancestor DoFs, bit for bit; without mimic joints every other entry left as it was
    std::vector<double> Ml(nv * nv, std::nan(""));
    crba<kMassLowerPattern>(mv, w, q.data(), Ml.data());
    std::vector<int> lambda(nv), run(nv);
    std::vector<char> pattern(nv * nv, 0);
    if (!m.has_mimic()) {
      dof_tree(mv, lambda.data(), run.data());
      for (int r = 0; r < nv; ++r)
        for (int c = r; c >= 0; c = lambda[c]) pattern[r * nv + c] = 1;
    }
    int written = 0;
    for (int r = 0; r < nv; ++r)
      for (int c = 0; c < nv; ++c) {
        if (m.has_mimic() || pattern[r * nv + c]) {
          EXPECT_EQ(Ml[r * nv + c], M[r * nv + c]) << r << ", " << c;
          ++written;
        } else {
          EXPECT_TRUE(std::isnan(Ml[r * nv + c])) << r << ", " << c;
        }
      }
    EXPECT_GE(written, nv);
  }
}

TEST_P(Derivatives, TeamPassesEqualTheSerialPasses) {
  // the team forms (phases of side-by-side indices, run here the last index first, as interpret mode
  // runs them) against the serial passes: RNEA's tau and forces, M⁻¹'s U and D⁻¹ and its columns,
  // ∇ID's two matrices. The same sums in the same order, so equal bit for bit where the compiler fuses
  // no multiply-add (the tests' default x86-64 build)
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  const ModelView<double> mv = m.view();
  if (m.has_mimic()) {  // the team forms are for models without mimic joints: the view routes these away
    EXPECT_EQ(mv.has_mimic, 1);
    return;
  }
  const ReversedTeam team;
  WorkspaceBuffer serial_buf(m), team_buf(m);
  Workspace<double>&ws = serial_buf.get(), &wt = team_buf.get();
  const int nv = m.nv, nb = m.nb();
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> q0 = m.neutral(), d(nv), q(m.nq), qd(nv), qdd(nv), fext(6 * nb);
  for (auto& x : d) x = 2 * U(rng);
  for (auto& x : qd) x = U(rng);
  for (auto& x : qdd) x = U(rng);
  for (auto& x : fext) x = U(rng);
  integrate(mv, q0.data(), d.data(), q.data());
#if defined(__FMA__)
  const double tol = 1e-13;  // (a build with fused multiply-adds may fuse them differently in each form)
#else
  const double tol = 0;
#endif
  auto expect_same = [&](const double* a, const double* b, int n, const char* what) {
    std::vector<double> x(a, a + n), y(b, b + n);
    EXPECT_LE(max_rel_err(x, y), tol) << what;
  };
  // RNEA
  std::vector<double> tau_s(nv), tau_t(nv);
  rnea(mv, ws, q.data(), qd.data(), qdd.data(), fext.data(), 9.81, tau_s.data());
  rnea_team(team, mv, wt, q.data(), qd.data(), qdd.data(), fext.data(), 9.81, tau_t.data());
  expect_same(tau_t.data(), tau_s.data(), nv, "RNEA's tau");
  for (int i = 0; i < nb; ++i) {
    double ft[6], fs[6];
    store(wt.f[i], ft), store(ws.f[i], fs);
    expect_same(ft, fs, 6, "RNEA's forces");
  }
  // M⁻¹: the articulated inertias' U and D⁻¹, then the columns, in the world frame and in a free root's
  for (const bool world : {true, false}) {
    SCOPED_TRACE(world ? "world frame" : "root frame");
    std::vector<double> scratch(nv * nv), Ms(nv * nv, 0.0), Mt(nv * nv, 0.0);
    ASSERT_TRUE(minv_backward_pass(mv, ws, q.data(), scratch.data(), world));
    for (int c = 0; c < nv; ++c) minv_column(mv, ws, c, Ms.data());
    int ok = 0;
    minv_team(team, mv, wt, q.data(), false, Mt.data(), &ok, world);
    ASSERT_EQ(ok, 1);
    for (int i = 0; i < nb; ++i) {
      const int n = m.bodies[i].nv;
      expect_same(wt.Dinv + 36 * i, ws.Dinv + 36 * i, n * n, "M⁻¹'s D⁻¹");
      if (i > 0 || m.bodies[i].type != kFree)  // (a free root's U is not formed)
        for (int k = 0; k < n; ++k) {
          double ut[6], us[6];
          store(wt.U[6 * i + k], ut), store(ws.U[6 * i + k], us);
          expect_same(ut, us, 6, "M⁻¹'s U");
        }
    }
    for (int r = 0; r < nv; ++r) expect_same(Mt.data() + r * nv + r, Ms.data() + r * nv + r, nv - r, "M⁻¹'s rows");
  }
  // ∇ID
  std::vector<double> dq_s(nv * nv), dv_s(nv * nv), dq_t(nv * nv), dv_t(nv * nv);
  rnea_derivatives(mv, ws, q.data(), qd.data(), qdd.data(), fext.data(), 9.81, dq_s.data(), dv_s.data());
  rnea_derivatives_team(team, mv, wt, q.data(), qd.data(), qdd.data(), fext.data(), 9.81, dq_t.data(), dv_t.data());
  expect_same(dq_t.data(), dq_s.data(), nv * nv, "∂ID/∂q");
  expect_same(dv_t.data(), dv_s.data(), nv * nv, "∂ID/∂qd");
  // ∇FD: qdd = M⁻¹ (tau - c) and -M⁻¹ ∂ID in both forms (the tiles' sums in the serial products' order;
  // the team's M⁻¹ is the column path's, which a free root's rows of the passes equal to 1e-13, not bit
  // for bit: MinvPassesEqualTheColumnPath; the products carry that to the derivatives, 3e-13 seen)
  std::vector<double> tau(nv), a_s(nv), a_t(nv), fq_s(nv * nv), fv_s(nv * nv), fq_t(nv * nv), fv_t(nv * nv);
  for (auto& x : tau) x = 10 * U(rng);
  std::vector<double> extra(aba_derivatives_team_bytes<double>(nb, nv) / sizeof(double) + 1);
  ASSERT_TRUE(aba_derivatives(mv, ws, q.data(), qd.data(), tau.data(), fext.data(), 9.81, a_s.data(), fq_s.data(),
                              fv_s.data()));
  ASSERT_TRUE(aba_derivatives_team(team, mv, wt, reinterpret_cast<unsigned char*>(extra.data()), q.data(), qd.data(),
                                   tau.data(), fext.data(), 9.81, a_t.data(), fq_t.data(), fv_t.data()));
  // (and where the serial ∇FD takes M⁻¹ by M's factorisation, minv_factored_pays, the two M⁻¹ agree to
  // rounding: 1e-14 seen)
  const double tol_fd = m.bodies[0].type == kFree || minv_factored_pays(mv) ? 1e-11 : tol;
  auto near = [&](const std::vector<double>& x, const std::vector<double>& y, const char* what) {
    EXPECT_LE(max_rel_err(x, y), tol_fd) << what;
  };
  near(a_t, a_s, "∇FD's qdd");
  near(fq_t, fq_s, "∂qdd/∂q");
  near(fv_t, fv_s, "∂qdd/∂qd");
}

// ∇FD's qdd is M⁻¹ (tau - c), not ABA's: the same acceleration to rounding (cond(M)·ε), with and
// without f_ext, mimic models (M's Cholesky factor) included
TEST_P(Derivatives, ForwardDynamicsGradientsAccelerationIsAbas) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nv = m.nv, nb = m.nb();
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> q0 = m.neutral(), d(nv), q(m.nq), qd(nv), tau(nv), fext(6 * nb);
  for (int trial = 0; trial < 3; ++trial) {
    for (auto& x : d) x = 2 * U(rng);
    for (auto& x : qd) x = 2 * U(rng);
    for (auto& x : tau) x = 10 * U(rng);
    for (auto& x : fext) x = U(rng);
    integrate(mv, q0.data(), d.data(), q.data());
    for (const double* f : {static_cast<const double*>(nullptr), static_cast<const double*>(fext.data())}) {
      std::vector<double> a_fd(nv), a_aba(nv), Fq(nv * nv), Fv(nv * nv);
      ASSERT_TRUE(aba_derivatives(mv, w, q.data(), qd.data(), tau.data(), f, -9.81, a_fd.data(), Fq.data(), Fv.data()));
      ASSERT_TRUE(aba(mv, w, q.data(), qd.data(), tau.data(), f, -9.81, a_aba.data()));
      EXPECT_LT(max_rel_err(a_fd, a_aba), 1e-11) << "trial " << trial << (f ? ", f_ext" : "");
    }
  }
}

// minv's direct passes (minv_passes) compute a tree with a free root in the root's own frame (world.hpp's
// reference frame; its S the identity) unless asked for world coordinates. On every floating model:
// M M⁻¹ = 1 in that frame with the base near the origin and far from it, to n u max|M| max|M⁻¹| (u = 1.1e-16,
// the unit roundoff), which the world frame's M⁻¹ misses 100 m out (M M⁻¹ - 1 at 2e-9 on iiwa, 1.5e-8 on
// Atlas, against 5e-14 and 2e-13 here); the two frames agree near the origin; and the column path (the
// team kernels') agrees with the passes in the root frame
TEST(RootFrame, MinvIsTheInverse) {
  for (const ModelCase& c : all_cases()) {
    const Model m = Model::from_urdf_file(c.path, c.floating);
    if (!c.floating || m.general_path()) continue;  // (no free root; mimic: M's Cholesky inverse, in no frame)
    SCOPED_TRACE(c.path);
    WorkspaceBuffer buf(m);
    Workspace<double>& w = buf.get();
    const ModelView<double> mv = m.view();
    ASSERT_EQ(m.bodies[0].type, kFree);
    const int nv = m.nv;
    std::mt19937 rng(29);
    std::uniform_real_distribution<double> U(-1, 1);
    std::vector<double> q0 = m.neutral(), d(nv), q(m.nq);
    for (int trial = 0; trial < 3; ++trial) {
      for (auto& x : d) x = 2 * U(rng);
      integrate(mv, q0.data(), d.data(), q.data());
      q[0] += 100 * trial, q[1] -= 50 * trial, q[2] += 20 * trial;
      std::vector<double> Mr(nv * nv), Mw(nv * nv), M(nv * nv), Mc(nv * nv, 0.0), scratch(nv * nv);
      ASSERT_TRUE(minv_passes(mv, w, q.data(), true, Mr.data()));
      ASSERT_TRUE(minv_passes(mv, w, q.data(), true, Mw.data(), true));
      crba(mv, w, q.data(), M.data());
      double scale = 0, err = 0, ident = 0, mnorm = 0;
      for (int r = 0; r < nv; ++r)
        for (int k = 0; k < nv; ++k) {
          scale = std::max(scale, std::abs(Mr[r * nv + k]));
          mnorm = std::max(mnorm, std::abs(M[r * nv + k]));
          err = std::max(err, std::abs(Mr[r * nv + k] - Mw[r * nv + k]));
          double s = 0;
          for (int l = 0; l < nv; ++l) s += M[r * nv + l] * Mr[l * nv + k];
          ident = std::max(ident, std::abs(s - (r == k ? 1.0 : 0.0)));
        }
      EXPECT_LT(ident, 1.1e-16 * nv * mnorm * scale) << "trial " << trial;
      if (trial == 0) EXPECT_LT(err, 1e-10 * scale);
      ASSERT_TRUE(minv_backward_pass(mv, w, q.data(), scratch.data(), false));
      for (int k = 0; k < nv; ++k) minv_column(mv, w, k, Mc.data());
      err = 0;
      for (int r = 0; r < nv; ++r)
        for (int k = r; k < nv; ++k) err = std::max(err, std::abs(Mr[r * nv + k] - Mc[r * nv + k]));
      EXPECT_LT(err, 1e-13 * scale) << "trial " << trial;
    }
  }
}

// With a free root, M⁻¹ (the direct passes), ∇ID and ∇FD are computed in the root's frame, where the
// base's position never enters: moving the base 100 m changes no bit of them (in world coordinates it
// changed them by 1e-10 to 4e-9 relative). Near the origin ∇ID and M⁻¹ agree with the world frame's
// passes to 1e-11 (the world frame's own rounding, 3e-12 seen on floating Atlas); a mimic model (M⁻¹ from
// the world-frame CRBA) only that
TEST(RootFrame, BasePositionDoesNotEnter) {
  for (const ModelCase& c : all_cases()) {
    if (!c.floating) continue;
    SCOPED_TRACE(c.path);
    const Model m = Model::from_urdf_file(c.path, c.floating);
    WorkspaceBuffer buf(m);
    Workspace<double>& w = buf.get();
    const ModelView<double> mv = m.view();
    ASSERT_EQ(m.bodies[0].type, kFree);
    const int nv = m.nv, nb = m.nb();
    std::mt19937 rng(31);
    std::uniform_real_distribution<double> U(-1, 1);
    std::vector<double> q0 = m.neutral(), d(nv), q(m.nq), qd(nv), tau(nv), fext(6 * nb);
    for (auto& x : d) x = 2 * U(rng);
    for (auto& x : qd) x = 2 * U(rng);
    for (auto& x : tau) x = 10 * U(rng);
    for (auto& x : fext) x = U(rng);
    integrate(mv, q0.data(), d.data(), q.data());
    // ∂tau/∂q, ∂tau/∂qd at ABA's qdd, M⁻¹ (in the frame asked for), then qdd, ∂qdd/∂q, ∂qdd/∂qd
    auto all = [&](const std::vector<double>& qq, bool leave_world) {
      std::vector<double> a(nv), Dq(nv * nv), Dv(nv * nv), Mi(nv * nv), Fq(nv * nv), Fv(nv * nv);
      EXPECT_TRUE(aba(mv, w, qq.data(), qd.data(), tau.data(), fext.data(), -9.81, a.data()));
      rnea_derivatives(mv, w, qq.data(), qd.data(), a.data(), fext.data(), -9.81, Dq.data(), Dv.data(),
                       static_cast<double*>(nullptr), false, leave_world);
      EXPECT_TRUE(minv_passes(mv, w, qq.data(), true, Mi.data(), leave_world));
      EXPECT_TRUE(aba_derivatives(mv, w, qq.data(), qd.data(), tau.data(), fext.data(), -9.81, a.data(), Fq.data(),
                                  Fv.data()));
      std::vector<double> out;
      for (const auto* v : {&Dq, &Dv, &Mi, &a, &Fq, &Fv}) out.insert(out.end(), v->begin(), v->end());
      return out;
    };
    const std::vector<double> at_q = all(q, false), world = all(q, true);
    const size_t n_frame = 3ul * nv * nv;  // (∇ID and M⁻¹: what leave_world changes)
    EXPECT_LT(max_rel_err(std::vector<double>(world.begin(), world.begin() + n_frame),
                          std::vector<double>(at_q.begin(), at_q.begin() + n_frame)),
              1e-11);
    if (m.general_path()) continue;  // (mimic: M is the world-frame CRBA's, and M⁻¹ its Cholesky inverse)
    std::vector<double> moved = q;
    moved[0] += 100, moved[1] -= 50, moved[2] += 20;
    const std::vector<double> there = all(moved, false);
    EXPECT_EQ(std::memcmp(at_q.data(), there.data(), at_q.size() * sizeof(double)), 0);
  }
}

// M⁻¹'s serial passes (minv_passes: F and P as 6 x nv, a one-DoF body's columns as row streams, a free
// root's as one 6 x 6 on its rows; vector lanes in double and float) against the column-at-a-time path
// the team kernels run (minv_column, nv x 6 per body, one column's scalar loop), in double to 1e-13; and
// in float (four lanes, the tails when nv is not a multiple of four) against double to 2e-3, the
// registry's float32 bound for M⁻¹. A model on the general path takes M's Cholesky inverse instead; there
// the double result is checked against M M⁻¹ = 1
TEST_P(Derivatives, MinvPassesEqualTheColumnPath) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const std::vector<BodyDesc<float>> bodies_f = m.bodies_as<float>();
  const ModelView<float> mf = {m.nb(), m.nq, m.nv, m.general_path() ? 1 : 0, bodies_f.data()};
  WorkspaceBufferT<float> buf_f(m);
  const int nv = m.nv;
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> q0 = m.neutral(), d(nv), q(m.nq);
  for (int trial = 0; trial < 3; ++trial) {
    for (auto& x : d) x = 2 * U(rng);
    integrate(mv, q0.data(), d.data(), q.data());
    std::vector<double> Mi(nv * nv), Mc(nv * nv, 0.0), M(nv * nv);
    ASSERT_TRUE(minv_passes(mv, w, q.data(), true, Mi.data()));
    if (!mv.has_mimic) {
      std::vector<double> scratch(nv * nv);
      ASSERT_TRUE(minv_backward_pass(mv, w, q.data(), scratch.data()));
      for (int c = 0; c < nv; ++c) minv_column(mv, w, c, Mc.data());
      double scale = 0, err = 0;
      for (int r = 0; r < nv; ++r)
        for (int c = r; c < nv; ++c) {
          scale = std::max(scale, std::abs(Mi[r * nv + c]));
          err = std::max(err, std::abs(Mi[r * nv + c] - Mc[r * nv + c]));
        }
      EXPECT_LT(err, 1e-13 * scale) << "trial " << trial;
    } else {
      crba(mv, w, q.data(), M.data());
      for (int r = 0; r < nv; ++r)
        for (int c = 0; c < nv; ++c) {
          double s = 0;
          for (int k = 0; k < nv; ++k) s += M[r * nv + k] * Mi[k * nv + c];
          EXPECT_NEAR(s, r == c ? 1.0 : 0.0, 1e-9) << r << ", " << c;
        }
    }
    std::vector<float> qf(q.begin(), q.end()), Mif(nv * nv);
    ASSERT_TRUE(minv(mf, buf_f.get(), qf.data(), true, Mif.data()));
    std::vector<double> Mid(Mif.begin(), Mif.end());
    EXPECT_LT(max_rel_err(Mid, Mi), 2e-3) << "float, trial " << trial;  // cond(M)·ε, registry_helpers.hpp
  }
}

// M⁻¹ through M's tree-sparse factorisation (minv_factored, CRBA then LTDL; the minv operation's path
// where minv_factored_pays) on every model without mimic joints, whichever path minv takes there:
// M Z = 1 to n u max|M| max|Z| (u = 1.1e-16, the unit roundoff; as RootFrame.MinvIsTheInverse bounds
// the passes) and Z equal to the direct passes' M⁻¹ to 1e-9 relative; without `dense` a zero strict
// lower triangle; and the minv operation takes it, bit for bit, exactly where minv_factored_pays says
// so. (float: MinvPassesEqualTheColumnPath's minv<float> takes it on the same models)
TEST(MinvFactored, IsTheInverse) {
  int checked = 0;
  for (const ModelCase& mc : all_cases()) {
    const Model m = Model::from_urdf_file(mc.path, mc.floating);
    if (m.general_path()) continue;  // (mimic joints: M's Cholesky inverse, MinvPassesEqualTheColumnPath)
    SCOPED_TRACE(mc.path + (mc.floating ? " floating" : ""));
    ++checked;
    WorkspaceBuffer buf(m);
    Workspace<double>& w = buf.get();
    const ModelView<double> mv = m.view();
    const int nv = m.nv;
    std::mt19937 rng(31);
    std::uniform_real_distribution<double> U(-1, 1);
    std::vector<double> q0 = m.neutral(), d(nv), q(m.nq);
    for (int trial = 0; trial < 3; ++trial) {
      for (auto& x : d) x = 2 * U(rng);
      integrate(mv, q0.data(), d.data(), q.data());
      std::vector<double> Z(nv * nv), Zu(nv * nv), Zp(nv * nv), Zop(nv * nv), M(nv * nv);
      ASSERT_TRUE(minv_factored(mv, w, q.data(), true, Z.data()));
      ASSERT_TRUE(minv_factored(mv, w, q.data(), false, Zu.data()));
      ASSERT_TRUE(minv_passes(mv, w, q.data(), true, Zp.data()));
      ASSERT_TRUE(minv(mv, w, q.data(), true, Zop.data()));
      crba(mv, w, q.data(), M.data());
      double mnorm = 0, znorm = 0, ident = 0, err = 0;
      for (int k = 0; k < nv * nv; ++k) {
        mnorm = std::max(mnorm, std::abs(M[k]));
        znorm = std::max(znorm, std::abs(Z[k]));
      }
      for (int r = 0; r < nv; ++r)
        for (int c = 0; c < nv; ++c) {
          double s = 0;
          for (int l = 0; l < nv; ++l) s += M[r * nv + l] * Z[l * nv + c];
          ident = std::max(ident, std::abs(s - (r == c ? 1.0 : 0.0)));
          err = std::max(err, std::abs(Z[r * nv + c] - Zp[r * nv + c]));
          EXPECT_EQ(Zu[r * nv + c], r > c ? 0.0 : Z[r * nv + c]) << r << ", " << c;
        }
      EXPECT_LT(ident, 1.1e-16 * nv * mnorm * znorm) << "trial " << trial;
      EXPECT_LT(err, 1e-9 * znorm) << "trial " << trial;
      EXPECT_EQ(std::memcmp(Zop.data(), (minv_factored_pays(mv) ? Z : Zp).data(), nv * nv * sizeof(double)), 0)
          << "trial " << trial;
    }
  }
  EXPECT_GE(checked, 8);
}

// a light link (I_zz = 1e-15) under a coaxial joint that carries a unit one: M_00 - M_01²/M_11 is
// (1 + 1e-15) - 1, the cancellation the factorisation's pivot check refuses
static Model coaxial_model() {
  const char* limit = R"(<limit lower="-3" upper="3" effort="1" velocity="1"/>)";
  const std::string xml = std::string(R"(<robot name="coaxial"><link name="base"/>
    <link name="light"><inertial><mass value="1"/>
      <inertia ixx="1e-3" iyy="1e-3" izz="1e-15" ixy="0" ixz="0" iyz="0"/></inertial></link>
    <link name="heavy"><inertial><mass value="1"/>
      <inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>
    <joint name="j1" type="revolute"><parent link="base"/><child link="light"/><axis xyz="0 0 1"/>)") +
                          limit + R"(</joint>
    <joint name="j2" type="revolute"><parent link="light"/><child link="heavy"/><axis xyz="0 0 1"/>)" +
                          limit + R"(</joint></robot>)";
  return Model::from_urdf_string(xml);
}

// The factorisation's pivot check scales D_k by the composite inertia's terms, which a light link
// (I_zz = 1e-15) under a coaxial joint carrying a unit one makes 1e15 times D_k: M_00 - M_01²/M_11 is
// then (1 + 1e-15) - 1, cancellation the check refuses, where the passes get D = 1e-15 from the
// articulated inertia exactly and accept it. minv then returns the passes' M⁻¹
TEST(MinvFactored, StricterPivotFallsBackToThePasses) {
  const Model m = coaxial_model();
  ASSERT_EQ(m.nv, 2);
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  ASSERT_TRUE(minv_factored_pays(mv));
  const double q[2] = {0.3, -0.7};
  std::vector<double> Z(4), Zp(4);
  EXPECT_FALSE(minv_factored(mv, w, q, true, Z.data()));
  ASSERT_TRUE(minv_passes(mv, w, q, true, Zp.data()));
  ASSERT_TRUE(minv(mv, w, q, true, Z.data()));
  EXPECT_EQ(std::memcmp(Z.data(), Zp.data(), sizeof(double) * 4), 0);
  EXPECT_NEAR(Zp[0] * 1e-15, 1.0, 1e-6);  // (M⁻¹)_00 = 1 / D_0 = 1 / I_light
}

// Forward dynamics through M's factorisation (aba_factored: RNEA, CRBA on its placements, Lᵀ D L and
// two sweeps) against the articulated-body passes (aba in a linear workspace, which has no room for
// M), on every model without mimic joints: the same qdd to 1e-12 relative, with and without external
// forces; aba in a full workspace is the factorisation's qdd bit for bit exactly where
// minv_factored_pays says so (else the passes'), and aba_layout gives the full layout there
TEST(AbaFactored, EqualsThePasses) {
  int checked = 0, factored = 0;
  for (const ModelCase& mc : all_cases()) {
    const Model m = Model::from_urdf_file(mc.path, mc.floating);
    if (m.general_path()) continue;  // (mimic joints: aba_dense, Cholesky)
    SCOPED_TRACE(mc.path + (mc.floating ? " floating" : ""));
    ++checked;
    const ModelView<double> mv = m.view();
    const bool pays = minv_factored_pays(mv);
    factored += pays;
    EXPECT_EQ(aba_layout(m), pays ? kFullWorkspace : kLinearWorkspace);
    WorkspaceBuffer full(m), linear(m, kLinearWorkspace);
    const int nv = m.nv;
    std::mt19937 rng(37);
    std::uniform_real_distribution<double> U(-1, 1);
    std::vector<double> q0 = m.neutral(), d(nv), q(m.nq), qd(nv), tau(nv), fext(6 * m.nb());
    for (int trial = 0; trial < 3; ++trial) {
      for (auto& x : d) x = 2 * U(rng);
      integrate(mv, q0.data(), d.data(), q.data());
      for (int k = 0; k < nv; ++k) qd[k] = 2 * U(rng), tau[k] = 10 * U(rng);
      for (auto& x : fext) x = U(rng);
      for (const double* fe : {static_cast<const double*>(nullptr), static_cast<const double*>(fext.data())}) {
        std::vector<double> a_passes(nv), a_full(nv), a_fact(nv, 0.0);
        ASSERT_TRUE(aba(mv, linear.get(), q.data(), qd.data(), tau.data(), fe, -9.81, a_passes.data()));
        ASSERT_TRUE(aba(mv, full.get(), q.data(), qd.data(), tau.data(), fe, -9.81, a_full.data()));
        ASSERT_TRUE(aba_factored(mv, full.get(), q.data(), qd.data(), tau.data(), fe, -9.81, a_fact.data()));
        EXPECT_LT(max_rel_err(a_fact, a_passes), 1e-12) << "trial " << trial;
        EXPECT_EQ(std::memcmp(a_full.data(), (pays ? a_fact : a_passes).data(), nv * sizeof(double)), 0)
            << "trial " << trial;
      }
    }
  }
  EXPECT_GE(checked, 8);
  EXPECT_GE(factored, 4);  // (the iiwa, HyQ and Atlas fixed, floating HyQ and iiwa, the small test models)
}

// The factorisation's stricter pivot (MinvFactored.StricterPivotFallsBackToThePasses's model): aba_factored
// refuses M, and aba, given room for it, returns the passes' qdd
TEST(AbaFactored, StricterPivotFallsBackToThePasses) {
  const Model m = coaxial_model();
  WorkspaceBuffer full(m), linear(m, kLinearWorkspace);
  const ModelView<double> mv = m.view();
  ASSERT_TRUE(minv_factored_pays(mv));
  const double q[2] = {0.3, -0.7}, qd[2] = {0.5, -1.0}, tau[2] = {1e-15, 0.2};
  double a_fact[2], a_full[2], a_passes[2];
  EXPECT_FALSE(aba_factored(mv, full.get(), q, qd, tau, static_cast<const double*>(nullptr), -9.81, a_fact));
  ASSERT_TRUE(aba(mv, full.get(), q, qd, tau, static_cast<const double*>(nullptr), -9.81, a_full));
  ASSERT_TRUE(aba(mv, linear.get(), q, qd, tau, static_cast<const double*>(nullptr), -9.81, a_passes));
  EXPECT_EQ(std::memcmp(a_full, a_passes, sizeof a_full), 0);
  EXPECT_TRUE(std::isfinite(a_full[0]) && std::isfinite(a_full[1]));
}

// place_joints (every placement pass's first step) gives body_transform's X_λi bit for bit, in double
// and float: the sines and cosines of a vector of joints are ssincos's lane for lane, beyond the
// reduction's range (|q| > 1e5: libm) too
template <typename S> void expect_placements_are_body_transforms(const Model& m, const ModelView<S>& mv, const S* q) {
  std::vector<Transform<S>> X(m.nb());
  place_joints(mv, X.data(), q);
  for (int i = 0; i < m.nb(); ++i) {
    const Transform<S> ref = body_transform(mv.body[i], q);
    EXPECT_EQ(std::memcmp(&X[i], &ref, sizeof ref), 0) << "body " << i;
  }
}
TEST_P(Derivatives, PlaceJointsIsBodyTransformBitForBit) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  const ModelView<double> mv = m.view();
  const std::vector<BodyDesc<float>> bodies_f = m.bodies_as<float>();
  const ModelView<float> mf = {m.nb(), m.nq, m.nv, m.general_path() ? 1 : 0, bodies_f.data()};
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> q0 = m.neutral(), d(m.nv), q(m.nq);
  for (int trial = 0; trial < 20; ++trial) {
    const double scale = trial < 10 ? 3.0 : 1e3;  // angles beyond ±π and a few beyond the reduction's range
    for (auto& x : d) x = scale * U(rng);
    integrate(mv, q0.data(), d.data(), q.data());
    if (trial >= 15)
      for (int i = 0; i < m.nb(); ++i)
        if (mv.body[i].type == kRevolute && !mv.body[i].mimic && i % 2 == trial % 2) q[mv.body[i].q_idx] = 2.5e5 * U(rng);
    expect_placements_are_body_transforms(m, mv, q.data());
    const std::vector<float> qf(q.begin(), q.end());
    expect_placements_are_body_transforms(m, mf, qf.data());
  }
}

INSTANTIATE_TEST_SUITE_P(Models, Derivatives, ::testing::ValuesIn(all_cases()), rbd_test::case_name);
