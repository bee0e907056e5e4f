// Operation handles: the algorithm table, dependency resolution, and the
// batched calls: run() checks a registered operation's call and gives it to
// the engine or the serial loop; the typed methods are calls of run().
#include "rbdkit/handle/handle.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "rbdkit/batch/integrators_api.hpp"
#include "rbdkit/ops/registry.hpp"
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

Backend backend_from_name(const std::string& name) {
  if (name == "cpu") return Backend::CPU;
  if (name == "cuda") return Backend::CUDA;
  throw std::invalid_argument("backend: expected 'cpu' or 'cuda', got '" + name + "'");
}

Handle::Handle(Model model, const std::vector<std::string>& algorithms, Backend backend, const std::string& dtype,
               const std::string& output_convention, int threads)
    : Handle(std::move(model), algorithms, backend == Backend::CUDA ? 0 : threads,
             backend == Backend::CUDA ? "float64" : dtype, output_convention) {
  backend_ = backend;
  if (backend != Backend::CUDA) return;
  if (dtype != "float64" && dtype != "float32")
    throw std::invalid_argument("dtype: expected 'float64' or 'float32', got '" + dtype + "'");
  if (threads < 0)
    throw std::invalid_argument("threads: expected 0 (no engine) or a positive thread count, got " +
                                std::to_string(threads));
  dtype_ = dtype;
  threads_ = threads;
  cuda_.reset(new CudaEngine(model_, dtype));
}

Handle::Handle(Model model, const std::vector<std::string>& algorithms, int threads)
    : Handle(std::move(model), algorithms, threads, "float64") {}

Handle::Handle(Model model, const std::vector<std::string>& algorithms, int threads, const std::string& dtype)
    : Handle(std::move(model), algorithms, threads, dtype, "pinocchio") {}

Handle::Handle(Model model, const std::vector<std::string>& algorithms, int threads, const std::string& dtype,
               const std::string& output_convention)
    : model_(std::move(model)), algorithms_(resolve_algorithms(algorithms)), threads_(threads), dtype_(dtype) {
  if (output_convention != "pinocchio" && output_convention != "mujoco")
    throw std::invalid_argument("output_convention: expected 'pinocchio' or 'mujoco', got '" + output_convention +
                                "'");
  convention_ = output_convention == "mujoco" ? kMujocoConvention : kPinocchioConvention;
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
  // the conventions differ on free-flyer and spherical joints
  bool quaternion_joints = false;
  for (const BodyDesc<double>& b : model_.bodies)
    quaternion_joints = quaternion_joints || (!b.mimic && (b.type == kFree || b.type == kSpherical));
  op_refused_.assign(ops::op_table().size(), false);
  for (const ops::OpEntry& e : ops::op_table())
    op_refused_[e.id] = convention_ == kMujocoConvention && quaternion_joints && !ops::takes_convention(*e.spec) &&
                        std::strcmp(e.spec->algorithm, "mujoco_convention") != 0;
}

std::vector<std::string> Handle::available_operations() const { return operations_; }

bool Handle::has(const std::string& operation) const {
  // the registered operations this handle's algorithms provide (the typed methods below are calls of them)
  return ops::find_op(operation) >= 0 &&
         std::find(operations_.begin(), operations_.end(), operation) != operations_.end();
}

void Handle::check(int op, const ops::OpCall& call, bool values) const {
  if (op < 0 || op >= static_cast<int>(ops::op_table().size()))
    throw std::invalid_argument("run: unknown operation id " + std::to_string(op));
  const ops::OpEntry& e = ops::op_table()[op];
  if (!has_op(op)) require(e.spec->name);
  if (call.B <= 0)
    throw std::invalid_argument(std::string(e.spec->name) + ": B: expected a positive batch size, got " +
                                std::to_string(call.B));
  if (op_refused_[op])
    throw std::invalid_argument(std::string(e.spec->name) +
                                ": does not support output_convention='mujoco' on a model with free-flyer or "
                                "spherical joints; use a handle with output_convention='pinocchio'");
  if (dtype_ == "float32") ops::check_call<float>(model_, *e.spec, call, values);
  else ops::check_call<double>(model_, *e.spec, call, values);
}

bool Handle::specialize(const SpecializeOptions& options) {
  std::lock_guard<std::mutex> lk(run_);  // (the serial loop reads instance_ under it)
  if (cuda_) {
    try {
      auto inst = load_cuda_instance(model_, options, !cuda_->interpret(), cuda_->device_name());
      cuda_->use_instance(inst);
      cuda_instance_ = std::move(inst);
      specialize_error_.clear();
    } catch (const std::exception& e) {
      cuda_->use_instance(nullptr);
      cuda_instance_.reset();
      specialize_error_ = e.what();
    }
    return cuda_instance_ != nullptr;
  }
  if (dtype_ == "float32") {
    specialize_error_ = "specialize: a float32 handle runs every call on the batch engine; an instance serves "
                        "the CPU's float64 serial loop";
    instance_.reset();
    return false;
  }
  try {
    instance_ = load_instance(model_, options);
    specialize_error_.clear();
  } catch (const std::exception& e) {
    instance_.reset();
    specialize_error_ = e.what();
  }
  return instance_ != nullptr;
}

std::string Handle::instance_library() const {
  return instance_ ? instance_path(*instance_) : cuda_instance_ ? instance_path(*cuda_instance_) : std::string();
}

void Handle::run(int op, const ops::OpCall& call) {
  check(op, call);
  resolve_and_dispatch(op, call, false);
}

void Handle::resolve_and_dispatch(int op, const ops::OpCall& call, bool device_arrays) {
  const ops::OpSpec& spec = *ops::op_table()[op].spec;
  if (!ops::takes_names(spec)) return dispatch(op, call, device_arrays);
  // frames and end effectors for the kernels, then the same call
  std::vector<double> f64;
  std::vector<float> f32;
  const ops::OpCall resolved = dtype_ == "float32" ? ops::resolve_names(model_, spec, call, f32)
                                                   : ops::resolve_names(model_, spec, call, f64);
  dispatch(op, resolved, device_arrays);
}

void Handle::run_device(int op, const ops::OpCall& call) {
  if (!cuda_)
    throw std::invalid_argument("run_device: device arrays need a handle with backend='cuda' (this one is 'cpu')");
  if (op < 0 || op >= static_cast<int>(ops::op_table().size()))
    throw std::invalid_argument("run: unknown operation id " + std::to_string(op));
  // the parameters here; the arrays' values in the kernels, which name a failing sample's argument
  // from a copy of its inputs (CudaEngine): no copy to the host on the way in
  check(op, call, false);
  resolve_and_dispatch(op, call, true);
}

void Handle::dispatch(int op, const ops::OpCall& call, bool device_arrays) {
  const ops::OpEntry& e = ops::op_table()[op];
  const bool no_bodies = model_.nb() == 0;
  if (cuda_ && (!no_bodies || device_arrays)) return cuda_->run_op(op, call, device_arrays);
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
  if (dtype_ != "float32") {
    // the compiled instance's kernel for this operation, where the handle has one
    const ops::Kernel<double> k = instance_ ? instance_kernel(*instance_, op) : nullptr;
    if (k) return ops::run_serial(model_, ops::OpEntry{e.id, e.spec, k}, call, w, op_scratch_.data());
    return ops::run_serial(model_, e, call, w, op_scratch_.data());
  }
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

// ---- the typed methods: registered operations on float64 arrays
namespace {
struct Call : ops::OpCall {
  explicit Call(long b) { B = b; }
  Call& input(int k, const double* p) { in[k] = p, batched[k] = true; return *this; }  // (B x shape)
  Call& one(int k, const double* p) { in[k] = p, batched[k] = false; return *this; }   // (shape), every sample
  Call& output(int k, double* p) { out[k] = p; return *this; }
  Call& value(int k, double x) { real[k] = x; return *this; }
  Call& pick(int k, int c) { choice[k] = c; return *this; }
};
template <typename Op> constexpr int id_of() { return ops::index_of<Op>(ops::AllOps{}); }
}  // namespace

void Handle::run_typed(int op, const ops::OpCall& call) {
  const ops::OpSpec& spec = *ops::op_table()[op].spec;
  if (dtype_ != "float64")
    throw std::invalid_argument(std::string(spec.name) +
                                ": the typed methods take float64 arrays; this handle is float32 (run() takes "
                                "float arrays)");
  if (!ops::takes_convention(spec)) return run(op, call);
  ops::OpCall c = call;  // the handle's output convention
  for (int k = 0; k < spec.n_args; ++k)
    if (spec.args[k].kind == ops::kConvention) c.choice[k] = convention_;
  run(op, c);
}

// ---- dynamics

void Handle::inverse_dynamics(long B, const double* q, const double* qd, const double* qdd, const double* fext,
                              double gravity, double* tau) {
  run_typed(id_of<ops::InverseDynamics>(),
            Call(B).input(0, q).input(1, qd).input(2, qdd).value(3, gravity).input(4, fext).output(0, tau));
}

void Handle::crba(long B, const double* q, double* M) {
  run_typed(id_of<ops::Crba>(), Call(B).input(0, q).output(0, M));
}

void Handle::minv(long B, const double* q, double* Minv) {
  run_typed(id_of<ops::Minv>(), Call(B).input(0, q).pick(1, 1).output(0, Minv));
}

void Handle::aba(long B, const double* q, const double* qd, const double* tau, const double* fext, double gravity,
                 double* qdd) {
  run_typed(id_of<ops::Aba>(),
            Call(B).input(0, q).input(1, qd).input(2, tau).input(3, fext).value(4, gravity).output(0, qdd));
}

void Handle::forward_dynamics(long B, const double* q, const double* qd, const double* tau, const double* fext,
                              double gravity, double* qdd) {
  run_typed(id_of<ops::ForwardDynamics>(),
            Call(B).input(0, q).input(1, qd).input(2, tau).input(3, fext).value(4, gravity).output(0, qdd));
}

// ---- first-order derivatives

void Handle::inverse_dynamics_gradient(long B, const double* q, const double* qd, const double* qdd,
                                       const double* fext, double gravity, double* dtau_dq, double* dtau_dqd) {
  run_typed(id_of<ops::InverseDynamicsGradient>(), Call(B).input(0, q).input(1, qd).input(2, qdd).value(3, gravity)
                                                       .input(4, fext).output(1, dtau_dq).output(2, dtau_dqd));
}

void Handle::forward_dynamics_gradient(long B, const double* q, const double* qd, const double* tau,
                                       const double* fext, double gravity, double* dqdd_dq, double* dqdd_dqd) {
  run_typed(id_of<ops::ForwardDynamicsGradient>(), Call(B).input(0, q).input(1, qd).input(2, tau).input(3, fext)
                                                       .value(4, gravity).output(0, dqdd_dq).output(1, dqdd_dqd));
}

// ---- integrators and the plant step (argument order: registry.hpp's RBD_STEP_ARGS)

void Handle::integrator(long B, const double* q, const double* qd, const double* u, const double* fext, double dt,
                        double gravity, int type, double* x_next) {
  run_typed(id_of<ops::Integrator>(), Call(B).input(0, q).input(1, qd).input(2, u).value(3, dt).pick(4, type)
                                          .input(5, fext).value(6, gravity).output(0, x_next));
}

void Handle::integrator_gradient(long B, const double* q, const double* qd, const double* u, const double* fext,
                                 double dt, double gravity, int type, double* x_next, double* AB) {
  run_typed(id_of<ops::IntegratorGradient>(), Call(B).input(0, q).input(1, qd).input(2, u).value(3, dt)
                                                  .pick(4, type).input(5, fext).value(6, gravity)
                                                  .output(0, x_next).output(1, AB));
}

void Handle::plant_step(long B, const double* x, const double* u, const double* fext, double dt, double gravity,
                        int type, double* x_next) {
  run_typed(id_of<ops::PlantStep>(), Call(B).input(0, x).input(1, u).value(2, dt).pick(3, type).input(4, fext)
                                         .value(5, gravity).output(0, x_next));
}

void Handle::plant_step_gradient(long B, const double* x, const double* u, const double* fext, double dt,
                                 double gravity, int type, double* AB) {
  run_typed(id_of<ops::PlantStepGradient>(), Call(B).input(0, x).input(1, u).value(2, dt).pick(3, type)
                                                 .input(4, fext).value(5, gravity).output(1, AB));
}

void Handle::plant_step_hessian(long B, const double* x, const double* u, double dt, double gravity, int type,
                                double* x_next, double* AB, double* H) {
  run_typed(id_of<ops::PlantStepHessian>(), Call(B).input(0, x).input(1, u).value(2, dt).pick(3, type)
                                                .value(4, gravity).output(0, x_next).output(1, AB).output(2, H));
}

// ---- costs and barriers (every input batched, one sample per row; ee_pos_cost's offset one for all)

void Handle::quadratic_state_cost(long B, const double* x, const double* x_des, const double* Q, double* value,
                                  double* grad, double* H) {
  run_typed(id_of<ops::QuadraticStateCost>(),
            Call(B).input(0, x).input(1, x_des).input(2, Q).output(0, value).output(1, grad).output(2, H));
}

void Handle::quadratic_state_cost_tangent(long B, const double* x, const double* x_des, const double* Q,
                                          double* value, double* grad, double* H) {
  run_typed(id_of<ops::QuadraticStateCostTangent>(),
            Call(B).input(0, x).input(1, x_des).input(2, Q).output(0, value).output(1, grad).output(2, H));
}

void Handle::quadratic_input_cost(long B, const double* u, const double* u_des, const double* R, double* value,
                                  double* grad, double* H) {
  run_typed(id_of<ops::QuadraticInputCost>(),
            Call(B).input(0, u).input(1, u_des).input(2, R).output(0, value).output(1, grad).output(2, H));
}

void Handle::ee_pos_cost(long B, const double* q, const double* p_des, const double* W, double* value, double* grad,
                         double* H, int body, const double* offset) {
  run_typed(id_of<ops::EePosCost>(), Call(B).input(0, q).input(1, p_des).input(2, W).pick(3, body < 0 ? -1 : body)
                                         .one(4, offset).output(0, value).output(1, grad).output(2, H));
}

void Handle::com_cost(long B, const double* q, const double* p_des, const double* W, double* value, double* grad,
                      double* H) {
  run_typed(id_of<ops::ComCost>(),
            Call(B).input(0, q).input(1, p_des).input(2, W).output(0, value).output(1, grad).output(2, H));
}

void Handle::momentum_cost(long B, const double* q, const double* qd, const double* h_des, const double* W,
                           double* value, double* grad, double* H) {
  run_typed(id_of<ops::MomentumCost>(), Call(B).input(0, q).input(1, qd).input(2, h_des).input(3, W)
                                            .output(0, value).output(1, grad).output(2, H));
}

void Handle::joint_position_barrier(long B, const double* q, const double* lower, const double* upper, double mu,
                                    double* value, double* grad, double* Hdiag) {
  run_typed(id_of<ops::JointPositionBarrier>(), Call(B).input(0, q).input(1, lower).input(2, upper).value(3, mu)
                                                    .output(0, value).output(1, grad).output(2, Hdiag));
}

void Handle::joint_velocity_barrier(long B, const double* qd, const double* lower, const double* upper, double mu,
                                    double* value, double* grad, double* Hdiag) {
  run_typed(id_of<ops::JointVelocityBarrier>(), Call(B).input(0, qd).input(1, lower).input(2, upper).value(3, mu)
                                                    .output(0, value).output(1, grad).output(2, Hdiag));
}

void Handle::joint_torque_barrier(long B, const double* u, const double* lower, const double* upper, double mu,
                                  double* value, double* grad, double* Hdiag) {
  run_typed(id_of<ops::JointTorqueBarrier>(), Call(B).input(0, u).input(1, lower).input(2, upper).value(3, mu)
                                                  .output(0, value).output(1, grad).output(2, Hdiag));
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
