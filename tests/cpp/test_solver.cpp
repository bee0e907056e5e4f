// The trajectory optimiser (solver.hpp): the Riccati recursion against the
// brute-force optimum of a linear-quadratic problem, the derivative path
// (the handle's batched calls, counted), an arm reach, and bad input.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "rbdkit/batch/kinematics_api.hpp"
#include "rbdkit/solver/solver.hpp"

namespace {

using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

rbd::Model iiwa() { return rbd::Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf"); }

// x⁺ = A x + B u + c on a fixed base with revolute joints (x ⊖ x̄ = x − x̄)
class LinearSteps : public rbd::PlantSteps {
 public:
  LinearSteps(Eigen::MatrixXd A, Eigen::MatrixXd B, Eigen::VectorXd c) : A(A), Bm(B), c(c) {}
  void step(long n, const double* x, const double* u, double* x_next) override {
    const int nx = A.rows(), nu = Bm.cols();
    for (long s = 0; s < n; ++s)
      Eigen::Map<Eigen::VectorXd>(x_next + s * nx, nx) =
          A * Eigen::Map<const Eigen::VectorXd>(x + s * nx, nx) + Bm * Eigen::Map<const Eigen::VectorXd>(u + s * nu, nu) + c;
  }
  void step_gradient(long n, const double*, const double*, double* AB) override {
    const int nx = A.rows(), nu = Bm.cols();
    RowMat ab(nx, nx + nu);
    ab << A, Bm;
    for (long s = 0; s < n; ++s) Eigen::Map<RowMat>(AB + s * nx * (nx + nu), nx, nx + nu) = ab;
  }
  void step_hessian(long n, const double*, const double*, double* H) override {
    const int nx = A.rows(), nz = nx + Bm.cols();
    std::fill(H, H + n * nx * nz * nz, 0.0);
  }
  Eigen::MatrixXd A, Bm;
  Eigen::VectorXd c;
};

// forwards to the handle and counts what the solver asks for
class CountingSteps : public rbd::HandleSteps {
 public:
  using rbd::HandleSteps::HandleSteps;
  void step(long B, const double* x, const double* u, double* x_next) override {
    ++steps, step_rows += B, max_step_batch = std::max(max_step_batch, B);
    rbd::HandleSteps::step(B, x, u, x_next);
  }
  void step_gradient(long B, const double* x, const double* u, double* AB) override {
    ++gradients, gradient_batches.push_back(B);
    rbd::HandleSteps::step_gradient(B, x, u, AB);
  }
  void step_hessian(long B, const double* x, const double* u, double* H) override {
    ++hessians, hessian_batches.push_back(B);
    rbd::HandleSteps::step_hessian(B, x, u, H);
  }
  long steps = 0, step_rows = 0, max_step_batch = 0, gradients = 0, hessians = 0;
  std::vector<long> gradient_batches, hessian_batches;
};

rbd::TrajectoryProblem reach_problem(const rbd::Model& m, int N) {
  rbd::TrajectoryProblem p;
  p.horizon = N, p.dt = 0.02, p.integrator = "rk4";
  p.x0 = Eigen::VectorXd::Zero(m.nq + m.nv);
  p.x0.head(m.nq) << 0.1, 0.5, 0.0, -1.2, 0.0, 0.8, 0.0;
  p.Q = Eigen::VectorXd::Constant(2 * m.nv, 1e-3);
  p.Q_terminal = Eigen::VectorXd::Zero(2 * m.nv);
  p.Q_terminal.tail(m.nv).setConstant(1.0);
  p.R = Eigen::VectorXd::Constant(m.nv, 1e-3);
  p.ee = true;
  p.ee_offset = Eigen::Vector3d(0, 0, 0.05);
  p.ee_target = Eigen::Vector3d(0.45, 0.25, 0.75);
  p.W_ee = Eigen::Vector3d::Constant(10.0);
  p.W_ee_terminal = Eigen::Vector3d::Constant(1e4);
  return p;
}

}  // namespace

// linear dynamics, quadratic cost: one iLQR iteration reaches the optimum of
// the stacked least-squares problem, and the first feedback gain is ∂U₀*/∂x₀
TEST(Solver, RiccatiMatchesBruteForceLQR) {
  rbd::Model m = iiwa();
  rbd::Handle h(m, {"state_costs", "barriers"});
  const int nv = m.nv, n = 2 * nv, N = 12;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(n, n), B(n, nv);
  Eigen::VectorXd c(n), x0(n), xr(n), ur(nv), Q(n), QN(n), R(nv);
  for (int i = 0; i < n * n; ++i) A.data()[i] += 0.1 * U(rng);
  for (int i = 0; i < n * nv; ++i) B.data()[i] = 0.2 * U(rng);
  for (int i = 0; i < n; ++i) c[i] = 0.05 * U(rng), x0[i] = U(rng), xr[i] = U(rng), Q[i] = 1 + U(rng),
                              QN[i] = 10 + U(rng);
  for (int i = 0; i < nv; ++i) ur[i] = U(rng), R[i] = 0.5 + 0.2 * U(rng);
  LinearSteps steps(A, B, c);
  rbd::TrajectoryProblem p;
  p.horizon = N, p.dt = 0.1, p.x0 = x0, p.x_ref = xr, p.u_ref = ur, p.Q = Q, p.Q_terminal = QN, p.R = R;
  p.position_limits = p.velocity_limits = p.torque_limits = false;
  rbd::SolverOptions o;
  o.mu_init = o.mu_min = 0, o.reg_init = o.reg_min = 1e-14, o.max_iterations = 5;
  const rbd::SolverResult r = rbd::solve_trajectory(m, steps, h, p, o);

  // brute force: X = F x0 + G U + h (knots 1..N), minimise over U
  Eigen::MatrixXd F(N * n, n), G = Eigen::MatrixXd::Zero(N * n, N * nv);
  Eigen::VectorXd hh(N * n);
  Eigen::MatrixXd Ak = Eigen::MatrixXd::Identity(n, n);
  Eigen::VectorXd ck = Eigen::VectorXd::Zero(n);
  for (int k = 0; k < N; ++k) {
    Ak = A * Ak, ck = A * ck + c;
    F.middleRows(k * n, n) = Ak, hh.segment(k * n, n) = ck;
    for (int j = 0; j <= k; ++j) {
      Eigen::MatrixXd P = B;
      for (int i = j; i < k; ++i) P = A * P;
      G.block(k * n, j * nv, n, nv) = P;
    }
  }
  Eigen::VectorXd Wx(N * n), Wu(N * nv), xref(N * n), uref(N * nv);
  for (int k = 0; k < N; ++k) {
    Wx.segment(k * n, n) = k == N - 1 ? QN : Eigen::VectorXd(Q * p.dt);
    Wu.segment(k * nv, nv) = R * p.dt;
    xref.segment(k * n, n) = xr, uref.segment(k * nv, nv) = ur;
  }
  const Eigen::MatrixXd H = G.transpose() * Wx.asDiagonal() * G + Eigen::MatrixXd(Wu.asDiagonal());
  const Eigen::VectorXd rhs = G.transpose() * Wx.asDiagonal() * (xref - F * x0 - hh) + Wu.asDiagonal() * uref;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(H);
  const Eigen::VectorXd Ustar = ldlt.solve(rhs);
  const Eigen::MatrixXd dU_dx0 = -ldlt.solve(G.transpose() * Wx.asDiagonal() * F);

  ASSERT_GE(r.log.size(), 2u);
  EXPECT_EQ(r.log[1].step, 1.0);  // the full step, first try
  // the quadratic model is exact: predicted = actual decrease
  EXPECT_NEAR(r.log[1].actual, r.log[1].expected, 1e-9 * std::abs(r.log[1].expected));
  EXPECT_TRUE(r.converged) << r.status;
  EXPECT_LE(r.iterations, 2);
  const Eigen::Map<const Eigen::VectorXd> Uflat(r.U.data(), N * nv);
  EXPECT_LT((Uflat - Ustar).cwiseAbs().maxCoeff(), 1e-9 * std::max(1.0, Ustar.cwiseAbs().maxCoeff()));
  // the first feedback gain: the sensitivity of the optimal u_0 to x_0
  EXPECT_LT((r.K[0] - dU_dx0.topRows(nv)).cwiseAbs().maxCoeff(), 1e-9 * std::max(1.0, dU_dx0.cwiseAbs().maxCoeff()));
}

// derivatives come from the batched handle calls: one plant_step_gradient of
// the N knots per iteration; plant_step only in rollouts (B = 1, N per rollout)
TEST(Solver, DerivativesFromBatchedHandleCalls) {
  rbd::Model m = iiwa();
  rbd::Handle h(m);
  const rbd::TrajectoryProblem p = reach_problem(m, 25);
  CountingSteps steps(h, p.dt, p.integrator, p.gravity);
  rbd::SolverOptions o;
  o.max_iterations = 60;
  const rbd::SolverResult r = rbd::solve_trajectory(m, steps, h, p, o);
  EXPECT_GE(steps.gradients, 1);
  for (long b : steps.gradient_batches) EXPECT_EQ(b, p.horizon);
  EXPECT_EQ(steps.hessians, 0);
  EXPECT_LE(steps.gradients, r.iterations);
  EXPECT_EQ(r.derivative_knots, steps.gradients * p.horizon);
  EXPECT_EQ(steps.max_step_batch, 1);
  EXPECT_EQ(steps.step_rows % p.horizon, 0);  // whole rollouts only: no perturbed steps
  long rollouts = 1;
  for (size_t i = 1; i < r.log.size(); ++i) rollouts += 1;  // at least one trial per iteration
  EXPECT_GE(steps.steps / p.horizon, rollouts);
  EXPECT_LE(steps.steps / p.horizon, 1 + static_cast<long>(r.log.size()) * o.line_search_steps);
}

// the arm reaches its target within the limits; full DDP too
TEST(Solver, IiwaReachConverges) {
  rbd::Model m = iiwa();
  rbd::Handle h(m);
  for (bool ddp : {false, true}) {
    const rbd::TrajectoryProblem p = reach_problem(m, ddp ? 15 : 25);
    CountingSteps steps(h, p.dt, p.integrator, p.gravity);
    rbd::SolverOptions o;
    o.ddp = ddp;
    o.max_iterations = 100;
    const rbd::SolverResult r = rbd::solve_trajectory(m, steps, h, p, o);
    EXPECT_TRUE(r.converged) << "ddp " << ddp << ": " << r.status;
    EXPECT_EQ(r.violation, 0.0);
    // the tool point at the last knot
    rbd::EndEffectors ee;
    ee.bodies = {rbd::leaf_bodies(m).front()};
    const double off[3] = {0, 0, 0.05};
    ee.offsets = off;
    double pose[6];
    rbd::batch::end_effector_pose(m, 1, r.X.row(p.horizon).data(), ee, pose);
    const double err = (Eigen::Vector3d(pose[0], pose[1], pose[2]) - p.ee_target).norm();
    EXPECT_LT(err, 1e-3) << "ddp " << ddp;
    // the cost never increases
    for (size_t i = 2; i < r.log.size(); ++i)
      if (r.log[i].mu == r.log[i - 1].mu) EXPECT_LE(r.log[i].merit, r.log[i - 1].merit + 1e-12);
    if (ddp) {
      EXPECT_EQ(steps.hessians, steps.gradients);
      for (long b : steps.hessian_batches) EXPECT_EQ(b, p.horizon);
    }
  }
}

TEST(Solver, BadInput) {
  rbd::Model m = iiwa();
  rbd::Handle h(m);
  auto expect_error = [&](rbd::TrajectoryProblem p, const std::string& needle, RowMat U = {}) {
    try {
      rbd::solve_trajectory(h, p, {}, U);
      ADD_FAILURE() << "no error for " << needle;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  rbd::TrajectoryProblem p = reach_problem(m, 10);
  auto q = p;
  q.horizon = -3;
  expect_error(q, "horizon");
  q = p, q.dt = 0;
  expect_error(q, "dt");
  q = p, q.x0 = Eigen::VectorXd::Zero(5);
  expect_error(q, "x0");
  q = p, q.integrator = "leapfrog";
  expect_error(q, "integrator");
  q = p, q.ee_target = Eigen::Vector3d(3, 0, 0.5);
  expect_error(q, "out of reach");
  q = p, q.x0[0] = 3.0;  // beyond the first joint's ±2.967 rad
  expect_error(q, "joint limits");
  expect_error(p, "U_init", RowMat::Zero(4, m.nv));
  q = p, q.R = -Eigen::VectorXd::Ones(m.nv);
  expect_error(q, "R");
}

// without limits there is no barrier, so no μ schedule: the solve stops as soon
// as the iterations stall, in the same iterations as with μ already at mu_min
TEST(Solver, NoLimitsSkipTheBarrierSchedule) {
  rbd::Model m = iiwa();
  rbd::Handle h(m);
  rbd::TrajectoryProblem p = reach_problem(m, 25);
  p.position_limits = p.velocity_limits = p.torque_limits = false;
  rbd::SolverOptions o;
  const rbd::SolverResult a = rbd::solve_trajectory(h, p, o);
  o.mu_init = o.mu_min;
  const rbd::SolverResult b = rbd::solve_trajectory(h, p, o);
  EXPECT_TRUE(a.converged);
  EXPECT_EQ(a.iterations, b.iterations);
  for (const auto& rec : a.log) EXPECT_EQ(rec.mu, o.mu_min);
}
