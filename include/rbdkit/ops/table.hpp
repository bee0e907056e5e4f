// rbdkit/ops/table.hpp — the registry at run time: one entry per operation of
// ops::AllOps (ops/registry.hpp), the checks every surface runs on a call's
// arguments (one pass over the inputs, messages that name the argument, the
// sample and the joint), and the serial per-sample loop. Host only.
//
// A call (OpCall) holds, per argument of the spec: an array's data (float64 or
// float32, as the caller says) and whether it carries the batch axis (an
// unbatched array is broadcast over the batch), or a parameter's value; and
// per output its (B x shape) storage or null (not requested).
#pragma once

#include <string>
#include <vector>

#include "rbdkit/model/workspace.hpp"
#include "rbdkit/ops/op.hpp"
#include "rbdkit/parsers/model.hpp"

namespace rbd {
namespace ops {

template <typename S> using Kernel = bool (*)(const ModelView<S>&, Workspace<S>&, const OpArgs<S>&);

struct OpEntry {
  int id;
  const OpSpec* spec;
  Kernel<double> run;  // the per-sample kernel on double
};

// every registered operation, in ops::AllOps order (entry k has id k)
const std::vector<OpEntry>& op_table();
// the id of an operation, -1 if none has that name
int find_op(const std::string& name);

struct OpCall {
  long B = 1;                       // samples
  const void* in[kMaxArgs] = {};    // arrays: (B x shape) when batched[k], else (shape); null: absent
  bool batched[kMaxArgs] = {};
  double real[kMaxArgs] = {};       // kReal, kTimeStep, kPositive
  int choice[kMaxArgs] = {};        // kFlag (0/1), kChoice, kIntegrator, kConvention, kFrame (the frame's
                                    // index), kEndEffector (the body, -1: the first leaf)
  void* out[kMaxOutputs] = {};      // (B x shape) or null
  const int* ee = nullptr;          // a kEndEffectors argument: the bodies (n_ee of them, at least one)
  int n_ee = 0;
};

// values per sample of an argument or output on a model
long arg_values(const ArgSpec& a, const Model& m, int n_ee = 0);
long out_values(const OutSpec& o, const Model& m, int n_ee = 0);
// scratch values per sample, and the workspace layout an operation needs
long scratch_values(const OpSpec& op, const Model& m);
WorkspaceLayout workspace_layout(const OpSpec& op, const Model& m);
// the convention a call's configurations are in (its kConvention parameter; Pinocchio's when none)
int call_convention(const OpSpec& op, const OpCall& c);

// the value checks of a call's arrays and parameters (std::invalid_argument
// naming the argument, "name[s]" for sample s of a batched one, and the
// joint): T = double (bounds kMaxInput, kMaxAngle) or float (kMaxInputF32,
// kMaxAngleF32). Shapes are the caller's (the bindings check them).
// values = false: the parameters and the outputs only, not the arrays' values
// (device arrays: the CUDA kernels check those, inputs_ok in rbdkit/cuda/kernels.cuh)
template <typename T> void check_call(const Model& m, const OpSpec& op, const OpCall& c, bool values = true);

// values (samples x n, float64) finite and of magnitude at most `bound`:
// std::invalid_argument naming `name` (name[s] when batched) otherwise, in
// check_call's words. For values about to be rounded to float32.
// non_finite_ok: inf and NaN pass (bounds that may be infinite: check_call
// checks them after rounding); finite values still within `bound`.
void check_bounded(const double* x, long samples, long n, const char* name, bool batched, double bound,
                   bool non_finite_ok = false);

// the serial loop: the kernel on each sample in double, on the caller's
// workspace (of workspace_layout(op, m) or the full one) and scratch
// (scratch_values(op, m) values); throws std::runtime_error for a sample
// whose kernel fails (naming the joint: throw_not_positive_definite) and
// for non-finite outputs. Inputs are not checked here (check_call).
void run_serial(const Model& m, const OpEntry& op, const OpCall& c, Workspace<double>& w, double* scratch);

// names resolved for the kernels (after check_call): a kFrame argument's
// index becomes its body (choice) and X_body_frame (in: 12 values of T,
// unbatched, held in `frames`, which must outlive the call), a kEndEffector
// -1 the first leaf body. takes_names: whether an operation has such arguments
bool takes_names(const OpSpec& op);
template <typename T> OpCall resolve_names(const Model& m, const OpSpec& op, const OpCall& c, std::vector<T>& frames);

// a failed sample: the error the operation's OpFailure names (q: that
// sample's configuration or state, nq values first)
// sample (nq values first), the call for what it names (an end effector)
[[noreturn]] void throw_failure(const Model& m, const OpSpec& op, const double* q, long sample,
                                const OpCall* call = nullptr);
// outputs (B x shape, T values) are finite: std::runtime_error naming the operation and output otherwise
template <typename T> void check_outputs(const Model& m, const OpSpec& op, const OpCall& c);

}  // namespace ops
}  // namespace rbd
