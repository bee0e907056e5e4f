// tests/cpp/cuda_read_only.cu — one operation's real kernel (inverse dynamics,
// float64), compiled to PTX by tests/cpp/cuda_read_only.cmake, which checks
// that the model's bodies are loaded through the read-only data cache
// (ld.global.nc: op_kernel's `const __restrict__` bodies, include/rbdkit/cuda/kernels.cuh)
#include "rbdkit/cuda/kernels.cuh"

namespace rbd {
namespace cuda {
template __global__ void op_kernel<ops::InverseDynamics, double>(DeviceCall<double>,
                                                                 const BodyDesc<double>* __restrict__);
}  // namespace cuda
}  // namespace rbd
