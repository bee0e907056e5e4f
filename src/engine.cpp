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

// ---- persistent pool: n - 1 workers; run() hands job(t) to threads
// t = 0..active-1 (the caller runs t = 0) and returns when all are done
class Pool {
 public:
  explicit Pool(int n) {
    for (int t = 1; t < n; ++t) workers_.emplace_back([this, t] { loop(t); });
  }
  ~Pool() {
    {
      std::lock_guard<std::mutex> lk(mu_);
      stop_ = true;
    }
    start_.notify_all();
    for (std::thread& th : workers_) th.join();
  }
  // fn must not throw
  void run(int active, void (*fn)(void*, int), void* ctx) {
    if (active > 1) {
      std::lock_guard<std::mutex> lk(mu_);
      fn_ = fn, ctx_ = ctx, active_ = active, pending_ = active - 1;
      ++generation_;
    }
    if (active > 1) start_.notify_all();
    fn(ctx, 0);
    if (active > 1) {
      std::unique_lock<std::mutex> lk(mu_);
      done_.wait(lk, [this] { return pending_ == 0; });
    }
  }

 private:
  void loop(int t) {
    long seen = 0;
    for (;;) {
      void (*fn)(void*, int);
      void* ctx;
      {
        std::unique_lock<std::mutex> lk(mu_);
        start_.wait(lk, [&] { return stop_ || generation_ != seen; });
        if (stop_) return;
        seen = generation_;
        if (t >= active_) continue;
        fn = fn_, ctx = ctx_;
      }
      fn(ctx, t);
      std::lock_guard<std::mutex> lk(mu_);
      if (--pending_ == 0) done_.notify_one();
    }
  }

  std::vector<std::thread> workers_;
  std::mutex mu_;
  std::condition_variable start_, done_;
  void (*fn_)(void*, int) = nullptr;
  void* ctx_ = nullptr;
  int active_ = 0, pending_ = 0;
  long generation_ = 0;
  bool stop_ = false;
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

  // kernel(w, in[], out[], scratch) -> false where a lane's mass matrix is not PD
  template <typename K> struct Job {
    EngineT* e;
    long B, packs;
    int active, nin, nout;
    In<T> in[kMaxArgs];
    Out<T> out[kMaxArgs];
    long scratch;
    const K* kernel;
    std::atomic<long> failed{-1};

    static void call(void* self, int t) { static_cast<Job*>(self)->work(t); }
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
      const long p0 = packs * t / active, p1 = packs * (t + 1) / active;
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
        if (!(*kernel)(e->mv, buf.ws, ins, outs, scr)) {
          long cur = failed.load();
          while ((cur < 0 || s0 < cur) && !failed.compare_exchange_weak(cur, s0)) {
          }
        }
        // scatter the valid lanes
        for (int i = 0; i < nout; ++i) {
          if (!out[i].p) continue;
          const long w = out[i].w;
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
    job.scratch = scratch;
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
    // results that overflowed despite the inputs' bounds (one pass over the outputs)
    for (int o = 0; o < job.nout; ++o) {
      const Out<T>& a = job.out[o];
      if (!a.p) continue;
      for (long k = 0; k < B * a.w; ++k)
        if (!std::isfinite(a.p[k])) {
          std::ostringstream os;
          os << what << ": output " << o << " is not finite at sample " << k / a.w
             << ": the computation overflowed; reduce the inputs' magnitudes (or dt)";
          throw std::runtime_error(os.str());
        }
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

template <typename T>
void Engine::inverse_dynamics(long B, const T* q, const T* qd, const T* qdd, T gravity, T* tau) {
  auto& e = impl_as<T>(impl_.get(), "inverse_dynamics");
  using P = typename EngineT<T>::P;
  const int nq = e.model.nq, nv = e.model.nv;
  const P g(gravity);
  auto k = [g](const ModelView<P>& m, Workspace<P>& w, P* const* in, P* const* out, P*) RBD_ENGINE_KERNEL {
    rnea(m, w, in[0], in[1], in[2], static_cast<const P*>(nullptr), g, out[0]);
    return true;
  };
  e.run("inverse_dynamics", B, {{q, nq}, {qd, nv}, {qdd, nv}}, {{tau, nv}}, 0, k, kLinearWorkspace);
}

template <typename T> void Engine::crba(long B, const T* q, T* M) {
  auto& e = impl_as<T>(impl_.get(), "crba");
  using P = typename EngineT<T>::P;
  const int nq = e.model.nq, nv = e.model.nv;
  auto k = [](const ModelView<P>& m, Workspace<P>& w, P* const* in, P* const* out, P*) RBD_ENGINE_KERNEL {
    rbd::crba(m, w, in[0], out[0]);
    return true;
  };
  e.run("crba", B, {{q, nq}}, {{M, long(nv) * nv}}, 0, k);
}

template <typename T> void Engine::minv(long B, const T* q, T* Minv) {
  auto& e = impl_as<T>(impl_.get(), "minv");
  using P = typename EngineT<T>::P;
  const int nq = e.model.nq, nv = e.model.nv;
  auto k = [](const ModelView<P>& m, Workspace<P>& w, P* const* in, P* const* out, P*) RBD_ENGINE_KERNEL {
    return rbd::minv(m, w, in[0], true, out[0]);
  };
  e.run("minv", B, {{q, nq}}, {{Minv, long(nv) * nv}}, 0, k);
}

template <typename T>
void Engine::forward_dynamics(long B, const T* q, const T* qd, const T* tau, T gravity, T* qdd) {
  auto& e = impl_as<T>(impl_.get(), "forward_dynamics");
  using P = typename EngineT<T>::P;
  const int nq = e.model.nq, nv = e.model.nv;
  const P g(gravity);
  auto k = [g](const ModelView<P>& m, Workspace<P>& w, P* const* in, P* const* out, P*) RBD_ENGINE_KERNEL {
    return aba(m, w, in[0], in[1], in[2], static_cast<const P*>(nullptr), g, out[0]);
  };
  e.run("forward_dynamics", B, {{q, nq}, {qd, nv}, {tau, nv}}, {{qdd, nv}}, 0, k, aba_layout(e.model));
}

template <typename T>
void Engine::inverse_dynamics_gradient(long B, const T* q, const T* qd, const T* qdd, T gravity, T* dtau_dq,
                                       T* dtau_dqd) {
  auto& e = impl_as<T>(impl_.get(), "inverse_dynamics_gradient");
  using P = typename EngineT<T>::P;
  const int nq = e.model.nq, nv = e.model.nv;
  const P g(gravity);
  auto k = [g](const ModelView<P>& m, Workspace<P>& w, P* const* in, P* const* out, P*) RBD_ENGINE_KERNEL {
    rnea_derivatives(m, w, in[0], in[1], in[2], static_cast<const P*>(nullptr), g, out[0], out[1]);
    return true;
  };
  e.run("inverse_dynamics_gradient", B, {{q, nq}, {qd, nv}, {qdd, nv}}, {{dtau_dq, long(nv) * nv}, {dtau_dqd, long(nv) * nv}},
        0, k);
}

template <typename T>
void Engine::forward_dynamics_gradient(long B, const T* q, const T* qd, const T* tau, T gravity, T* dqdd_dq,
                                       T* dqdd_dqd, T* Minv) {
  auto& e = impl_as<T>(impl_.get(), "forward_dynamics_gradient");
  using P = typename EngineT<T>::P;
  const int nq = e.model.nq, nv = e.model.nv;
  const P g(gravity);
  auto k = [g, nv](const ModelView<P>& m, Workspace<P>& w, P* const* in, P* const* out, P* scratch) RBD_ENGINE_KERNEL {
    if (!aba_derivatives(m, w, in[0], in[1], in[2], static_cast<const P*>(nullptr), g, scratch, out[0], out[1]))
      return false;
    if (out[2]) {
      if (m.has_mimic) return rbd::minv(m, w, in[0], true, out[2]);  // w.dense holds a Cholesky factor there
      for (long i = 0; i < long(nv) * nv; ++i) out[2][i] = w.dense[i];
    }
    return true;
  };
  e.run("forward_dynamics_gradient", B, {{q, nq}, {qd, nv}, {tau, nv}},
        {{dqdd_dq, long(nv) * nv}, {dqdd_dqd, long(nv) * nv}, {Minv, long(nv) * nv}}, nv, k);
}

template <typename T>
void Engine::integrator(long B, const T* q, const T* qd, const T* u, T dt, T gravity, int type, T* x) {
  auto& e = impl_as<T>(impl_.get(), "integrator");
  check_type("integrator", type);
  check_dt("integrator", dt);
  using P = typename EngineT<T>::P;
  const int nq = e.model.nq, nv = e.model.nv;
  const P g(gravity), h(dt);
  auto k = [g, h, type, nq](const ModelView<P>& m, Workspace<P>& w, P* const* in, P* const* out, P* scratch) RBD_ENGINE_KERNEL {
    return integrator_step(m, w, type, in[0], in[1], in[2], static_cast<const P*>(nullptr), h, g, out[0],
                           out[0] + nq, scratch);
  };
  e.run("integrator", B, {{q, nq}, {qd, nv}, {u, nv}}, {{x, nq + nv}}, integrator_scratch_values(nq, nv), k,
        aba_layout(e.model));  // every explicit step runs on aba
}

template <typename T>
void Engine::integrator_gradient(long B, const T* q, const T* qd, const T* u, T dt, T gravity, int type, T* x,
                                 T* AB) {
  auto& e = impl_as<T>(impl_.get(), "integrator_gradient");
  check_type("integrator_gradient", type);
  check_dt("integrator_gradient", dt);
  using P = typename EngineT<T>::P;
  const int nq = e.model.nq, nv = e.model.nv;
  const P g(gravity), h(dt);
  auto k = [g, h, type, nq](const ModelView<P>& m, Workspace<P>& w, P* const* in, P* const* out, P* scratch) RBD_ENGINE_KERNEL {
    return rbd::integrator_gradient(m, w, type, in[0], in[1], in[2], static_cast<const P*>(nullptr), h, g, out[0],
                                    out[0] + nq, out[1], scratch);
  };
  e.run("integrator_gradient", B, {{q, nq}, {qd, nv}, {u, nv}}, {{x, nq + nv}, {AB, 6L * nv * nv}},
        integrator_gradient_scratch_values(nq, nv), k);
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
