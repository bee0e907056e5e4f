// src/cuda/interpret.cpp — the interpret device (RBDKIT_CUDA_INTERPRET=1):
// "device memory" is host memory and a launch runs the kernel's source
// (kernels.cuh) under the emulated launch, blocks and threads serially.
#include <cstdlib>
#include <cstring>
#include <new>
#include <stdexcept>

#include "device.hpp"

namespace rbd {
namespace cuda {
namespace {

struct InterpretDevice : Device {
  std::string name() const override { return "interpret (CPU)"; }
  // a small GPU's (so that small test batches already share blocks), with an H100's shared memory
  DeviceLimits limits() const override { return {4, 227ul * 1024}; }
  void* alloc(size_t bytes) override {
    void* p = std::aligned_alloc(64, (bytes + 63) / 64 * 64 + 64);
    if (!p) throw std::runtime_error("cuda (interpret): out of host memory for " + std::to_string(bytes) + " bytes");
    return p;
  }
  void release(void* p) override { std::free(p); }
  void* alloc_host(size_t bytes) override { return alloc(bytes); }
  void release_host(void* p) override { std::free(p); }
  void* device_address(void* host) override { return host; }
  void to_device(void* dst, const void* src, size_t bytes, void*) override { std::memcpy(dst, src, bytes); }
  void to_host(void* dst, const void* src, size_t bytes, void*) override { std::memcpy(dst, src, bytes); }
  void launch(int op, const DeviceCall<double>& c, LaunchShape shape, void* stream) override {
    interpret_routes<double>()[op](c, shape, stream);
  }
  void launch(int op, const DeviceCall<float>& c, LaunchShape shape, void* stream) override {
    interpret_routes<float>()[op](c, shape, stream);
  }
  void synchronize(void*) override {}
  void* create_stream() override { return nullptr; }
  void destroy_stream(void*) override {}
  void wait_for(unsigned long, void*) override {}  // launches run to completion
  void activate() override {}
};

}  // namespace

std::unique_ptr<Device> make_interpret_device() { return std::make_unique<InterpretDevice>(); }

}  // namespace cuda
}  // namespace rbd
