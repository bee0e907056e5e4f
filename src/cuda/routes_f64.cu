// src/cuda/routes_f64.cu — the real kernels on double (device_routes.cuh)
#include "device.hpp"
#include "rbdkit/cuda/device_routes.cuh"

namespace rbd {
namespace cuda {
template <> const Launcher<double>* device_routes<double>() { return device_table<double>(ops::AllOps{}); }
}  // namespace cuda
}  // namespace rbd
