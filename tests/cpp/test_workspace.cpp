// Workspace layouts (workspace.hpp): the linear layout grows linearly with
// the model, the O(n) algorithms give bit-identical results in it and in the
// full one (the linear one poisoned with NaN bytes, so that a read before a
// write shows), Dynamics grows its workspace on need, and a 100,000-link
// chain loads and runs RNEA, checked against the closed-form gravity torques
// of a horizontal chain.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rbdkit/batch/integrators_api.hpp"
#include "rbdkit/batch/kinematics_api.hpp"
#include "test_models.hpp"

using namespace rbd;

namespace {

using Vec = std::vector<double>;

TEST(WorkspaceLayout, LinearBytesGrowLinearly) {
  // a chain: nb = nv
  const double lin = double(workspace_bytes<double>(2000, 2000, kLinearWorkspace)) /
                     double(workspace_bytes<double>(1000, 1000, kLinearWorkspace));
  EXPECT_NEAR(lin, 2.0, 0.01);
  // the full layout is quadratic: that is what the linear one leaves out
  const double full = double(workspace_bytes<double>(2000, 2000)) / double(workspace_bytes<double>(1000, 1000));
  EXPECT_GT(full, 3.9);
  // and its size does not overflow at 20,000 links (6·nb·nv > 2³¹)
  EXPECT_GT(workspace_bytes<double>(20000, 20000), 6ul * 20000ul * 20000ul * sizeof(double));
  // a 20,000-link chain's linear workspace: well under the 1 GB target
  EXPECT_LT(workspace_bytes<double>(20000, 20000, kLinearWorkspace), 100ul << 20);
}

TEST(WorkspaceLayout, LinearLeavesTheQuadraticArraysOut) {
  const int nb = 7, nv = 9;
  std::vector<unsigned char> buf(workspace_bytes<double>(nb, nv, kLinearWorkspace));
  const Workspace<double> w = carve_workspace<double>(buf.data(), nb, nv, kLinearWorkspace);
  EXPECT_EQ(w.P, nullptr);
  EXPECT_EQ(w.so_dense, nullptr);
  EXPECT_EQ(w.dense, nullptr);
  EXPECT_EQ(w.dense2, nullptr);
  // the last linear array ends inside the buffer
  EXPECT_LE(reinterpret_cast<unsigned char*>(w.so_i + 2 * (nv + nb)), buf.data() + buf.size());
}

// a workspace over a buffer we own, filled with `fill` bytes (0xff: NaN doubles)
struct RawWorkspace {
  std::vector<double> storage;  // double: 16-byte aligned by the allocator on the platforms we build for
  Workspace<double> w;
  RawWorkspace(const Model& m, WorkspaceLayout layout, unsigned char fill)
      : storage(workspace_bytes<double>(m.nb(), m.nv, layout) / sizeof(double) + 2) {
    std::memset(storage.data(), fill, storage.size() * sizeof(double));
    w = carve_workspace<double>(storage.data(), m.nb(), m.nv, layout);
  }
};

void expect_bit_identical(const Vec& a, const Vec& b, const char* what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(double)), 0) << what;
}

// every output of the O(n) family for one state, in workspace w
Vec linear_family(const Model& m, Workspace<double>& w, const Vec& q, const Vec& qd, const Vec& qdd,
                  const Vec& fext) {
  const ModelView<double> mv = m.view();
  const int nb = m.nb(), nv = m.nv, nq = m.nq;
  Vec out, x(6 * nv), tau(nv);
  auto append = [&out](const double* p, long n) { out.insert(out.end(), p, p + n); };
  rnea(mv, w, q.data(), qd.data(), qdd.data(), fext.data(), -9.81, tau.data());
  append(tau.data(), nv);
  std::vector<Motion<double>> a(nb);
  remove_gravity(mv, w, -9.81, a.data());
  for (const Motion<double>& ai : a) append(&ai.lin.x, 3), append(&ai.ang.x, 3);
  Vec qdd_aba(nv);
  EXPECT_TRUE(aba(mv, w, q.data(), qd.data(), tau.data(), fext.data(), -9.81, qdd_aba.data()));
  append(qdd_aba.data(), nv);
  forward_kinematics(mv, w, q.data(), qd.data());
  for (int i = 0; i < nb; ++i) append(w.X_world[i].R.m, 9), append(&w.X_world[i].p.x, 3);
  const int leaf = nb - 1;
  frame_jacobian(mv, w, leaf, Transform<double>::identity(), kWorld, x.data());
  append(x.data(), 6 * nv);
  frame_jacobian_dot(mv, w, leaf, Transform<double>::identity(), kLocal, x.data());
  append(x.data(), 6 * nv);
  end_effector_pose_gradient(mv, w, leaf, Vec3<double>{0.1, 0.0, 0.2}, x.data());
  append(x.data(), 6 * nv);
  Vec scratch(integrator_scratch_values(nq, nv)), next(nq + nv);
  for (int conv : {kPinocchioConvention, kMujocoConvention})
    for (int type : {kEuler, kSemiImplicitEuler, kRK4}) {
      EXPECT_TRUE(integrator_step(mv, w, type, q.data(), qd.data(), tau.data(), fext.data(), 1e-3, -9.81,
                                  next.data(), next.data() + nq, scratch.data(), conv));
      append(next.data(), nq + nv);
    }
  return out;
}

class LinearWorkspace : public ::testing::TestWithParam<rbd_test::ModelCase> {};

TEST_P(LinearWorkspace, GivesTheFullLayoutsResults) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  Vec d(m.nv), q(m.nq), qd(m.nv), qdd(m.nv), fext(6 * m.nb());
  for (double& x : d) x = U(rng);
  batch::integrate(m, 1, m.neutral().data(), d.data(), q.data());
  for (Vec* x : {&qd, &qdd, &fext})
    for (double& y : *x) y = U(rng);
  RawWorkspace full(m, kFullWorkspace, 0x00);
  RawWorkspace small(m, aba_layout(m), 0xff);  // mimic models: aba takes the dense path, full layout
  expect_bit_identical(linear_family(m, small.w, q, qd, qdd, fext), linear_family(m, full.w, q, qd, qdd, fext),
                       "rnea, aba, kinematics, integrator steps");
}

INSTANTIATE_TEST_SUITE_P(Models, LinearWorkspace, ::testing::ValuesIn(rbd_test::all_cases()), rbd_test::case_name);

// Dynamics holds a linear workspace until an O(n²) call needs the full one:
// in any order of calls, every result equals the batched call's with a fresh
// workspace of its own
TEST(WorkspaceCache, DynamicsGrowsToTheFullLayoutOnNeed) {
  for (const char* name : {"mimic", "mixed"}) {
    const Model m = Model::from_urdf_file(std::string(RBDKIT_TEST_URDF_DIR) + "/" + name + ".urdf", true);
    Dynamics d(m);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> U(-1, 1);
    Eigen::VectorXd dq(m.nv), q(m.nq), qd(m.nv), u(m.nv);
    for (Eigen::VectorXd* x : {&dq, &qd, &u})
      for (int k = 0; k < x->size(); ++k) (*x)[k] = U(rng);
    batch::integrate(m, 1, m.neutral().data(), dq.data(), q.data());
    Vec tau(m.nv), qdd(m.nv), M(m.nv * m.nv);
    auto same = [](const Eigen::VectorXd& a, const Vec& b) {
      return std::memcmp(a.data(), b.data(), b.size() * sizeof(double)) == 0;
    };
    batch::inverse_dynamics(m, 1, q.data(), qd.data(), u.data(), nullptr, -9.81, tau.data(), nullptr, nullptr,
                            nullptr);
    EXPECT_TRUE(same(d.inverse_dynamics(q, qd, u), tau)) << name;  // linear
    batch::aba(m, 1, q.data(), qd.data(), u.data(), nullptr, -9.81, qdd.data());
    EXPECT_TRUE(same(d.aba(q, qd, u), qdd)) << name;  // linear (mimic: full)
    batch::crba(m, 1, q.data(), M.data());
    const Eigen::MatrixXd Md = d.crba(q);  // full from here on
    for (int r = 0; r < m.nv; ++r)
      for (int c = 0; c < m.nv; ++c) EXPECT_EQ(Md(r, c), M[r * m.nv + c]) << name;
    batch::forward_dynamics(m, 1, q.data(), qd.data(), u.data(), nullptr, -9.81, qdd.data());
    EXPECT_TRUE(same(d.forward_dynamics(q, qd, u), qdd)) << name;
    EXPECT_TRUE(same(d.inverse_dynamics(q, qd, u), tau)) << name;  // the full workspace serves it too
  }
}

// a horizontal chain of n revolute links about x: joint k sits 0.1 along y
// from joint k-1, link k has mass 1 at 0.05 along y from its joint
std::string horizontal_chain(int n) {
  std::ostringstream os;
  os << "<robot name=\"chain\"><link name=\"l0\"/>";
  for (int i = 1; i <= n; ++i)
    os << "<link name=\"l" << i << "\"><inertial><origin xyz=\"0 0.05 0\"/><mass value=\"1\"/>"
       << "<inertia ixx=\"0.01\" iyy=\"0.01\" izz=\"0.01\" ixy=\"0\" ixz=\"0\" iyz=\"0\"/></inertial></link>"
       << "<joint name=\"j" << i << "\" type=\"revolute\"><parent link=\"l" << i - 1 << "\"/><child link=\"l" << i
       << "\"/><origin xyz=\"0 0.1 0\"/><axis xyz=\"1 0 0\"/>"
       << "<limit lower=\"-3\" upper=\"3\" effort=\"1\" velocity=\"1\"/></joint>";
  os << "</robot>";
  return os.str();
}

TEST(LongChain, HundredThousandLinksLoadAndRunRnea) {
  const int n = 100000;
  const Model m = Model::from_urdf_string(horizontal_chain(n));
  ASSERT_EQ(m.nb(), n);
  ASSERT_EQ(m.nv, n);
  // at rest at q = 0 the joint torques hold the links up against gravity g:
  // joint k carries links k..n, N = n - k + 1 of them, at 0.05, 0.15, ...
  // along y from it: tau_k = g·Σ_{i<N} (0.1 i + 0.05) = g·(0.05 N(N-1) + 0.05 N)
  const Vec q(m.nq, 0.0), zero(m.nv, 0.0);
  Vec tau(m.nv);
  batch::inverse_dynamics(m, 1, q.data(), zero.data(), nullptr, nullptr, -9.81, tau.data(), nullptr, nullptr,
                          nullptr);
  double err = 0, scale = 0;
  for (int k = 1; k <= n; ++k) {
    const double N = n - k + 1;
    const double expect = 9.81 * 0.05 * N * N;  // = g·(0.05 N(N-1) + 0.05 N)
    err = std::max(err, std::fabs(tau[k - 1] - expect));
    scale = std::max(scale, std::fabs(expect));
  }
  EXPECT_LT(err / scale, 1e-9);
  // ABA at those torques inverts RNEA: the torques of its qdd are tau again
  // (the backward error; qdd itself, ideally zero, is ~1e-4 on a chain this
  // ill-conditioned)
  Vec qdd(m.nv), back(m.nv);
  batch::aba(m, 1, q.data(), zero.data(), tau.data(), nullptr, -9.81, qdd.data());
  batch::inverse_dynamics(m, 1, q.data(), zero.data(), qdd.data(), nullptr, -9.81, back.data(), nullptr, nullptr,
                          nullptr);
  EXPECT_LT(rbd_test::max_rel_err(back, tau), 1e-10);
}

}  // namespace
