// rbdkit/cuda/instance.cuh — the entry point of a per-robot CUDA instance
// (Handle::specialize on a backend='cuda' handle; codegen/specialize.hpp). Its
// source is the robot's generated header, this header and one line:
//
//   RBDKIT_CUDA_INSTANCE(rbdkit_generated::Robot)
//
// which defines rbdkit_cuda_instance(): the ABI, a fingerprint of the types the
// engine and the instance pass each other, the robot's sizes, and per dtype the
// launches of the operations below. Each launch is the backend's own
// (device_routes.cuh under nvcc, interpret_routes.hpp under the host compiler
// for interpret mode) with the kernels' Model parameter set to the robot's
// constants (codegen/robot_model.hpp): the same kernel source, the same
// arguments (DeviceCall), the same outputs and statuses, with the sizes,
// parents, joint types and placements known to the compiler. The engine runs
// the instance's launch for these operations and its own for the rest.
// The entry points report errors as text (guarded): the instance may have been
// built by another compiler's runtime, which could not catch the library's
// exceptions, nor the library its.
#pragma once

#include <algorithm>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>

#include "rbdkit/codegen/instance.hpp"
#include "rbdkit/codegen/robot_model.hpp"
#if defined(__CUDACC__)
#include "rbdkit/cuda/device_routes.cuh"
#else
#include "rbdkit/cuda/interpret_routes.hpp"
#endif

namespace rbd {
namespace cuda {
namespace instance {

// changes whenever the entry point's types or meaning change (a key of the cache, checked on load)
constexpr int kAbi = 2;

// the operations an instance compiles: the dynamics, the mass matrix and its inverse, their first
// derivatives and the step with its gradient (every one with a team kernel among them)
using Ops = ops::OpList<ops::InverseDynamics, ops::Minv, ops::ForwardDynamics, ops::InverseDynamicsGradient,
                        ops::ForwardDynamicsGradient, ops::IntegratorGradient>;

template <class List> struct Names;
template <class... Op> struct Names<ops::OpList<Op...>> {
  static constexpr int count = sizeof...(Op);
  static constexpr const char* names[] = {Op::spec.name...};
};

// the types the engine and the instance pass each other, as each side compiled them
template <class... Op> constexpr unsigned long long fingerprint(ops::OpList<Op...>*) {
  using rbd::instance::mix;
  unsigned long long h = rbd::instance::kFnvBasis;
  h = mix(mix(mix(h, sizeof(DeviceCall<double>)), sizeof(DeviceCall<float>)), sizeof(LaunchShape));
  h = mix(mix(mix(h, sizeof(BodyDesc<double>)), sizeof(BodyDesc<float>)), sizeof(ModelView<double>));
  h = mix(mix(mix(h, static_cast<unsigned>(ops::kMaxArgs)), static_cast<unsigned>(ops::kMaxOutputs)),
          static_cast<unsigned>(kTeam));
  ((h = rbd::instance::mix_op<Op>(h)), ...);
  return h;
}
constexpr unsigned long long kLayout = fingerprint(static_cast<Ops*>(nullptr));

// f() with its exception turned into text: 0, or 1 with the message in error[0, size) (cut to fit,
// NUL-terminated). The instance's entry points run through it (see above)
template <typename F> int guarded(F&& f, char* error, int size) noexcept {
  // (the copy is made inside the handler: what() dies with the exception)
  auto report = [&](const char* what) {
    if (size <= 0) return;
    const size_t n = std::min(std::strlen(what), static_cast<size_t>(size - 1));
    std::memcpy(error, what, n);
    error[n] = '\0';
  };
  try {
    f();
    return 0;
  } catch (const std::exception& e) {
    report(e.what());
  } catch (...) {
    report("backend='cuda' (the robot's instance): an exception that is not a std::exception");
  }
  return 1;
}

// what rbdkit_cuda_instance() returns (abi first: the loader reads it before the rest)
struct Description {
  int abi;                    // kAbi
  unsigned long long layout;  // kLayout
  int nb, nq, nv, has_mimic;  // the robot's (has_mimic: ModelView's, the general paths)
  int device;                 // 1: real kernels (nvcc); 0: interpret launches (the host compiler)
  // makes CUDA device k the current one of the instance's runtime (before a launch); 0, or 1 and
  // the error in error[0, size) (guarded)
  int (*activate)(int device, char* error, int size);
  int n_ops;
  const char* const* names;           // (n_ops) registered operations' names
  const GuardedLauncher<double>* f64;  // (n_ops) their launches, per dtype (guarded)
  const GuardedLauncher<float>* f32;
};

#if defined(__CUDACC__)
// the instance links a CUDA runtime of its own: a launch's error is its runtime's to report, and the
// engine's current device is set in it too
inline void select_device(int device) {
  const cudaError_t e = cudaSetDevice(device);
  if (e != cudaSuccess)
    throw std::runtime_error(std::string("backend='cuda' (the robot's instance): selecting device ") +
                             std::to_string(device) + ": " + cudaGetErrorString(e));
}
template <class R, typename Op, typename T> void launch(const DeviceCall<T>& c, LaunchShape shape, void* stream) {
  device_launch<Op, T, rbd::instance::RobotModel<R>>(c, shape, stream);
  const cudaError_t e = cudaGetLastError();  // (read and cleared: a later launch reports its own)
  if (e != cudaSuccess)
    throw std::runtime_error(std::string("backend='cuda' (the robot's instance): kernel launch: ") +
                             cudaGetErrorString(e));
}
#else
inline void select_device(int) {}
template <class R, typename Op, typename T> void launch(const DeviceCall<T>& c, LaunchShape shape, void* stream) {
  interpret_launch<Op, T, rbd::instance::RobotModel<R>>(c, shape, stream);
}
#endif
inline int activate(int device, char* error, int size) {
  return guarded([&] { select_device(device); }, error, size);
}
template <class R, typename Op, typename T>
int guarded_launch(const DeviceCall<T>& c, LaunchShape shape, void* stream, char* error, int size) {
  return guarded([&] { launch<R, Op, T>(c, shape, stream); }, error, size);
}
template <class R, typename T, class... Op> const GuardedLauncher<T>* table(ops::OpList<Op...>) {
  static const GuardedLauncher<T> t[] = {&guarded_launch<R, Op, T>...};
  return t;
}

}  // namespace instance
}  // namespace cuda
}  // namespace rbd

// the instance's C entry point for the generated struct R (compiled with -fvisibility=hidden: its only
// exported symbol)
#if defined(__CUDACC__)
#define RBDKIT_CUDA_INSTANCE_DEVICE 1
#else
#define RBDKIT_CUDA_INSTANCE_DEVICE 0
#endif
#define RBDKIT_CUDA_INSTANCE(R)                                                                                   \
  extern "C" __attribute__((visibility("default"))) const rbd::cuda::instance::Description* rbdkit_cuda_instance() { \
    using N = rbd::cuda::instance::Names<rbd::cuda::instance::Ops>;                                               \
    static const rbd::cuda::instance::Description d = {rbd::cuda::instance::kAbi,                                 \
                                                       rbd::cuda::instance::kLayout,                              \
                                                       R::nb,                                                     \
                                                       R::nq,                                                     \
                                                       R::nv,                                                     \
                                                       R::has_mimic,                                              \
                                                       RBDKIT_CUDA_INSTANCE_DEVICE,                               \
                                                       &rbd::cuda::instance::activate,                            \
                                                       N::count,                                                  \
                                                       N::names,                                                  \
                                                       rbd::cuda::instance::table<R, double>(rbd::cuda::instance::Ops{}), \
                                                       rbd::cuda::instance::table<R, float>(rbd::cuda::instance::Ops{})}; \
    return &d;                                                                                                    \
  }
