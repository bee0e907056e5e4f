// src/cuda/device.cu — the CUDA runtime's device: memory, copies, streams,
// and the launch of an operation's kernel (the routes of
// src/cuda/routes_<dtype>.cu). Compiled when CMake finds nvcc.
#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

#include "device.hpp"

namespace rbd {
namespace cuda {

namespace {

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("backend='cuda': ") + what + ": " + cudaGetErrorString(e));
}

struct CudaDevice : Device {
  std::string device;
  CudaDevice() {
    int n = 0;
    const cudaError_t e = cudaGetDeviceCount(&n);
    if (e != cudaSuccess || n == 0)
      throw std::runtime_error(std::string("backend='cuda': no CUDA device is available (") +
                               (e != cudaSuccess ? cudaGetErrorString(e) : "the driver reports 0 devices") +
                               "); set RBDKIT_CUDA_INTERPRET=1 to run the kernels on the CPU");
    cudaDeviceProp p;
    check(cudaGetDeviceProperties(&p, 0), "cudaGetDeviceProperties");
    device = p.name;
  }
  std::string name() const override { return device; }
  void* alloc(size_t bytes) override {
    void* p = nullptr;
    check(cudaMalloc(&p, bytes ? bytes : 1), ("cudaMalloc of " + std::to_string(bytes) + " bytes").c_str());
    return p;
  }
  void release(void* p) override { cudaFree(p); }
  void to_device(void* dst, const void* src, size_t bytes, void* s) override {
    check(cudaMemcpyAsync(dst, src, bytes, cudaMemcpyHostToDevice, static_cast<cudaStream_t>(s)), "copy to device");
  }
  void to_host(void* dst, const void* src, size_t bytes, void* s) override {
    check(cudaMemcpyAsync(dst, src, bytes, cudaMemcpyDeviceToHost, static_cast<cudaStream_t>(s)), "copy to host");
  }
  void launch(int op, const DeviceCall<double>& c, void* s) override { device_routes<double>()[op](c, s); }
  void launch(int op, const DeviceCall<float>& c, void* s) override { device_routes<float>()[op](c, s); }
  void synchronize(void* s) override {
    check(cudaGetLastError(), "kernel launch");
    check(cudaStreamSynchronize(static_cast<cudaStream_t>(s)), "kernel");
  }
  void* create_stream() override {
    cudaStream_t s;
    check(cudaStreamCreateWithFlags(&s, cudaStreamNonBlocking), "cudaStreamCreate");
    return s;
  }
  void destroy_stream(void* s) override { cudaStreamDestroy(static_cast<cudaStream_t>(s)); }
};

}  // namespace

bool cuda_compiled() { return true; }
int cuda_device_count() {
  int n = 0;
  return cudaGetDeviceCount(&n) == cudaSuccess ? n : 0;
}
std::unique_ptr<Device> make_cuda_device() { return std::make_unique<CudaDevice>(); }

}  // namespace cuda
}  // namespace rbd
