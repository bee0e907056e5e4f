// rbdkit/cuda/cuda_engine.hpp — the CUDA backend: every registered operation
// (ops/registry.hpp) over a batch on a GPU, one thread per sample, float64 or
// float32. Host only; the kernels are rbdkit/cuda/kernels.cuh.
//
//   rbd::CudaEngine e(model, "float64");            // the device, or interpret mode
//   e.run_op(op, call);                             // host arrays: copied in and out
//   e.run_op(op, call, /*device_arrays=*/true);     // device arrays, used in place
//
// Where it runs:
//   - RBDKIT_CUDA_INTERPRET=1 (or `interpret` = true): the kernels' source on
//     the CPU, blocks and threads serially (the same code nvcc compiles;
//     "device memory" is host memory). No GPU needed: CI tests every
//     operation this way against the CPU engine.
//   - otherwise a CUDA device, if this build has the real kernels (nvcc was
//     found: cuda_compiled()) and the machine has a device; without either, the
//     constructor throws std::runtime_error naming what is missing.
//
// Calls (ops::OpCall) are the Handle's, already checked (ops::check_call)
// and with names resolved (ops::resolve_names). Host arrays are copied into
// device buffers that grow on the first call of a size and are reused after
// (no device allocation per call); device arrays (device_arrays = true: the
// arrays and outputs, not the end effectors' list or a frame's placement,
// which are host memory) are read and written in place. Launches go on the
// engine's stream (set_stream: the caller's cudaStream_t, 0 the default
// stream; use_own_stream: a blocking stream of its own, the default) on the
// device that was current when the engine was made, and a call returns when
// they are done.
// Device arrays' values are checked by the kernels (the same checks as the
// host's ops::check_call, without copying them to the host first); a sample
// that fails is copied back, to name the argument and the sample.
// A sample whose kernel fails (a mass matrix that is not positive definite)
// or whose outputs overflow makes the call throw, naming the samples: the
// kernels write a status per sample, never a silent wrong number.
// One call at a time per engine (calls from several threads serialise).
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "rbdkit/ops/table.hpp"
#include "rbdkit/parsers/model.hpp"

namespace rbd {

struct CudaInstance;  // codegen/specialize.hpp

class CudaEngine {
 public:
  // dtype "float64" or "float32"; interpret: run the kernels on the CPU
  // (default: the environment variable RBDKIT_CUDA_INTERPRET=1)
  CudaEngine(const Model& model, const std::string& dtype, bool interpret = interpret_requested());
  ~CudaEngine();
  CudaEngine(const CudaEngine&) = delete;
  CudaEngine& operator=(const CudaEngine&) = delete;

  // whether RBDKIT_CUDA_INTERPRET is set to 1 in the environment
  static bool interpret_requested();
  // whether this build compiled the real kernels (nvcc found at build time)
  static bool cuda_compiled();
  // the CUDA devices this process sees (0 without a driver, a device, or real kernels)
  static int device_count();

  bool interpret() const;
  const std::string& dtype() const;
  // "interpret (CPU)" or the device's name
  std::string device_name() const;
  // the CUDA device's index every call runs on (interpret mode: 0)
  int device_ordinal() const;
  // the stream launches go on: a cudaStream_t (null: the default stream), or the engine's own
  void set_stream(void* stream);
  void use_own_stream();
  void* stream() const;
  // launches from now on wait for the work queued so far on `producer` (a
  // __cuda_array_interface__ stream: 1 legacy default, 2 per-thread default,
  // else a cudaStream_t): the ordering a device array's producer asks for
  void wait_for_stream(unsigned long producer);
  // samples per launch are bounded so that their work buffers take at most
  // `bytes` (default 1 GiB; 0: the default); larger batches take several launches
  void set_max_work_bytes(unsigned long bytes);
  // where each sample's work (workspace and scratch) lives: "shared" (the
  // block's shared memory, when a sample's fits), "global" (one device
  // buffer), or "auto" (the default: shared when it fits and the batch runs
  // in at most three waves there; docs/cuda.md, "Kernel layout").
  // The environment variable RBDKIT_CUDA_WORK sets it when an engine is made
  void set_work_memory(const std::string& where);
  std::string work_memory() const;
  // which kernel computes an operation that has a team kernel (ID, M⁻¹, FD,
  // ∇ID, ∇FD, the step's gradient: a block of threads per sample;
  // docs/cuda.md, "Team kernels"): "team", "sample" (one thread per sample,
  // as every other operation), or "auto" (the default: the team kernel on a
  // model without mimic joints, for a batch of at most 8 samples per SM (32
  // for a step), or at any B when nv >= 16 except for ID; a step in MuJoCo's
  // convention keeps the sample kernel unless the team is asked for).
  // The environment variable RBDKIT_CUDA_KERNEL sets it when an engine is made
  void set_kernel(const std::string& which);
  std::string kernel() const;
  // the kernel that computes registered operation `op` over B samples in the output convention
  // `convention` (OutputConvention; 0: Pinocchio's) on this engine now: "team" or "sample"
  std::string kernel_for(int op, long B, int convention = 0) const;
  // device bytes the engine holds (work buffers, copies, the model)
  unsigned long device_bytes() const;

  // the registered operation `op` on call.B samples (arrays of the engine's
  // dtype): host arrays, or device arrays when device_arrays
  void run_op(int op, const ops::OpCall& call, bool device_arrays = false);
  // the robot's compiled CUDA instance (codegen/specialize.hpp, load_cuda_instance; null: none): its
  // kernels compute the operations it holds from now on, the generic ones the rest. Its kind must be
  // the engine's (interpret launches for interpret mode, GPU kernels on a device): std::invalid_argument
  void use_instance(std::shared_ptr<const CudaInstance> instance);
  bool has_instance() const;
  // bytes of device memory to host memory, on the engine's stream (returns when done)
  void copy_to_host(void* dst, const void* device_src, size_t bytes);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace rbd
