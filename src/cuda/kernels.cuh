// src/cuda/kernels.cuh — the CUDA backend's kernel source: one registered
// operation (ops/registry.hpp) over a batch, one thread per sample. The same
// source compiles twice:
//   nvcc (src/cuda/routes_<dtype>.cu)       a __global__ kernel per operation and dtype
//   the host compiler (src/cuda/interpret_<dtype>.cpp)  the same body under an emulated
//                                            launch: blocks and threads run serially
//                                            (RBDKIT_CUDA_INTERPRET=1, docs/cuda.md)
// A kernel is written as "for each sample this thread owns" over a grid-stride
// loop; a kernel with a barrier would be written as phases of such loops, and
// the emulated launch runs a phase for every thread of a block before the
// next one (emulate_launch below).
//
// Layout (docs/cuda.md): inputs and outputs are the caller's row-major
// (B x shape) arrays (an unbatched input has stride 0); each sample owns a
// slice of one global work buffer, its workspace (model/workspace.hpp,
// carved per sample) then its scratch; the model's bodies are uploaded once
// per handle and reach the kernel as a `const __restrict__` parameter: read
// only for the kernel's lifetime, so nvcc loads them through the read-only
// data cache (ld.global.nc), and every thread of a warp reads the same body
// at the same time (one broadcast load). A sample whose kernel fails, or
// whose outputs are not finite, writes its status; the host names those
// samples.
#pragma once

#include "rbdkit/ops/registry.hpp"

namespace rbd {
namespace cuda {

// a sample's status (DeviceCall::status)
enum SampleStatus : int {
  kSampleOk = 0,
  kSampleFailed = 1,    // the kernel returned false (OpSpec::failure names why)
  kSampleNonFinite = 2  // + o: output o holds an inf or a NaN (an overflow)
};

// one launch of an operation on device memory (pointers the kernel reads:
// device pointers, host pointers in interpret mode)
template <typename T> struct DeviceCall {
  long B;
  const T* in[ops::kMaxArgs];      // (B x values) or (values) when in_stride is 0; null: absent
  long in_stride[ops::kMaxArgs];   // values from one sample to the next
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
  unsigned char* work;             // (B x work_bytes)
  int* status;                     // (B): SampleStatus
};

// whether x[0..n) are all finite (x - x is 0 only for a finite x)
template <typename T> RBD_HD bool all_finite(const T* x, long n) {
  T acc = T(0);
  for (long k = 0; k < n; ++k) acc += x[k] - x[k];
  return acc == acc;
}

// sample s of Op on model m (c.model, its bodies as the kernel reads them):
// its arguments, workspace and scratch, the kernel, its status
template <typename Op, typename T> RBD_HD void op_sample(const DeviceCall<T>& c, const ModelView<T>& m, long s) {
  constexpr int n_out = Op::spec.n_out;
  constexpr bool finite_outputs = Op::spec.outputs == ops::kFiniteOutputs;
  unsigned char* work = c.work + static_cast<unsigned long>(s) * c.work_bytes;
  Workspace<T> w = carve_workspace<T>(work, m.nb, m.nv, c.layout);
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
  int status = kSampleOk;
  if (!Op::run(m, w, a)) {
    status = kSampleFailed;
  } else if (finite_outputs) {
    for (int o = n_out - 1; o >= 0; --o)
      if (a.out[o] && !all_finite(a.out[o], c.out_values[o])) status = kSampleNonFinite + o;
  }
  c.status[s] = status;
}

// the samples one thread owns: first, first + stride, ... below B
template <typename Op, typename T>
RBD_HD void op_samples(const DeviceCall<T>& c, const ModelView<T>& m, long first, long stride) {
  for (long s = first; s < c.B; s += stride) op_sample<Op>(c, m, s);
}

#if defined(__CUDACC__)
// `bodies` is c.model.body, passed apart so that it can be declared read only
// and unaliased for the kernel (a qualifier on a struct member is not honoured)
template <typename Op, typename T>
__global__ void op_kernel(DeviceCall<T> c, const BodyDesc<T>* __restrict__ bodies) {
  const ModelView<T> m{c.model.nb, c.model.nq, c.model.nv, c.model.has_mimic, bodies};
  op_samples<Op>(c, m, static_cast<long>(blockIdx.x) * blockDim.x + threadIdx.x,
                 static_cast<long>(gridDim.x) * blockDim.x);
}
#endif

// ---- the emulated launch (interpret mode): grid x block threads, run
// serially; `phase(block, thread)` is one phase of the kernel for one thread
// (a barrier-free kernel has one)
struct LaunchShape {
  long blocks;
  int threads;
};
template <typename Phase> void emulate_launch(LaunchShape shape, Phase&& phase) {
  for (long b = 0; b < shape.blocks; ++b)
    for (int t = 0; t < shape.threads; ++t) phase(b, t);
}

// the launch of B samples: 128 threads per block (one warp-multiple block
// that keeps the per-thread workspaces' footprint moderate), enough blocks to
// give every sample a thread, at most kMaxBlocks (then the grid strides)
constexpr int kThreadsPerBlock = 128;
constexpr long kMaxBlocks = 65535;
inline LaunchShape launch_shape(long B) {
  long blocks = (B + kThreadsPerBlock - 1) / kThreadsPerBlock;
  if (blocks > kMaxBlocks) blocks = kMaxBlocks;
  return {blocks < 1 ? 1 : blocks, kThreadsPerBlock};
}

// Op's launch in interpret mode: the kernel's body for every (block, thread)
template <typename Op, typename T> void interpret_op(const DeviceCall<T>& c) {
  const LaunchShape shape = launch_shape(c.B);
  const long stride = shape.blocks * shape.threads;
  emulate_launch(shape, [&](long b, int t) { op_samples<Op>(c, c.model, b * shape.threads + t, stride); });
}

template <typename T> using Launcher = void (*)(const DeviceCall<T>&, void* stream);

}  // namespace cuda
}  // namespace rbd
