// src/cuda/device.hpp — what the CUDA engine (src/cuda/cuda_engine.cpp) asks
// of a device: memory, copies, launches of an operation's kernel, streams.
// Two implementations: the interpret device (host memory, the kernels under
// an emulated launch; src/cuda/interpret.cpp) and the CUDA runtime
// (src/cuda/device.cu, compiled when nvcc is found; src/cuda/no_device.cpp
// otherwise). One virtual call per call or copy, never per sample.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "rbdkit/cuda/team_kernels.cuh"

namespace rbd {
namespace cuda {

struct Device {
  virtual ~Device() = default;
  virtual std::string name() const = 0;
  virtual int ordinal() const { return 0; }  // the CUDA device's index (interpret mode: 0)
  virtual DeviceLimits limits() const = 0;
  virtual void* alloc(size_t bytes) = 0;  // throws std::runtime_error when out of memory
  virtual void release(void* p) = 0;
  // page-locked host memory (copies to it are asynchronous DMA), freed by release_host; mapped into the
  // device's address space: kernels write it directly at device_address(p)
  virtual void* alloc_host(size_t bytes) = 0;
  virtual void release_host(void* p) = 0;
  virtual void* device_address(void* host) = 0;
  virtual void to_device(void* dst, const void* src, size_t bytes, void* stream) = 0;
  virtual void to_host(void* dst, const void* src, size_t bytes, void* stream) = 0;
  virtual void launch(int op, const DeviceCall<double>& c, LaunchShape shape, void* stream) = 0;
  virtual void launch(int op, const DeviceCall<float>& c, LaunchShape shape, void* stream) = 0;
  virtual void synchronize(void* stream) = 0;  // throws std::runtime_error on a launch's failure
  virtual void* create_stream() = 0;
  virtual void destroy_stream(void* stream) = 0;
  // work on `stream` waits for what was queued on `producer` so far (a CUDA
  // stream handle as __cuda_array_interface__ gives it: 1 the legacy default
  // stream, 2 the per-thread default stream, else a cudaStream_t)
  virtual void wait_for(unsigned long producer, void* stream) = 0;
  // makes the engine's device the calling thread's current one (before any call)
  virtual void activate() = 0;
};

// the launch of B samples of `work_bytes` each on a device (src/cuda/cuda_engine.cpp)
LaunchShape launch_shape(long B, unsigned long work_bytes, DeviceLimits d, WorkMemory mode);
// the same for a team kernel (team_kernels.cuh): a block per sample
LaunchShape team_launch_shape(long B, unsigned long work_bytes, DeviceLimits d, WorkMemory mode);

std::unique_ptr<Device> make_interpret_device();
// the CUDA runtime's device 0; throws std::runtime_error naming what is missing
std::unique_ptr<Device> make_cuda_device();
bool cuda_compiled();
int cuda_device_count();

// the interpret launches of every operation (ops::AllOps order), per dtype
template <typename T> const Launcher<T>* interpret_routes();
// the real launches (src/cuda/routes_<dtype>.cu; builds with nvcc only)
template <typename T> const Launcher<T>* device_routes();

}  // namespace cuda
}  // namespace rbd
