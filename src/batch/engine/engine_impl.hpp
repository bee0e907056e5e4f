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
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
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

// thread t's share of a call's packs, [next, end): claimed from the front by t, and by the others once
// their own is done (Job::claim); a cache line each
struct alignas(64) HomeRange {
  std::atomic<long> next{0};
  long end = 0;
};

template <typename T> struct EngineT : Engine::Impl {
  static constexpr int W = Width<T>::value;
  using P = Pack<T, W>;

  std::vector<BodyDesc<P>> bodies;
  ModelView<P> mv;
  std::vector<ThreadBuffer<P>> buffers;
  std::unique_ptr<HomeRange[]> ranges;  // (threads), set by each call
  Pool pool;

  EngineT(const Model& m, int t, const std::string& d)
      : Engine::Impl(m, t, d, W), bodies(m.bodies_as<P>()), buffers(t), ranges(new HomeRange[t]), pool(t) {
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

// the registered operation Op (ops/registry.hpp) on B knot points: the
// arrays in argument order (a parameter's slot is empty), the outputs in order
template <typename T, typename Op> struct Job {
  using E = EngineT<T>;
  using P = typename E::P;
  static constexpr int W = E::W;
  static constexpr const ops::OpSpec& op = Op::spec;

  E* e;
  long B, packs;
  int active;
  In<T> in[ops::kMaxArgs];
  Out<T> out[ops::kMaxOutputs];
  ops::OpArgs<P> params{};               // the parameters (real, choice), broadcast to every lane
  std::atomic<long> failed{-1};          // the first sample of the first pack whose kernel failed
  std::atomic<long> nonfinite[ops::kMaxOutputs];  // per output: the first sample with an inf or a NaN
  HomeRange* ranges = nullptr;           // (active): thread t's share of the packs, e->ranges

  static void call(void* self, int t) { static_cast<Job*>(self)->work(t); }
  // thread t's share: packs [t·packs/active, (t+1)·packs/active), the same from call to call, so that
  // repeated calls on the same arrays find each thread's inputs and outputs in its own core's cache
  void share(int t) {
    ranges[t].next.store(t * packs / active, std::memory_order_relaxed);
    ranges[t].end = (t + 1) * packs / active;
  }
  // the next packs [p0, p1) for thread t: guided chunks, half of what is left of its own share (at
  // least one), then of the others' shares in turn, so that threads that start late or run slow still
  // finish together, in O(active · log(packs)) claims
  bool claim(int t, long& p0, long& p1) {
    for (int k = 0; k < active; ++k) {
      HomeRange& r = ranges[(t + k) % active];
      long p = r.next.load(std::memory_order_relaxed);
      while (p < r.end) {
        const long n = std::max(1L, (r.end - p) / 2);
        if (r.next.compare_exchange_weak(p, p + n, std::memory_order_relaxed)) {
          p0 = p, p1 = p + n;
          return true;
        }
      }
    }
    return false;
  }
  // thread t's share, on its own buffer; which thread runs a pack does not
  // change its result (every pack runs the same code from its own inputs)
  void work(int t) {
    ThreadBuffer<P>& buf = e->buffers[t];
    // this thread's packed arrays: inputs, outputs, then the scratch
    ops::OpArgs<P> a = params;
    P* v = buf.values();
    for (int i = 0; i < op.n_args; ++i) {
      a.in[i] = in[i].p ? v : nullptr;
      if (in[i].p) v += in[i].w;
    }
    for (int o = 0; o < op.n_out; ++o) {
      a.out[o] = out[o].p ? v : nullptr;
      if (out[o].p) v += out[o].w;
    }
    a.scratch = v;
    // the default parameters' kernel (operations with a convention only)
    bool defaults = ops::takes_convention(Op::spec);
    for (int k = 0; k < op.n_args; ++k) {
      if (op.args[k].kind == ops::kOptionalArray && in[k].p) defaults = false;
      if (op.args[k].kind == ops::kConvention && params.choice[k] != kPinocchioConvention) defaults = false;
    }
    long p0, p1;
    while (claim(t, p0, p1))
      for (long p = p0; p < p1; ++p) {
        const long s0 = p * W;
        const int valid = static_cast<int>(std::min<long>(W, B - s0));
        // gather: lane l holds sample s0 + l (the last valid one for padding)
        for (int i = 0; i < op.n_args; ++i) {
          if (!in[i].p) continue;
          P* dst = const_cast<P*>(a.in[i]);
          const long w = in[i].w;
          for (int l = 0; l < W; ++l) {
            const T* src = in[i].p + (s0 + std::min(l, valid - 1)) * in[i].stride;
            for (long k = 0; k < w; ++k) dst[k].v[l] = src[k];
          }
        }
        bool ok;
        if constexpr (Op::spec.kernel == ops::kCalled)
          ok = run_pack_called<Op, false>(e->mv, buf.ws, a);
        else if constexpr (ops::takes_convention(Op::spec))
          ok = defaults ? run_pack<Op, true>(e->mv, buf.ws, a) : run_pack<Op, false>(e->mv, buf.ws, a);
        else
          ok = run_pack<Op, false>(e->mv, buf.ws, a);
        if (!ok) lower(failed, s0);
        for (int o = 0; o < op.n_out; ++o) {
          if (!out[o].p) continue;
          const long w = out[o].w;
          // results that overflowed despite the inputs' bounds
          if (op.outputs == ops::kFiniteOutputs) {
            const P bad = nonfinite_lanes(a.out[o], w);
            for (int l = 0; l < valid; ++l)
              if (bad.v[l] != bad.v[l]) {
                lower(nonfinite[o], s0 + l);
                break;
              }
          }
          // scatter the valid lanes
          for (int l = 0; l < valid; ++l) {
            T* dst = out[o].p + (s0 + l) * w;
            for (long k = 0; k < w; ++k) dst[k] = a.out[o][k].v[l];
          }
        }
      }
  }
};

// Op on c.B samples of engine e: pack the call, share the packs among the
// threads, then name the first failed sample or the first overflowed output
template <typename T, typename Op> void op_route(EngineT<T>& e, const ops::OpCall& c) {
  using P = typename EngineT<T>::P;
  const ops::OpSpec& op = Op::spec;
  const Model& m = e.model;
  std::lock_guard<std::mutex> lk(e.call);
  Job<T, Op> job;
  job.e = &e;
  job.B = c.B;
  job.packs = (c.B + EngineT<T>::W - 1) / EngineT<T>::W;
  job.active = static_cast<int>(std::min<long>(e.threads, job.packs));
  long values = ops::scratch_values(op, m);
  for (int k = 0; k < op.n_args; ++k) {
    const long w = ops::arg_values(op.args[k], m, c.n_ee);
    // arrays, and a frame's placement (ops::resolve_names), packed per lane
    if ((op.args[k].kind == ops::kArray || op.args[k].kind == ops::kOptionalArray || op.args[k].kind == ops::kFrame) &&
        c.in[k]) {
      job.in[k] = {static_cast<const T*>(c.in[k]), w, c.batched[k] ? w : 0};
      values += w;
    }
    job.params.real[k] = P(static_cast<T>(c.real[k]));
    job.params.choice[k] = c.choice[k];
  }
  job.params.ee = c.ee;
  job.params.n_ee = c.n_ee;
  for (int o = 0; o < op.n_out; ++o) {
    job.out[o] = {static_cast<T*>(c.out[o]), ops::out_values(op.out[o], m, c.n_ee)};
    values += c.out[o] ? job.out[o].w : 0;
  }
  for (std::atomic<long>& s : job.nonfinite) s.store(-1, std::memory_order_relaxed);
  const WorkspaceLayout layout = ops::workspace_layout(op, m);
  job.ranges = e.ranges.get();
  for (int t = 0; t < job.active; ++t) {
    e.buffers[t].reserve(m.nb(), m.nv, values, layout);
    job.share(t);
  }
  e.pool.run(job.active, &Job<T, Op>::call, &job);

  const long f = job.failed.load();
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
    const long s = job.nonfinite[o].load();
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

