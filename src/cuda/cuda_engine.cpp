// src/cuda/cuda_engine.cpp — the CUDA engine (include/rbdkit/cuda/cuda_engine.hpp):
// device buffers, one launch per call (per chunk of samples when a global
// work buffer would exceed kMaxWorkBytes), its shape (cuda::launch_shape), the
// samples' status, and the errors that name them.
#include "rbdkit/cuda/cuda_engine.hpp"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "device.hpp"
#include "memory.hpp"
#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/codegen/specialize.hpp"

namespace rbd {

namespace cuda {

// The launch of B samples of `work_bytes` each (the same for every operation of that size;
// docs/cuda.md, "Kernel layout", with the H100 measurements behind it):
//   work in shared memory while the batch runs in at most three waves of samples resident with
//     their slices there (fit slices per block, a block per SM: B <= 3 x SMs x fit), else in global
//     memory, whose residency only registers bound: past three waves, the waves cost more than
//     global memory's slower accesses (measured: docs/gpu.md, 2026-11-26 on an H100);
//   threads per block: the samples spread over the SMs first (a block per SM until every SM has
//     one), then as many as fit in shared memory (at most 32), or warps up to 128 in global memory;
//   blocks: one thread per sample, at most kMaxBlocks (then the grid strides)
LaunchShape launch_shape(long B, unsigned long work_bytes, DeviceLimits d, WorkMemory mode) {
  const long sms = d.multiprocessors > 0 ? d.multiprocessors : 1;
  const long per_sm = (B + sms - 1) / sms;  // samples per SM when every SM has a block
  const long fit = work_bytes ? static_cast<long>(d.shared_bytes / work_bytes) : 0;
  const long resident = sms * std::min(fit, 32L);  // samples in shared memory at once
  const bool shared = mode == kWorkShared || (mode == kWorkAuto && fit >= 1 && B <= 3 * resident);
  long threads;
  if (shared) {
    threads = std::min(std::min(per_sm, 32L), fit);
    threads = std::max(threads, 1L);  // (kWorkShared with a slice larger than a block's: the engine refuses it)
  } else {
    threads = std::min(std::max((per_sm + 31) / 32 * 32, 32L), static_cast<long>(kThreadsPerBlock));
  }
  const long blocks = std::min(std::max((B + threads - 1) / threads, 1L), kMaxBlocks);
  return {blocks, static_cast<int>(threads), shared ? work_bytes * threads : 0ul, d.shared_bytes};
}

// A team kernel's launch (team_kernels.cuh): a block of kTeam threads per sample, its work slice in
// the block's shared memory under the same three-waves rule (a block per slice that fits, at most
// 32 blocks per SM), else in global memory; at most kMaxBlocks blocks (then the grid strides)
LaunchShape team_launch_shape(long B, unsigned long work_bytes, DeviceLimits d, WorkMemory mode) {
  const long sms = d.multiprocessors > 0 ? d.multiprocessors : 1;
  const long fit = work_bytes ? static_cast<long>(d.shared_bytes / work_bytes) : 0;
  const bool shared = mode == kWorkShared || (mode == kWorkAuto && fit >= 1 && B <= 3 * sms * std::min(fit, 32L));
  const long blocks = std::min(std::max(B, 1L), kMaxBlocks);
  return {blocks, kTeam, shared ? work_bytes : 0ul, d.shared_bytes, 1};
}

}  // namespace cuda

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
  cuda::WorkMemory work_memory = cuda::kWorkAuto;
  std::string kernel = "auto";  // set_kernel
  std::vector<cuda::TeamInfo> teams;  // per operation: its team kernel's extra bytes and rule
  cuda::DeviceLimits limits{};
  std::shared_ptr<const CudaInstance> instance;  // use_instance: the robot's own kernels (null: none)
  std::mutex call;
  std::vector<int> status_host;
  // the flag samples set when they fail (DeviceCall::failed): pinned host memory that the kernels write
  // directly (failed_device, its device address), read after the synchronisation with no copy
  int* failed_host = nullptr;
  int* failed_device = nullptr;
  int call_id = 0;

  Impl(const Model& m, const std::string& d, bool interp) : model(m), dtype(d), interpret(interp) {
    if (d != "float64" && d != "float32")
      throw std::invalid_argument("dtype: expected 'float64' or 'float32', got '" + d + "'");
    dev = interp ? cuda::make_interpret_device() : cuda::make_cuda_device();
    for (Buffer* b : {&bodies, &work, &status, &io}) b->dev = dev.get();
    own_stream = dev->create_stream();
    stream = own_stream;
    limits = dev->limits();
    try {
      work_memory = work_memory_from_env();
      if (const char* k = std::getenv("RBDKIT_CUDA_KERNEL"); k && *k) kernel = checked_kernel(k, "RBDKIT_CUDA_KERNEL");
      teams.assign(ops::op_table().size(), cuda::TeamInfo{});
      if (d == "float64") cuda::team_infos<double>(ops::AllOps{}, model.nb(), model.nv, teams.data());
      else cuda::team_infos<float>(ops::AllOps{}, model.nb(), model.nv, teams.data());
      failed_host = static_cast<int*>(dev->alloc_host(sizeof(int)));
      *failed_host = 0;
      failed_device = static_cast<int*>(dev->device_address(failed_host));
      // the model's bodies in the engine's scalar, uploaded once
      if (d == "float64") upload_bodies(model.bodies_as<double>());
      else upload_bodies(model.bodies_as<float>());
    } catch (...) {
      if (failed_host) dev->release_host(failed_host);
      dev->destroy_stream(own_stream);
      own_stream = nullptr;
      throw;
    }
  }
  ~Impl() {
    if (failed_host) dev->release_host(failed_host);
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
  template <typename T> [[noreturn]] void fail_inputs(const ops::OpSpec& op, const ops::OpCall& c,
                                                      const std::vector<long>& samples);
  // the team kernel (team_kernels.cuh) where the op has one, on a model without mimic joints: asked
  // for, or (auto) while the batch is small for the GPU (at most the op's per_sm samples per SM: a
  // sample per thread leaves the GPU idle), or where one thread's chain is too long for any B (the
  // op's wide_nv: nv >= 16, except ID's O(nb)). On an H200 (docs/gpu.md, 2026-11-27) the team was
  // faster on iiwa up to 8 samples per SM for ID, M⁻¹, FD, ∇ID and ∇FD and up to 32 for the rk4
  // step's gradient, level or slower past them, and faster on floating Atlas at every B but ID's
  // from B = 4096. A step in MuJoCo's convention has no team form (its team runs it on one thread):
  // auto keeps the sample kernel for it, `convention` being the call's (OutputConvention); the costs
  // and barriers have theirs in both conventions (mujoco_form)
  bool uses_team(int op, long B, int convention) const {
    const cuda::TeamInfo& r = teams[op];
    if (!r.per_sm || model.general_path() || kernel == "sample") return false;  // (0: no team kernel)
    if (kernel == "team") return true;
    if (convention != kPinocchioConvention && !r.mujoco_form) return false;
    return B <= static_cast<long>(r.per_sm) * std::max(limits.multiprocessors, 1) ||
           (r.wide_nv > 0 && model.nv >= r.wide_nv);
  }
  // the call's output convention (Pinocchio's for an operation without one)
  static int call_convention(const ops::OpSpec& op, const ops::OpCall& c) {
    for (int k = 0; k < op.n_args; ++k)
      if (op.args[k].kind == ops::kConvention) return c.choice[k];
    return kPinocchioConvention;
  }
  static std::string checked_kernel(const std::string& k, const char* what) {
    if (k != "auto" && k != "team" && k != "sample")
      throw std::invalid_argument(std::string(what) + ": expected 'auto', 'team' or 'sample', got '" + k + "'");
    return k;
  }
  static cuda::WorkMemory work_memory_from_env() {
    const char* v = std::getenv("RBDKIT_CUDA_WORK");
    if (!v || !*v || std::strcmp(v, "auto") == 0) return cuda::kWorkAuto;
    if (std::strcmp(v, "global") == 0) return cuda::kWorkGlobal;
    if (std::strcmp(v, "shared") == 0) return cuda::kWorkShared;
    throw std::invalid_argument(std::string("RBDKIT_CUDA_WORK: expected 'auto', 'global' or 'shared', got '") + v +
                                "'");
  }
};

template <typename T> void CudaEngine::Impl::run(int op_id, const ops::OpCall& c, bool device_arrays) {
  const ops::OpSpec& op = *ops::op_table()[op_id].spec;
  const Model& m = model;
  const long B = c.B;
  cuda::DeviceCall<T> dc{};
  dc.model = {m.nb(), m.nq, m.nv, m.general_path() ? 1 : 0, static_cast<const BodyDesc<T>*>(bodies.p)};
  const bool team = uses_team(op_id, B, call_convention(op, c));
  // (a team that needs the full workspace gets it where the op's own is linear: TeamInfo::full_workspace)
  dc.layout = team && teams[op_id].full_workspace ? kFullWorkspace : ops::workspace_layout(op, m);
  dc.ws_bytes = round16(workspace_bytes<T>(m.nb(), m.nv, dc.layout));
  const unsigned long scratch_bytes = sizeof(T) * ops::scratch_values(op, m);
  // a team's slice: the workspace, the op's scratch, the team's extra at the end (team_sample)
  dc.work_bytes = std::max(16ul, round16(dc.ws_bytes + (team ? round16(scratch_bytes) + teams[op_id].extra : scratch_bytes)));
  auto shape_of = [&](long n, cuda::WorkMemory where) {
    return team ? cuda::team_launch_shape(n, dc.work_bytes, limits, where)
                : cuda::launch_shape(n, dc.work_bytes, limits, where);
  };
  dc.n_ee = c.n_ee;
  dc.check_inputs = device_arrays ? 1 : 0;  // (host arrays were checked on the host)

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
  // the interpret device reads device arrays on the CPU: a GPU's array is refused, not read
  if (device_arrays && interpret) {
    auto refuse = [&](const char* name) {
      throw std::invalid_argument(std::string(op.name) + ": " + name +
                                  ": an array in GPU memory, and this backend='cuda' handle runs in interpret "
                                  "mode on the CPU (RBDKIT_CUDA_INTERPRET=1), which cannot read it; pass host "
                                  "arrays, or make the handle without RBDKIT_CUDA_INTERPRET to run on the GPU");
    };
    for (int k = 0; k < op.n_args; ++k)
      if (c.in[k] && op.args[k].kind != ops::kFrame && cuda::gpu_only_memory(c.in[k])) refuse(op.args[k].name);
    for (int o = 0; o < op.n_out; ++o)
      if (c.out[o] && cuda::gpu_only_memory(c.out[o])) refuse(op.out[o].name);
  }
  unsigned char* io_p = static_cast<unsigned char*>(io.reserve(std::max<size_t>(io_bytes, 1)));
  for (int k = 0; k < op.n_args; ++k) {
    dc.real[k] = static_cast<T>(c.real[k]);
    dc.choice[k] = c.choice[k];
    if (!c.in[k]) continue;
    dc.in_stride[k] = c.batched[k] ? in_values[k] : 0;
    dc.in_values[k] = in_values[k];
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

  // the launches: the work in shared memory (one launch), or over chunks of samples whose global work
  // buffer fits max_work_bytes
  const cuda::LaunchShape whole = shape_of(B, work_memory);
  if (whole.shared_bytes > limits.shared_bytes)
    throw std::invalid_argument(std::string(op.name) + ": work memory 'shared': a sample's work (" +
                                std::to_string(dc.work_bytes) + " bytes) exceeds a block's shared memory (" +
                                std::to_string(limits.shared_bytes) + " bytes) on this device; use 'auto' or 'global'");
  dc.work_shared = whole.shared_bytes ? 1 : 0;
  const long chunk = dc.work_shared ? B
                                    : std::max(1L, std::min<long>(B, static_cast<long>(max_work_bytes / dc.work_bytes)));
  if (!dc.work_shared) work.reserve(dc.work_bytes * chunk);
  status.reserve(sizeof(int) * B);
  dc.work = dc.work_shared ? nullptr : static_cast<unsigned char*>(work.p);
  int* status_d = static_cast<int*>(status.p);
  dc.failed = failed_device;
  dc.call_id = call_id = call_id == 0x7fffffff ? 1 : call_id + 1;  // (never 0, the flag's first value)
  // the robot's instance launches the operations it compiled (use_instance), the device the rest
  const cuda::GuardedLauncher<T> own =
      instance ? reinterpret_cast<cuda::GuardedLauncher<T>>(cuda_instance_launch(*instance, op_id, sizeof(T) == 4))
               : nullptr;
  for (long s0 = 0; s0 < B; s0 += chunk) {
    cuda::DeviceCall<T> part = dc;
    part.B = std::min(chunk, B - s0);
    for (int k = 0; k < op.n_args; ++k)
      if (part.in[k]) part.in[k] += s0 * part.in_stride[k];
    for (int o = 0; o < op.n_out; ++o)
      if (part.out[o]) part.out[o] += s0 * out_values[o];
    part.status = status_d + s0;
    const cuda::LaunchShape shape = part.B == B ? whole : shape_of(part.B, cuda::kWorkGlobal);  // (a chunk: global)
    if (own) {
      char error[512];
      if (own(part, shape, stream, error, sizeof error)) throw std::runtime_error(error);
    } else {
      dev->launch(op_id, part, shape, stream);
    }
  }
  // the outputs of host arrays; the statuses only when the flag (written in place) says
  for (int o = 0; o < op.n_out; ++o)
    if (c.out[o] && !device_arrays) dev->to_host(c.out[o], dc.out[o], sizeof(T) * out_values[o] * B, stream);
  dev->synchronize(stream);
  if (*failed_host != dc.call_id) return;
  status_host.resize(static_cast<size_t>(B));
  dev->to_host(status_host.data(), status_d, sizeof(int) * B, stream);
  dev->synchronize(stream);

  // the samples that failed: inputs that fail the value checks first, else the first status seen
  std::vector<long> bad;
  for (long s = 0; s < B; ++s)
    if (status_host[s] == cuda::kSampleBadInput) bad.push_back(s);
  if (!bad.empty()) fail_inputs<T>(op, c, bad);
  long first = -1;
  for (long s = 0; s < B; ++s)
    if (status_host[s] != cuda::kSampleOk) {
      if (first < 0) first = s;
      if (status_host[s] == status_host[first]) bad.push_back(s);
    }
  if (first >= 0) fail(op_id, c, first, bad, status_host[first], device_arrays, sizeof(T));
}

// device arrays whose values the kernels refused (inputs_ok): check_call's error, from a host copy
template <typename T>
void CudaEngine::Impl::fail_inputs(const ops::OpSpec& op, const ops::OpCall& c, const std::vector<long>& samples) {
  std::vector<std::vector<T>> host(op.n_args);
  ops::OpCall h = c;
  for (int k = 0; k < op.n_args; ++k) {
    if (!c.in[k] || op.args[k].kind == ops::kFrame) continue;  // (a frame's placement is host memory)
    host[k].resize(static_cast<size_t>(ops::arg_values(op.args[k], model, c.n_ee) * (c.batched[k] ? c.B : 1)));
    dev->to_host(host[k].data(), c.in[k], sizeof(T) * host[k].size(), stream);
    h.in[k] = host[k].data();
  }
  dev->synchronize(stream);
  ops::check_call<T>(model, op, h);  // throws std::invalid_argument naming the argument and the sample
  std::ostringstream os;  // (the two checks disagree: a bug, named rather than hidden)
  os << op.name << ": the device refused the inputs of sample " << samples.front()
     << " but the host's checks pass them (please report this)";
  throw std::logic_error(os.str());
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
int CudaEngine::device_ordinal() const { return impl_->dev->ordinal(); }
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
void CudaEngine::set_work_memory(const std::string& where) {
  cuda::WorkMemory w;
  if (where == "auto") w = cuda::kWorkAuto;
  else if (where == "global") w = cuda::kWorkGlobal;
  else if (where == "shared") w = cuda::kWorkShared;
  else throw std::invalid_argument("work memory: expected 'auto', 'global' or 'shared', got '" + where + "'");
  std::lock_guard<std::mutex> lk(impl_->call);
  impl_->work_memory = w;
}
std::string CudaEngine::work_memory() const {
  std::lock_guard<std::mutex> lk(impl_->call);
  const cuda::WorkMemory w = impl_->work_memory;
  return w == cuda::kWorkGlobal ? "global" : w == cuda::kWorkShared ? "shared" : "auto";
}
void CudaEngine::set_kernel(const std::string& which) {
  const std::string k = Impl::checked_kernel(which, "kernel");
  std::lock_guard<std::mutex> lk(impl_->call);
  impl_->kernel = k;
}
std::string CudaEngine::kernel() const {
  std::lock_guard<std::mutex> lk(impl_->call);
  return impl_->kernel;
}
std::string CudaEngine::kernel_for(int op, long B, int convention) const {
  if (op < 0 || op >= static_cast<int>(ops::op_table().size()))
    throw std::invalid_argument("kernel_for: unknown operation id " + std::to_string(op));
  std::lock_guard<std::mutex> lk(impl_->call);
  return impl_->uses_team(op, B, convention) ? "team" : "sample";
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
  if (impl_->instance) cuda_instance_activate(*impl_->instance, impl_->dev->ordinal());
  if (impl_->dtype == "float32") impl_->run<float>(op, call, device_arrays);
  else impl_->run<double>(op, call, device_arrays);
}

void CudaEngine::use_instance(std::shared_ptr<const CudaInstance> instance) {
  std::lock_guard<std::mutex> lk(impl_->call);
  if (instance && cuda_instance_device(*instance) == impl_->interpret)
    throw std::invalid_argument(std::string("use_instance: ") + instance_path(*instance) + " holds " +
                                (impl_->interpret ? "GPU kernels; this engine runs in interpret mode"
                                                  : "interpret launches; this engine runs on a GPU"));
  const std::string other = instance ? cuda_instance_mismatch(*instance, impl_->model) : "";
  if (!other.empty()) throw std::invalid_argument("use_instance: " + instance_path(*instance) + " " + other);
  impl_->instance = std::move(instance);
}
bool CudaEngine::has_instance() const {
  std::lock_guard<std::mutex> lk(impl_->call);
  return impl_->instance != nullptr;
}

}  // namespace rbd
