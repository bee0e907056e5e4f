// src/batch/engine/engine_impl.hpp — the engine's implementation (private to
// src/batch/engine.cpp and src/batch/engine/routes_<dtype>.cpp): the per-dtype engine, its
// per-thread buffers, and the route of a registered operation, op_route<T, Op>:
// gather a pack of W samples into SIMD lanes, run Op's per-sample kernel
// (ops/registry.hpp) on Pack<T, W> (simd.hpp), scatter the lanes back.
//
// The routes of each dtype are compiled in a file of their own
// (src/batch/engine/routes_<dtype>.cpp), so that a parallel build compiles the two
// side by side; src/batch/engine.cpp holds one table per dtype (routes<T>()).
//
// Every file that includes this one is compiled with RBDKIT_ENGINE_ARCH
// (CMake option, default "native": the build machine's vector instructions);
// W follows from it: 8 doubles / 16 floats with AVX-512, 4 / 8 with AVX, 2 / 4
// otherwise.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/batch/engine.hpp"
#include "rbdkit/batch/simd.hpp"
#include "rbdkit/ops/registry.hpp"
#include "rbdkit/ops/table.hpp"
#include "pool.hpp"

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

// a pack's kernel inlines everything it calls (the engine's speed);
// RBDKIT_NO_FLATTEN (the sanitizer build) skips that to compile faster, as RBD_FLATTEN does
#ifdef RBDKIT_NO_FLATTEN
#define RBD_ENGINE_KERNEL
#else
#define RBD_ENGINE_KERNEL __attribute__((flatten))
#endif

namespace rbd {

struct Engine::Impl {
  Model model;
  int threads;
  std::string dtype;
  int W;
  long max_job_packs = engine_detail::Pool::kMaxUnits;  // the packs of one pool job (Engine::set_max_job_packs)
  std::mutex call;
  Impl(const Model& m, int t, const std::string& d, int w) : model(m), threads(t), dtype(d), W(w) {}
  virtual ~Impl() = default;
  virtual unsigned long workspace_bytes() const = 0;
};

namespace engine_detail {

template <typename T> struct Width;
template <> struct Width<double> { static constexpr int value = RBDKIT_ENGINE_W64; };
template <> struct Width<float> { static constexpr int value = RBDKIT_ENGINE_W32; };

// one thread's buffer: a workspace of packs, then the call's packed
// inputs, outputs and scratch (64-byte aligned). The workspace has the
// linear layout until an operation needs the full one, and keeps the full
// one from then on (a full workspace serves every operation).
//
// Thread t's buffer is read by thread t in every call, and set up by the
// caller before it; reserve() writes it only when it changes (a new layout
// or more memory), so that the worker's cached copy stays valid from call to
// call. Each buffer has cache lines of its own.
template <typename P> struct alignas(64) ThreadBuffer {
  std::unique_ptr<unsigned char[]> mem;
  unsigned long bytes = 0, ws_bytes = 0;
  WorkspaceLayout layout = kLinearWorkspace;
  bool carved = false;
  Workspace<P> ws;
  unsigned char* base = nullptr;

  void reserve(int nb, int nv, long values, WorkspaceLayout need_layout) {
    const bool relayout = need_layout == kFullWorkspace && layout != kFullWorkspace;
    if (relayout) layout = kFullWorkspace;
    if (relayout || !carved) ws_bytes = (workspace_bytes<P>(nb, nv, layout) + 63ul) & ~63ul;
    const unsigned long need = ws_bytes + sizeof(P) * static_cast<unsigned long>(values) + 64;
    const bool grow = need > bytes;
    if (grow) {
      mem.reset(new unsigned char[need]);
      bytes = need;
      const auto addr = reinterpret_cast<std::uintptr_t>(mem.get());
      base = mem.get() + ((64 - addr % 64) % 64);
    }
    if (grow || relayout || !carved) ws = carve_workspace<P>(base, nb, nv, layout), carved = true;
  }
  P* values() { return reinterpret_cast<P*>(base + ws_bytes); }
};

// a row-major batch array: w values per sample, `stride` values from one
// sample to the next (w, or 0 for one sample broadcast over the batch); null: absent
template <typename T> struct In {
  const T* p = nullptr;
  long w = 0;
  long stride = 0;
};
template <typename T> struct Out {
  T* p = nullptr;
  long w = 0;
};

// a call as the threads read it: its arrays and parameters, the same for
// every registered operation (the ones it lacks are empty). The engine keeps
// one, and a call writes only the cache lines of it that change (publish),
// so that a worker's copy of the rest stays valid: repeated calls on the
// same arrays hand the worker nothing but the pool's job word.
template <typename T> struct alignas(64) JobDesc {
  long B, packs;
  long first;  // the pool's unit u is pack first + u (a batch of more than max_job_packs packs runs as several jobs)
  In<T> in[ops::kMaxArgs];  // the arrays in argument order (a parameter's slot is empty)
  Out<T> out[ops::kMaxOutputs];
  T real[ops::kMaxArgs];  // the parameters, broadcast to every lane by each thread
  int choice[ops::kMaxArgs];
  const int* ee;
  int n_ee;
};
// copy `from` over `to`, line by line, writing only the lines that differ
template <typename D> void publish(D& to, const D& from) {
  static_assert(std::is_trivially_copyable<D>::value && alignof(D) >= 64, "a job description");
  auto* dst = reinterpret_cast<unsigned char*>(&to);
  const auto* src = reinterpret_cast<const unsigned char*>(&from);
  for (std::size_t k = 0; k < sizeof(D); k += 64) {
    const std::size_t n = std::min<std::size_t>(64, sizeof(D) - k);
    if (std::memcmp(dst + k, src + k, n) != 0) std::memcpy(dst + k, src + k, n);
  }
}
// where a call's kernels failed, written by the threads only on failure
struct alignas(64) JobFaults {
  std::atomic<long> failed{-1};                   // the first sample of the first pack whose kernel failed
  std::atomic<long> nonfinite[ops::kMaxOutputs];  // per output: the first sample with an inf or a NaN
  JobFaults() { reset(); }
  void reset() {  // without a write where nothing failed
    if (failed.load(std::memory_order_relaxed) != -1) failed.store(-1, std::memory_order_relaxed);
    for (std::atomic<long>& s : nonfinite)
      if (s.load(std::memory_order_relaxed) != -1) s.store(-1, std::memory_order_relaxed);
  }
};

template <typename T> struct EngineT : Engine::Impl {
  static constexpr int W = Width<T>::value;
  using P = Pack<T, W>;

  std::vector<BodyDesc<P>> bodies;
  ModelView<P> mv;
  std::vector<ThreadBuffer<P>> buffers;
  JobDesc<T> job{};  // the current call (JobDesc)
  JobFaults faults;
  Pool pool;

  EngineT(const Model& m, int t, const std::string& d)
      : Engine::Impl(m, t, d, W), bodies(m.bodies_as<P>()), buffers(t), pool(t) {
    mv = {m.nb(), m.nq, m.nv, m.general_path() ? 1 : 0, bodies.data()};
  }
  unsigned long workspace_bytes() const override {
    unsigned long n = 0;
    for (const ThreadBuffer<P>& b : buffers) n += b.bytes;
    return n;
  }
};

// the smallest sample any thread reports into `first` (-1: none yet)
inline void lower(std::atomic<long>& first, long s) {
  long cur = first.load(std::memory_order_relaxed);
  while ((cur < 0 || s < cur) && !first.compare_exchange_weak(cur, s, std::memory_order_relaxed)) {
  }
}
// NaN in lane l where one of x[0..n) holds an inf or a NaN in lane l, else
// 0 (x - x is 0 for a finite x; four sums to overlap the additions)
template <typename P> P nonfinite_lanes(const P* x, long n) {
  P a0(0), a1(0), a2(0), a3(0);
  long k = 0;
  for (; k + 4 <= n; k += 4)
    a0 += x[k] - x[k], a1 += x[k + 1] - x[k + 1], a2 += x[k + 2] - x[k + 2], a3 += x[k + 3] - x[k + 3];
  for (; k < n; ++k) a0 += x[k] - x[k];
  return (a0 + a1) + (a2 + a3);
}

// one pack through Op's kernel: a function of its own with everything it
// calls inlined (the engine's speed), called once per pack. Defaults: the
// call has no optional array and the Pinocchio convention, and the kernel
// is compiled with those as constants (the MuJoCo path and the f_ext terms
// drop out of the common case)
template <typename Op, bool Defaults, typename P>
inline bool run_kernel(const ModelView<P>& m, Workspace<P>& w, const ops::OpArgs<P>& a) {
  if constexpr (Defaults) {
    ops::OpArgs<P> d = a;
    for (int k = 0; k < Op::spec.n_args; ++k) {
      if (Op::spec.args[k].kind == ops::kOptionalArray) d.in[k] = nullptr;
      if (Op::spec.args[k].kind == ops::kConvention) d.choice[k] = kPinocchioConvention;
    }
    return Op::run(m, w, d);
  } else {
    return Op::run(m, w, a);
  }
}
template <typename Op, bool Defaults, typename P>
RBD_ENGINE_KERNEL __attribute__((noinline)) bool run_pack(const ModelView<P>& m, Workspace<P>& w,
                                                         const ops::OpArgs<P>& a) {
  return run_kernel<Op, Defaults>(m, w, a);
}
// a kernel the spec marks kCalled: compiled as written (ops/op.hpp, OpKernel)
template <typename Op, bool Defaults, typename P>
__attribute__((noinline)) bool run_pack_called(const ModelView<P>& m, Workspace<P>& w, const ops::OpArgs<P>& a) {
  return run_kernel<Op, Defaults>(m, w, a);
}

// the registered operation Op (ops/registry.hpp) on the engine's current
// call (EngineT::job), thread t's part
template <typename T, typename Op> struct Job {
  using E = EngineT<T>;
  using P = typename E::P;
  static constexpr int W = E::W;
  static constexpr const ops::OpSpec& op = Op::spec;

  static void call(void* engine, int t, Pool::Claims& claims) { work(*static_cast<E*>(engine), t, claims); }
  // thread t's packs, on its own buffer; which thread runs a pack does not
  // change its result (every pack runs the same code from its own inputs)
  static void work(E& e, int t, Pool::Claims& claims) {
    const JobDesc<T>& d = e.job;
    ThreadBuffer<P>& buf = e.buffers[t];
    // this thread's packed arrays: inputs, outputs, then the scratch; the parameters broadcast
    ops::OpArgs<P> a{};
    P* v = buf.values();
    for (int i = 0; i < op.n_args; ++i) {
      a.in[i] = d.in[i].p ? v : nullptr;
      if (d.in[i].p) v += d.in[i].w;
      a.real[i] = P(d.real[i]);
      a.choice[i] = d.choice[i];
    }
    for (int o = 0; o < op.n_out; ++o) {
      a.out[o] = d.out[o].p ? v : nullptr;
      if (d.out[o].p) v += d.out[o].w;
    }
    a.scratch = v, a.ee = d.ee, a.n_ee = d.n_ee;
    // the default parameters' kernel (operations with a convention only)
    bool defaults = ops::takes_convention(Op::spec);
    for (int k = 0; k < op.n_args; ++k) {
      if (op.args[k].kind == ops::kOptionalArray && d.in[k].p) defaults = false;
      if (op.args[k].kind == ops::kConvention && d.choice[k] != kPinocchioConvention) defaults = false;
    }
    const long B = d.B;
    long p0, p1;
    while (claims.next(p0, p1))
      for (long p = d.first + p0; p < d.first + p1; ++p) {
        const long s0 = p * W;
        const int valid = static_cast<int>(std::min<long>(W, B - s0));
        // gather: lane l holds sample s0 + l (the last valid one for padding)
        for (int i = 0; i < op.n_args; ++i) {
          const In<T>& in = d.in[i];
          if (!in.p) continue;
          P* dst = const_cast<P*>(a.in[i]);
          for (int l = 0; l < W; ++l) {
            const T* src = in.p + (s0 + std::min(l, valid - 1)) * in.stride;
            for (long k = 0; k < in.w; ++k) dst[k].v[l] = src[k];
          }
        }
        bool ok;
        if constexpr (Op::spec.kernel == ops::kCalled)
          ok = run_pack_called<Op, false>(e.mv, buf.ws, a);
        else if constexpr (ops::takes_convention(Op::spec))
          ok = defaults ? run_pack<Op, true>(e.mv, buf.ws, a) : run_pack<Op, false>(e.mv, buf.ws, a);
        else
          ok = run_pack<Op, false>(e.mv, buf.ws, a);
        if (!ok) lower(e.faults.failed, s0);
        for (int o = 0; o < op.n_out; ++o) {
          const Out<T>& out = d.out[o];
          if (!out.p) continue;
          // results that overflowed despite the inputs' bounds
          if (op.outputs == ops::kFiniteOutputs) {
            const P bad = nonfinite_lanes(a.out[o], out.w);
            for (int l = 0; l < valid; ++l)
              if (bad.v[l] != bad.v[l]) {
                lower(e.faults.nonfinite[o], s0 + l);
                break;
              }
          }
          // scatter the valid lanes
          for (int l = 0; l < valid; ++l) {
            T* dst = out.p + (s0 + l) * out.w;
            for (long k = 0; k < out.w; ++k) dst[k] = a.out[o][k].v[l];
          }
        }
      }
  }
};

// Op on c.B samples of engine e: pack the call, share the packs among the
// threads, then name the first failed sample or the first overflowed output
template <typename T, typename Op> void op_route(EngineT<T>& e, const ops::OpCall& c) {
  const ops::OpSpec& op = Op::spec;
  const Model& m = e.model;
  std::lock_guard<std::mutex> lk(e.call);
  // the call's description, written over the engine's where it changed
  JobDesc<T> job;
  std::memset(static_cast<void*>(&job), 0, sizeof job);  // padding too: publish compares bytes
  job.B = c.B;
  job.packs = (c.B + EngineT<T>::W - 1) / EngineT<T>::W;
  long values = ops::scratch_values(op, m);
  for (int k = 0; k < op.n_args; ++k) {
    const long w = ops::arg_values(op.args[k], m, c.n_ee);
    // arrays, and a frame's placement (ops::resolve_names), packed per lane
    if ((op.args[k].kind == ops::kArray || op.args[k].kind == ops::kOptionalArray || op.args[k].kind == ops::kFrame) &&
        c.in[k]) {
      job.in[k] = {static_cast<const T*>(c.in[k]), w, c.batched[k] ? w : 0};
      values += w;
    }
    job.real[k] = static_cast<T>(c.real[k]);
    job.choice[k] = c.choice[k];
  }
  job.ee = c.ee;
  job.n_ee = c.n_ee;
  for (int o = 0; o < op.n_out; ++o) {
    job.out[o] = {static_cast<T*>(c.out[o]), ops::out_values(op.out[o], m, c.n_ee)};
    values += c.out[o] ? job.out[o].w : 0;
  }
  e.faults.reset();
  const WorkspaceLayout layout = ops::workspace_layout(op, m);
  const int active = static_cast<int>(std::min<long>(e.threads, job.packs));
  for (int t = 0; t < active; ++t) e.buffers[t].reserve(m.nb(), m.nv, values, layout);
  for (job.first = 0; job.first < job.packs; job.first += e.max_job_packs) {
    const long units = std::min(e.max_job_packs, job.packs - job.first);
    publish(e.job, job);
    e.pool.run(static_cast<int>(std::min<long>(active, units)), units, &Job<T, Op>::call, &e);
  }

  const long f = e.faults.failed.load();
  if (f >= 0) {
    // the failed pack's lanes one at a time, in float64 on the serial kernel: the first that fails is
    // the sample to name (f when none does: a float32 failure float64 does not see)
    const long last = std::min(c.B, f + EngineT<T>::W);
    long s_fail = -1;
    {
      const ops::Kernel<double> kernel = ops::op_table()[ops::index_of<Op>(ops::AllOps{})].run;
      WorkspaceBuffer wb(m, ops::workspace_layout(op, m));
      std::vector<double> scratch(static_cast<size_t>(ops::scratch_values(op, m)) + 1);
      std::vector<std::vector<double>> ins(op.n_args), outs(op.n_out);
      for (long s = f; s < last && s_fail < 0; ++s) {
        ops::OpArgs<double> a{};
        for (int k = 0; k < op.n_args; ++k) {
          a.real[k] = c.real[k], a.choice[k] = c.choice[k];
          if (!job.in[k].p) continue;
          const T* x = job.in[k].p + s * job.in[k].stride;
          ins[k].assign(x, x + job.in[k].w);
          a.in[k] = ins[k].data();
        }
        for (int o = 0; o < op.n_out; ++o)
          if (job.out[o].p) outs[o].assign(static_cast<size_t>(job.out[o].w), 0.0), a.out[o] = outs[o].data();
        a.scratch = scratch.data(), a.ee = c.ee, a.n_ee = c.n_ee;
        if (!kernel(m.view(), wb.get(), a)) s_fail = s;
      }
    }
    if (s_fail < 0) s_fail = f;
    // name the joint where one is singular (q: the first input)
    std::vector<double> qs(m.nq);
    for (int k = 0; k < m.nq; ++k) qs[k] = static_cast<double>(job.in[0].p[s_fail * job.in[0].stride + k]);
    if (op.failure != ops::kNoMass && singular_joint(m, qs.data()) >= 0)
      throw_not_positive_definite(m, op.name, qs.data(), s_fail);
    ops::throw_failure(m, op, qs.data(), s_fail, &c);
  }
  // the first output that overflowed, at its first such sample
  for (int o = 0; o < op.n_out; ++o) {
    const long s = e.faults.nonfinite[o].load();
    if (s < 0) continue;
    std::ostringstream os;
    os << op.name << ": output " << o << " is not finite at sample " << s
       << ": the computation overflowed; reduce the inputs' magnitudes (or dt)";
    throw std::runtime_error(os.str());
  }
}

template <typename T> using OpRoute = void (*)(EngineT<T>&, const ops::OpCall&);

// the routes of every operation, table[i] = op_route<T, Op_i> for the i-th
// operation of ops::AllOps; instantiated in src/batch/engine/routes_<dtype>.cpp
// only (engine.cpp declares them extern)
template <typename T, typename... Op> void fill_routes(OpRoute<T>* table, ops::OpList<Op...>) {
  int i = 0;
  ((table[i++] = &op_route<T, Op>), ...);
}
template <typename T> void add_routes(OpRoute<T>* table) { fill_routes<T>(table, ops::AllOps{}); }

}  // namespace engine_detail
}  // namespace rbd

