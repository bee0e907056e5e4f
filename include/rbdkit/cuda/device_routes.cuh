// rbdkit/cuda/device_routes.cuh — the real launches of every registered
// operation for one dtype: op_kernel<Op, T> (kernels.cuh) on the engine's
// stream, instantiated in src/cuda/routes_<dtype>.cu (and, on a robot's
// constants, in a per-robot instance: cuda/instance.cuh)
#pragma once

#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

#include "rbdkit/cuda/team_kernels.cuh"

namespace rbd {
namespace cuda {

// a kernel's dynamic shared memory past the default 48 kB must be allowed, per kernel and device:
// always to the device's maximum, so that engines on other threads never lower it
template <typename K> void allow_shared(K kernel, LaunchShape shape) {
  if (shape.shared_bytes <= 48 * 1024) return;
  const cudaError_t e =
      cudaFuncSetAttribute(kernel, cudaFuncAttributeMaxDynamicSharedMemorySize, static_cast<int>(shape.shared_limit));
  if (e != cudaSuccess)
    throw std::runtime_error(std::string("backend='cuda': allowing ") + std::to_string(shape.shared_bytes) +
                             " bytes of shared memory per block: " + cudaGetErrorString(e));
}

// Model: where the kernels' model comes from (kernels.cuh's CallModel, or a per-robot instance's)
template <typename Op, typename T, typename Model = CallModel>
void device_launch(const DeviceCall<T>& c, LaunchShape shape, void* stream) {
  const dim3 grid(static_cast<unsigned>(shape.blocks)), block(shape.threads);
  if constexpr (TeamOp<Op>::available) {
    if (shape.team) {  // (the engine asks for a team only where Op has one)
      allow_shared(team_kernel<Op, T, Model>, shape);
      team_kernel<Op, T, Model>
          <<<grid, block, shape.shared_bytes, static_cast<cudaStream_t>(stream)>>>(c, c.model.body);
      return;
    }
  }
  allow_shared(op_kernel<Op, T, Model>, shape);
  op_kernel<Op, T, Model><<<grid, block, shape.shared_bytes, static_cast<cudaStream_t>(stream)>>>(c, c.model.body);
}

template <typename T, typename Model = CallModel, typename... Op> const Launcher<T>* device_table(ops::OpList<Op...>) {
  static const Launcher<T> table[] = {&device_launch<Op, T, Model>...};
  return table;
}

}  // namespace cuda
}  // namespace rbd
