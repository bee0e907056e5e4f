// rbd::Handle: the algorithm table and its dependency resolution, the
// operations a handle has, clear errors for the others, and every batched
// call equal to the batch:: entry point it stands for (bit for bit) plus
// identities (FD(ID(qdd)) = qdd, M·M⁻¹ = I).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <set>

#include "rbdkit/batch/costs_api.hpp"
#include "rbdkit/batch/derivatives_api.hpp"
#include "rbdkit/batch/integrators_api.hpp"
#include "rbdkit/handle/handle.hpp"
#include "test_models.hpp"

using rbd::Handle;
using rbd::Model;

namespace {

std::set<std::string> as_set(const std::vector<std::string>& v) { return {v.begin(), v.end()}; }

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

Model hyq_floating() { return Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", true); }

// B random valid samples: q (B x nq), and uniform(-1, 1) arrays of width nv
struct Samples {
  long B;
  std::vector<double> q, qd, qdd, u, x;
  Samples(const Model& m, long B_, unsigned seed) : B(B_) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> U(-1, 1);
    auto vec = [&](long n) {
      std::vector<double> v(static_cast<size_t>(n));
      for (double& e : v) e = U(rng);
      return v;
    };
    const std::vector<double> neutral = m.neutral(), dq = vec(B * m.nv);
    q.resize(static_cast<size_t>(B * m.nq));
    for (long s = 0; s < B; ++s) rbd::batch::integrate(m, 1, neutral.data(), dq.data() + s * m.nv, q.data() + s * m.nq);
    qd = vec(B * m.nv), qdd = vec(B * m.nv), u = vec(B * m.nv);
    for (long s = 0; s < B; ++s) {
      x.insert(x.end(), q.begin() + s * m.nq, q.begin() + (s + 1) * m.nq);
      x.insert(x.end(), qd.begin() + s * m.nv, qd.begin() + (s + 1) * m.nv);
    }
  }
};

}  // namespace

TEST(HandleTable, NamesUniqueDependenciesEarlierOperationsOnce) {
  std::set<std::string> seen, ops;
  for (const rbd::AlgorithmInfo& a : rbd::handle_algorithms()) {
    EXPECT_TRUE(seen.insert(a.name).second) << a.name;
    for (const std::string& d : a.dependencies) EXPECT_TRUE(seen.count(d)) << a.name << " needs " << d;
    for (const std::string& op : a.operations) {
      EXPECT_TRUE(ops.insert(op).second) << op << " in two algorithms";
      EXPECT_EQ(rbd::algorithm_of(op), a.name);
    }
  }
  EXPECT_EQ(rbd::algorithm_of("nope"), "");
}

TEST(HandleTable, DependenciesAsTheSpecSays) {
  // the step Hessian needs fdsva_so; CoM costs com and ccrba; momentum costs dccrba;
  // integrator gradients the forward-dynamics gradient
  const auto hess = as_set(rbd::resolve_algorithms({"plant_step_hessian"}));
  for (const char* d : {"fdsva_so", "idsva_so", "integrator_gradient", "integrator", "forward_dynamics_gradient",
                        "inverse_dynamics_gradient", "forward_dynamics", "configuration"})
    EXPECT_TRUE(hess.count(d)) << d;
  EXPECT_EQ(as_set(rbd::resolve_algorithms({"com_cost"})), (std::set<std::string>{"com", "ccrba", "com_cost"}));
  EXPECT_EQ(as_set(rbd::resolve_algorithms({"momentum_cost"})),
            (std::set<std::string>{"com", "ccrba", "dccrba", "momentum_cost"}));
  EXPECT_TRUE(as_set(rbd::resolve_algorithms({"integrator_gradient"})).count("forward_dynamics_gradient"));
  EXPECT_EQ(rbd::resolve_algorithms({"crba"}), std::vector<std::string>{"crba"});
  // empty = everything, in table order; duplicates collapse
  EXPECT_EQ(rbd::resolve_algorithms({}).size(), rbd::handle_algorithms().size());
  EXPECT_EQ(rbd::resolve_algorithms({"crba", "crba"}), std::vector<std::string>{"crba"});
}

TEST(HandleTable, UnknownAlgorithmListsTheValidOnes) {
  try {
    rbd::resolve_algorithms({"crba", "rk3"});
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("algorithms: unknown algorithm 'rk3'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("plant_step_hessian"), std::string::npos) << msg;
  }
}

TEST(Handle, OnlyTheBuiltOperations) {
  Handle h(hyq_floating(), {"crba", "com_cost"});
  EXPECT_EQ(as_set(h.available_operations()),
            (std::set<std::string>{"crba", "com", "jacobian_com", "ccrba", "centroidal_momentum", "com_cost"}));
  EXPECT_TRUE(h.has("crba"));
  EXPECT_FALSE(h.has("aba"));
  EXPECT_FALSE(h.has("nope"));
  const Samples s(h.model(), 2, 1);
  std::vector<double> out(2 * 18 * 18 * 3);
  try {
    h.aba(2, s.q.data(), s.qd.data(), s.u.data(), nullptr, -9.81, out.data());
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "aba: this handle was not built with it; add 'aba' to its algorithms");
  }
  EXPECT_THROW(h.plant_step_gradient(2, s.x.data(), s.u.data(), nullptr, 0.01, -9.81, rbd::kRK4, out.data()),
               std::invalid_argument);
  h.crba(2, s.q.data(), out.data());  // built: runs
}

// the handle's output convention: the default of the operations that take
// one (typed methods included), equal to batch::integrator in that
// convention; on a floating base the others are refused, but the conversions
TEST(Handle, OutputConventionIsTheHandles) {
  const Model m = hyq_floating();
  Handle h(m, {}, 0, "float64", "mujoco");
  EXPECT_EQ(h.output_convention(), rbd::kMujocoConvention);
  const Samples s(m, 2, 3);
  std::vector<double> qpos(2 * m.nq), qvel(2 * m.nv), x(2 * (m.nq + m.nv)), ref(x.size());
  for (int k = 0; k < 2; ++k) {
    rbd::configuration_to_mujoco(m.view(), s.q.data() + k * m.nq, qpos.data() + k * m.nq);
    std::copy_n(s.qd.data() + k * m.nv, m.nv, qvel.data() + k * m.nv);
  }
  h.integrator(2, qpos.data(), qvel.data(), s.u.data(), nullptr, 0.01, -9.81, rbd::kRK4, x.data());
  rbd::batch::integrator(m, 2, qpos.data(), qvel.data(), s.u.data(), nullptr, 0.01, -9.81, rbd::kRK4, ref.data(),
                         rbd::kMujocoConvention);
  for (size_t k = 0; k < x.size(); ++k) EXPECT_EQ(x[k], ref[k]) << k;
  std::vector<double> M(2 * m.nv * m.nv);
  try {
    h.crba(2, s.q.data(), M.data());
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "crba: does not support output_convention='mujoco' on a model with free-flyer or "
                           "spherical joints; use a handle with output_convention='pinocchio'");
  }
  // without quaternion joints the conventions agree: every operation runs
  Handle hi(Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false), {}, 0, "float64", "mujoco");
  const Samples si(hi.model(), 2, 4);
  std::vector<double> Mi(2 * 7 * 7);
  hi.crba(2, si.q.data(), Mi.data());
  EXPECT_THROW(Handle(m, {}, 0, "float64", "MuJoCo"), std::invalid_argument);
}

TEST(Handle, BadInputIsReportedByTheEntryPoint) {
  Handle h(hyq_floating());
  Samples s(h.model(), 2, 2);
  s.q[19 + 6] = 2;  // the second sample's quaternion w
  std::vector<double> M(2 * 18 * 18);
  try {
    h.crba(2, s.q.data(), M.data());
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("q[1]: the quaternion of joint 'root_joint'"), std::string::npos) << e.what();
  }
  const rbd::BatchMatrix q(2, 18);  // nv columns instead of nq
  EXPECT_THROW(h.crba(q), std::invalid_argument);
  EXPECT_THROW(h.integrator(rbd::BatchMatrix::Zero(1, 19), rbd::BatchMatrix::Zero(1, 18),
                            rbd::BatchMatrix::Zero(1, 18), 0.01, "rk3"),
               std::invalid_argument);
}

class HandleCalls : public ::testing::TestWithParam<rbd_test::ModelCase> {};

TEST_P(HandleCalls, EqualTheBatchEntryPoints) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  Handle h(m);
  const long B = 3;
  const int nq = m.nq, nv = m.nv, nx = nq + nv, nb = m.nb();
  const Samples s(m, B, 7);
  auto buf = [&](long per) { return std::vector<double>(static_cast<size_t>(B * per)); };
  auto same = [](const std::vector<double>& a, const std::vector<double>& b, const char* what) {
    EXPECT_EQ(a, b) << what;
  };

  // ---- dynamics
  auto tau = buf(nv), tau_ref = buf(nv);
  h.inverse_dynamics(B, s.q.data(), s.qd.data(), s.qdd.data(), nullptr, -9.81, tau.data());
  rbd::batch::inverse_dynamics(m, B, s.q.data(), s.qd.data(), s.qdd.data(), nullptr, -9.81, tau_ref.data(), nullptr,
                               nullptr, nullptr);
  same(tau, tau_ref, "inverse_dynamics");
  auto M = buf(nv * nv), M_ref = buf(nv * nv), Mi = buf(nv * nv), Mi_ref = buf(nv * nv);
  h.crba(B, s.q.data(), M.data());
  rbd::batch::crba(m, B, s.q.data(), M_ref.data());
  same(M, M_ref, "crba");
  h.minv(B, s.q.data(), Mi.data());
  rbd::batch::minv(m, B, s.q.data(), true, Mi_ref.data());
  same(Mi, Mi_ref, "minv");
  auto qdd = buf(nv), qdd_ref = buf(nv);
  h.aba(B, s.q.data(), s.qd.data(), tau.data(), nullptr, -9.81, qdd.data());
  rbd::batch::aba(m, B, s.q.data(), s.qd.data(), tau.data(), nullptr, -9.81, qdd_ref.data());
  same(qdd, qdd_ref, "aba");
  h.forward_dynamics(B, s.q.data(), s.qd.data(), tau.data(), nullptr, -9.81, qdd.data());
  rbd::batch::forward_dynamics(m, B, s.q.data(), s.qd.data(), tau.data(), nullptr, -9.81, qdd_ref.data());
  same(qdd, qdd_ref, "forward_dynamics");
  // identities: FD(ID(qdd)) = qdd, M M⁻¹ = I
  EXPECT_LT(rbd_test::max_rel_err(qdd, s.qdd), 1e-9);
  for (long b = 0; b < B; ++b)
    for (int i = 0; i < nv; ++i)
      for (int j = 0; j < nv; ++j) {
        double e = 0;
        for (int k = 0; k < nv; ++k) e += M[b * nv * nv + i * nv + k] * Mi[b * nv * nv + k * nv + j];
        EXPECT_NEAR(e, i == j ? 1.0 : 0.0, 1e-9);
      }

  // ---- first-order derivatives
  auto dq = buf(nv * nv), dv = buf(nv * nv), both = buf(2 * nv * nv);
  h.inverse_dynamics_gradient(B, s.q.data(), s.qd.data(), s.qdd.data(), nullptr, -9.81, dq.data(), dv.data());
  rbd::batch::inverse_dynamics_gradient(m, B, s.q.data(), s.qd.data(), s.qdd.data(), nullptr, -9.81, both.data());
  for (long r = 0; r < B * nv; ++r)
    for (int c = 0; c < nv; ++c) {
      EXPECT_EQ(dq[r * nv + c], both[r * 2 * nv + c]);
      EXPECT_EQ(dv[r * nv + c], both[r * 2 * nv + nv + c]);
    }
  auto dq_ref = buf(nv * nv), dv_ref = buf(nv * nv);
  h.forward_dynamics_gradient(B, s.q.data(), s.qd.data(), s.u.data(), nullptr, -9.81, dq.data(), dv.data());
  rbd::batch::forward_dynamics_gradient(m, B, s.q.data(), s.qd.data(), s.u.data(), nullptr, -9.81, dq_ref.data(),
                                        dv_ref.data(), nullptr);
  same(dq, dq_ref, "forward_dynamics_gradient dq");
  same(dv, dv_ref, "forward_dynamics_gradient dqd");

  // ---- integrators and plant step (rk4 and semi-implicit Euler)
  for (int type : {rbd::kRK4, rbd::kSemiImplicitEuler}) {
    auto x = buf(nx), x_ref = buf(nx), xp = buf(nx), AB = buf(6 * nv * nv), AB_ref = buf(6 * nv * nv),
         ABp = buf(6 * nv * nv);
    h.integrator(B, s.q.data(), s.qd.data(), s.u.data(), nullptr, 0.01, -9.81, type, x.data());
    rbd::batch::integrator(m, B, s.q.data(), s.qd.data(), s.u.data(), nullptr, 0.01, -9.81, type, x_ref.data());
    same(x, x_ref, "integrator");
    h.plant_step(B, s.x.data(), s.u.data(), nullptr, 0.01, -9.81, type, xp.data());
    same(xp, x_ref, "plant_step");
    h.integrator_gradient(B, s.q.data(), s.qd.data(), s.u.data(), nullptr, 0.01, -9.81, type, nullptr, AB.data());
    rbd::batch::integrator_gradient(m, B, s.q.data(), s.qd.data(), s.u.data(), nullptr, 0.01, -9.81, type,
                                    x_ref.data(), AB_ref.data());
    same(AB, AB_ref, "integrator_gradient");
    h.plant_step_gradient(B, s.x.data(), s.u.data(), nullptr, 0.01, -9.81, type, ABp.data());
    same(ABp, AB_ref, "plant_step_gradient");
    // the step Hessian: H from the batch entry point, AB equal to the gradient's
    auto H = buf(18 * nv * nv * nv), H_ref = buf(18 * nv * nv * nv), ABh = buf(6 * nv * nv);
    h.plant_step_hessian(B, s.x.data(), s.u.data(), 0.01, -9.81, type, nullptr, ABh.data(), H.data());
    rbd::batch::plant_step_hessian(m, B, s.q.data(), s.qd.data(), s.u.data(), 0.01, -9.81, type, x_ref.data(),
                                   AB_ref.data(), H_ref.data());
    same(H, H_ref, "plant_step_hessian");
    same(ABh, AB_ref, "plant_step_hessian AB");
  }

  // ---- costs and barriers
  auto val = buf(1), val_ref = buf(1);
  {
    std::vector<double> Q(static_cast<size_t>(B * nx), 2.0), g = buf(nx), H = buf(nx * nx), g_ref = buf(nx),
                                                               H_ref = buf(nx * nx);
    h.quadratic_state_cost(B, s.x.data(), std::vector<double>(B * nx, 0.1).data(), Q.data(), val.data(), g.data(),
                           H.data());
    rbd::batch::quadratic_cost(B, nx, s.x.data(), std::vector<double>(B * nx, 0.1).data(), Q.data(), val_ref.data(),
                               g_ref.data(), H_ref.data(), "x", "x_des", "Q");
    same(val, val_ref, "quadratic_state_cost");
    same(H, H_ref, "quadratic_state_cost H");
    const std::vector<double> Q2(static_cast<size_t>(B * 2 * nv), 1.5);
    auto g2 = buf(2 * nv), H2 = buf(4 * nv * nv), g2_ref = buf(2 * nv), H2_ref = buf(4 * nv * nv);
    std::vector<double> x_des = s.x;  // another valid state per sample: the samples rotated by one
    std::rotate(x_des.begin(), x_des.begin() + nx, x_des.end());
    h.quadratic_state_cost_tangent(B, s.x.data(), x_des.data(), Q2.data(), val.data(), g2.data(), H2.data());
    rbd::batch::quadratic_state_cost_tangent(m, B, s.x.data(), x_des.data(), Q2.data(), val_ref.data(),
                                             g2_ref.data(), H2_ref.data());
    same(g2, g2_ref, "quadratic_state_cost_tangent");
    const std::vector<double> R(static_cast<size_t>(B * nv), 0.5);
    auto gu = buf(nv), Hu = buf(nv * nv), gu_ref = buf(nv), Hu_ref = buf(nv * nv);
    h.quadratic_input_cost(B, s.u.data(), s.qd.data(), R.data(), val.data(), gu.data(), Hu.data());
    rbd::batch::quadratic_cost(B, nv, s.u.data(), s.qd.data(), R.data(), val_ref.data(), gu_ref.data(),
                               Hu_ref.data(), "u", "u_des", "R");
    same(gu, gu_ref, "quadratic_input_cost");
    const std::vector<double> p(static_cast<size_t>(B * 3), 0.3), W(static_cast<size_t>(B * 3), 2.0);
    h.ee_pos_cost(B, s.q.data(), p.data(), W.data(), val.data(), g.data(), H.data());
    rbd::batch::ee_pos_cost(m, B, s.q.data(), p.data(), W.data(), rbd::leaf_bodies(m).front(), nullptr,
                            val_ref.data(), g_ref.data(), H_ref.data());
    same(g, g_ref, "ee_pos_cost");
    h.com_cost(B, s.q.data(), p.data(), W.data(), val.data(), g.data(), H.data());
    rbd::batch::com_cost(m, B, s.q.data(), p.data(), W.data(), val_ref.data(), g_ref.data(), H_ref.data());
    same(g, g_ref, "com_cost");
    const std::vector<double> hd(static_cast<size_t>(B * 6), 0.2), W6(static_cast<size_t>(B * 6), 1.0);
    h.momentum_cost(B, s.q.data(), s.qd.data(), hd.data(), W6.data(), val.data(), g2.data(), H2.data());
    rbd::batch::momentum_cost(m, B, s.q.data(), s.qd.data(), hd.data(), W6.data(), val_ref.data(), g2_ref.data(),
                              H2_ref.data());
    same(H2, H2_ref, "momentum_cost");
    const std::vector<double> lo(static_cast<size_t>(B * nx), -5.0), hi(static_cast<size_t>(B * nx), 5.0);
    auto gb = buf(nv), hb = buf(nv), gb_ref = buf(nv), hb_ref = buf(nv);
    h.joint_torque_barrier(B, s.u.data(), lo.data(), hi.data(), 0.1, val.data(), gb.data(), hb.data());
    rbd::batch::log_barrier(B, nv, s.u.data(), lo.data(), hi.data(), 0.1, val_ref.data(), gb_ref.data(),
                            hb_ref.data(), "u");
    same(hb, hb_ref, "joint_torque_barrier");
    auto gq = buf(nq), hq = buf(nq), gq_ref = buf(nq), hq_ref = buf(nq);
    h.joint_position_barrier(B, s.q.data(), lo.data(), hi.data(), 0.1, val.data(), gq.data(), hq.data());
    rbd::batch::log_barrier(B, nq, s.q.data(), lo.data(), hi.data(), 0.1, val_ref.data(), gq_ref.data(),
                            hq_ref.data(), "q");
    same(gq, gq_ref, "joint_position_barrier");
  }
  (void)nb;

  // ---- the Eigen front ends equal the raw calls
  using rbd::BatchMatrix;
  const Eigen::Map<const BatchMatrix> Qm(s.q.data(), B, nq), QDm(s.qd.data(), B, nv), QDDm(s.qdd.data(), B, nv),
      Um(s.u.data(), B, nv);
  h.inverse_dynamics(B, s.q.data(), s.qd.data(), s.qdd.data(), nullptr, -9.81, tau.data());
  const BatchMatrix T = h.inverse_dynamics(BatchMatrix(Qm), BatchMatrix(QDm), BatchMatrix(QDDm));
  EXPECT_EQ(std::vector<double>(T.data(), T.data() + T.size()), tau);
  const BatchMatrix A = h.forward_dynamics(BatchMatrix(Qm), BatchMatrix(QDm), T);
  EXPECT_LT((A - BatchMatrix(QDDm)).cwiseAbs().maxCoeff(), 1e-9);
  const std::vector<Eigen::MatrixXd> Ms = h.crba(BatchMatrix(Qm));
  for (long b = 0; b < B; ++b)
    for (int i = 0; i < nv; ++i)
      for (int j = 0; j < nv; ++j) EXPECT_EQ(Ms[b](i, j), M[b * nv * nv + i * nv + j]);
  auto x = buf(nx), AB = buf(6 * nv * nv);
  h.integrator_gradient(B, s.q.data(), s.qd.data(), s.u.data(), nullptr, 0.02, -9.81, rbd::kRK4, x.data(), AB.data());
  const BatchMatrix X = h.integrator(BatchMatrix(Qm), BatchMatrix(QDm), BatchMatrix(Um), 0.02, "rk4");
  // (the step's stages take ABA's qdd, the gradient's M⁻¹ (u - c): the same x⁺ to rounding)
  EXPECT_LT(rbd_test::max_rel_err(std::vector<double>(X.data(), X.data() + X.size()), x), 1e-12);
  const std::vector<Eigen::MatrixXd> ABs = h.integrator_gradient(BatchMatrix(Qm), BatchMatrix(QDm), BatchMatrix(Um),
                                                                 0.02, "rk4");
  for (long b = 0; b < B; ++b)
    for (int i = 0; i < 2 * nv; ++i)
      for (int j = 0; j < 3 * nv; ++j) EXPECT_EQ(ABs[b](i, j), AB[(b * 2 * nv + i) * 3 * nv + j]);
}

// the bundled robots, fixed and floating, and the spherical model
INSTANTIATE_TEST_SUITE_P(Models, HandleCalls,
                         ::testing::Values(
                             rbd_test::ModelCase{std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false},
                             rbd_test::ModelCase{std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", true},
                             rbd_test::ModelCase{std::string(RBDKIT_ROBOTS_DIR) + "/atlas.urdf", true},
                             rbd_test::ModelCase{std::string(RBDKIT_TEST_URDF_DIR) + "/spherical.urdf", true}),
                         rbd_test::case_name);

// ---- a handle with the batched engine (threads > 0)

TEST(HandleThreads, NegativeThreadsAreAnError) {
  EXPECT_THROW(Handle(hyq_floating(), {}, -1), std::invalid_argument);
  EXPECT_EQ(Handle(hyq_floating()).threads(), 0);
  EXPECT_EQ(Handle(hyq_floating(), {}, 2).threads(), 2);
}

TEST(HandleThreads, EngineInputsAreChecked) {
  Handle h(hyq_floating(), {}, 2);
  Samples s(h.model(), 3, 5);
  s.q[1 * h.model().nq + 4] = 2.0;  // sample 1: not a unit quaternion
  std::vector<double> M(3 * 18 * 18);
  EXPECT_THROW(h.crba(3, s.q.data(), M.data()), std::invalid_argument);
  Samples t(h.model(), 3, 6);
  t.qd[5] = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> qdd(3 * 18);
  EXPECT_THROW(h.aba(3, t.q.data(), t.qd.data(), t.u.data(), nullptr, -9.81, qdd.data()), std::invalid_argument);
}

class HandleEngine : public ::testing::TestWithParam<rbd_test::ModelCase> {};

// the engine-backed calls: bit-identical for 1 and 3 threads, equal to the
// one-sample-at-a-time handle (threads = 0) to rounding
TEST_P(HandleEngine, ThreadCountDoesNotChangeTheNumbers) {
  const Model m = Model::from_urdf_file(GetParam().path, GetParam().floating);
  Handle h0(m), h1(m, {}, 1), h3(m, {}, 3);
  const long B = 7;  // not a multiple of the SIMD width
  const int nq = m.nq, nv = m.nv, nx = nq + nv;
  const Samples s(m, B, 11);
  using Call = std::function<void(Handle&, double*)>;
  const std::vector<std::pair<const char*, std::pair<long, Call>>> calls = {
      {"inverse_dynamics", {nv, [&](Handle& h, double* o) {
         h.inverse_dynamics(B, s.q.data(), s.qd.data(), s.qdd.data(), nullptr, -9.81, o); }}},
      {"crba", {nv * nv, [&](Handle& h, double* o) { h.crba(B, s.q.data(), o); }}},
      {"minv", {nv * nv, [&](Handle& h, double* o) { h.minv(B, s.q.data(), o); }}},
      {"aba", {nv, [&](Handle& h, double* o) { h.aba(B, s.q.data(), s.qd.data(), s.u.data(), nullptr, -9.81, o); }}},
      {"inverse_dynamics_gradient", {2 * nv * nv, [&](Handle& h, double* o) {
         h.inverse_dynamics_gradient(B, s.q.data(), s.qd.data(), s.qdd.data(), nullptr, -9.81, o, o + B * nv * nv); }}},
      {"forward_dynamics_gradient", {2 * nv * nv, [&](Handle& h, double* o) {
         h.forward_dynamics_gradient(B, s.q.data(), s.qd.data(), s.u.data(), nullptr, -9.81, o, o + B * nv * nv); }}},
      {"plant_step", {nx, [&](Handle& h, double* o) {
         h.plant_step(B, s.x.data(), s.u.data(), nullptr, 0.01, -9.81, rbd::kRK4, o); }}},
      {"plant_step_gradient", {6 * nv * nv, [&](Handle& h, double* o) {
         h.plant_step_gradient(B, s.x.data(), s.u.data(), nullptr, 0.01, -9.81, rbd::kRK4, o); }}},
  };
  for (const auto& c : calls) {
    const long n = B * c.second.first;
    std::vector<double> r0(n), r1(n), r3(n);
    c.second.second(h0, r0.data());
    c.second.second(h1, r1.data());
    c.second.second(h3, r3.data());
    EXPECT_EQ(0, std::memcmp(r1.data(), r3.data(), n * sizeof(double))) << c.first;
    EXPECT_LT(rbd_test::max_rel_err(r1, r0), 1e-10) << c.first;
  }
}

INSTANTIATE_TEST_SUITE_P(Models, HandleEngine,
                         ::testing::Values(
                             rbd_test::ModelCase{std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false},
                             rbd_test::ModelCase{std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", true},
                             rbd_test::ModelCase{std::string(RBDKIT_TEST_URDF_DIR) + "/spherical.urdf", true}),
                         rbd_test::case_name);
