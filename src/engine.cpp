// The batched CPU engine (engine.hpp): a persistent thread pool, a static
// split of the batch into runs of whole packs, and the per-sample
// algorithms instantiated on Pack<T, W> (simd.hpp).
//
// This file is compiled with RBDKIT_ENGINE_ARCH (CMake option, default
// "native": the build machine's vector instructions); W follows from it:
// 8 doubles / 16 floats with AVX-512, 4 / 8 with AVX, 2 / 4 otherwise.
#include "rbdkit/engine.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/algorithms/integrators.hpp"
#include "rbdkit/dynamics.hpp"
#include "rbdkit/ops/registry.hpp"
#include "rbdkit/ops/table.hpp"
#include "rbdkit/simd.hpp"

#ifndef RBDKIT_ENGINE_W64
#if defined(__AVX512F__)
#define RBDKIT_ENGINE_W64 8
#elif defined(__AVX__)
#define RBDKIT_ENGINE_W64 4
#else
#define RBDKIT_ENGINE_W64 2
#endif
#endif
#ifndef RBDKIT_ENGINE_W32
#define RBDKIT_ENGINE_W32 (2 * RBDKIT_ENGINE_W64)
#endif

// the per-pack kernels inline everything they call (the engine's speed);
// RBDKIT_ENGINE_NO_FLATTEN (the sanitizer build) skips that to compile faster
#ifdef RBDKIT_ENGINE_NO_FLATTEN
#define RBD_ENGINE_KERNEL
#else
#define RBD_ENGINE_KERNEL __attribute__((flatten))
#endif

namespace rbd {
namespace {

template <typename T> struct Width;
template <> struct Width<double> { static constexpr int value = RBDKIT_ENGINE_W64; };
template <> struct Width<float> { static constexpr int value = RBDKIT_ENGINE_W32; };

// ---- persistent pool of n - 1 workers. run() publishes a job and works on
// it as thread 0; each worker t < active that arrives before the caller has
// finished and closed the job works on it too, so a late worker (asleep,
// or its core busy) delays nothing. The job hands out its work itself (a
// shared counter: Job::claim below), so whichever threads come share it.
//
// Between jobs a worker spins on the state word for up to kSpin (a pause
// instruction per try), then sleeps on a condition variable; the caller
// waits for the workers inside its job the same way. A call while the
// workers spin costs two cache-line transfers each way and no system call.
class Pool {
 public:
  explicit Pool(int n) {
    for (int t = 1; t < n; ++t) workers_.emplace_back([this, t] { loop(t); });
  }
  ~Pool() {
    stop_.store(true);
    { std::lock_guard<std::mutex> lk(mu_); }  // a worker between its check and its wait is waiting now
    start_.notify_all();
    for (std::thread& th : workers_) th.join();
  }
  // fn(ctx, t) on threads 0 (the caller) .. active - 1; fn must not throw
  void run(int active, void (*fn)(void*, int), void* ctx) {
    active = std::min<int>(active, static_cast<int>(workers_.size()) + 1);
    if (active <= 1) {
      fn(ctx, 0);
      return;
    }
    fn_ = fn, ctx_ = ctx;
    // publish (no worker is inside: the last job was closed and left)
    const std::uint64_t e = (epoch(state_.load(std::memory_order_relaxed)) + 1u) & 0xffffffffu;
    state_.store(e << 32 | std::uint64_t(active) << 16 | kOpen);
    if (sleeping_.load() > 0) {
      { std::lock_guard<std::mutex> lk(mu_); }
      start_.notify_all();
    }
    fn(ctx, 0);
    // close: no worker joins from here on; wait for those inside
    if ((state_.fetch_and(~kOpen) & kInside) == 0) return;
    if (spin([this] { return (state_.load(std::memory_order_acquire) & kInside) == 0; })) return;
    std::unique_lock<std::mutex> lk(mu_);
    caller_sleeping_.store(true);
    done_.wait(lk, [this] { return (state_.load() & kInside) == 0; });
    caller_sleeping_.store(false, std::memory_order_relaxed);
  }

 private:
  // state_: epoch (bits 32..63, +1 per job), active (16..31), open (15: workers may join), inside (0..14)
  static constexpr std::uint64_t kOpen = 1u << 15, kInside = kOpen - 1;
  static constexpr std::chrono::microseconds kSpin{50};
  static std::uint32_t epoch(std::uint64_t s) { return static_cast<std::uint32_t>(s >> 32); }
  static int active(std::uint64_t s) { return static_cast<int>((s >> 16) & 0xffffu); }

  static void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    __asm__ __volatile__("yield");
#endif
  }
  // true once ready() holds, false if it did not within kSpin
  template <typename F> static bool spin(F ready) {
    const auto until = std::chrono::steady_clock::now() + kSpin;
    for (unsigned i = 1;; ++i) {
      if (ready()) return true;
      cpu_relax();
      if (i % 64 == 0 && std::chrono::steady_clock::now() >= until) return ready();
    }
  }

  void loop(int t) {
    std::uint32_t seen = 0;
    for (;;) {
      std::uint64_t s = state_.load(std::memory_order_acquire);
      if (epoch(s) == seen) {  // wait for the next job: spin, then sleep
        auto next = [&] {
          s = state_.load();
          return stop_.load(std::memory_order_relaxed) || epoch(s) != seen;
        };
        if (!spin(next)) {
          std::unique_lock<std::mutex> lk(mu_);
          sleeping_.fetch_add(1);
          start_.wait(lk, next);
          sleeping_.fetch_sub(1);
        }
        if (stop_.load()) return;
      }
      seen = epoch(s);
      // join while the job is open and counts this thread in
      while ((s & kOpen) && t < active(s) && epoch(s) == seen)
        if (state_.compare_exchange_weak(s, s + 1)) {
          fn_(ctx_, t);
          const std::uint64_t before = state_.fetch_sub(1);
          if ((before & kInside) == 1 && !(before & kOpen) && caller_sleeping_.load()) {
            { std::lock_guard<std::mutex> lk(mu_); }
            done_.notify_one();
          }
          break;
        }
    }
  }

  std::vector<std::thread> workers_;
  alignas(64) std::atomic<std::uint64_t> state_{0};
  std::atomic<int> sleeping_{0};      // workers asleep on start_
  std::atomic<bool> caller_sleeping_{false}, stop_{false};
  void (*fn_)(void*, int) = nullptr;  // the job (written before it is published)
  void* ctx_ = nullptr;
  alignas(64) std::mutex mu_;
  std::condition_variable start_, done_;
};

// one thread's buffer: a workspace of packs, then the call's packed
// inputs, outputs and scratch (64-byte aligned). The workspace has the
// linear layout until an operation needs the full one, and keeps the full
// one from then on (a full workspace serves every operation).
template <typename P> struct ThreadBuffer {
  std::unique_ptr<unsigned char[]> mem;
  unsigned long bytes = 0, ws_bytes = 0;
  WorkspaceLayout layout = kLinearWorkspace;
  Workspace<P> ws;
  unsigned char* base = nullptr;

  void reserve(int nb, int nv, long values, WorkspaceLayout need_layout) {
    if (need_layout == kFullWorkspace) layout = kFullWorkspace;
    ws_bytes = (workspace_bytes<P>(nb, nv, layout) + 63ul) & ~63ul;
    const unsigned long need = ws_bytes + sizeof(P) * static_cast<unsigned long>(values) + 64;
    if (need > bytes) {
      mem.reset(new unsigned char[need]);
      bytes = need;
      const auto addr = reinterpret_cast<std::uintptr_t>(mem.get());
      base = mem.get() + ((64 - addr % 64) % 64);
    }
    ws = carve_workspace<P>(base, nb, nv, layout);
  }
  P* values() { return reinterpret_cast<P*>(base + ws_bytes); }
};

}  // namespace

struct Engine::Impl {
  Model model;
  int threads;
  std::string dtype;
  int W;
  std::mutex call;
  Impl(const Model& m, int t, const std::string& d, int w) : model(m), threads(t), dtype(d), W(w) {}
  virtual ~Impl() = default;
  virtual unsigned long workspace_bytes() const = 0;
};

namespace {

// a row-major batch array: w values per sample, `stride` values from one
// sample to the next (w, or 0 for one sample broadcast over the batch); null: absent
template <typename T> struct In {
  const T* p;
  long w;
  long stride;
  In(const T* p_ = nullptr, long w_ = 0, long stride_ = -1) : p(p_), w(w_), stride(stride_ < 0 ? w_ : stride_) {}
};
template <typename T> struct Out {
  T* p;
  long w;
};

template <typename T> struct EngineT : Engine::Impl {
  static constexpr int W = Width<T>::value;
  using P = Pack<T, W>;
  static constexpr int kMaxArgs = ops::kMaxArgs;

  std::vector<BodyDesc<P>> bodies;
  ModelView<P> mv;
  std::vector<ThreadBuffer<P>> buffers;
  Pool pool;

  EngineT(const Model& m, int t, const std::string& d)
      : Engine::Impl(m, t, d, W), bodies(m.bodies_as<P>()), buffers(t), pool(t) {
    mv = {m.nb(), m.nq, m.nv, m.has_mimic() ? 1 : 0, bodies.data()};
  }
  unsigned long workspace_bytes() const override {
    unsigned long n = 0;
    for (const ThreadBuffer<P>& b : buffers) n += b.bytes;
    return n;
  }

  // the smallest sample any thread reports into `first` (-1: none yet)
  static void lower(std::atomic<long>& first, long s) {
    long cur = first.load(std::memory_order_relaxed);
    while ((cur < 0 || s < cur) && !first.compare_exchange_weak(cur, s, std::memory_order_relaxed)) {
    }
  }
  // NaN in lane l where one of x[0..n) holds an inf or a NaN in lane l, else
  // 0 (x - x is 0 for a finite x; four sums to overlap the additions)
  static P nonfinite_lanes(const P* x, long n) {
    P a0(0), a1(0), a2(0), a3(0);
    long k = 0;
    for (; k + 4 <= n; k += 4)
      a0 += x[k] - x[k], a1 += x[k + 1] - x[k + 1], a2 += x[k + 2] - x[k + 2], a3 += x[k + 3] - x[k + 3];
    for (; k < n; ++k) a0 += x[k] - x[k];
    return (a0 + a1) + (a2 + a3);
  }

  // kernel(w, in[], out[], scratch) -> false where a lane's mass matrix is not PD
  template <typename K> struct Job {
    EngineT* e;
    long B, packs;
    int active, nin, nout;
    In<T> in[kMaxArgs];
    Out<T> out[kMaxArgs];
    const K* kernel;
    std::atomic<long> failed{-1};          // the first sample of the first pack whose kernel failed
    std::atomic<long> nonfinite[kMaxArgs];  // per output: the first sample with an inf or a NaN
    alignas(64) std::atomic<long> next{0};  // the first pack not handed out yet (a cache line of its own)

    static void call(void* self, int t) { static_cast<Job*>(self)->work(t); }
    // the next packs [p0, p1) for one thread: guided chunks, each 1/(2·active)
    // of those left (at least one), so that threads that start late or run
    // slow still finish together, in O(active · log(packs)) claims
    bool claim(long& p0, long& p1) {
      long p = next.load(std::memory_order_relaxed);
      for (;;) {
        if (p >= packs) return false;
        const long n = std::max(1L, (packs - p) / (2L * active));
        if (next.compare_exchange_weak(p, p + n, std::memory_order_relaxed)) {
          p0 = p, p1 = p + n;
          return true;
        }
      }
    }
    // thread t's share, on its own buffer; which thread runs a pack does not
    // change its result (every pack runs the same code from its own inputs)
    void work(int t) {
      ThreadBuffer<P>& buf = e->buffers[t];
      P* ins[kMaxArgs] = {};
      P* outs[kMaxArgs] = {};
      P* v = buf.values();
      for (int i = 0; i < nin; ++i)
        if (in[i].p) ins[i] = v, v += in[i].w;
      for (int i = 0; i < nout; ++i)
        if (out[i].p) outs[i] = v, v += out[i].w;
      P* scr = v;
      long p0, p1;
      while (claim(p0, p1))
        for (long p = p0; p < p1; ++p) {
          const long s0 = p * W;
          const int valid = static_cast<int>(std::min<long>(W, B - s0));
          // gather: lane l holds sample s0 + l (the last valid one for padding)
          for (int i = 0; i < nin; ++i) {
            if (!in[i].p) continue;
            const long w = in[i].w;
            for (int l = 0; l < W; ++l) {
              const T* src = in[i].p + (s0 + std::min(l, valid - 1)) * in[i].stride;
              for (long k = 0; k < w; ++k) ins[i][k].v[l] = src[k];
            }
          }
          if (!(*kernel)(e->mv, buf.ws, ins, outs, scr)) lower(failed, s0);
          for (int i = 0; i < nout; ++i) {
            if (!out[i].p) continue;
            const long w = out[i].w;
            // results that overflowed despite the inputs' bounds
            const P bad = nonfinite_lanes(outs[i], w);
            for (int l = 0; l < valid; ++l)
              if (bad.v[l] != bad.v[l]) {
                lower(nonfinite[i], s0 + l);
                break;
              }
            // scatter the valid lanes
            for (int l = 0; l < valid; ++l) {
              T* dst = out[i].p + (s0 + l) * w;
              for (long k = 0; k < w; ++k) dst[k] = outs[i][k].v[l];
            }
          }
        }
    }
  };

  // the kernel on B knot points; `layout`: the workspace the kernel needs
  template <typename K>
  void run(const char* what, long B, std::initializer_list<In<T>> ins, std::initializer_list<Out<T>> outs,
           long scratch, const K& kernel, WorkspaceLayout layout = kFullWorkspace) {
    run(what, B, ins.begin(), static_cast<int>(ins.size()), outs.begin(), static_cast<int>(outs.size()), scratch,
        kernel, layout);
  }
  // the same on arrays; `failure`: the registered operation (its OpFailure names a failed sample's error)
  template <typename K>
  void run(const char* what, long B, const In<T>* ins, int nin, const Out<T>* outs, int nout, long scratch,
           const K& kernel, WorkspaceLayout layout, const ops::OpSpec* failure = nullptr) {
    if (B <= 0) {
      std::ostringstream os;
      os << what << ": B: expected a positive batch size, got " << B;
      throw std::invalid_argument(os.str());
    }
    std::lock_guard<std::mutex> lk(call);
    Job<K> job;
    job.e = this;
    job.B = B;
    job.packs = (B + W - 1) / W;
    job.active = static_cast<int>(std::min<long>(threads, job.packs));
    job.nin = nin;
    job.nout = nout;
    long values = scratch;
    for (int i = 0; i < nin; ++i) job.in[i] = ins[i], values += ins[i].p ? ins[i].w : 0;
    for (int i = 0; i < nout; ++i) job.out[i] = outs[i], values += outs[i].p ? outs[i].w : 0;
    for (std::atomic<long>& s : job.nonfinite) s.store(-1, std::memory_order_relaxed);
    job.kernel = &kernel;
    for (int t = 0; t < job.active; ++t) buffers[t].reserve(model.nb(), model.nv, values, layout);
    pool.run(job.active, &Job<K>::call, &job);
    const long f = job.failed.load();
    if (f >= 0) {
      // name the joint: the first sample of the failed pack (q: the first input) where one is singular
      std::vector<double> qs(model.nq);
      for (long s = f; s < std::min(B, f + W) && !(failure && failure->failure == ops::kNoMass); ++s) {
        for (int k = 0; k < model.nq; ++k) qs[k] = static_cast<double>(job.in[0].p[s * job.in[0].stride + k]);
        if (singular_joint(model, qs.data()) >= 0) throw_not_positive_definite(model, what, qs.data(), s);
      }
      if (failure) {
        for (int k = 0; k < model.nq; ++k) qs[k] = static_cast<double>(job.in[0].p[f * job.in[0].stride + k]);
        ops::throw_failure(model, *failure, qs.data(), f);
      }
      std::ostringstream os;
      os << what << ": the mass matrix (or a joint's articulated inertia) is not positive definite, or a stage "
         << "of an integrator step overflowed, in samples " << f << ".." << std::min(B, f + W) - 1;
      throw std::runtime_error(os.str());
    }
    // the first output that overflowed, at its first such sample
    for (int o = 0; o < job.nout; ++o) {
      const long s = job.nonfinite[o].load();
      if (s < 0) continue;
      std::ostringstream os;
      os << what << ": output " << o << " is not finite at sample " << s
         << ": the computation overflowed; reduce the inputs' magnitudes (or dt)";
      throw std::runtime_error(os.str());
    }
  }
};

template <typename T> EngineT<T>& impl_as(Engine::Impl* impl, const char* what) {
  const char* want = sizeof(T) == sizeof(double) ? "float64" : "float32";
  if (impl->dtype != want) {
    std::ostringstream os;
    os << what << ": the arrays are " << want << " but the engine was built for " << impl->dtype;
    throw std::invalid_argument(os.str());
  }
  return static_cast<EngineT<T>&>(*impl);
}

void check_type(const char* what, int type) {
  if (type < kEuler || type > kConstantAcceleration) {
    std::ostringstream os;
    os << what << ": integrator_type: expected 0..5 (euler, semi_implicit_euler, midpoint, rk4, trapezoidal, "
          "constant_acceleration), got "
       << type;
    throw std::invalid_argument(os.str());
  }
}
template <typename T> void check_dt(const char* what, T dt) {
  if (!(dt > 0) || !(dt <= T(kMaxTimeStep))) {
    std::ostringstream os;
    os << what << ": dt: expected a positive finite time step of at most " << kMaxTimeStep << " s, got " << dt;
    throw std::invalid_argument(os.str());
  }
}


// ---- the registered operations (ops/registry.hpp): one route per operation,
// generated from ops::AllOps in its order
template <typename T> using OpRoute = void (*)(EngineT<T>&, const ops::OpCall&);

template <typename T, typename Op> void op_route(EngineT<T>& e, const ops::OpCall& c) {
  using P = typename EngineT<T>::P;
  const ops::OpSpec& op = Op::spec;
  const Model& m = e.model;
  // arrays in argument order (a parameter holds an empty slot), outputs in order
  In<T> ins[ops::kMaxArgs];
  Out<T> outs[ops::kMaxOutputs];
  ops::OpArgs<P> base{};
  for (int k = 0; k < op.n_args; ++k) {
    const long w = ops::arg_values(op.args[k], m);
    if (op.args[k].kind == ops::kArray || op.args[k].kind == ops::kOptionalArray)
      ins[k] = In<T>(static_cast<const T*>(c.in[k]), c.in[k] ? w : 0, c.batched[k] ? w : 0);
    base.real[k] = P(static_cast<T>(c.real[k]));
    base.choice[k] = c.choice[k];
  }
  for (int o = 0; o < op.n_out; ++o) outs[o] = {static_cast<T*>(c.out[o]), ops::out_values(op.out[o], m)};
  auto kernel = [&base, &op](const ModelView<P>& mv, Workspace<P>& w, P* const* in, P* const* out,
                             P* scratch) RBD_ENGINE_KERNEL {
    ops::OpArgs<P> a = base;
    for (int k = 0; k < op.n_args; ++k) a.in[k] = in[k];
    for (int o = 0; o < op.n_out; ++o) a.out[o] = out[o];
    a.scratch = scratch;
    return Op::run(mv, w, a);
  };
  e.run(op.name, c.B, ins, op.n_args, outs, op.n_out, ops::scratch_values(op, m), kernel, ops::workspace_layout(op, m),
        &op);
}

template <typename T, typename... Op> const OpRoute<T>* op_routes(ops::OpList<Op...>) {
  static const OpRoute<T> routes[] = {&op_route<T, Op>...};
  return routes;
}

}  // namespace

// ---------------------------------------------------------------- Engine
int Engine::default_threads() {
  const unsigned n = std::thread::hardware_concurrency();
  return n > 0 ? static_cast<int>(n) : 1;
}

Engine::Engine(const Model& model, int threads, const std::string& dtype) {
  if (threads <= 0 || threads > 1024) {
    std::ostringstream os;
    os << "threads: expected a thread count in 1..1024, got " << threads;
    throw std::invalid_argument(os.str());
  }
  if (dtype == "float64") impl_.reset(new EngineT<double>(model, threads, dtype));
  else if (dtype == "float32") impl_.reset(new EngineT<float>(model, threads, dtype));
  else throw std::invalid_argument("dtype: expected 'float64' or 'float32', got '" + dtype + "'");
}
Engine::~Engine() = default;

int Engine::threads() const { return impl_->threads; }
const std::string& Engine::dtype() const { return impl_->dtype; }
int Engine::simd_width() const { return impl_->W; }
const Model& Engine::model() const { return impl_->model; }
unsigned long Engine::workspace_bytes() const { return impl_->workspace_bytes(); }

// ---- the typed entry points: registered operations (ops/registry.hpp)
namespace {
template <typename T> struct Call : ops::OpCall {
  explicit Call(long b) { B = b; }
  Call& input(int k, const T* p) { in[k] = p, batched[k] = true; return *this; }
  Call& output(int k, T* p) { out[k] = p; return *this; }
};
template <typename Op> constexpr int id_of() { return ops::index_of<Op>(ops::AllOps{}); }
}  // namespace

template <typename T>
void Engine::inverse_dynamics(long B, const T* q, const T* qd, const T* qdd, T gravity, T* tau) {
  impl_as<T>(impl_.get(), "inverse_dynamics");  // the engine's dtype only
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, qdd).output(0, tau).real[3] = gravity;
  run_op(id_of<ops::InverseDynamics>(), c);
}

template <typename T> void Engine::crba(long B, const T* q, T* M) {
  impl_as<T>(impl_.get(), "crba");  // the engine's dtype only
  run_op(id_of<ops::Crba>(), Call<T>(B).input(0, q).output(0, M));
}

template <typename T> void Engine::minv(long B, const T* q, T* Minv) {
  impl_as<T>(impl_.get(), "minv");  // the engine's dtype only
  Call<T> c(B);
  c.input(0, q).output(0, Minv).choice[1] = 1;  // dense
  run_op(id_of<ops::Minv>(), c);
}

template <typename T>
void Engine::forward_dynamics(long B, const T* q, const T* qd, const T* tau, T gravity, T* qdd) {
  impl_as<T>(impl_.get(), "forward_dynamics");  // the engine's dtype only
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, tau).output(0, qdd).real[4] = gravity;
  run_op(id_of<ops::Aba>(), c);
}

template <typename T>
void Engine::inverse_dynamics_gradient(long B, const T* q, const T* qd, const T* qdd, T gravity, T* dtau_dq,
                                       T* dtau_dqd) {
  impl_as<T>(impl_.get(), "inverse_dynamics_gradient");  // the engine's dtype only
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, qdd).output(1, dtau_dq).output(2, dtau_dqd).real[3] = gravity;
  run_op(id_of<ops::InverseDynamicsGradient>(), c);
}

template <typename T>
void Engine::forward_dynamics_gradient(long B, const T* q, const T* qd, const T* tau, T gravity, T* dqdd_dq,
                                       T* dqdd_dqd, T* Minv) {
  impl_as<T>(impl_.get(), "forward_dynamics_gradient");  // the engine's dtype only
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, tau).output(0, dqdd_dq).output(1, dqdd_dqd).output(3, Minv).real[4] = gravity;
  run_op(id_of<ops::ForwardDynamicsGradient>(), c);
}

template <typename T>
void Engine::integrator(long B, const T* q, const T* qd, const T* u, T dt, T gravity, int type, T* x) {
  impl_as<T>(impl_.get(), "integrator");  // the engine's dtype only
  check_type("integrator", type);
  check_dt("integrator", dt);
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, u).output(0, x);
  c.real[3] = dt, c.choice[4] = type, c.real[6] = gravity;
  run_op(id_of<ops::Integrator>(), c);
}

template <typename T>
void Engine::integrator_gradient(long B, const T* q, const T* qd, const T* u, T dt, T gravity, int type, T* x,
                                 T* AB) {
  impl_as<T>(impl_.get(), "integrator_gradient");  // the engine's dtype only
  check_type("integrator_gradient", type);
  check_dt("integrator_gradient", dt);
  Call<T> c(B);
  c.input(0, q).input(1, qd).input(2, u).output(0, x).output(1, AB);
  c.real[3] = dt, c.choice[4] = type, c.real[6] = gravity;
  run_op(id_of<ops::IntegratorGradient>(), c);
}

void Engine::run_op(int op, const ops::OpCall& call) {
  if (op < 0 || op >= ops::AllOps::size) throw std::invalid_argument("run_op: unknown operation id " + std::to_string(op));
  const char* what = ops::op_table()[op].spec->name;
  if (call.B <= 0) {
    std::ostringstream os;
    os << what << ": B: expected a positive batch size, got " << call.B;
    throw std::invalid_argument(os.str());
  }
  if (impl_->dtype == "float64") op_routes<double>(ops::AllOps{})[op](impl_as<double>(impl_.get(), what), call);
  else op_routes<float>(ops::AllOps{})[op](impl_as<float>(impl_.get(), what), call);
}


#define RBD_ENGINE_INSTANTIATE(T)                                                                              \
  template void Engine::inverse_dynamics<T>(long, const T*, const T*, const T*, T, T*);                       \
  template void Engine::crba<T>(long, const T*, T*);                                                          \
  template void Engine::minv<T>(long, const T*, T*);                                                          \
  template void Engine::forward_dynamics<T>(long, const T*, const T*, const T*, T, T*);                       \
  template void Engine::inverse_dynamics_gradient<T>(long, const T*, const T*, const T*, T, T*, T*);          \
  template void Engine::forward_dynamics_gradient<T>(long, const T*, const T*, const T*, T, T*, T*, T*);      \
  template void Engine::integrator<T>(long, const T*, const T*, const T*, T, T, int, T*);                     \
  template void Engine::integrator_gradient<T>(long, const T*, const T*, const T*, T, T, int, T*, T*);
RBD_ENGINE_INSTANTIATE(double)
RBD_ENGINE_INSTANTIATE(float)
#undef RBD_ENGINE_INSTANTIATE

}  // namespace rbd
