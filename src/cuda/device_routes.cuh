// src/cuda/device_routes.cuh — the real launches of every registered
// operation for one dtype: op_kernel<Op, T> (kernels.cuh) on the engine's
// stream, instantiated in src/cuda/routes_<dtype>.cu
#pragma once

#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

#include "device.hpp"

namespace rbd {
namespace cuda {

template <typename Op, typename T> void device_launch(const DeviceCall<T>& c, LaunchShape shape, void* stream) {
  if (shape.shared_bytes > 48 * 1024) {
    // past the default 48 kB, a kernel's dynamic shared memory must be allowed, per kernel and
    // device: always to the device's maximum, so that engines on other threads never lower it
    const cudaError_t e = cudaFuncSetAttribute(op_kernel<Op, T>, cudaFuncAttributeMaxDynamicSharedMemorySize,
                                               static_cast<int>(shape.shared_limit));
    if (e != cudaSuccess)
      throw std::runtime_error(std::string("backend='cuda': allowing ") + std::to_string(shape.shared_bytes) +
                               " bytes of shared memory per block: " + cudaGetErrorString(e));
  }
  op_kernel<Op, T><<<static_cast<unsigned>(shape.blocks), shape.threads, shape.shared_bytes,
                     static_cast<cudaStream_t>(stream)>>>(c, c.model.body);
}

template <typename T, typename... Op> const Launcher<T>* device_table(ops::OpList<Op...>) {
  static const Launcher<T> table[] = {&device_launch<Op, T>...};
  return table;
}

}  // namespace cuda
}  // namespace rbd
