// rbdkit/codegen/specialize.hpp — per-robot compiled instances
// (Handle::specialize, rbdkit.Handle(model, specialize=True)).
//
// An instance is the robot's generated header (codegen/generate.hpp) and the
// per-sample kernels of the registered operations single calls use most
// (codegen/instance.hpp), compiled by the system's C++ compiler into a shared
// library and loaded with dlopen. A CUDA instance (below) is the same for
// the CUDA backend's kernels. Its kernels are the registry's own, run on
// the robot's bodies written as literals, so the compiler sees every joint
// type, parent and size as a constant. A handle's float64 serial loop (one
// sample, or every call of a handle with threads = 0) then runs them instead
// of the generic kernels; everything else is unchanged.
//
// Libraries are cached: <cache>/<robot>-<key>.so, where the key hashes the
// instance's source (so the model), the compiler, its flags, the instance
// ABI and every rbdkit header the source includes. A second handle on the
// same model loads the cached library (in one process, the one already
// loaded); a changed model, compiler, flag or header compiles a new one.
#pragma once

#include <memory>
#include <string>

#include "rbdkit/ops/table.hpp"
#include "rbdkit/parsers/model.hpp"

namespace rbd {

struct SpecializeOptions {
  // the library cache ("": $RBDKIT_CACHE_DIR, else $XDG_CACHE_HOME/rbdkit, else ~/.cache/rbdkit)
  std::string cache_dir;
  // the C++ compiler ("": $CXX, else c++); it must take g++'s options
  std::string compiler;
  // the folder holding rbdkit/ (its headers; "": the source tree this library was built from)
  std::string include_dir;
  std::string flags = "-O3 -march=native";
  // a CUDA instance's compiler for the real kernels ("": $CUDACXX, else nvcc on the PATH, else
  // /usr/local/cuda/bin/nvcc) and its flags
  std::string cuda_compiler;
  std::string cuda_flags = "-O3 -arch=native -split-compile=0";  // (-split-compile=0: optimise on every core)
};

// a loaded instance (its library stays loaded while an instance refers to it)
struct Instance;

// the C++ source of model's instance: its generated header, then the entry points
std::string instance_source(const Model& model);

// the instance of `model`: the cached library, else compiled into the cache first. Throws
// std::runtime_error saying why none could be made (no compiler, a failed compilation with the
// compiler's first lines of output, a library that does not load, a model without bodies).
std::shared_ptr<const Instance> load_instance(const Model& model, const SpecializeOptions& options = {});

// the instance's kernel for registered operation `op` (ops::op_table()'s id); null where it has none
ops::Kernel<double> instance_kernel(const Instance& instance, int op);
// the library's path
const std::string& instance_path(const Instance& instance);

// ---- a CUDA instance (rbdkit/cuda/instance.cuh): the CUDA backend's kernels for the operations
// single calls and trajectory optimisation use most, on the robot's constants. device: the real
// kernels, compiled by nvcc (cuda_compiler, cuda_flags) for this machine's GPU (device_key, the GPU's
// name, is part of the cache key: required); else the interpret launches, compiled by the C++
// compiler (compiler, flags; interpret mode, RBDKIT_CUDA_INTERPRET=1). Cached and checked as a CPU
// instance; throws std::runtime_error saying why none could be made (a robot whose bodies do not fit
// the GPU's constant memory, past about 140 bodies, among them)
struct CudaInstance;
std::shared_ptr<const CudaInstance> load_cuda_instance(const Model& model, const SpecializeOptions& options,
                                                       bool device, const std::string& device_key = "");
// "" when the instance is model's robot (its sizes and its general paths), else what differs (the
// engine's work sizes are the model's, the instance's kernels carve them for its own robot)
std::string cuda_instance_mismatch(const CudaInstance& instance, const Model& model);
// the C++ source of model's CUDA instance
std::string cuda_instance_source(const Model& model);
// the instance's launch of registered operation `op` for one dtype (a cuda::GuardedLauncher<double> or
// <float>, rbdkit/cuda/kernels.cuh), null where it has none; whether it holds GPU kernels (else
// interpret launches); the device selection in its own CUDA runtime (throws std::runtime_error)
const void* cuda_instance_launch(const CudaInstance& instance, int op, bool f32);
bool cuda_instance_device(const CudaInstance& instance);
void cuda_instance_activate(const CudaInstance& instance, int device);
const std::string& instance_path(const CudaInstance& instance);

}  // namespace rbd
