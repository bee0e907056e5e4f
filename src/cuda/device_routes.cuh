// src/cuda/device_routes.cuh — the real launches of every registered
// operation for one dtype: op_kernel<Op, T> (kernels.cuh) on the engine's
// stream, instantiated in src/cuda/routes_<dtype>.cu
#pragma once

#include <cuda_runtime.h>

#include "device.hpp"

namespace rbd {
namespace cuda {

template <typename Op, typename T> void device_launch(const DeviceCall<T>& c, void* stream) {
  const LaunchShape shape = launch_shape(c.B);
  op_kernel<Op, T><<<static_cast<unsigned>(shape.blocks), shape.threads, 0, static_cast<cudaStream_t>(stream)>>>(
      c, c.model.body);
}

template <typename T, typename... Op> const Launcher<T>* device_table(ops::OpList<Op...>) {
  static const Launcher<T> table[] = {&device_launch<Op, T>...};
  return table;
}

}  // namespace cuda
}  // namespace rbd
