// src/cuda/no_device.cpp — a build without nvcc: no real kernels, so no CUDA
// device (interpret mode still runs the kernels' source on the CPU)
#include <stdexcept>

#include "device.hpp"
#include "memory.hpp"

namespace rbd {
namespace cuda {

bool cuda_compiled() { return false; }
int cuda_device_count() { return 0; }
bool gpu_only_memory(const void*) { return false; }
std::unique_ptr<Device> make_cuda_device() {
  throw std::runtime_error(
      "backend='cuda': this build of rbdkit has no CUDA kernels (nvcc was not found when it was built); "
      "rebuild with the CUDA toolkit, or set RBDKIT_CUDA_INTERPRET=1 to run the kernels on the CPU");
}

}  // namespace cuda
}  // namespace rbd
