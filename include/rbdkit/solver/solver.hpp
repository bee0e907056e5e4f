// rbdkit/solver/solver.hpp — trajectory optimisation on the plant layer: iLQR
// (Gauss–Newton) and, optionally, full DDP with the step Hessian. Host only
// (Eigen; per-iteration code, not per-sample device maths).
//
// Problem (N knot points, tangent state δx = x ⊖ x̄ = [difference(q̄, q); qd - q̄d], 2nv):
//   minimise  Σ_{k<N} ℓ(x_k, u_k)·dt + ℓ_N(x_N) + μ·Σ barriers
//   subject to x_{k+1} = step(x_k, u_k) (any integrator scheme), x_0 given,
//   ℓ   = ½‖x ⊖ x_ref‖²_Q + ½‖u − u_ref‖²_R + ½‖p_ee(q) − p*‖²_Wee + ½‖c(q) − c*‖²_Wcom
//   ℓ_N = the same with the terminal weights and no input term;
//   barriers: −Σ log of the distance to the finite joint position (q_1..q_N),
//   velocity (qd_1..qd_N) and torque (u_0..u_{N−1}) limits.
//
// Method, per iteration:
//   derivatives  one batched plant_step_gradient over the N knots (and, with
//                ddp, one batched plant_step_hessian), the costs and barriers
//                batched over the knots, all through an rbd::Handle;
//   backward     Riccati recursion in the tangent space, Quu + λI
//                (Levenberg–Marquardt; λ grows on a non-PD Quu or a failed
//                line search, shrinks on success); full DDP adds Σ_i V'_x,i H_i;
//   forward      rollout u = ū + α·k + K·(x ⊖ x̄), backtracking α = 1, ½, ¼, …
//                on the actual cost (accepted when the actual decrease is at
//                least 1e-4 of the quadratic model's);
//   barrier      μ is divided by mu_factor⁻¹ each time the inner iterations
//                stall (relative cost decrease < tol_cost or ‖Qu‖∞ < tol_grad),
//                down to mu_min: converged when they stall at mu_min.
// The iterates stay strictly inside the limits (a rollout leaving them costs
// +∞ and is rejected by the line search); the start must be inside them.
//
//   rbd::Handle h(model);
//   rbd::TrajectoryProblem p;  p.horizon = 100;  p.x0 = ...;  p.ee = true;  p.ee_target = {0.5, 0, 0.6};
//   rbd::SolverResult r = rbd::solve_trajectory(h, p);           // r.X (N+1 x NX), r.U (N x nv)
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "rbdkit/handle/handle.hpp"

namespace rbd {

// The solver's view of the dynamics: batched steps and their tangent-space
// derivatives (integrators_api.hpp, integrator_hessian.hpp). One call per
// batch; a test or an accelerated engine substitutes its own.
class PlantSteps {
 public:
  virtual ~PlantSteps() = default;
  // x (B x NX), u (B x nv) -> x⁺ (B x NX)
  virtual void step(long B, const double* x, const double* u, double* x_next) = 0;
  // [A | B] (B x 2nv x 3nv)
  virtual void step_gradient(long B, const double* x, const double* u, double* AB) = 0;
  // H (B x 2nv x 3nv x 3nv), H[i, j, k] = ∂²ψ_i/∂z_j∂z_k (full DDP only)
  virtual void step_hessian(long B, const double* x, const double* u, double* H) = 0;
};

// PlantSteps through a handle's plant_step, plant_step_gradient and plant_step_hessian
class HandleSteps : public PlantSteps {
 public:
  HandleSteps(Handle& h, double dt, const std::string& integrator, double gravity);
  void step(long B, const double* x, const double* u, double* x_next) override;
  void step_gradient(long B, const double* x, const double* u, double* AB) override;
  void step_hessian(long B, const double* x, const double* u, double* H) override;

 private:
  Handle& h_;
  double dt_, gravity_;
  int type_;
};

struct TrajectoryProblem {
  int horizon = 0;                    // N: controls u_0..u_{N−1}, states x_0..x_N
  double dt = 0.01;
  std::string integrator = "rk4";     // integrator_from_name
  double gravity = -9.81;
  Eigen::VectorXd x0;                 // (NX) initial state
  // state regularisation (tangent): x_ref (NX; empty: x0), Q, Q_terminal (2nv; empty: zero)
  Eigen::VectorXd x_ref, Q, Q_terminal;
  // input regularisation: u_ref (nv; empty: gravity compensation at x0), R (nv; empty: zero)
  Eigen::VectorXd u_ref, R;
  // end-effector position: body (−1: the first leaf body), tool point in its frame
  bool ee = false;
  int ee_body = -1;
  Eigen::Vector3d ee_offset = Eigen::Vector3d::Zero(), ee_target = Eigen::Vector3d::Zero();
  Eigen::Vector3d W_ee = Eigen::Vector3d::Zero(), W_ee_terminal = Eigen::Vector3d::Zero();
  // centre of mass
  bool com = false;
  Eigen::Vector3d com_target = Eigen::Vector3d::Zero();
  Eigen::Vector3d W_com = Eigen::Vector3d::Zero(), W_com_terminal = Eigen::Vector3d::Zero();
  // limits through log barriers; empty bounds: the model's (URDF) limits
  bool position_limits = true, velocity_limits = true, torque_limits = true;
  Eigen::VectorXd q_lower, q_upper;   // (nq), ±inf: none (only 1-dof joints may be bounded)
  Eigen::VectorXd v_limit, u_limit;   // (nv) symmetric |qd| ≤ v_limit, |u| ≤ u_limit
};

struct SolverOptions {
  int max_iterations = 200;
  bool ddp = false;                   // add the step Hessian (full DDP)
  double mu_init = 1e-2, mu_min = 1e-7, mu_factor = 0.1;     // barrier parameter schedule
  double reg_init = 1e-6, reg_min = 1e-9, reg_max = 1e10, reg_factor = 10;
  double tol_cost = 1e-8;             // relative decrease of the cost that counts as stalled
  double tol_grad = 1e-7;             // ‖Qu‖∞ that counts as stalled
  int line_search_steps = 14;
  std::function<void(const struct IterationRecord&)> callback;  // after every iteration
};

struct IterationRecord {
  int iteration = 0;
  double cost = 0;          // the objective without the barriers
  double merit = 0;         // cost + μ·barriers (what the line search compares)
  double violation = 0;     // max limit violation over the trajectory (≥ 0)
  double step = 0;          // accepted α (0: rejected)
  double reg = 0;           // λ used in the accepted backward pass
  double mu = 0;            // barrier parameter
  double grad_norm = 0;     // max_k ‖Qu_k‖∞
  double expected = 0, actual = 0;  // predicted and actual merit decrease
  double time = 0;          // wall time of the iteration (s)
  double derivatives_time = 0;      // of the batched derivative calls (s)
};

struct SolverResult {
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> X, U;  // (N+1 x NX), (N x nv)
  std::vector<Eigen::MatrixXd> K;     // (N) feedback gains (nv x 2nv) on x ⊖ X_k
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> k;      // (N x nv) feedforward
  std::vector<IterationRecord> log;   // log[0]: the initial rollout
  std::string status;                 // converged | max_iterations | stalled (λ at reg_max)
  bool converged = false;
  int iterations = 0;
  double cost = 0, merit = 0, violation = 0, mu = 0;
  double time = 0, derivatives_time = 0;   // totals (s)
  long derivative_knots = 0;          // knot points differentiated (N per iteration)
};

// Warm start: U_init (N x nv; empty: u_ref at every knot); with X_init (N+1 x NX)
// and K_init (N gains nv x 2nv) the first rollout is u_k = U_k + K_k (x̂_k ⊖ X_k),
// else open loop. Throws std::invalid_argument naming a bad argument (shapes,
// horizon, dt, a start outside the limits).
SolverResult solve_trajectory(
    const Model& model, PlantSteps& steps, Handle& costs, const TrajectoryProblem& problem,
    const SolverOptions& options = {},
    const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& U_init = {},
    const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& X_init = {},
    const std::vector<Eigen::MatrixXd>& K_init = {});
// the same with the handle's own steps (HandleSteps)
SolverResult solve_trajectory(
    Handle& h, const TrajectoryProblem& problem, const SolverOptions& options = {},
    const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& U_init = {},
    const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& X_init = {},
    const std::vector<Eigen::MatrixXd>& K_init = {});

// the longest distance the tool point of `body` can be from the root joint's
// origin (sum of the joint-to-joint distances along the chain plus the offset;
// fixed bases): a target farther than this is out of reach
double reach_radius(const Model& model, int body, const Eigen::Vector3d& offset);

}  // namespace rbd
