// src/cuda/memory.hpp — where a pointer's memory lives, for the interpret
// device, which reads "device" arrays on the CPU: a GPU array handed to it
// must be refused, not read (src/cuda/cuda_engine.cpp).
#pragma once

namespace rbd {
namespace cuda {

// true when p is memory on a GPU that the CPU cannot read (cudaMemoryTypeDevice);
// false for host memory, page-locked or managed memory, and in builds or on
// machines without CUDA (src/cuda/device.cu, src/cuda/no_device.cpp)
bool gpu_only_memory(const void* p);

}  // namespace cuda
}  // namespace rbd
