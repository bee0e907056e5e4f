// rbdkit/cuda/kernels.cuh — the CUDA backend's kernel source: one registered
// operation (ops/registry.hpp) over a batch, one thread per sample. The same
// source compiles twice:
//   nvcc (src/cuda/routes_<dtype>.cu)       a __global__ kernel per operation and dtype
//   the host compiler (src/cuda/interpret_<dtype>.cpp)  the same body under an emulated
//                                            launch: blocks and threads run serially
//                                            (RBDKIT_CUDA_INTERPRET=1, docs/cuda.md)
// and both again in a per-robot instance (cuda/instance.cuh), on the robot's constants.
// A kernel is written as "for each sample this thread owns" over a grid-stride
// loop; a kernel with barriers is written as phases of such loops, which the
// emulation runs for every thread of a block before the next one (the team
// kernels of ∇ID, ∇FD and the steps: team_kernels.cuh).
//
// Layout (docs/cuda.md): inputs and outputs are the caller's row-major
// (B x shape) arrays (an unbatched input has stride 0); each sample's work
// slice, its workspace (model/workspace.hpp, carved per sample) then its
// scratch, lives in the block's shared memory when the block's samples fit
// there (launch_shape), else in one global work buffer; the model's bodies
// are uploaded once per handle and reach the kernel as a `const __restrict__`
// parameter: read only for the kernel's lifetime, so nvcc loads them through
// the read-only data cache (ld.global.nc), and every thread of a warp reads
// the same body at the same time (one broadcast load). A sample whose inputs
// fail the value checks (device arrays: inputs_ok), whose kernel fails, or
// whose outputs are not finite, writes its status; the host names those
// samples.
#pragma once

#include <utility>

#include "rbdkit/model/input_bounds.hpp"
#include "rbdkit/ops/registry.hpp"

namespace rbd {
namespace cuda {

// a sample's status (DeviceCall::status)
enum SampleStatus : int {
  kSampleOk = 0,
  kSampleFailed = 1,    // the kernel returned false (OpSpec::failure names why)
  kSampleNonFinite = 2,  // + o: output o holds an inf or a NaN (an overflow)
  kSampleBadInput = -1   // an input fails check_call's value checks (inputs_ok; not computed)
};

// one launch of an operation on device memory (pointers the kernel reads:
// device pointers, host pointers in interpret mode)
template <typename T> struct DeviceCall {
  long B;
  const T* in[ops::kMaxArgs];      // (B x values) or (values) when in_stride is 0; null: absent
  long in_stride[ops::kMaxArgs];   // values from one sample to the next
  long in_values[ops::kMaxArgs];   // values per sample
  int check_inputs;                // 1: check the arrays' values (inputs_ok) before computing
  T real[ops::kMaxArgs];           // kReal, kTimeStep, kPositive
  int choice[ops::kMaxArgs];       // flags, choices, a frame's body, an end effector's body
  T* out[ops::kMaxOutputs];        // (B x out_values) or null
  long out_values[ops::kMaxOutputs];
  const int* ee;                   // kEndEffectors: the bodies (device memory)
  int n_ee;
  ModelView<T> model;              // body: device memory, read only (op_kernel's `bodies`)
  WorkspaceLayout layout;
  unsigned long work_bytes;        // per sample: the workspace, then the scratch (16-byte multiple)
  unsigned long ws_bytes;          // the workspace part
  unsigned char* work;             // (B x work_bytes), or null when the work is in shared memory
  int work_shared;                 // 1: each thread's work slice is in its block's shared memory
  int* status;                     // (B): SampleStatus
  int* failed;                     // (1): set to call_id by a sample whose status is not kSampleOk
  int call_id;                     // this call's (the host reads one int, and the statuses only when set)
};

// whether x[0..n) are all finite (x - x is 0 only for a finite x)
template <typename T> RBD_HD bool all_finite(const T* x, long n) {
  T acc = T(0);
  for (long k = 0; k < n; ++k) acc += x[k] - x[k];
  return acc == acc;
}

// the value checks of ops::check_call (src/ops/ops.cpp) on sample s's arrays, as a predicate, in
// double as there (the same within_bound and configuration_within_bounds, model/input_bounds.hpp):
// finite values of magnitude at most the dtype's bound, non-negative weights, ordered bounds,
// configurations with bounded angles and unit quaternions. For device arrays, which the host
// cannot read without a copy; a sample that fails is not computed, and the host words the error
// from a copy of the inputs (CudaEngine::Impl::fail_inputs)
template <typename T> RBD_HD constexpr double input_bound() { return sizeof(T) == 4 ? kMaxInputF32 : kMaxInput; }
template <typename T> RBD_HD constexpr double angle_bound() { return sizeof(T) == 4 ? kMaxAngleF32 : kMaxAngle; }
template <typename T> RBD_HD bool bounded_values(const T* x, long n) { return within_bound(x, n, input_bound<T>()); }
template <typename T> RBD_HD bool configuration_ok(const ModelView<T>& m, const T* q) {
  return configuration_within_bounds(m.body, m.nb, m.nq, q, input_bound<T>(), angle_bound<T>());
}
// argument K of Op (its kind and check read at compile time: the spec is host data)
template <typename Op, int K, typename T> RBD_HD bool arg_ok(const DeviceCall<T>& c, const ModelView<T>& m, long s) {
  constexpr ops::ArgKind kind = Op::spec.args[K].kind;
  constexpr ops::ValueCheck check = Op::spec.args[K].check;
  if constexpr (kind != ops::kArray && kind != ops::kOptionalArray) {
    return true;
  } else {
    if (!c.in[K]) return true;
    const T* x = c.in[K] + s * c.in_stride[K];
    const long n = c.in_values[K];
    bool ok = true;
    if constexpr (check == ops::kFiniteValues) {
      ok = bounded_values(x, n);
    } else if constexpr (check == ops::kWeights) {
      ok = bounded_values(x, n);
      for (long j = 0; j < n; ++j) ok &= x[j] >= T(0);
    } else if constexpr (check == ops::kUpperBound && K > 0) {  // with its lower bound, the argument before
      const T* lo = c.in[K - 1] + s * c.in_stride[K - 1];
      for (long j = 0; j < n; ++j) {
        const double l = lo[j], h = x[j];  // each finite within the bound or infinite; l < h; no NaN
        ok &= (fabs(l) <= input_bound<T>() || isinf(l)) && (fabs(h) <= input_bound<T>() || isinf(h));
        ok &= l < h && l != INFINITY && h != -INFINITY;
      }
    } else if constexpr (check == ops::kConfiguration || check == ops::kMujocoConfiguration) {
      ok = configuration_ok(m, x) && bounded_values(x, n);  // (a quaternion's norm is the same in either layout)
    }
    return ok;  // (kLowerBound: with its upper bound)
  }
}
template <typename Op, typename T, int... K>
RBD_HD bool args_ok(const DeviceCall<T>& c, const ModelView<T>& m, long s, std::integer_sequence<int, K...>) {
  return (arg_ok<Op, K>(c, m, s) & ... & true);
}
template <typename Op, typename T> RBD_HD bool inputs_ok(const DeviceCall<T>& c, const ModelView<T>& m, long s) {
  return args_ok<Op>(c, m, s, std::make_integer_sequence<int, Op::spec.n_args>{});
}

// sample s's arguments: its rows of the arrays, the call's reals and choices, the scratch after the
// workspace in its work slice
template <typename T> RBD_HD ops::OpArgs<T> sample_args(const DeviceCall<T>& c, long s, unsigned char* work) {
  ops::OpArgs<T> a;
  for (int k = 0; k < ops::kMaxArgs; ++k) {
    a.in[k] = c.in[k] ? c.in[k] + s * c.in_stride[k] : nullptr;
    a.real[k] = c.real[k];
    a.choice[k] = c.choice[k];
  }
  for (int o = 0; o < ops::kMaxOutputs; ++o) a.out[o] = c.out[o] ? c.out[o] + s * c.out_values[o] : nullptr;
  a.scratch = reinterpret_cast<T*>(work + c.ws_bytes);
  a.ee = c.ee;
  a.n_ee = c.n_ee;
  return a;
}

// sample s of Op on model m (c.model, its bodies as the kernel reads them)
// in `work` (its work slice: workspace, then scratch): its arguments, the
// kernel, its status
template <typename Op, typename T>
RBD_HD void op_sample(const DeviceCall<T>& c, const ModelView<T>& m, long s, unsigned char* work) {
  constexpr int n_out = Op::spec.n_out;
  constexpr bool finite_outputs = Op::spec.outputs == ops::kFiniteOutputs;
  if (c.check_inputs && !inputs_ok<Op>(c, m, s)) {
    c.status[s] = kSampleBadInput;
    *c.failed = c.call_id;
    return;
  }
  Workspace<T> w = carve_workspace<T>(work, m.nb, m.nv, c.layout);
  const ops::OpArgs<T> a = sample_args(c, s, work);
  int status = kSampleOk;
  if (!Op::run(m, w, a)) {
    status = kSampleFailed;
  } else if (finite_outputs) {
    for (int o = n_out - 1; o >= 0; --o)
      if (a.out[o] && !all_finite(a.out[o], c.out_values[o])) status = kSampleNonFinite + o;
  }
  c.status[s] = status;
  if (status != kSampleOk) *c.failed = c.call_id;  // (every failing sample writes the same value)
}

// the samples one thread owns: first, first + stride, ... below B; `slot`:
// the thread's work slice in shared memory (c.work_shared), reused for each
template <typename Op, typename T>
RBD_HD void op_samples(const DeviceCall<T>& c, const ModelView<T>& m, long first, long stride, unsigned char* slot) {
  for (long s = first; s < c.B; s += stride)
    op_sample<Op>(c, m, s, c.work_shared ? slot : c.work + static_cast<unsigned long>(s) * c.work_bytes);
}

// where a kernel's model comes from (its Model parameter): CallModel, the call's view with its bodies
// in device memory (the generic kernels); or instance::RobotModel<R> (codegen/robot_model.hpp), a
// robot's sizes and bodies as compile-time constants (a per-robot instance's kernels)
struct CallModel {
  template <typename T> RBD_HD static ModelView<T> view(const ModelView<T>& call) { return call; }
};

#if defined(__CUDACC__)
// `bodies` is c.model.body, passed apart so that it can be declared read only
// and unaliased for the kernel (a qualifier on a struct member is not honoured).
// Dynamic shared memory: blockDim.x work slices when c.work_shared
template <typename Op, typename T, typename Model = CallModel>
__global__ void op_kernel(DeviceCall<T> c, const BodyDesc<T>* __restrict__ bodies) {
  extern __shared__ __align__(16) unsigned char shared_work[];
  const ModelView<T> m = Model::view(ModelView<T>{c.model.nb, c.model.nq, c.model.nv, c.model.has_mimic, bodies});
  op_samples<Op>(c, m, static_cast<long>(blockIdx.x) * blockDim.x + threadIdx.x,
                 static_cast<long>(gridDim.x) * blockDim.x, shared_work + threadIdx.x * c.work_bytes);
}
#endif

// ---- the launch
// what the engine needs of the device to shape a launch
struct DeviceLimits {
  int multiprocessors;         // SMs
  unsigned long shared_bytes;  // dynamic shared memory a block may have (the opt-in maximum)
};
// where the samples' work slices live: the launch shape decides (kWorkAuto),
// or the caller (CudaEngine::set_work_memory; RBDKIT_CUDA_WORK=global|shared)
enum WorkMemory : int { kWorkAuto = 0, kWorkGlobal = 1, kWorkShared = 2 };

struct LaunchShape {
  long blocks;
  int threads;
  unsigned long shared_bytes;  // per block; 0: the work slices are in global memory
  unsigned long shared_limit;  // the device's (DeviceLimits::shared_bytes): what a kernel is allowed
  int team = 0;                // 1: the op's team kernel (team_kernels.cuh), a block of kTeam threads per sample
};

// the emulated launch (interpret mode): grid x block threads, run serially;
// `phase(block, thread, shared)` is one phase of the kernel for one thread
// (a barrier-free kernel has one), `shared` its block's shared memory
template <typename Phase> void emulate_launch(LaunchShape shape, Phase&& phase) {
  struct alignas(16) Chunk {
    unsigned char b[16];
  };
  Chunk* shared = shape.shared_bytes ? new Chunk[(shape.shared_bytes + 15) / 16] : nullptr;
  for (long b = 0; b < shape.blocks; ++b)
    for (int t = 0; t < shape.threads; ++t) phase(b, t, reinterpret_cast<unsigned char*>(shared));
  delete[] shared;
}

// the most threads per block, and blocks per launch (past it the grid strides);
// the shape of a launch: launch_shape (src/cuda/cuda_engine.cpp)
constexpr int kThreadsPerBlock = 128;
constexpr long kMaxBlocks = 65535;

// Op's launch in interpret mode: the kernel's body for every (block, thread)
template <typename Op, typename T, typename Model = CallModel>
void interpret_op(const DeviceCall<T>& c, LaunchShape shape) {
  const long stride = shape.blocks * shape.threads;
  const ModelView<T> m = Model::view(c.model);
  emulate_launch(shape, [&](long b, int t, unsigned char* shared) {
    op_samples<Op>(c, m, b * shape.threads + t, stride, shared ? shared + t * c.work_bytes : nullptr);
  });
}

template <typename T> using Launcher = void (*)(const DeviceCall<T>&, LaunchShape shape, void* stream);
// a launch that reports its error as text rather than throwing it: 0, or 1 with the message in
// error[0, size), NUL-terminated. A per-robot instance's entry points are these (cuda/instance.cuh):
// no C++ exception crosses the boundary of a library loaded with dlopen
template <typename T>
using GuardedLauncher = int (*)(const DeviceCall<T>&, LaunchShape shape, void* stream, char* error, int size);

}  // namespace cuda
}  // namespace rbd
