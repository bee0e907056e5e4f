// rbdkit/handle/handle.hpp — an operation handle: a robot plus the algorithms it is
// built with, the dependencies they pull in, and batched calls of the
// operations those algorithms provide. Host only.
//
// The algorithm table (handle_algorithms()) is the one source of truth for
// algorithm names, the operations each provides and what each requires; the
// Python rbdkit.Handle reads the same table through the binding.
//
//   rbd::Handle h(rbd::Model::from_urdf_file("iiwa.urdf"), {"integrator_gradient", "com_cost"});
//   h.has("plant_step_gradient");            // true: integrator_gradient provides it
//   h.has("com");                            // true: com_cost requires com and ccrba
//   h.integrator_gradient(B, q, qd, u, nullptr, 0.01, -9.81, rbd::kRK4, x_next, AB);
//   h.crba(B, q, M);                         // std::invalid_argument: add 'crba' to the algorithms
//
// Batched calls take B samples stacked on the leading axis, row-major:
// q (B x nq), qd / qdd / tau / u (B x nv), x (B x (nq + nv)), f_ext
// (B x nb x 6) or null. Every call is a registered operation
// (ops/registry.hpp): run(id, call) checks it (ops::check_call: finite values,
// unit quaternions, bounds; a bad one throws std::invalid_argument naming it
// and the sample) and computes it; the typed methods below are run() calls on
// float64 arrays. An operation the handle was not built with throws
// std::invalid_argument naming the algorithm to add. A Handle keeps one
// workspace: one Handle per thread.
//
// threads > 0 gives the handle a batched CPU engine (engine.hpp) with that
// many threads: run() sends every operation there for a batch of B > 1 (a
// float32 handle: always), f_ext and the MuJoCo convention included; results
// are bit-identical whatever the thread count. threads = 0 (the default): one
// sample at a time on the calling thread.
//
// Backend::CUDA runs every registered operation on a GPU instead
// (cuda/cuda_engine.hpp; RBDKIT_CUDA_INTERPRET=1: the kernels' source on the
// CPU): the same checks, the same results, host arrays copied in and out, or
// device arrays in place (run_device).
//
// specialize() loads the robot's compiled instance (codegen/specialize.hpp):
// the float64 serial loop then runs its per-robot kernels for the operations
// it has (the dynamics, M, M⁻¹, their first derivatives, the step); on a
// Backend::CUDA handle, the CUDA backend's kernels compiled on the robot's
// constants (cuda/instance.cuh) for ID, M⁻¹, FD, ∇ID, ∇FD and the step's gradient.
#pragma once

#include <Eigen/Core>
#include <mutex>
#include <string>
#include <vector>

#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/batch/engine.hpp"
#include "rbdkit/codegen/specialize.hpp"
#include "rbdkit/cuda/cuda_engine.hpp"

namespace rbd {

// where a handle computes: the CPU (serial loop or batch engine) or a CUDA device
enum class Backend { CPU, CUDA };
// "cpu" / "cuda" (std::invalid_argument naming the valid ones otherwise)
Backend backend_from_name(const std::string& name);

// one row of the algorithm table
struct AlgorithmInfo {
  std::string name;                     // what goes in a handle's algorithm list
  std::vector<std::string> operations;  // the operations it provides (rbdkit.RBD method names)
  std::vector<std::string> dependencies;  // algorithms it needs (resolved transitively)
};

// every algorithm, in table order
const std::vector<AlgorithmInfo>& handle_algorithms();
// the names in `names` and everything they require, in table order; empty
// `names` means every algorithm. An unknown name throws std::invalid_argument
// listing the valid ones.
std::vector<std::string> resolve_algorithms(const std::vector<std::string>& names);
// the algorithm that provides `operation` ("" when no algorithm does)
std::string algorithm_of(const std::string& operation);

// B samples of width n stacked row-major (the Eigen form of a batch)
using BatchMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

class Handle {
 public:
  // algorithms: names from handle_algorithms(); empty = every algorithm;
  // threads: 0 (no engine) or the engine's thread count (negative: error)
  explicit Handle(Model model, const std::vector<std::string>& algorithms = {}, int threads = 0);
  // dtype "float64" or "float32"; a float32 handle computes the registered
  // operations on the engine (one thread when threads = 0)
  Handle(Model model, const std::vector<std::string>& algorithms, int threads, const std::string& dtype);
  // output_convention "pinocchio" or "mujoco": the convention of the
  // operations that take one (the integrators, the plant step, the costs) when
  // a call does not say; on a model with free-flyer or spherical joints, a
  // MuJoCo handle refuses the operations that take none (their values are
  // Pinocchio's), except the conversions between the conventions
  Handle(Model model, const std::vector<std::string>& algorithms, int threads, const std::string& dtype,
         const std::string& output_convention);

  // a handle on a backend: Backend::CUDA needs a CUDA device or interpret mode
  // (std::runtime_error naming what is missing otherwise)
  Handle(Model model, const std::vector<std::string>& algorithms, Backend backend,
         const std::string& dtype = "float64", const std::string& output_convention = "pinocchio",
         int threads = 0);

  const Model& model() const { return model_; }
  Backend backend() const { return backend_; }
  // the CUDA engine of a Backend::CUDA handle (null otherwise)
  CudaEngine* cuda() const { return cuda_.get(); }
  int threads() const { return threads_; }
  const std::string& dtype() const { return dtype_; }
  int output_convention() const { return convention_; }  // OutputConvention
  // the resolved algorithm list (the requested ones and their dependencies)
  const std::vector<std::string>& algorithms() const { return algorithms_; }
  // the operations this handle's algorithms provide, in table order (the
  // Python rbdkit.Handle offers all of them)
  std::vector<std::string> available_operations() const;
  // whether C++ can call `operation` on this handle: a method below or a
  // registered operation, provided by the handle's algorithms
  bool has(const std::string& operation) const;

  // ---- registered operations (ops/registry.hpp), by id, on call.B samples
  // whose arrays hold the handle's dtype: the values are checked
  // (ops::check_call), then the engine (float32, or a float64 batch of B > 1 with
  // threads > 0) or the serial loop on the calling thread runs them. The Python bindings call this.
  // A call's output_convention argument is the caller's (the bindings and
  // the typed methods default it to the handle's).
  void run(int op, const ops::OpCall& call);
  // the same on device arrays (a Backend::CUDA handle): read and written in
  // place, on the handle's stream (cuda()->set_stream). The values are checked
  // as run() checks them, by the kernels (a failing sample's inputs are then
  // copied to the host to word the same error)
  void run_device(int op, const ops::OpCall& call);
  bool has_op(int op) const { return op >= 0 && op < static_cast<int>(op_enabled_.size()) && op_enabled_[op]; }

  // ---- a compiled per-robot instance (codegen/specialize.hpp): compiled on first use (cached
  // after), then the serial loop (float64: one sample, or every call of a threads = 0 handle) runs
  // its kernels for the operations it has; on a CUDA handle, the backend's kernels on the robot's
  // constants (nvcc for a GPU, the C++ compiler for interpret mode; both dtypes). Returns whether it
  // is in use; when it could not be made (no compiler, a failed compilation, a library that fails its
  // checks, a CPU float32 handle: the engine computes its every call), false, the generic kernels
  // stay, and specialize_error() says why. Not while other calls run.
  bool specialize(const SpecializeOptions& options = {});
  bool specialized() const { return instance_ != nullptr || cuda_instance_ != nullptr; }
  const std::string& specialize_error() const { return specialize_error_; }
  // the instance's library ("" when not specialized)
  std::string instance_library() const;

  // ---- dynamics
  // tau (B x nv); qdd, fext may be null
  void inverse_dynamics(long B, const double* q, const double* qd, const double* qdd, const double* fext,
                        double gravity, double* tau);
  void crba(long B, const double* q, double* M);                    // M (B x nv x nv)
  void minv(long B, const double* q, double* Minv);                 // dense M⁻¹ (B x nv x nv)
  void aba(long B, const double* q, const double* qd, const double* tau, const double* fext, double gravity,
           double* qdd);                                            // qdd (B x nv)
  void forward_dynamics(long B, const double* q, const double* qd, const double* tau, const double* fext,
                        double gravity, double* qdd);               // qdd = M⁻¹ (tau - c) (B x nv)

  // ---- first-order derivatives
  // dtau_dq, dtau_dqd (B x nv x nv each)
  void inverse_dynamics_gradient(long B, const double* q, const double* qd, const double* qdd, const double* fext,
                                 double gravity, double* dtau_dq, double* dtau_dqd);
  // dqdd_dq, dqdd_dqd (B x nv x nv each)
  void forward_dynamics_gradient(long B, const double* q, const double* qd, const double* tau, const double* fext,
                                 double gravity, double* dqdd_dq, double* dqdd_dqd);

  // ---- integrators and the plant step (type: IntegratorType, or integrator_from_name)
  // x⁺ (B x (nq + nv))
  void integrator(long B, const double* q, const double* qd, const double* u, const double* fext, double dt,
                  double gravity, int type, double* x_next);
  // x⁺ (B x (nq + nv)) when not null and [A | B] (B x 2nv x 3nv), tangent space
  void integrator_gradient(long B, const double* q, const double* qd, const double* u, const double* fext,
                           double dt, double gravity, int type, double* x_next, double* AB);
  // the same on x = [q; qd] (B x (nq + nv))
  void plant_step(long B, const double* x, const double* u, const double* fext, double dt, double gravity, int type,
                  double* x_next);
  void plant_step_gradient(long B, const double* x, const double* u, const double* fext, double dt, double gravity,
                           int type, double* AB);
  // the step Hessian H (B x 2nv x 3nv x 3nv), plant/integrator_hessian.hpp; x_next, AB may be null
  void plant_step_hessian(long B, const double* x, const double* u, double dt, double gravity, int type,
                          double* x_next, double* AB, double* H);

  // ---- costs (value (B), grad, H) and barriers (value (B), grad, Hdiag); layouts in costs_api.hpp
  void quadratic_state_cost(long B, const double* x, const double* x_des, const double* Q, double* value,
                            double* grad, double* H);             // Q (B x NX): grad (B x NX), H (B x NX x NX)
  void quadratic_state_cost_tangent(long B, const double* x, const double* x_des, const double* Q, double* value,
                                    double* grad, double* H);     // Q (B x 2nv): grad (B x 2nv), H (B x 2nv x 2nv)
  void quadratic_input_cost(long B, const double* u, const double* u_des, const double* R, double* value,
                            double* grad, double* H);             // R (B x nv): grad (B x nv), H (B x nv x nv)
  // the first end effector (first leaf body) unless `body` >= 0; offset (3) or null
  void ee_pos_cost(long B, const double* q, const double* p_des, const double* W, double* value, double* grad,
                   double* H, int body = -1, const double* offset = nullptr);  // grad (B x NX), H (B x NX x NX)
  void com_cost(long B, const double* q, const double* p_des, const double* W, double* value, double* grad,
                double* H);                                       // grad (B x NX), H (B x NX x NX)
  void momentum_cost(long B, const double* q, const double* qd, const double* h_des, const double* W,
                     double* value, double* grad, double* H);     // grad (B x 2nv), H (B x 2nv x 2nv)
  void joint_position_barrier(long B, const double* q, const double* lower, const double* upper, double mu,
                              double* value, double* grad, double* Hdiag);  // bounds, grad, Hdiag (B x nq)
  void joint_velocity_barrier(long B, const double* qd, const double* lower, const double* upper, double mu,
                              double* value, double* grad, double* Hdiag);  // (B x nv)
  void joint_torque_barrier(long B, const double* u, const double* lower, const double* upper, double mu,
                            double* value, double* grad, double* Hdiag);    // (B x nv)

  // ---- Eigen front ends: one sample per row (B x n); matrices per sample in a vector
  BatchMatrix inverse_dynamics(const BatchMatrix& q, const BatchMatrix& qd, const BatchMatrix& qdd,
                               double gravity = -9.81);
  BatchMatrix forward_dynamics(const BatchMatrix& q, const BatchMatrix& qd, const BatchMatrix& tau,
                               double gravity = -9.81);
  std::vector<Eigen::MatrixXd> crba(const BatchMatrix& q);
  BatchMatrix integrator(const BatchMatrix& q, const BatchMatrix& qd, const BatchMatrix& u, double dt,
                         const std::string& type = "euler", double gravity = -9.81);
  std::vector<Eigen::MatrixXd> integrator_gradient(const BatchMatrix& q, const BatchMatrix& qd, const BatchMatrix& u,
                                                   double dt, const std::string& type = "euler",
                                                   double gravity = -9.81);

 private:
  void require(const char* operation) const;  // throws unless has(operation)
  // run's checked call, names resolved: serial loop, engine or CUDA engine (device_arrays: run_device's)
  void dispatch(int op, const ops::OpCall& call, bool device_arrays = false);
  // the backend, the convention, the values (values = false: not the arrays' values, which the
  // CUDA kernels check on device arrays)
  void check(int op, const ops::OpCall& call, bool values = true) const;
  void resolve_and_dispatch(int op, const ops::OpCall& call, bool device_arrays);  // names resolved, then dispatch
  void run_typed(int op, const ops::OpCall& call);  // run() for the typed methods (a float64 handle)
  void check_rows(const BatchMatrix& a, int width, const char* name, long B) const;

  Model model_;
  std::vector<std::string> algorithms_;
  std::vector<std::string> operations_;
  std::vector<bool> op_enabled_;  // per registered operation: provided by the algorithms
  int threads_ = 0;
  std::string dtype_ = "float64";
  int convention_ = 0;  // OutputConvention (plant/mujoco_convention.hpp): 0 Pinocchio, 1 MuJoCo
  // per registered operation: refused by the output convention (a MuJoCo handle on a model with
  // free-flyer or spherical joints, an operation without a convention argument, not a conversion)
  std::vector<bool> op_refused_;
  WorkspaceCache ws_;  // linear until an O(n²) operation runs
  std::vector<double> op_scratch_;  // the serial loop's scratch
  std::mutex run_;  // one run() at a time (the workspace is shared)
  std::unique_ptr<Engine> engine_;  // null when threads = 0 (and dtype float64), and on Backend::CUDA
  Backend backend_ = Backend::CPU;
  std::unique_ptr<CudaEngine> cuda_;  // Backend::CUDA
  std::shared_ptr<const Instance> instance_;  // specialize(): the compiled per-robot kernels
  std::shared_ptr<const CudaInstance> cuda_instance_;  // specialize() on a CUDA handle
  std::string specialize_error_;
};

}  // namespace rbd
