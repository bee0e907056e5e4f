// rbdkit/ops/op.hpp — how an operation is described: its arguments (arrays
// and parameters, in the order a caller passes them), their per-sample shapes
// as functions of the model's sizes, their value checks, its outputs, its
// workspace and scratch, and the per-sample call its kernel receives.
// Host/device: plain data and one Scalar-templated struct.
//
// An operation is a struct with
//   static constexpr OpSpec spec = {...};       // the description below
//   template <typename S> RBD_HD static bool run(const ModelView<S>&, Workspace<S>&, const OpArgs<S>&);
// listed in ops/registry.hpp. Every surface (the checked serial loop, the
// batch engine, the handle, the Python bindings) is generated from the list:
// see docs/adding-an-operation.md.
#pragma once

#include "rbdkit/spatial/config.hpp"
#include "rbdkit/spatial/spatial.hpp"

namespace rbd {
namespace ops {

constexpr int kMaxArgs = 10;    // arguments (arrays and parameters) of one operation
constexpr int kMaxOutputs = 4;  // outputs of one operation
constexpr int kMaxRank = 4;     // dimensions of one sample of an array

// one dimension of a per-sample shape: a literal size (> 0) or a size of the model
enum Dim : int {
  kNq = -1,   // configuration coordinates
  kNv = -2,   // velocity coordinates
  kNb = -3,   // bodies
  kNx = -4,   // nq + nv (a state x = [q; qd])
  k2Nv = -5,  // 2 nv (tangent state)
  k3Nv = -6,  // 3 nv (tangent state and input)
  k10Nb = -7, // 10 nb (inertial parameters, Model::inertial_parameters)
  kNee = -8,  // the call's end effectors (its kEndEffectors argument)
};

// the per-sample shape of an array: rank 0..kMaxRank
struct Shape {
  int rank;
  int d[kMaxRank];
};
constexpr Shape scalar() { return {0, {0, 0, 0, 0}}; }  // one value per sample
constexpr Shape shape(int a) { return {1, {a, 0, 0, 0}}; }
constexpr Shape shape(int a, int b) { return {2, {a, b, 0, 0}}; }
constexpr Shape shape(int a, int b, int c) { return {3, {a, b, c, 0}}; }
constexpr Shape shape(int a, int b, int c, int d) { return {4, {a, b, c, d}}; }

// the extent of a dimension on a model of sizes (nq, nv, nb), for a call with n_ee end effectors
RBD_HD constexpr long extent(int d, int nq, int nv, int nb, int n_ee = 0) {
  return d > 0 ? d
       : d == kNq ? nq
       : d == kNv ? nv
       : d == kNb ? nb
       : d == kNx ? nq + nv
       : d == k2Nv ? 2L * nv
       : d == k3Nv ? 3L * nv
       : d == k10Nb ? 10L * nb
       : d == kNee ? n_ee
       : 0;
}
RBD_HD constexpr long values_of(const Shape& s, int nq, int nv, int nb, int n_ee = 0) {
  long n = 1;
  for (int k = 0; k < s.rank; ++k) n *= extent(s.d[k], nq, nv, nb, n_ee);
  return n;
}

// what an argument is
enum ArgKind : unsigned char {
  kArray,          // an array (required)
  kOptionalArray,  // an array or nothing (None / null: the kernel gets a null pointer)
  kReal,           // a finite real number (default: `value`; NaN: required)
  kTimeStep,       // 0 < dt <= kMaxTimeStep (required)
  kFlag,           // a bool (default: value != 0)
  kChoice,         // one of `choices` by name (default index: `value`)
  kIntegrator,     // an integrator by name (integrator_from_name; default index: `value`)
  kConvention,     // an output convention by name (convention_from_name; default index: `value`)
  kPositive,       // a finite real > 0 (default: `value`); `choices[0]` says what it is ("barrier weight")
  kFrame,          // a frame by name (required; an OpCall holds its index in Model::frames). The kernel gets
                   // the frame's body in choice[k] (-1: the world) and X_body_frame in in[k] (12 values:
                   // R row-major, then p): resolve_names
  kEndEffector,    // a joint by name whose body is an end effector (rbd::end_effector_bodies; an OpCall holds
                   // the body, -1: the first leaf body, the default). The kernel gets the body in choice[k]
  kEndEffectors,   // joints by name whose bodies are the end effectors (default: the leaf bodies, in body
                   // order); their number is the dimension kNee. An OpCall and the kernel's OpArgs hold the
                   // bodies in ee[0, n_ee)
};

// the value checks of an array, one pass over its values
enum ValueCheck : unsigned char {
  kFiniteValues,   // finite, magnitude at most kMaxInput
  kConfiguration,  // a configuration: finite, angles at most kMaxAngle, unit quaternions (in the op's
                   // convention when it has a kConvention parameter)
  kMujocoConfiguration,  // the same in MuJoCo's layout (quaternions w x y z), whatever the op's convention
  kWeights,        // finite, non-negative (a cost's diagonal weights)
  kLowerBound,     // a lower bound: finite or -inf (no bound)
  kUpperBound,     // an upper bound: finite or +inf, above the argument before it (a kLowerBound) entry by entry
};

struct ArgSpec {
  const char* name;
  ArgKind kind;
  Shape shape;                 // arrays
  ValueCheck check;            // arrays
  double value;                // parameters: the default
  const char* const* choices;  // kChoice: the names, null-terminated
};

constexpr ArgSpec array(const char* name, Shape s, ValueCheck c = kFiniteValues) {
  return {name, kArray, s, c, 0, nullptr};
}
constexpr ArgSpec optional_array(const char* name, Shape s, ValueCheck c = kFiniteValues) {
  return {name, kOptionalArray, s, c, 0, nullptr};
}
constexpr ArgSpec real(const char* name, double def) { return {name, kReal, scalar(), kFiniteValues, def, nullptr}; }
constexpr ArgSpec param(const char* name, ArgKind kind, double def = 0, const char* const* choices = nullptr) {
  return {name, kind, scalar(), kFiniteValues, def, choices};
}
// a frame by name, and a joint by name whose body is an end effector (default: the first leaf body)
constexpr ArgSpec frame(const char* name) {
  return {name, kFrame, shape(12), kFiniteValues, __builtin_nan(""), nullptr};  // required
}
constexpr ArgSpec end_effector(const char* name) {
  return {name, kEndEffector, scalar(), kFiniteValues, -1, nullptr};
}
constexpr ArgSpec end_effectors(const char* name) { return {name, kEndEffectors, scalar(), kFiniteValues, 0, nullptr}; }
// X_body_frame from a kFrame argument's 12 values
template <typename S> RBD_HD Transform<S> frame_transform(const S* x) {
  Transform<S> X;
  for (int k = 0; k < 9; ++k) X.R.m[k] = x[k];
  X.p = {x[9], x[10], x[11]};
  return X;
}
// a positive real; `what` names it in messages ("expected a positive <what>")
constexpr ArgSpec positive(const char* name, double def, const char* const* what) {
  return {name, kPositive, scalar(), kFiniteValues, def, what};
}

struct OutSpec {
  const char* name;
  Shape shape;
};

// the workspace an operation needs (workspace.hpp)
enum OpWorkspace : unsigned char {
  kLinear,            // the O(nb + nv) arrays
  kLinearUnlessMimic, // linear, full on a model with mimic joints (aba's dense path) or where M's factorisation pays (aba_layout)
  kFull,              // every array
};

// what a kernel returning false means
enum OpFailure : unsigned char {
  kNotPositiveDefinite,  // a mass matrix (or articulated inertia) that is not PD: names the joint
  kStepFailed,           // an integrator step: a joint that moves no mass, or a stage that overflowed
  kNoMass,               // a robot of total mass 0: its centre of mass is undefined
  kOscSingular,          // J M⁻¹ Jᵀ of an end effector is singular (a mass matrix that is not PD: as above)
};

// the scratch values (of the kernel's scalar) one sample needs
enum OpScratch : unsigned char {
  kNoScratch,
  kScratchNv,              // nv
  kScratch6Nv,             // 6 nv (a 6 x nv matrix)
  kScratch2NvNv,           // 2 nv²
  kScratchIntegrator,      // integrator_scratch_values(nq, nv)
  kScratchIntegratorGrad,  // integrator_gradient_scratch_values(nq, nv)
  kScratchNvNv,            // nv²
  kScratchDccrbaFd,        // dccrba_fd_scratch(nq, nv)
  kScratchCmmFd,           // 6 nv² + dccrba_fd_scratch(nq, nv)
  kScratchComCost,         // com_cost_scratch(nq, nv)
  kScratchMomentumCost,    // momentum_cost_scratch(nq, nv)
  kScratchEePosCost,       // ee_pos_cost_scratch(nq, nv)
  kScratchIntegratorHessian,  // integrator_hessian_scratch_values(nq, nv) + nq + nv + 6 nv²
  kScratchD2Integrate,        // 2 (2 nq + 2 nv + nv²): dual numbers
  kScratchEeHessianDual,      // ee_hessian_dual_scratch(nb, nq, nv): a model and a workspace in dual numbers
  kScratchIntegratorFExtGrad, // integrator_fext_gradient_scratch_values(nq, nv, nb) + nq + nv + 6 nv²
};

// what an operation's outputs may hold
enum OpOutputs : unsigned char {
  kFiniteOutputs,   // finite values: an inf or a NaN is an overflow, reported as an error
  kInfiniteOutside, // +inf and NaN where an input is outside the domain (a log barrier outside its bounds)
};

// what an operation needs of the model
enum OpModel : unsigned char {
  kAnyModel,
  kNoMimic,  // a model without mimic joints (the direct M⁻¹'s passes)
};

// how the engine compiles an operation's kernel for a pack
enum OpKernel : unsigned char {
  kFlattened,  // everything it calls inlined into one function (the engine's speed)
  kCalled,     // compiled as written: a kernel too large to flatten in reasonable time (the jets of the
               // step Hessian, the dual-number passes, the step gradients: 150 s each per dtype flattened,
               // for no fewer instructions), whose cost is its arithmetic, not its calls
};

struct OpSpec {
  const char* name;       // the operation (the rbdkit.RBD method)
  const char* algorithm;  // the handle algorithm providing it (handle.hpp's table)
  const char* family;     // the algorithm family (its header under algorithms/ or plant/)
  const char* doc;        // one paragraph: what it computes, shapes
  int n_args;
  ArgSpec args[kMaxArgs];  // in call order
  int n_out;
  OutSpec out[kMaxOutputs];
  unsigned returns;         // rbdkit.RBD returns these outputs (bit k: output k); one bit: the array alone
  unsigned handle_returns;  // rbdkit.Handle returns these (0: as `returns`)
  OpWorkspace workspace;
  OpScratch scratch;
  OpFailure failure;
  OpModel model = kAnyModel;
  OpOutputs outputs = kFiniteOutputs;
  // outputs of `returns` that a caller may leave null all the same (the kernel
  // skips them); the other returned ones are required (ops::check_call)
  unsigned optional_outputs = 0;
  OpKernel kernel = kFlattened;
};

// whether an operation takes an output convention (a kConvention argument)
constexpr bool takes_convention(const OpSpec& op) {
  for (int k = 0; k < op.n_args; ++k)
    if (op.args[k].kind == kConvention) return true;
  return false;
}

// the outputs a call must provide: those every surface asks for
constexpr unsigned required_outputs(const OpSpec& op) {
  return op.returns & (op.handle_returns ? op.handle_returns : op.returns) & ~op.optional_outputs;
}

// one sample's call, indexed by argument (the spec's order): an array's
// values in `in` (null where an optional one is absent), a real parameter in
// `real`, a flag or a choice in `choice`; the outputs (null where not
// requested) and the scratch
template <typename S> struct OpArgs {
  const S* in[kMaxArgs];
  S real[kMaxArgs];
  int choice[kMaxArgs];
  S* out[kMaxOutputs];
  S* scratch;
  const int* ee;  // the end effectors' bodies (a kEndEffectors argument), n_ee of them
  int n_ee;
};

}  // namespace ops
}  // namespace rbd
