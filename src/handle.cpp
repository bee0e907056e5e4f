// Operation handles: the algorithm table, dependency resolution and the
// batched calls, each forwarding to a batch:: entry point.
#include "rbdkit/handle.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "rbdkit/costs_api.hpp"
#include "rbdkit/derivatives_api.hpp"
#include "rbdkit/integrators_api.hpp"
#include "rbdkit/ops/table.hpp"

namespace rbd {

namespace {
// the algorithms: name, operations (rbdkit.RBD method names; the registered
// ones are added from the registry, by their spec's algorithm), dependencies;
// a dependency always comes earlier in the table than the algorithms needing it
std::vector<AlgorithmInfo> algorithm_list() {
  std::vector<AlgorithmInfo> table = {
      {"configuration", {"integrate", "difference", "dIntegrate", "dDifference", "d2Integrate"}, {}},
      {"inverse_dynamics",
       {"inverse_dynamics", "generalized_gravity", "nonlinear_effects", "apply_external_forces",
        "inverse_dynamics_fpass", "inverse_dynamics_bpass"},
       {}},
      {"crba", {"crba"}, {}},
      {"minv", {"minv", "minv_bpass", "minv_fpass"}, {}},
      {"aba", {"aba"}, {}},
      {"forward_dynamics", {"forward_dynamics"}, {"inverse_dynamics", "minv"}},
      {"inverse_dynamics_gradient",
       {"inverse_dynamics_gradient", "inverse_dynamics_gradient_fpass_dq", "inverse_dynamics_gradient_fpass_dqd",
        "inverse_dynamics_gradient_bpass_dq", "inverse_dynamics_gradient_bpass_dqd"},
       {"inverse_dynamics"}},
      {"forward_dynamics_gradient", {"forward_dynamics_gradient"}, {"forward_dynamics", "inverse_dynamics_gradient"}},
      {"kinematics",
       {"forward_kinematics", "frame_placement", "frame_jacobian", "frame_jacobian_dot", "end_effector_pose",
        "end_effector_pose_gradient"},
       {}},
      {"end_effector_pose_hessian", {"end_effector_pose_hessian", "end_effector_pose_hessian_analytic"},
       {"kinematics"}},
      {"osc_inertia", {"osc_inertia"}, {"kinematics", "minv"}},
      {"f_ext_gradient", {"f_ext_gradient"}, {"kinematics", "minv"}},
      {"energy", {"kinetic_energy", "potential_energy", "mechanical_energy"}, {}},
      {"coriolis_matrix", {"coriolis_matrix"}, {}},
      {"com", {"com", "jacobian_com"}, {}},
      {"ccrba", {"ccrba", "centroidal_momentum"}, {"com"}},
      {"dccrba",
       {"dccrba", "dccrba_fd", "cmm_time_variation", "cmm_time_variation_fd", "centroidal_momentum_time_variation"},
       {"ccrba"}},
      {"centroidal_dynamics_derivatives", {"centroidal_dynamics_derivatives"}, {"dccrba", "inverse_dynamics_gradient"}},
      {"regressor", {"inverse_dynamics_regressor", "kinetic_energy_regressor", "potential_energy_regressor"}, {}},
      {"regressor_gradient", {"inverse_dynamics_regressor_gradient"}, {"regressor"}},
      {"forward_dynamics_parameter_gradient", {"forward_dynamics_parameter_gradient"}, {"regressor", "minv"}},
      {"idsva_so", {"idsva_so", "idsva_so_body_frame", "idsva_so_world_frame"}, {"inverse_dynamics_gradient"}},
      {"fdsva_so", {"fdsva_so"}, {"idsva_so", "forward_dynamics_gradient"}},
      {"integrator", {"integrator", "plant_step"}, {"configuration", "forward_dynamics"}},
      {"integrator_gradient", {"integrator_gradient", "plant_step_gradient"},
       {"integrator", "forward_dynamics_gradient"}},
      {"plant_step_hessian", {"plant_step_hessian"}, {"integrator_gradient", "fdsva_so"}},
      {"state_costs", {"quadratic_state_cost", "quadratic_state_cost_tangent", "quadratic_input_cost"},
       {"configuration"}},
      {"ee_pos_cost", {"ee_pos_cost"}, {"kinematics"}},
      {"com_cost", {"com_cost"}, {"com", "ccrba"}},
      {"momentum_cost", {"momentum_cost"}, {"dccrba"}},
      {"barriers", {"joint_position_barrier", "joint_velocity_barrier", "joint_torque_barrier"}, {}},
      // conversions between the output conventions (the same in either convention)
      {"mujoco_convention",
       {"state_to_mujoco", "state_from_mujoco", "force_to_mujoco", "force_from_mujoco", "mujoco_integrate",
        "mujoco_difference"},
       {}},
  };
  for (const ops::OpEntry& e : ops::op_table())
    for (AlgorithmInfo& a : table)
      if (a.name == e.spec->algorithm &&
          std::find(a.operations.begin(), a.operations.end(), e.spec->name) == a.operations.end())
        a.operations.push_back(e.spec->name);
  return table;
}
}  // namespace

const std::vector<AlgorithmInfo>& handle_algorithms() {
  static const std::vector<AlgorithmInfo> table = algorithm_list();
  return table;
}

namespace {

const AlgorithmInfo* find_algorithm(const std::string& name) {
  for (const AlgorithmInfo& a : handle_algorithms())
    if (a.name == name) return &a;
  return nullptr;
}

void add_with_dependencies(const AlgorithmInfo& a, std::vector<bool>& chosen) {
  const auto& t = handle_algorithms();
  const size_t i = static_cast<size_t>(&a - t.data());
  if (chosen[i]) return;
  chosen[i] = true;
  for (const std::string& d : a.dependencies) add_with_dependencies(*find_algorithm(d), chosen);
}

}  // namespace

std::vector<std::string> resolve_algorithms(const std::vector<std::string>& names) {
  const auto& t = handle_algorithms();
  std::vector<bool> chosen(t.size(), names.empty());
  for (const std::string& n : names) {
    const AlgorithmInfo* a = find_algorithm(n);
    if (!a) {
      std::string valid;
      for (const AlgorithmInfo& b : t) valid += (valid.empty() ? "" : ", ") + b.name;
      throw std::invalid_argument("algorithms: unknown algorithm '" + n + "'; expected names from: " + valid);
    }
    add_with_dependencies(*a, chosen);
  }
  std::vector<std::string> out;
  for (size_t i = 0; i < t.size(); ++i)
    if (chosen[i]) out.push_back(t[i].name);
  return out;
}

std::string algorithm_of(const std::string& operation) {
  for (const AlgorithmInfo& a : handle_algorithms())
    if (std::find(a.operations.begin(), a.operations.end(), operation) != a.operations.end()) return a.name;
  return "";
}

Handle::Handle(Model model, const std::vector<std::string>& algorithms, int threads)
    : Handle(std::move(model), algorithms, threads, "float64") {}

Handle::Handle(Model model, const std::vector<std::string>& algorithms, int threads, const std::string& dtype)
    : model_(std::move(model)), algorithms_(resolve_algorithms(algorithms)), threads_(threads), dtype_(dtype) {
  if (threads < 0)
    throw std::invalid_argument("threads: expected 0 (no engine) or a positive thread count, got " +
                                std::to_string(threads));
  if (dtype != "float64" && dtype != "float32")
    throw std::invalid_argument("dtype: expected 'float64' or 'float32', got '" + dtype + "'");
  if (threads > 0 || dtype == "float32") engine_.reset(new Engine(model_, threads > 0 ? threads : 1, dtype));
  for (const std::string& n : algorithms_)
    for (const std::string& op : find_algorithm(n)->operations) operations_.push_back(op);
  op_enabled_.assign(ops::op_table().size(), false);
  for (const ops::OpEntry& e : ops::op_table())
    op_enabled_[e.id] = std::find(operations_.begin(), operations_.end(), e.spec->name) != operations_.end();
}

std::vector<std::string> Handle::available_operations() const { return operations_; }

bool Handle::has(const std::string& operation) const {
  // the typed methods below that are not registered operations
  static const char* methods[] = {"quadratic_state_cost", "quadratic_state_cost_tangent", "quadratic_input_cost",
                                  "ee_pos_cost", "com_cost", "momentum_cost", "joint_position_barrier",
                                  "joint_velocity_barrier", "joint_torque_barrier", "plant_step_hessian"};
  if (std::find(operations_.begin(), operations_.end(), operation) == operations_.end()) return false;
  if (ops::find_op(operation) >= 0) return true;
  return std::find(std::begin(methods), std::end(methods), operation) != std::end(methods);
}

void Handle::run(int op, const ops::OpCall& call) {
  if (op < 0 || op >= static_cast<int>(ops::op_table().size()))
    throw std::invalid_argument("run: unknown operation id " + std::to_string(op));
  const ops::OpEntry& e = ops::op_table()[op];
  if (!has_op(op)) require(e.spec->name);
  if (call.B <= 0)
    throw std::invalid_argument(std::string(e.spec->name) + ": B: expected a positive batch size, got " +
                                std::to_string(call.B));
  if (dtype_ == "float32") ops::check_call<float>(model_, *e.spec, call);
  else ops::check_call<double>(model_, *e.spec, call);
  if (ops::takes_names(*e.spec)) {  // frames and end effectors for the kernels, then the same call
    std::vector<double> f64;
    std::vector<float> f32;
    const ops::OpCall resolved = dtype_ == "float32" ? ops::resolve_names(model_, *e.spec, call, f32)
                                                     : ops::resolve_names(model_, *e.spec, call, f64);
    return dispatch(op, resolved);
  }
  dispatch(op, call);
}

void Handle::dispatch(int op, const ops::OpCall& call) {
  const ops::OpEntry& e = ops::op_table()[op];
  const bool no_bodies = model_.nb() == 0;
  if (no_bodies && !ops::takes_names(*e.spec)) {
    // no joints: no bodies and no mass. Outputs of the model's sizes are empty; the others (an energy, a
    // centre of mass) are a sum over no bodies, 0, or undefined without mass. (A frame on the world has
    // its placement: the serial loop below.)
    if (e.spec->failure == ops::kNoMass) ops::throw_failure(model_, *e.spec, nullptr, -1);
    const size_t bytes = dtype_ == "float32" ? sizeof(float) : sizeof(double);
    for (int o = 0; o < e.spec->n_out; ++o)
      if (call.out[o]) std::memset(call.out[o], 0, bytes * call.B * ops::out_values(e.spec->out[o], model_, call.n_ee));
    return;
  }
  // the engine for float32 and for batches; one float64 sample on the serial
  // loop (a pack of W lanes would compute W - 1 copies of it)
  if (engine_ && !no_bodies && (dtype_ == "float32" || call.B > 1)) return engine_->run_op(op, call);
  std::lock_guard<std::mutex> lk(run_);
  const long n = ops::scratch_values(*e.spec, model_);
  if (static_cast<long>(op_scratch_.size()) < n) op_scratch_.resize(static_cast<size_t>(n));
  Workspace<double>& w = ws_.get(model_, ops::workspace_layout(*e.spec, model_));
  if (dtype_ != "float32") return ops::run_serial(model_, e, call, w, op_scratch_.data());
  // float32 on a model without joints (a frame's placement): the float64 loop, rounded
  const ops::OpSpec& spec = *e.spec;
  ops::OpCall d = call;
  std::vector<std::vector<double>> in(spec.n_args), out(spec.n_out);
  for (int k = 0; k < spec.n_args; ++k)
    if (call.in[k]) {
      const float* x = static_cast<const float*>(call.in[k]);
      in[k].assign(x, x + (call.batched[k] ? call.B : 1) * ops::arg_values(spec.args[k], model_, call.n_ee));
      d.in[k] = in[k].data();
    }
  for (int o = 0; o < spec.n_out; ++o)
    if (call.out[o]) out[o].resize(call.B * ops::out_values(spec.out[o], model_, call.n_ee)), d.out[o] = out[o].data();
  ops::run_serial(model_, e, d, w, op_scratch_.data());
  for (int o = 0; o < spec.n_out; ++o)
    if (call.out[o]) std::copy(out[o].begin(), out[o].end(), static_cast<float*>(call.out[o]));
}

void Handle::require(const char* operation) const {
  if (has(operation)) return;
  const std::string a = algorithm_of(operation);
  throw std::invalid_argument(std::string(operation) + ": this handle was not built with it; add '" + a +
                              "' to its algorithms");
}

void Handle::check_inputs(long B, const double* q, const double* qd, const char* qd_name, const double* w,
                          const char* w_name) const {
  check_configurations(model_, B, q, "q");
  if (qd) check_finite(qd, B * model_.nv, qd_name);
  if (w) check_finite(w, B * model_.nv, w_name);
}

// ---- dynamics

void Handle::inverse_dynamics(long B, const double* q, const double* qd, const double* qdd, const double* fext,
                              double gravity, double* tau) {
  require("inverse_dynamics");
  if (engine64() && !fext) {
    check_inputs(B, q, qd, "qd", qdd, "qdd");
    check_finite(&gravity, 1, "gravity");
    return engine_->inverse_dynamics<double>(B, q, qd, qdd, gravity, tau);
  }
  batch::inverse_dynamics(model_, B, q, qd, qdd, fext, gravity, tau, nullptr, nullptr, nullptr,
                          &ws_.get(model_, kLinearWorkspace));
}

void Handle::crba(long B, const double* q, double* M) {
  require("crba");
  if (engine64()) return check_inputs(B, q, nullptr, "", nullptr, ""), engine_->crba<double>(B, q, M);
  batch::crba(model_, B, q, M, &ws_.get(model_, kFullWorkspace));
}

void Handle::minv(long B, const double* q, double* Minv) {
  require("minv");
  if (engine64()) return check_inputs(B, q, nullptr, "", nullptr, ""), engine_->minv<double>(B, q, Minv);
  batch::minv(model_, B, q, true, Minv, &ws_.get(model_, kFullWorkspace));
}

void Handle::aba(long B, const double* q, const double* qd, const double* tau, const double* fext, double gravity,
                 double* qdd) {
  require("aba");
  if (engine64() && !fext) {
    check_inputs(B, q, qd, "qd", tau, "tau");
    check_finite(&gravity, 1, "gravity");
    return engine_->forward_dynamics<double>(B, q, qd, tau, gravity, qdd);
  }
  batch::aba(model_, B, q, qd, tau, fext, gravity, qdd, &ws_.get(model_, aba_layout(model_)));
}

void Handle::forward_dynamics(long B, const double* q, const double* qd, const double* tau, const double* fext,
                              double gravity, double* qdd) {
  require("forward_dynamics");
  if (engine64() && !fext) {
    check_inputs(B, q, qd, "qd", tau, "tau");
    check_finite(&gravity, 1, "gravity");
    return engine_->forward_dynamics<double>(B, q, qd, tau, gravity, qdd);
  }
  batch::forward_dynamics(model_, B, q, qd, tau, fext, gravity, qdd, &ws_.get(model_, kFullWorkspace));
}

// ---- first-order derivatives

void Handle::inverse_dynamics_gradient(long B, const double* q, const double* qd, const double* qdd,
                                       const double* fext, double gravity, double* dtau_dq, double* dtau_dqd) {
  require("inverse_dynamics_gradient");
  if (engine64() && !fext) {
    check_inputs(B, q, qd, "qd", qdd, "qdd");
    check_finite(&gravity, 1, "gravity");
    return engine_->inverse_dynamics_gradient<double>(B, q, qd, qdd, gravity, dtau_dq, dtau_dqd);
  }
  // batch:: writes [∂tau/∂q | ∂tau/∂qd] (B x nv x 2nv): split it per row
  const long nv = model_.nv;
  scratch_.resize(static_cast<size_t>(B * nv * 2 * nv));
  batch::inverse_dynamics_gradient(model_, B, q, qd, qdd, fext, gravity, scratch_.data(),
                                   &ws_.get(model_, kFullWorkspace));
  for (long r = 0; r < B * nv; ++r) {
    std::copy_n(scratch_.data() + r * 2 * nv, nv, dtau_dq + r * nv);
    std::copy_n(scratch_.data() + r * 2 * nv + nv, nv, dtau_dqd + r * nv);
  }
}

void Handle::forward_dynamics_gradient(long B, const double* q, const double* qd, const double* tau,
                                       const double* fext, double gravity, double* dqdd_dq, double* dqdd_dqd) {
  require("forward_dynamics_gradient");
  if (engine64() && !fext) {
    check_inputs(B, q, qd, "qd", tau, "tau");
    check_finite(&gravity, 1, "gravity");
    return engine_->forward_dynamics_gradient<double>(B, q, qd, tau, gravity, dqdd_dq, dqdd_dqd);
  }
  batch::forward_dynamics_gradient(model_, B, q, qd, tau, fext, gravity, dqdd_dq, dqdd_dqd, nullptr,
                                   &ws_.get(model_, kFullWorkspace));
}

// ---- integrators and the plant step

void Handle::integrator(long B, const double* q, const double* qd, const double* u, const double* fext, double dt,
                        double gravity, int type, double* x_next) {
  require("integrator");
  if (engine64() && !fext) {
    check_inputs(B, q, qd, "qd", u, "u");
    check_finite(&gravity, 1, "gravity");
    return engine_->integrator<double>(B, q, qd, u, dt, gravity, type, x_next);
  }
  batch::integrator(model_, B, q, qd, u, fext, dt, gravity, type, x_next);
}

void Handle::integrator_gradient(long B, const double* q, const double* qd, const double* u, const double* fext,
                                 double dt, double gravity, int type, double* x_next, double* AB) {
  require("integrator_gradient");
  std::vector<double> x;
  if (!x_next) {
    x.resize(static_cast<size_t>(B * (model_.nq + model_.nv)));
    x_next = x.data();
  }
  if (engine64() && !fext) {
    check_inputs(B, q, qd, "qd", u, "u");
    check_finite(&gravity, 1, "gravity");
    return engine_->integrator_gradient<double>(B, q, qd, u, dt, gravity, type, x_next, AB);
  }
  batch::integrator_gradient(model_, B, q, qd, u, fext, dt, gravity, type, x_next, AB);
}

namespace {
// q (B x nq) and qd (B x nv) copied out of x (B x (nq + nv)) into `buf`
void split_state(const Model& m, long B, const double* x, std::vector<double>& buf) {
  const long nq = m.nq, nv = m.nv;
  buf.resize(static_cast<size_t>(B * (nq + nv)));
  for (long s = 0; s < B; ++s) {
    std::copy_n(x + s * (nq + nv), nq, buf.data() + s * nq);
    std::copy_n(x + s * (nq + nv) + nq, nv, buf.data() + B * nq + s * nv);
  }
}
}  // namespace

void Handle::plant_step(long B, const double* x, const double* u, const double* fext, double dt, double gravity,
                        int type, double* x_next) {
  require("plant_step");
  split_state(model_, B, x, scratch_);
  integrator(B, scratch_.data(), scratch_.data() + B * model_.nq, u, fext, dt, gravity, type, x_next);
}

void Handle::plant_step_gradient(long B, const double* x, const double* u, const double* fext, double dt,
                                 double gravity, int type, double* AB) {
  require("plant_step_gradient");
  split_state(model_, B, x, scratch_);
  std::vector<double> x_next(static_cast<size_t>(B * (model_.nq + model_.nv)));
  integrator_gradient(B, scratch_.data(), scratch_.data() + B * model_.nq, u, fext, dt, gravity, type, x_next.data(), AB);
}

void Handle::plant_step_hessian(long B, const double* x, const double* u, double dt, double gravity, int type,
                                double* x_next, double* AB, double* H) {
  require("plant_step_hessian");
  split_state(model_, B, x, scratch_);
  const long nq = model_.nq, nv = model_.nv;
  std::vector<double> x_own, AB_own;
  if (!x_next) x_own.resize(static_cast<size_t>(B * (nq + nv))), x_next = x_own.data();
  if (!AB) AB_own.resize(static_cast<size_t>(B * 6 * nv * nv)), AB = AB_own.data();
  batch::plant_step_hessian(model_, B, scratch_.data(), scratch_.data() + B * nq, u, dt, gravity, type, x_next, AB, H);
}

// ---- costs and barriers

void Handle::quadratic_state_cost(long B, const double* x, const double* x_des, const double* Q, double* value,
                                  double* grad, double* H) {
  require("quadratic_state_cost");
  batch::quadratic_cost(B, model_.nq + model_.nv, x, x_des, Q, value, grad, H, "x", "x_des", "Q");
}

void Handle::quadratic_state_cost_tangent(long B, const double* x, const double* x_des, const double* Q,
                                          double* value, double* grad, double* H) {
  require("quadratic_state_cost_tangent");
  batch::quadratic_state_cost_tangent(model_, B, x, x_des, Q, value, grad, H);
}

void Handle::quadratic_input_cost(long B, const double* u, const double* u_des, const double* R, double* value,
                                  double* grad, double* H) {
  require("quadratic_input_cost");
  batch::quadratic_cost(B, model_.nv, u, u_des, R, value, grad, H, "u", "u_des", "R");
}

void Handle::ee_pos_cost(long B, const double* q, const double* p_des, const double* W, double* value, double* grad,
                         double* H, int body, const double* offset) {
  require("ee_pos_cost");
  if (body < 0) {
    const std::vector<int> leaves = leaf_bodies(model_);
    if (leaves.empty()) throw std::invalid_argument("ee_pos_cost: the robot has no end effector");
    body = leaves.front();
  }
  if (body >= model_.nb()) throw std::invalid_argument("body: expected a body index below nb");
  batch::ee_pos_cost(model_, B, q, p_des, W, body, offset, value, grad, H);
}

void Handle::com_cost(long B, const double* q, const double* p_des, const double* W, double* value, double* grad,
                      double* H) {
  require("com_cost");
  batch::com_cost(model_, B, q, p_des, W, value, grad, H);
}

void Handle::momentum_cost(long B, const double* q, const double* qd, const double* h_des, const double* W,
                           double* value, double* grad, double* H) {
  require("momentum_cost");
  batch::momentum_cost(model_, B, q, qd, h_des, W, value, grad, H);
}

void Handle::joint_position_barrier(long B, const double* q, const double* lower, const double* upper, double mu,
                                    double* value, double* grad, double* Hdiag) {
  require("joint_position_barrier");
  batch::log_barrier(B, model_.nq, q, lower, upper, mu, value, grad, Hdiag, "q");
}

void Handle::joint_velocity_barrier(long B, const double* qd, const double* lower, const double* upper, double mu,
                                    double* value, double* grad, double* Hdiag) {
  require("joint_velocity_barrier");
  batch::log_barrier(B, model_.nv, qd, lower, upper, mu, value, grad, Hdiag, "qd");
}

void Handle::joint_torque_barrier(long B, const double* u, const double* lower, const double* upper, double mu,
                                  double* value, double* grad, double* Hdiag) {
  require("joint_torque_barrier");
  batch::log_barrier(B, model_.nv, u, lower, upper, mu, value, grad, Hdiag, "u");
}

// ---- Eigen front ends

void Handle::check_rows(const BatchMatrix& a, int width, const char* name, long B) const {
  if (a.cols() != width || a.rows() != B || B < 1)
    throw std::invalid_argument(std::string(name) + ": expected " + std::to_string(B) + " x " +
                                std::to_string(width) + " (one sample per row), got " + std::to_string(a.rows()) +
                                " x " + std::to_string(a.cols()));
}

BatchMatrix Handle::inverse_dynamics(const BatchMatrix& q, const BatchMatrix& qd, const BatchMatrix& qdd,
                                     double gravity) {
  const long B = q.rows();
  check_rows(q, model_.nq, "q", B);
  check_rows(qd, model_.nv, "qd", B);
  check_rows(qdd, model_.nv, "qdd", B);
  BatchMatrix tau(B, model_.nv);
  inverse_dynamics(B, q.data(), qd.data(), qdd.data(), nullptr, gravity, tau.data());
  return tau;
}

BatchMatrix Handle::forward_dynamics(const BatchMatrix& q, const BatchMatrix& qd, const BatchMatrix& tau,
                                     double gravity) {
  const long B = q.rows();
  check_rows(q, model_.nq, "q", B);
  check_rows(qd, model_.nv, "qd", B);
  check_rows(tau, model_.nv, "tau", B);
  BatchMatrix qdd(B, model_.nv);
  forward_dynamics(B, q.data(), qd.data(), tau.data(), nullptr, gravity, qdd.data());
  return qdd;
}

std::vector<Eigen::MatrixXd> Handle::crba(const BatchMatrix& q) {
  const long B = q.rows();
  check_rows(q, model_.nq, "q", B);
  const int nv = model_.nv;
  std::vector<double> M(static_cast<size_t>(B * nv * nv));
  crba(B, q.data(), M.data());
  std::vector<Eigen::MatrixXd> out;
  for (long s = 0; s < B; ++s) out.push_back(Eigen::Map<const BatchMatrix>(M.data() + s * nv * nv, nv, nv));
  return out;
}

BatchMatrix Handle::integrator(const BatchMatrix& q, const BatchMatrix& qd, const BatchMatrix& u, double dt,
                               const std::string& type, double gravity) {
  const int t = integrator_from_name(type);
  const long B = q.rows();
  check_rows(q, model_.nq, "q", B);
  check_rows(qd, model_.nv, "qd", B);
  check_rows(u, model_.nv, "u", B);
  BatchMatrix x(B, model_.nq + model_.nv);
  integrator(B, q.data(), qd.data(), u.data(), nullptr, dt, gravity, t, x.data());
  return x;
}

std::vector<Eigen::MatrixXd> Handle::integrator_gradient(const BatchMatrix& q, const BatchMatrix& qd,
                                                         const BatchMatrix& u, double dt, const std::string& type,
                                                         double gravity) {
  const int t = integrator_from_name(type);
  const long B = q.rows();
  check_rows(q, model_.nq, "q", B);
  check_rows(qd, model_.nv, "qd", B);
  check_rows(u, model_.nv, "u", B);
  const int r = 2 * model_.nv, c = 3 * model_.nv;
  std::vector<double> AB(static_cast<size_t>(B * r * c));
  integrator_gradient(B, q.data(), qd.data(), u.data(), nullptr, dt, gravity, t, nullptr, AB.data());
  std::vector<Eigen::MatrixXd> out;
  for (long s = 0; s < B; ++s) out.push_back(Eigen::Map<const BatchMatrix>(AB.data() + s * r * c, r, c));
  return out;
}

}  // namespace rbd
