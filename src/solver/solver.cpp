// Trajectory optimisation: iLQR / DDP over the plant layer (solver.hpp).
#include "rbdkit/solver/solver.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "rbdkit/batch/integrators_api.hpp"
#include "rbdkit/batch/kinematics_api.hpp"
#include "rbdkit/model/configuration.hpp"

namespace rbd {

using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using Eigen::MatrixXd;
using Eigen::VectorXd;

// ---------------------------------------------------------------- the handle's steps

HandleSteps::HandleSteps(Handle& h, double dt, const std::string& integrator, double gravity)
    : h_(h), dt_(dt), gravity_(gravity), type_(integrator_from_name(integrator)) {}

void HandleSteps::step(long B, const double* x, const double* u, double* x_next) {
  h_.plant_step(B, x, u, nullptr, dt_, gravity_, type_, x_next);
}

void HandleSteps::step_gradient(long B, const double* x, const double* u, double* AB) {
  h_.plant_step_gradient(B, x, u, nullptr, dt_, gravity_, type_, AB);
}

void HandleSteps::step_hessian(long B, const double* x, const double* u, double* H) {
  h_.plant_step_hessian(B, x, u, dt_, gravity_, type_, nullptr, nullptr, H);
}

// ---------------------------------------------------------------- reach

double reach_radius(const Model& m, int body, const Eigen::Vector3d& offset) {
  double r = offset.norm();
  for (int b = body; b >= 0; b = m.bodies[b].parent) {
    const BodyDesc<double>& d = m.bodies[b];
    if (d.type == kFree) return std::numeric_limits<double>::infinity();
    // the joint origin's distance from the parent's joint origin (the root's is the reference point)
    if (d.parent >= 0) r += std::sqrt(d.X_tree.p.x * d.X_tree.p.x + d.X_tree.p.y * d.X_tree.p.y +
                                      d.X_tree.p.z * d.X_tree.p.z);
    // a sliding joint adds its largest travel
    if (d.type == kPrismatic || d.type == kHelical) {
      const JointInfo& j = m.joints[b];
      const double t = std::max(std::abs(m.lower[j.q_idx]), std::abs(m.upper[j.q_idx]));
      r += d.type == kPrismatic ? t : std::abs(d.pitch) * t;
    }
  }
  return r;
}

namespace {

std::string shape(long r, long c) { return std::to_string(r) + " x " + std::to_string(c); }

void expect_size(const VectorXd& v, long n, const char* name) {
  if (v.size() != n)
    throw std::invalid_argument(std::string(name) + ": expected " + std::to_string(n) + " values, got " +
                                std::to_string(v.size()));
  if (!v.allFinite()) throw std::invalid_argument(std::string(name) + ": expected finite values");
}

void expect_weights(const VectorXd& v, const char* name) {
  if ((v.array() < 0).any()) throw std::invalid_argument(std::string(name) + ": expected non-negative weights");
}

// the problem with every default filled in and its arrays tiled per knot
struct Setup {
  int N, nq, nv, nx, ndx;
  VectorXd x_ref, Q, Q_N, u_ref, R;
  VectorXd q_lo, q_hi, v_lo, v_hi, u_lo, u_hi;   // bounds (±inf: none)
  std::vector<int> q_to_v;                        // per q coordinate: its v coordinate (1-dof) or −1
  bool any_q = false, any_v = false, any_u = false;
  // per-knot tiles: state knots 0..N (N+1 rows), input knots 0..N−1
  RowMat Xref, Qk, Uref, Rk, Pee, Wee, Pcom, Wcom, Qlo, Qhi, Vlo, Vhi, Ulo, Uhi;
  int ee_body = -1;
};

Setup make_setup(const Model& m, Handle& h, const TrajectoryProblem& p) {
  Setup s;
  if (p.horizon < 1)
    throw std::invalid_argument("horizon: expected a positive number of knot points, got " +
                                std::to_string(p.horizon));
  check_time_step(p.dt);
  integrator_from_name(p.integrator);
  s.N = p.horizon;
  s.nq = m.nq, s.nv = m.nv, s.nx = m.nq + m.nv, s.ndx = 2 * m.nv;
  const int N = s.N, nv = s.nv, nq = s.nq;
  expect_size(p.x0, s.nx, "x0");
  check_configurations(m, 1, p.x0.data(), "x0");
  s.x_ref = p.x_ref.size() ? p.x_ref : p.x0;
  expect_size(s.x_ref, s.nx, "x_ref");
  check_configurations(m, 1, s.x_ref.data(), "x_ref");
  s.Q = p.Q.size() ? p.Q : VectorXd::Zero(s.ndx);
  s.Q_N = p.Q_terminal.size() ? p.Q_terminal : VectorXd::Zero(s.ndx);
  expect_size(s.Q, s.ndx, "Q");
  expect_size(s.Q_N, s.ndx, "Q_terminal");
  expect_weights(s.Q, "Q");
  expect_weights(s.Q_N, "Q_terminal");
  if (p.u_ref.size()) {
    s.u_ref = p.u_ref;
  } else {
    // gravity compensation at x0
    s.u_ref.resize(nv);
    VectorXd zero = VectorXd::Zero(nv);
    batch::inverse_dynamics(m, 1, p.x0.data(), zero.data(), zero.data(), nullptr, p.gravity, s.u_ref.data(), nullptr,
                            nullptr, nullptr);
  }
  expect_size(s.u_ref, nv, "u_ref");
  s.R = p.R.size() ? p.R : VectorXd::Zero(nv);
  expect_size(s.R, nv, "R");
  expect_weights(s.R, "R");
  for (const auto* w : {&p.W_ee, &p.W_ee_terminal, &p.W_com, &p.W_com_terminal})
    if (!w->allFinite() || (w->array() < 0).any())
      throw std::invalid_argument("W_ee, W_com: expected finite non-negative weights");
  if (!p.ee_target.allFinite() || !p.ee_offset.allFinite() || !p.com_target.allFinite())
    throw std::invalid_argument("ee_target, ee_offset, com_target: expected finite values");

  // limits: the model's unless given
  const double inf = std::numeric_limits<double>::infinity();
  s.q_lo = VectorXd::Constant(nq, -inf), s.q_hi = VectorXd::Constant(nq, inf);
  s.v_lo = VectorXd::Constant(nv, -inf), s.v_hi = VectorXd::Constant(nv, inf);
  s.u_lo = s.v_lo, s.u_hi = s.v_hi;
  if (p.position_limits) {
    s.q_lo = p.q_lower.size() ? p.q_lower : Eigen::Map<const VectorXd>(m.lower.data(), nq);
    s.q_hi = p.q_upper.size() ? p.q_upper : Eigen::Map<const VectorXd>(m.upper.data(), nq);
    if (s.q_lo.size() != nq || s.q_hi.size() != nq)
      throw std::invalid_argument("q_lower, q_upper: expected " + std::to_string(nq) + " values each");
  }
  if (p.velocity_limits) {
    s.v_hi = p.v_limit.size() ? p.v_limit : Eigen::Map<const VectorXd>(m.velocity_limit.data(), nv);
    if (s.v_hi.size() != nv) throw std::invalid_argument("v_limit: expected " + std::to_string(nv) + " values");
    s.v_lo = -s.v_hi;
  }
  if (p.torque_limits) {
    s.u_hi = p.u_limit.size() ? p.u_limit : Eigen::Map<const VectorXd>(m.effort_limit.data(), nv);
    if (s.u_hi.size() != nv) throw std::invalid_argument("u_limit: expected " + std::to_string(nv) + " values");
    s.u_lo = -s.u_hi;
  }
  for (const auto& [v, name] : {std::pair<const VectorXd*, const char*>{&s.v_hi, "v_limit"}, {&s.u_hi, "u_limit"}})
    if ((v->array().isNaN()).any() || (v->array() <= 0).any())
      throw std::invalid_argument(std::string(name) + ": expected positive limits (inf: none)");
  if ((s.q_lo.array().isNaN()).any() || (s.q_hi.array().isNaN()).any() || !(s.q_lo.array() < s.q_hi.array()).all())
    throw std::invalid_argument("q_lower, q_upper: expected lower < upper (±inf: none)");
  // position bounds act on 1-dof coordinates, where q and the tangent coincide
  s.q_to_v.assign(nq, -1);
  for (const JointInfo& j : m.joints)
    if (j.nq == 1 && j.nv == 1) s.q_to_v[j.q_idx] = j.v_idx;
  for (int i = 0; i < nq; ++i)
    if (s.q_to_v[i] < 0 && (std::isfinite(s.q_lo[i]) || std::isfinite(s.q_hi[i])))
      throw std::invalid_argument("q_lower, q_upper: coordinate " + std::to_string(i) +
                                  " belongs to a multi-dof joint; expected no bound (±inf) there");
  s.any_q = s.q_lo.array().isFinite().any() || s.q_hi.array().isFinite().any();
  s.any_v = s.v_hi.array().isFinite().any();
  s.any_u = s.u_hi.array().isFinite().any();

  // end effector: the first leaf body unless given
  if (p.ee) {
    s.ee_body = p.ee_body;
    if (s.ee_body < 0) {
      const std::vector<int> leaves = leaf_bodies(m);
      if (leaves.empty()) throw std::invalid_argument("ee_body: the robot has no end effector");
      s.ee_body = leaves.front();
    }
    if (s.ee_body >= m.nb())
      throw std::invalid_argument("ee_body: expected a body index below " + std::to_string(m.nb()));
    if (!m.floating_base) {
      const double r = reach_radius(m, s.ee_body, p.ee_offset);
      int root = s.ee_body;
      while (m.bodies[root].parent >= 0) root = m.bodies[root].parent;
      const Vec3<double> o = m.bodies[root].X_tree.p;
      const double d = (p.ee_target - Eigen::Vector3d(o.x, o.y, o.z)).norm();
      if (d > r) {
        std::ostringstream os;
        os << "ee_target: out of reach: it is " << d << " m from the arm's base joint, the arm reaches at most "
           << r << " m";
        throw std::invalid_argument(os.str());
      }
    }
  }
  if (p.com && !h.has("com_cost")) throw std::invalid_argument("com: the handle was not built with 'com_cost'");

  // per-knot tiles (running weights scaled by dt, terminal ones at knot N)
  auto tile = [](const VectorXd& v, long rows) {
    RowMat t(rows, v.size());
    for (long r = 0; r < rows; ++r) t.row(r) = v.transpose();
    return t;
  };
  s.Xref = tile(s.x_ref, N + 1);
  s.Qk = tile(s.Q * p.dt, N + 1);
  s.Qk.row(N) = s.Q_N.transpose();
  s.Uref = tile(s.u_ref, N);
  s.Rk = tile(s.R * p.dt, N);
  s.Pee = tile(p.ee_target, N + 1);
  s.Wee = tile(p.W_ee * p.dt, N + 1);
  s.Wee.row(N) = p.W_ee_terminal.transpose();
  s.Pcom = tile(p.com_target, N + 1);
  s.Wcom = tile(p.W_com * p.dt, N + 1);
  s.Wcom.row(N) = p.W_com_terminal.transpose();
  s.Qlo = tile(s.q_lo, N), s.Qhi = tile(s.q_hi, N);
  s.Vlo = tile(s.v_lo, N), s.Vhi = tile(s.v_hi, N);
  s.Ulo = tile(s.u_lo, N), s.Uhi = tile(s.u_hi, N);
  return s;
}

// cost value and (optionally) derivatives of a whole trajectory, batched over the knots
struct CostEval {
  double cost = 0;         // without barriers
  double barrier = 0;      // Σ −log (unscaled; +inf outside)
  double violation = 0;    // max limit violation
  RowMat lx, lu;           // (N+1 x 2nv), (N x nv): cost gradients
  std::vector<MatrixXd> lxx;  // (N+1) 2nv x 2nv
  RowMat luu_diag;         // (N x nv): the input Hessian is diagonal
  RowMat bx, bu;           // barrier gradients (unscaled), same shapes as lx, lu
  RowMat bxx, buu;         // barrier Hessian diagonals
};

class Evaluator {
 public:
  Evaluator(Handle& h, const TrajectoryProblem& p, const Setup& s) : h_(h), p_(p), s_(s) {}

  void eval(const RowMat& X, const RowMat& U, bool derivatives, CostEval& c) {
    const int N = s_.N, nq = s_.nq, nv = s_.nv, nx = s_.nx, ndx = s_.ndx;
    const long S = N + 1;
    c.cost = 0, c.barrier = 0, c.violation = 0;
    if (derivatives) {
      c.lx.setZero(S, ndx), c.lu.setZero(N, nv), c.luu_diag.setZero(N, nv);
      c.lxx.assign(S, MatrixXd::Zero(ndx, ndx));
      c.bx.setZero(S, ndx), c.bu.setZero(N, nv), c.bxx.setZero(S, ndx), c.buu.setZero(N, nv);
    }
    val_.resize(S), g_.resize(S * std::max(nx, ndx)), H_.resize(S * std::max(nx, ndx) * std::max(nx, ndx));
    // state regularisation (tangent)
    h_.quadratic_state_cost_tangent(S, X.data(), s_.Xref.data(), s_.Qk.data(), val_.data(), g_.data(), H_.data());
    for (long k = 0; k < S; ++k) {
      c.cost += val_[k];
      if (!derivatives) continue;
      c.lx.row(k) += Eigen::Map<const VectorXd>(g_.data() + k * ndx, ndx).transpose();
      c.lxx[k] += Eigen::Map<const RowMat>(H_.data() + k * ndx * ndx, ndx, ndx);
    }
    // input regularisation
    h_.quadratic_input_cost(N, U.data(), s_.Uref.data(), s_.Rk.data(), val_.data(), g_.data(), H_.data());
    for (long k = 0; k < N; ++k) {
      c.cost += val_[k];
      if (!derivatives) continue;
      c.lu.row(k) += Eigen::Map<const VectorXd>(g_.data() + k * nv, nv).transpose();
      for (int i = 0; i < nv; ++i) c.luu_diag(k, i) += H_[k * nv * nv + i * nv + i];
    }
    // position costs: tangent blocks embedded in the NX layout ([0, nv): δq)
    Qs_.resize(S, nq);
    for (long k = 0; k < S; ++k) Qs_.row(k) = X.row(k).head(nq);
    auto add_position = [&](auto&& call) {
      call();
      for (long k = 0; k < S; ++k) {
        c.cost += val_[k];
        if (!derivatives) continue;
        c.lx.row(k).head(nv) += Eigen::Map<const VectorXd>(g_.data() + k * nx, nv).transpose();
        c.lxx[k].topLeftCorner(nv, nv) += Eigen::Map<const RowMat, 0, Eigen::OuterStride<>>(
            H_.data() + k * nx * nx, nv, nv, Eigen::OuterStride<>(nx));
      }
    };
    const Eigen::Vector3d off = p_.ee_offset;
    if (p_.ee)
      add_position([&] {
        h_.ee_pos_cost(S, Qs_.data(), s_.Pee.data(), s_.Wee.data(), val_.data(), g_.data(), H_.data(), s_.ee_body,
                       off.data());
      });
    if (p_.com)
      add_position([&] { h_.com_cost(S, Qs_.data(), s_.Pcom.data(), s_.Wcom.data(), val_.data(), g_.data(), H_.data()); });
    // barriers on q_1..q_N, qd_1..qd_N, u_0..u_{N−1} (μ = 1 here; the caller scales)
    const long Bn = N;
    if (s_.any_q) {
      Qb_ = Qs_.bottomRows(N);
      h_.joint_position_barrier(Bn, Qb_.data(), s_.Qlo.data(), s_.Qhi.data(), 1.0, val_.data(), g_.data(),
                                H_.data());
      for (long k = 0; k < Bn; ++k) {
        c.barrier += val_[k];
        for (int i = 0; i < nq; ++i) {
          const double qi = Qb_(k, i);
          c.violation = std::max({c.violation, s_.q_lo[i] - qi, qi - s_.q_hi[i]});
          const int j = s_.q_to_v[i];
          if (!derivatives || j < 0 || !std::isfinite(g_[k * nq + i])) continue;
          c.bx(k + 1, j) += g_[k * nq + i];
          c.bxx(k + 1, j) += H_[k * nq + i];
        }
      }
    }
    if (s_.any_v) {
      Vb_ = X.bottomRows(N).rightCols(nv);
      h_.joint_velocity_barrier(Bn, Vb_.data(), s_.Vlo.data(), s_.Vhi.data(), 1.0, val_.data(), g_.data(),
                                H_.data());
      for (long k = 0; k < Bn; ++k) {
        c.barrier += val_[k];
        for (int i = 0; i < nv; ++i) {
          c.violation = std::max({c.violation, s_.v_lo[i] - Vb_(k, i), Vb_(k, i) - s_.v_hi[i]});
          if (!derivatives || !std::isfinite(g_[k * nv + i])) continue;
          c.bx(k + 1, nv + i) += g_[k * nv + i];
          c.bxx(k + 1, nv + i) += H_[k * nv + i];
        }
      }
    }
    if (s_.any_u) {
      h_.joint_torque_barrier(Bn, U.data(), s_.Ulo.data(), s_.Uhi.data(), 1.0, val_.data(), g_.data(), H_.data());
      for (long k = 0; k < Bn; ++k) {
        c.barrier += val_[k];
        for (int i = 0; i < nv; ++i) {
          c.violation = std::max({c.violation, s_.u_lo[i] - U(k, i), U(k, i) - s_.u_hi[i]});
          if (!derivatives || !std::isfinite(g_[k * nv + i])) continue;
          c.bu(k, i) += g_[k * nv + i];
          c.buu(k, i) += H_[k * nv + i];
        }
      }
    }
    if (std::isnan(c.barrier)) c.barrier = std::numeric_limits<double>::infinity();
  }

 private:
  Handle& h_;
  const TrajectoryProblem& p_;
  const Setup& s_;
  std::vector<double> val_, g_, H_;
  RowMat Qs_, Qb_, Vb_;
};

// δx = x ⊖ x̄ = [difference(q̄, q); qd − q̄d] (2nv)
void state_difference(const ModelView<double>& mv, const double* xbar, const double* x, double* dx) {
  difference(mv, xbar, x, dx);
  for (int i = 0; i < mv.nv; ++i) dx[mv.nv + i] = x[mv.nq + i] - xbar[mv.nq + i];
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// ---------------------------------------------------------------- the passes
// solve_trajectory: the checks, the initial rollout, then per iteration the
// step derivatives, the backward pass, the line search (over rollouts), the
// damping update and the barrier schedule.

// the solver options' checks
void check_options(const SolverOptions& o) {
  if (o.max_iterations < 0) throw std::invalid_argument("max_iterations: expected a non-negative integer");
  if (!(o.mu_init >= 0 && o.mu_min >= 0 && o.mu_min <= o.mu_init && o.mu_factor > 0 && o.mu_factor < 1))
    throw std::invalid_argument("mu_init, mu_min, mu_factor: expected 0 <= mu_min <= mu_init and 0 < mu_factor < 1");
  if (!(o.reg_min > 0 && o.reg_init >= o.reg_min && o.reg_max > o.reg_init && o.reg_factor > 1))
    throw std::invalid_argument("reg_init, reg_min, reg_max, reg_factor: expected 0 < reg_min <= reg_init < "
                                "reg_max and reg_factor > 1");
}

// the warm start's checks: U (U_init, or u_ref at every knot), X_init (empty:
// open loop), K_init (empty: no feedback)
void check_warm_start(const Model& model, const Setup& s, const RowMat& U, const RowMat& X_init,
                      const std::vector<MatrixXd>& K_init) {
  const int N = s.N, nv = s.nv, nx = s.nx, ndx = s.ndx;
  if (U.rows() != N || U.cols() != nv)
    throw std::invalid_argument("U_init: expected " + shape(N, nv) + " (horizon x nv), got " +
                                shape(U.rows(), U.cols()));
  if (!U.allFinite()) throw std::invalid_argument("U_init: expected finite values");
  const bool closed_loop = X_init.size() > 0;
  if (closed_loop) {
    if (X_init.rows() != N + 1 || X_init.cols() != nx)
      throw std::invalid_argument("X_init: expected " + shape(N + 1, nx) + " (horizon + 1 x NX), got " +
                                  shape(X_init.rows(), X_init.cols()));
    check_configurations(model, N + 1, RowMat(X_init.leftCols(model.nq)).data(), "X_init");
    if (!X_init.allFinite()) throw std::invalid_argument("X_init: expected finite values");
  }
  if (!K_init.empty()) {
    if (!closed_loop) throw std::invalid_argument("K_init: needs X_init (the trajectory the gains act around)");
    if (static_cast<int>(K_init.size()) != N)
      throw std::invalid_argument("K_init: expected " + std::to_string(N) + " gains, got " +
                                  std::to_string(K_init.size()));
    for (const MatrixXd& K : K_init)
      if (K.rows() != nv || K.cols() != ndx || !K.allFinite())
        throw std::invalid_argument("K_init: expected finite gains of " + shape(nv, ndx) + " (nv x 2nv)");
  }
}

// the policy a backward pass leaves: u_k = Ū_k + α k_k + K_k (x_k ⊖ X̄_k)
struct Policy {
  std::vector<MatrixXd> K;  // (N) feedback gains (nv x 2nv)
  RowMat k;                 // (N x nv) feedforward
};

// what a rollout runs on besides the policy
struct Plant {
  const Model& model;
  ModelView<double> mv;
  PlantSteps& steps;
  const VectorXd& x0;  // (NX) the initial state
  VectorXd dx;         // (2nv) scratch: x ⊖ X̄
};

// ---- rollout: Xo (N+1 x NX), Uo (N x nv) from x0 under the policy around
// (Xbar, Ubar) with step α, with its feedback or without (Xbar then unused);
// false if a state diverges (non-finite or beyond the input bounds)
bool rollout(Plant& pl, const Policy& pol, const RowMat& Xbar, const RowMat& Ubar, double alpha, bool feedback,
             RowMat& Xo, RowMat& Uo) {
  const Model& model = pl.model;
  const int N = static_cast<int>(pol.k.rows()), nv = model.nv;
  Xo.row(0) = pl.x0.transpose();
  for (int k = 0; k < N; ++k) {
    Uo.row(k) = Ubar.row(k) + alpha * pol.k.row(k);
    if (feedback) {
      state_difference(pl.mv, Xbar.row(k).data(), Xo.row(k).data(), pl.dx.data());
      Uo.row(k) += (pol.K[k] * pl.dx).transpose();
    }
    try {
      pl.steps.step(1, Xo.row(k).data(), Uo.row(k).data(), Xo.row(k + 1).data());
      // a state beyond the input bounds (dynamics.hpp) has diverged as surely as a non-finite one
      check_configuration(model, Xo.row(k + 1).data(), "x");
      check_finite(Xo.row(k + 1).data() + model.nq, nv, "x");
    } catch (const std::runtime_error&) {
      return false;  // a diverging trial (e.g. a mass matrix lost to round-off): rejected
    } catch (const std::invalid_argument&) {
      return false;
    }
  }
  return true;
}

// ---- step derivatives at the knots 0..N−1, one batched call per family:
// AB (N x 2nv x 3nv) and, for DDP, Hs (N x 2nv x 3nv x 3nv); Xk (N x NX) scratch
void step_derivatives(PlantSteps& steps, const RowMat& X, const RowMat& U, bool ddp, RowMat& Xk,
                      std::vector<double>& AB, std::vector<double>& Hs) {
  const long N = U.rows();
  Xk = X.topRows(N);
  steps.step_gradient(N, Xk.data(), U.data(), AB.data());
  if (ddp) steps.step_hessian(N, Xk.data(), U.data(), Hs.data());
}

// the Levenberg–Marquardt damping λ on Quu and its multiplicative step
struct Damping {
  double reg, step;
  // λ grows: a backward pass met a non-PD Quu + λI, or a line search failed
  void grow(const SolverOptions& o) {
    step = std::max(step * o.reg_factor, o.reg_factor);
    reg = std::max(reg * step, o.reg_min);
  }
  // λ shrinks on an accepted step
  void shrink(const SolverOptions& o) {
    step = std::min(step / o.reg_factor, 1.0 / o.reg_factor);
    reg = std::max(reg * step, o.reg_min);
  }
  // λ restarts (a new μ)
  void restart(const SolverOptions& o) { reg = std::max(o.reg_init, o.reg_min), step = 1; }
};

// the backward pass's buffers, allocated once per solve
struct Riccati {
  MatrixXd Qxx, Quu, Qux, Vxx;  // (2nv x 2nv), (nv x nv), (nv x 2nv), (2nv x 2nv)
  VectorXd Qx, Qu, Vx;          // (2nv), (nv), (2nv)
};

// what a backward pass predicts: the merit's model decrease along α is
// −(α d1 + ½ α² d2); gnorm = max_k ‖Qu_k‖∞; pd false when λ passed reg_max
struct BackwardPass {
  bool pd;
  double d1, d2, gnorm;
};

// ---- backward pass: the Riccati recursion in the tangent space from the cost
// derivatives c (barriers weighted by μ) and the step derivatives AB, Hs
// (step_derivatives), with λ on Quu, raised (d.grow) and the pass restarted
// until Quu + λI is positive definite at every knot. Writes the policy.
BackwardPass backward_pass(const Setup& s, const CostEval& c, const std::vector<double>& AB,
                           const std::vector<double>& Hs, double mu, const SolverOptions& o, Damping& d, Riccati& w,
                           Policy& pol) {
  const int N = s.N, nv = s.nv, ndx = s.ndx, nz = 3 * nv;
  MatrixXd &Qxx = w.Qxx, &Quu = w.Quu, &Qux = w.Qux, &Vxx = w.Vxx;
  VectorXd &Qx = w.Qx, &Qu = w.Qu, &Vx = w.Vx;
  std::vector<MatrixXd>& K = pol.K;
  RowMat& kff = pol.k;
  double d1 = 0, d2 = 0, gnorm = 0;
  bool pd = false;
  while (!pd) {
    Vx = c.lx.row(N).transpose() + mu * c.bx.row(N).transpose();
    Vxx = c.lxx[N];
    Vxx.diagonal() += mu * c.bxx.row(N).transpose();
    d1 = d2 = gnorm = 0;
    pd = true;
    for (int k = N - 1; k >= 0; --k) {
      const Eigen::Map<const RowMat> ABk(AB.data() + static_cast<size_t>(k) * ndx * nz, ndx, nz);
      const auto A = ABk.leftCols(ndx);
      const auto Bm = ABk.rightCols(nv);
      Qx = c.lx.row(k).transpose() + mu * c.bx.row(k).transpose() + A.transpose() * Vx;
      Qu = c.lu.row(k).transpose() + mu * c.bu.row(k).transpose() + Bm.transpose() * Vx;
      const MatrixXd VA = Vxx * A, VB = Vxx * Bm;
      Qxx = c.lxx[k] + A.transpose() * VA;
      Qxx.diagonal() += mu * c.bxx.row(k).transpose();
      Quu = Bm.transpose() * VB;
      Quu.diagonal() += c.luu_diag.row(k).transpose() + mu * c.buu.row(k).transpose();
      Qux = Bm.transpose() * VA;
      MatrixXd Qreg = Quu;
      Qreg.diagonal().array() += d.reg;
      if (o.ddp) {
        // + Σ_i V'_x,i H_i: the step's curvature weighted by the cost-to-go gradient; at a
        // knot where it makes Quu + λI indefinite, that knot keeps the Gauss–Newton terms
        const double* Hk = Hs.data() + static_cast<size_t>(k) * ndx * nz * nz;
        MatrixXd Hz = MatrixXd::Zero(nz, nz);
        for (int i = 0; i < ndx; ++i) Hz += Vx[i] * Eigen::Map<const RowMat>(Hk + static_cast<size_t>(i) * nz * nz, nz, nz);
        // the whole [Qxx Qxu; Qux Quu] block (+ λI) must stay positive definite
        MatrixXd Qzz(nz, nz);
        Qzz << Qxx, Qux.transpose(), Qux, Quu;
        Qzz += Hz;
        Qzz.diagonal().array() += d.reg;
        const MatrixXd Qfull = Qreg + Hz.bottomRightCorner(nv, nv);
        if (Eigen::LLT<MatrixXd>(Qzz).info() == Eigen::Success) {
          Qxx += Hz.topLeftCorner(ndx, ndx);
          Quu += Hz.bottomRightCorner(nv, nv);
          Qux += Hz.bottomLeftCorner(nv, ndx);
          Qreg = Qfull;
        }
      }
      Eigen::LLT<MatrixXd> llt(Qreg);
      if (llt.info() != Eigen::Success) {
        pd = false;
        break;
      }
      kff.row(k) = -llt.solve(Qu).transpose();
      K[k] = -llt.solve(Qux);
      const VectorXd kk = kff.row(k).transpose();
      gnorm = std::max(gnorm, Qu.cwiseAbs().maxCoeff());
      d1 += kk.dot(Qu);
      d2 += kk.dot(Quu * kk);
      // V = Q minimised over δu
      Vx = Qx + K[k].transpose() * (Quu * kk) + K[k].transpose() * Qu + Qux.transpose() * kk;
      Vxx = Qxx + K[k].transpose() * Quu * K[k] + K[k].transpose() * Qux + Qux.transpose() * K[k];
      Vxx = 0.5 * (Vxx + Vxx.transpose()).eval();
    }
    if (!pd) {
      d.grow(o);
      if (d.reg > o.reg_max) break;
    }
  }
  return {pd, d1, d2, gnorm};
}

// an accepted line-search trial: its α (0: none accepted) and merit
struct Trial {
  double alpha, merit;
};

// ---- line search: backtracking α = 1, ½, ¼, … (line_search_steps trials) on
// the actual merit of a rollout under the policy around (X, U); a trial is
// accepted when its decrease is at least 1e-4 of the model's (bp), and left in
// (Xn, Un) with its predicted and actual decrease in rec
Trial line_search(Plant& pl, Evaluator& ev, const Policy& pol, const RowMat& X, const RowMat& U, double merit,
                  double mu, const BackwardPass& bp, const SolverOptions& o, RowMat& Xn, RowMat& Un, CostEval& cn,
                  IterationRecord& rec) {
  const double d1 = bp.d1, d2 = bp.d2;
  double alpha = 1, accepted = 0, merit_new = merit;
  for (int ls = 0; ls < o.line_search_steps; ++ls, alpha *= 0.5) {
    const double expected = -(alpha * d1 + 0.5 * alpha * alpha * d2);
    if (!rollout(pl, pol, X, U, alpha, true, Xn, Un)) continue;
    ev.eval(Xn, Un, false, cn);
    const double m_new = cn.cost + mu * cn.barrier;
    if (!std::isfinite(m_new)) continue;
    const double actual = merit - m_new;
    if (actual > 1e-4 * expected || (expected <= 0 && actual >= 0)) {
      accepted = alpha, merit_new = m_new, rec.expected = expected, rec.actual = actual;
      break;
    }
  }
  return {accepted, merit_new};
}

// the first μ; no limits: no barrier term, so no μ schedule to run through
double initial_mu(const TrajectoryProblem& p, const SolverOptions& o) {
  return p.position_limits || p.velocity_limits || p.torque_limits ? o.mu_init : o.mu_min;
}

// ---- barrier schedule: when the iterations at this μ stall, μ shrinks by
// mu_factor down to mu_min, the merit re-weighted (c: the current costs) and λ
// restarted; true when they stall at mu_min (converged)
bool barrier_schedule(bool stalled, const SolverOptions& o, const CostEval& c, double& mu, double& merit,
                      Damping& d) {
  if (!stalled) return false;
  if (mu <= o.mu_min) return true;
  mu = std::max(mu * o.mu_factor, o.mu_min);
  merit = c.cost + mu * c.barrier;
  d.restart(o);
  return false;
}

// log one iteration and report it to the callback
void record(SolverResult& r, const SolverOptions& o, const IterationRecord& rec) {
  r.log.push_back(rec);
  if (o.callback) o.callback(rec);
}

}  // namespace

SolverResult solve_trajectory(const Model& model, PlantSteps& steps, Handle& h, const TrajectoryProblem& p,
                              const SolverOptions& o, const RowMat& U_init, const RowMat& X_init,
                              const std::vector<MatrixXd>& K_init) {
  using clock = std::chrono::steady_clock;
  const auto t_start = clock::now();
  // ---- checks and defaults
  check_options(o);
  const Setup s = make_setup(model, h, p);
  const int N = s.N, nv = s.nv, nx = s.nx, ndx = s.ndx, nz = 3 * nv;
  RowMat U = U_init.size() ? U_init : RowMat(s.Uref);
  check_warm_start(model, s, U, X_init, K_init);
  const bool closed_loop = X_init.size() > 0;

  SolverResult r;
  Evaluator ev(h, p, s);
  Plant pl{model, model.view(), steps, p.x0, VectorXd(ndx)};
  RowMat X(N + 1, nx), Xn(N + 1, nx), Un(N, nv);
  Policy pol{std::vector<MatrixXd>(N, MatrixXd::Zero(nv, ndx)), RowMat::Zero(N, nv)};

  // ---- initial rollout (warm start)
  if (closed_loop && !K_init.empty()) pol.K = K_init;
  {
    RowMat Uo(N, nv);
    const bool ok = rollout(pl, pol, closed_loop ? X_init : RowMat(), U, 0.0, closed_loop && !K_init.empty(), X, Uo);
    if (!ok) throw std::invalid_argument("U_init: the initial rollout diverges (non-finite or out-of-bounds states)");
    U = Uo;
  }
  for (auto& Kk : pol.K) Kk.setZero();
  CostEval c, cn;
  double mu = initial_mu(p, o);
  ev.eval(X, U, true, c);
  if (!std::isfinite(c.barrier)) {
    std::ostringstream os;
    os << (U_init.size() ? "U_init" : "x0") << ": the initial trajectory leaves the joint limits (max violation "
       << c.violation << "); the barrier method needs a start strictly inside them";
    throw std::invalid_argument(os.str());
  }
  double merit = c.cost + mu * c.barrier;
  {
    IterationRecord rec;
    rec.cost = c.cost, rec.merit = merit, rec.violation = c.violation, rec.mu = mu, rec.reg = o.reg_init;
    rec.time = seconds_since(t_start);
    record(r, o, rec);
  }

  // ---- buffers of the batched derivatives and the backward pass
  std::vector<double> AB(static_cast<size_t>(N) * ndx * nz), Hs;
  if (o.ddp) Hs.resize(static_cast<size_t>(N) * ndx * nz * nz);
  RowMat Xk(N, nx);
  Damping damping{o.reg_init, 1};
  bool have_derivatives = false;
  Riccati w{MatrixXd(ndx, ndx), MatrixXd(nv, nv), MatrixXd(nv, ndx), MatrixXd(ndx, ndx),
            VectorXd(ndx),      VectorXd(nv),      VectorXd(ndx)};
  r.status = "max_iterations";

  for (int it = 1; it <= o.max_iterations; ++it) {
    const auto t_it = clock::now();
    IterationRecord rec;
    rec.iteration = it;
    // ---- derivatives of the whole trajectory (once per accepted trajectory)
    if (!have_derivatives) {
      const auto t_d = clock::now();
      step_derivatives(steps, X, U, o.ddp, Xk, AB, Hs);
      rec.derivatives_time = seconds_since(t_d);
      r.derivative_knots += N;
      have_derivatives = true;
    }

    // ---- backward pass
    const BackwardPass bp = backward_pass(s, c, AB, Hs, mu, o, damping, w, pol);
    rec.reg = damping.reg, rec.mu = mu, rec.grad_norm = bp.gnorm;
    if (!bp.pd) {
      r.status = "stalled";
      rec.cost = c.cost, rec.merit = merit, rec.violation = c.violation, rec.time = seconds_since(t_it);
      record(r, o, rec);
      break;
    }

    // ---- forward pass: line search
    const Trial t = line_search(pl, ev, pol, X, U, merit, mu, bp, o, Xn, Un, cn, rec);

    // ---- the step taken (λ shrinks) or refused (λ grows); stalled: no progress at this μ
    bool stalled_now;
    if (t.alpha > 0) {
      const double decrease = merit - t.merit;
      X.swap(Xn), U.swap(Un);
      ev.eval(X, U, true, c);
      have_derivatives = false;
      merit = t.merit;
      damping.shrink(o);
      stalled_now = decrease <= o.tol_cost * std::max(1.0, std::abs(merit)) || bp.gnorm < o.tol_grad;
    } else {
      damping.grow(o);
      stalled_now =
          bp.gnorm < o.tol_grad || -(bp.d1 + 0.5 * bp.d2) <= o.tol_cost * std::max(1.0, std::abs(merit));
    }
    rec.step = t.alpha, rec.cost = c.cost, rec.merit = merit, rec.violation = c.violation;

    // ---- barrier schedule
    const bool done = barrier_schedule(stalled_now, o, c, mu, merit, damping);
    rec.time = seconds_since(t_it);
    record(r, o, rec);
    r.iterations = it;
    if (done) {
      r.status = "converged";
      break;
    }
    if (damping.reg > o.reg_max) {
      r.status = "stalled";
      break;
    }
  }

  // ---- result
  r.converged = r.status == "converged";
  r.X = X, r.U = U, r.K = pol.K, r.k = pol.k;
  r.cost = c.cost, r.violation = c.violation, r.mu = mu, r.merit = c.cost + mu * c.barrier;
  for (const IterationRecord& rec : r.log) r.derivatives_time += rec.derivatives_time;
  r.time = seconds_since(t_start);
  return r;
}

SolverResult solve_trajectory(Handle& h, const TrajectoryProblem& p, const SolverOptions& o, const RowMat& U_init,
                              const RowMat& X_init, const std::vector<MatrixXd>& K_init) {
  HandleSteps steps(h, p.dt, p.integrator, p.gravity);
  return solve_trajectory(h.model(), steps, h, p, o, U_init, X_init, K_init);
}

}  // namespace rbd
