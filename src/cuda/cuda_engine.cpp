// src/cuda/cuda_engine.cpp — the CUDA engine (include/rbdkit/cuda/cuda_engine.hpp):
// device buffers, one launch per call (per chunk of samples when the work
// buffer would exceed kMaxWorkBytes), the samples' status, and the errors
// that name them.
#include "rbdkit/cuda/cuda_engine.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "device.hpp"
#include "rbdkit/batch/dynamics.hpp"

namespace rbd {

namespace {

constexpr unsigned long kMaxWorkBytes = 1ul << 30;  // default, per launch: samples x (workspace + scratch)

unsigned long round16(unsigned long n) { return (n + 15ul) & ~15ul; }

// a device buffer that grows on demand and is reused afterwards
struct Buffer {
  cuda::Device* dev = nullptr;
  void* p = nullptr;
  size_t bytes = 0;
  ~Buffer() {
    if (p) dev->release(p);
  }
  void* reserve(size_t need) {
    if (need > bytes) {
      if (p) dev->release(p);
      p = nullptr, bytes = 0;  // (if alloc throws, the next call allocates again)
      p = dev->alloc(need);
      bytes = need;
    }
    return p;
  }
};

}  // namespace

struct CudaEngine::Impl {
  Model model;
  std::string dtype;
  bool interpret;
  std::unique_ptr<cuda::Device> dev;
  void* own_stream = nullptr;
  void* stream = nullptr;
  Buffer bodies, work, status, io;
  unsigned long max_work_bytes = kMaxWorkBytes;
  std::mutex call;
  std::vector<int> status_host;

  Impl(const Model& m, const std::string& d, bool interp) : model(m), dtype(d), interpret(interp) {
    if (d != "float64" && d != "float32")
      throw std::invalid_argument("dtype: expected 'float64' or 'float32', got '" + d + "'");
    dev = interp ? cuda::make_interpret_device() : cuda::make_cuda_device();
    for (Buffer* b : {&bodies, &work, &status, &io}) b->dev = dev.get();
    own_stream = dev->create_stream();
    stream = own_stream;
    try {  // the model's bodies in the engine's scalar, uploaded once
      if (d == "float64") upload_bodies(model.bodies_as<double>());
      else upload_bodies(model.bodies_as<float>());
    } catch (...) {
      dev->destroy_stream(own_stream);
      own_stream = nullptr;
      throw;
    }
  }
  ~Impl() {
    if (own_stream) dev->destroy_stream(own_stream);
  }
  template <typename T> void upload_bodies(const std::vector<BodyDesc<T>>& b) {
    const size_t n = sizeof(BodyDesc<T>) * b.size();
    bodies.reserve(n);
    if (n) dev->to_device(bodies.p, b.data(), n, stream);
    dev->synchronize(stream);
  }

  template <typename T> void run(int op, const ops::OpCall& c, bool device_arrays);
  [[noreturn]] void fail(int op, const ops::OpCall& c, long first, const std::vector<long>& samples, int status,
                         bool device_arrays, size_t value_bytes);
};

template <typename T> void CudaEngine::Impl::run(int op_id, const ops::OpCall& c, bool device_arrays) {
  const ops::OpSpec& op = *ops::op_table()[op_id].spec;
  const Model& m = model;
  const long B = c.B;
  cuda::DeviceCall<T> dc{};
  dc.model = {m.nb(), m.nq, m.nv, m.has_mimic() ? 1 : 0, static_cast<const BodyDesc<T>*>(bodies.p)};
  dc.layout = ops::workspace_layout(op, m);
  dc.ws_bytes = round16(workspace_bytes<T>(m.nb(), m.nv, dc.layout));
  dc.work_bytes = std::max(16ul, round16(dc.ws_bytes + sizeof(T) * ops::scratch_values(op, m)));
  dc.n_ee = c.n_ee;

  // the io buffer: host arrays' copies, a frame's placement, the end effectors' list
  long in_values[ops::kMaxArgs] = {}, out_values[ops::kMaxOutputs] = {};
  size_t io_bytes = 0;
  size_t in_at[ops::kMaxArgs] = {}, out_at[ops::kMaxOutputs] = {}, ee_at = 0;
  auto place = [&io_bytes](size_t bytes) {
    const size_t at = io_bytes;
    io_bytes += (bytes + 255) & ~size_t(255);
    return at;
  };
  for (int k = 0; k < op.n_args; ++k) {
    if (!c.in[k]) continue;
    in_values[k] = ops::arg_values(op.args[k], m, c.n_ee);
    const bool copy = !device_arrays || op.args[k].kind == ops::kFrame;  // a frame's placement is host memory
    if (copy) in_at[k] = place(sizeof(T) * in_values[k] * (c.batched[k] ? B : 1));
  }
  for (int o = 0; o < op.n_out; ++o) {
    out_values[o] = ops::out_values(op.out[o], m, c.n_ee);
    if (c.out[o] && !device_arrays) out_at[o] = place(sizeof(T) * out_values[o] * B);
  }
  if (c.n_ee) ee_at = place(sizeof(int) * c.n_ee);
  unsigned char* io_p = static_cast<unsigned char*>(io.reserve(std::max<size_t>(io_bytes, 1)));
  for (int k = 0; k < op.n_args; ++k) {
    dc.real[k] = static_cast<T>(c.real[k]);
    dc.choice[k] = c.choice[k];
    if (!c.in[k]) continue;
    dc.in_stride[k] = c.batched[k] ? in_values[k] : 0;
    if (!device_arrays || op.args[k].kind == ops::kFrame) {
      dev->to_device(io_p + in_at[k], c.in[k], sizeof(T) * in_values[k] * (c.batched[k] ? B : 1), stream);
      dc.in[k] = reinterpret_cast<const T*>(io_p + in_at[k]);
    } else {
      dc.in[k] = static_cast<const T*>(c.in[k]);
    }
  }
  for (int o = 0; o < op.n_out; ++o) {
    dc.out_values[o] = out_values[o];
    if (c.out[o]) dc.out[o] = device_arrays ? static_cast<T*>(c.out[o]) : reinterpret_cast<T*>(io_p + out_at[o]);
  }
  if (c.n_ee) {
    dev->to_device(io_p + ee_at, c.ee, sizeof(int) * c.n_ee, stream);
    dc.ee = reinterpret_cast<const int*>(io_p + ee_at);
  }

  // launches over chunks of samples whose work buffer fits kMaxWorkBytes
  const long chunk = std::max(1L, std::min<long>(B, static_cast<long>(max_work_bytes / dc.work_bytes)));
  work.reserve(dc.work_bytes * chunk);
  status.reserve(sizeof(int) * B);
  dc.work = static_cast<unsigned char*>(work.p);
  int* status_d = static_cast<int*>(status.p);
  for (long s0 = 0; s0 < B; s0 += chunk) {
    cuda::DeviceCall<T> part = dc;
    part.B = std::min(chunk, B - s0);
    for (int k = 0; k < op.n_args; ++k)
      if (part.in[k]) part.in[k] += s0 * part.in_stride[k];
    for (int o = 0; o < op.n_out; ++o)
      if (part.out[o]) part.out[o] += s0 * out_values[o];
    part.status = status_d + s0;
    dev->launch(op_id, part, stream);
  }
  status_host.resize(static_cast<size_t>(B));
  dev->to_host(status_host.data(), status_d, sizeof(int) * B, stream);
  for (int o = 0; o < op.n_out; ++o)
    if (c.out[o] && !device_arrays) dev->to_host(c.out[o], dc.out[o], sizeof(T) * out_values[o] * B, stream);
  dev->synchronize(stream);

  // the samples that failed (the first status seen decides the error)
  long first = -1;
  std::vector<long> bad;
  for (long s = 0; s < B; ++s)
    if (status_host[s] != cuda::kSampleOk) {
      if (first < 0) first = s;
      if (status_host[s] == status_host[first]) bad.push_back(s);
    }
  if (first >= 0) fail(op_id, c, first, bad, status_host[first], device_arrays, sizeof(T));
}

void CudaEngine::Impl::fail(int op_id, const ops::OpCall& c, long first, const std::vector<long>& samples,
                            int status_code, bool device_arrays, size_t value_bytes) {
  const ops::OpSpec& op = *ops::op_table()[op_id].spec;
  const Model& m = model;
  std::ostringstream which;
  which << " [backend='cuda': " << samples.size() << " of " << c.B << " samples, ";
  const size_t shown = std::min<size_t>(samples.size(), 8);
  which << (samples.size() == 1 ? "sample " : "samples ");
  for (size_t i = 0; i < shown; ++i) which << (i ? ", " : "") << samples[i];
  if (shown < samples.size()) which << ", ...";
  which << "]";
  if (status_code >= cuda::kSampleNonFinite) {
    const int o = status_code - cuda::kSampleNonFinite;
    std::ostringstream os;
    os << op.name << ": the result " << op.out[o].name << " is not finite at sample " << first
       << ": the computation overflowed; reduce the inputs' magnitudes (or dt)" << which.str();
    throw std::runtime_error(os.str());
  }
  // the first failed sample's configuration (its first input), in float64, for the message
  std::vector<double> q(static_cast<size_t>(m.nq), 0.0);
  if (c.in[0]) {
    const long w = ops::arg_values(op.args[0], m, c.n_ee), n = std::min<long>(w, m.nq);
    const long at = c.batched[0] ? first * w : 0;
    std::vector<unsigned char> raw(value_bytes * n);
    if (device_arrays && !interpret) {
      dev->to_host(raw.data(), static_cast<const unsigned char*>(c.in[0]) + value_bytes * at, raw.size(), stream);
      dev->synchronize(stream);
    } else {
      std::memcpy(raw.data(), static_cast<const unsigned char*>(c.in[0]) + value_bytes * at, raw.size());
    }
    for (long k = 0; k < n; ++k)
      q[k] = value_bytes == sizeof(double) ? reinterpret_cast<const double*>(raw.data())[k]
                                           : reinterpret_cast<const float*>(raw.data())[k];
  }
  try {
    if (op.failure != ops::kNoMass && singular_joint(m, q.data()) >= 0)
      throw_not_positive_definite(m, op.name, q.data(), first);
    ops::throw_failure(m, op, q.data(), first, &c);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(e.what() + which.str());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(e.what() + which.str());
  }
}

CudaEngine::CudaEngine(const Model& model, const std::string& dtype, bool interpret)
    : impl_(new Impl(model, dtype, interpret)) {}
CudaEngine::~CudaEngine() = default;

bool CudaEngine::interpret_requested() {
  const char* v = std::getenv("RBDKIT_CUDA_INTERPRET");
  return v && std::strcmp(v, "1") == 0;
}
bool CudaEngine::cuda_compiled() { return cuda::cuda_compiled(); }
int CudaEngine::device_count() { return cuda::cuda_device_count(); }
bool CudaEngine::interpret() const { return impl_->interpret; }
const std::string& CudaEngine::dtype() const { return impl_->dtype; }
std::string CudaEngine::device_name() const { return impl_->dev->name(); }
void CudaEngine::set_stream(void* s) {
  std::lock_guard<std::mutex> lk(impl_->call);
  impl_->stream = s;
}
void CudaEngine::use_own_stream() {
  std::lock_guard<std::mutex> lk(impl_->call);
  impl_->stream = impl_->own_stream;
}
void* CudaEngine::stream() const { return impl_->stream; }
void CudaEngine::wait_for_stream(unsigned long producer) {
  std::lock_guard<std::mutex> lk(impl_->call);
  impl_->dev->activate();
  impl_->dev->wait_for(producer, impl_->stream);
}
void CudaEngine::set_max_work_bytes(unsigned long bytes) {
  std::lock_guard<std::mutex> lk(impl_->call);
  impl_->max_work_bytes = bytes ? bytes : kMaxWorkBytes;
}
unsigned long CudaEngine::device_bytes() const {
  return impl_->bodies.bytes + impl_->work.bytes + impl_->status.bytes + impl_->io.bytes;
}

void CudaEngine::copy_to_host(void* dst, const void* src, size_t bytes) {
  std::lock_guard<std::mutex> lk(impl_->call);
  impl_->dev->activate();
  impl_->dev->to_host(dst, src, bytes, impl_->stream);
  impl_->dev->synchronize(impl_->stream);
}

void CudaEngine::run_op(int op, const ops::OpCall& call, bool device_arrays) {
  if (op < 0 || op >= static_cast<int>(ops::op_table().size()))
    throw std::invalid_argument("run_op: unknown operation id " + std::to_string(op));
  if (call.B <= 0)
    throw std::invalid_argument(std::string(ops::op_table()[op].spec->name) +
                                ": B: expected a positive batch size, got " + std::to_string(call.B));
  std::lock_guard<std::mutex> lk(impl_->call);
  impl_->dev->activate();
  if (impl_->dtype == "float32") impl_->run<float>(op, call, device_arrays);
  else impl_->run<double>(op, call, device_arrays);
}

}  // namespace rbd
