// src/cuda/routes_f32.cu — the real kernels on float (device_routes.cuh)
#include "device.hpp"
#include "rbdkit/cuda/device_routes.cuh"

namespace rbd {
namespace cuda {
template <> const Launcher<float>* device_routes<float>() { return device_table<float>(ops::AllOps{}); }
}  // namespace cuda
}  // namespace rbd
