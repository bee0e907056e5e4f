// src/cuda/device.cu — the CUDA runtime's device: memory, copies, streams,
// and the launch of an operation's kernel (the routes of
// src/cuda/routes_<dtype>.cu). Compiled when CMake finds nvcc.
#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

#include "device.hpp"
#include "memory.hpp"

namespace rbd {
namespace cuda {

namespace {

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string("backend='cuda': ") + what + ": " + cudaGetErrorString(e));
}

struct CudaDevice : Device {
  std::string device;
  DeviceLimits lim{};
  int id = 0;  // the device current when the engine was made: every call runs there
  CudaDevice() {
    int n = 0;
    const cudaError_t e = cudaGetDeviceCount(&n);
    if (e != cudaSuccess || n == 0)
      throw std::runtime_error(std::string("backend='cuda': no CUDA device is available (") +
                               (e != cudaSuccess ? cudaGetErrorString(e) : "the driver reports 0 devices") +
                               "); set RBDKIT_CUDA_INTERPRET=1 to run the kernels on the CPU");
    check(cudaGetDevice(&id), "cudaGetDevice");
    cudaDeviceProp p;
    check(cudaGetDeviceProperties(&p, id), "cudaGetDeviceProperties");
    device = p.name;
    lim.multiprocessors = p.multiProcessorCount;
    lim.shared_bytes = p.sharedMemPerBlockOptin;
  }
  void activate() override { check(cudaSetDevice(id), "cudaSetDevice"); }
  std::string name() const override { return device; }
  int ordinal() const override { return id; }
  DeviceLimits limits() const override { return lim; }
  void* alloc(size_t bytes) override {
    void* p = nullptr;
    check(cudaMalloc(&p, bytes ? bytes : 1), ("cudaMalloc of " + std::to_string(bytes) + " bytes").c_str());
    return p;
  }
  void release(void* p) override { cudaFree(p); }
  void* alloc_host(size_t bytes) override {
    void* p = nullptr;
    check(cudaHostAlloc(&p, bytes ? bytes : 1, cudaHostAllocMapped),
          ("cudaHostAlloc of " + std::to_string(bytes) + " bytes").c_str());
    return p;
  }
  void release_host(void* p) override { cudaFreeHost(p); }
  void* device_address(void* host) override {
    void* d = nullptr;
    check(cudaHostGetDevicePointer(&d, host, 0), "cudaHostGetDevicePointer");
    return d;
  }
  void to_device(void* dst, const void* src, size_t bytes, void* s) override {
    check(cudaMemcpyAsync(dst, src, bytes, cudaMemcpyHostToDevice, static_cast<cudaStream_t>(s)), "copy to device");
  }
  void to_host(void* dst, const void* src, size_t bytes, void* s) override {
    check(cudaMemcpyAsync(dst, src, bytes, cudaMemcpyDeviceToHost, static_cast<cudaStream_t>(s)), "copy to host");
  }
  void launch(int op, const DeviceCall<double>& c, LaunchShape shape, void* s) override {
    device_routes<double>()[op](c, shape, s);
    check(cudaGetLastError(), "kernel launch");
  }
  void launch(int op, const DeviceCall<float>& c, LaunchShape shape, void* s) override {
    device_routes<float>()[op](c, shape, s);
    check(cudaGetLastError(), "kernel launch");
  }
  void synchronize(void* s) override { check(cudaStreamSynchronize(static_cast<cudaStream_t>(s)), "kernel"); }
  // a blocking stream: it waits for the legacy default stream, where PyTorch and CuPy work by default
  void* create_stream() override {
    cudaStream_t s;
    check(cudaStreamCreate(&s), "cudaStreamCreate");
    return s;
  }
  void wait_for(unsigned long producer, void* s) override {
    const cudaStream_t p = producer == 1   ? cudaStreamLegacy
                           : producer == 2 ? cudaStreamPerThread
                                           : reinterpret_cast<cudaStream_t>(producer);
    if (p == static_cast<cudaStream_t>(s)) return;
    cudaEvent_t e;
    check(cudaEventCreateWithFlags(&e, cudaEventDisableTiming), "cudaEventCreate");
    const cudaError_t r1 = cudaEventRecord(e, p), r2 = cudaStreamWaitEvent(static_cast<cudaStream_t>(s), e, 0);
    cudaEventDestroy(e);
    check(r1, "cudaEventRecord on the arrays' stream");
    check(r2, "cudaStreamWaitEvent");
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

bool gpu_only_memory(const void* p) {
  static const bool any_device = cuda_device_count() > 0;  // (no query, and no context, without one)
  if (!any_device || !p) return false;
  cudaPointerAttributes a{};
  const cudaError_t e = cudaPointerGetAttributes(&a, p);
  if (e != cudaSuccess) {
    if (cudaPeekAtLastError() == e) cudaGetLastError();  // (clears the query's error, not another's)
    return false;
  }
  return a.type == cudaMemoryTypeDevice;
}

}  // namespace cuda
}  // namespace rbd
