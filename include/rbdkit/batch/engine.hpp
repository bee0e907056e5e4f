// rbdkit/batch/engine.hpp — the batched CPU engine: many knot points per call,
// spread over a persistent thread pool and, inside each thread, over SIMD
// lanes (W samples side by side in Pack<T, W>, simd.hpp). Host only.
//
// Arrays are row-major with the batch on the leading axis; shapes are the
// caller's responsibility in C++ (the Python binding checks them):
//   q (B x nq), qd / qdd / tau / u (B x nv), M / Minv / gradients
//   (B x nv x nv), x = [q⁺; qd⁺] (B x (nq + nv)), AB (B x 2nv x 3nv).
// Outputs mean exactly what the single-sample functions of the same names
// compute (rnea, crba, minv (dense), aba, rnea_derivatives,
// aba_derivatives, integrator_step, integrator_gradient). External forces
// are not taken. No input values are checked (finite numbers, unit
// quaternions): the checked entry points are in dynamics.hpp.
//
// Determinism: samples are grouped into packs of W consecutive samples
// (the last pack padded with copies of the batch's last sample); the
// threads take runs of packs from a shared counter as they come. Every
// sample goes through the same pack code in a lane of its own, whichever
// thread runs its pack, so its result is bit-identical whatever the thread
// count and the batch size.
//
// Threads: a persistent pool; the calling thread works too. Between calls
// a worker spins for up to 50 µs, then sleeps: calls in quick succession
// hand off without a system call, and an idle engine uses no CPU. A worker
// that is not there in time (asleep, or its core busy) is not waited for.
//
// Memory: each thread keeps one buffer, grown on the first call that needs
// more and reused afterwards (no allocation per call after that). Per pack
// of W knot points it holds one workspace (workspace_bytes<Pack>(nb, nv),
// i.e. W · workspace_bytes<T>(nb, nv)), the lane-interleaved inputs and
// outputs of the call, and the integrators' scratch
// (integrator_gradient_scratch_values(nq, nv) values per knot point):
// per knot point, workspace_bytes<T>(nb, nv, layout) + sizeof(T) · (inputs +
// outputs + scratch values). The layout is linear (O(nb + nv)) while only
// inverse_dynamics, forward_dynamics and integrator have run (on a model
// without mimic joints whose M's factorisation does not pay: aba_layout),
// full (O(nb·nv + nv²)) from the first call of any other operation on.
// workspace_bytes() reports the current total.
//
// One call at a time per engine (calls from several threads serialise).
#pragma once

#include <memory>
#include <string>

#include "rbdkit/ops/table.hpp"
#include "rbdkit/parsers/model.hpp"

namespace rbd {

class Engine {
 public:
  // threads: > 0 (default: the hardware threads); dtype: "float64" or
  // "float32". Throws std::invalid_argument otherwise.
  explicit Engine(const Model& model, int threads = default_threads(), const std::string& dtype = "float64");
  ~Engine();
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  static int default_threads();
  int threads() const;
  const std::string& dtype() const;
  int simd_width() const;              // samples per pack for this dtype
  const Model& model() const;
  unsigned long workspace_bytes() const;  // bytes held by the per-thread buffers now

  // T must be the engine's dtype (double for "float64", float for
  // "float32"), else std::invalid_argument; B > 0. Integrator types as in
  // plant/integrators.hpp (integrator_from_name gives them by name).
  template <typename T>
  void inverse_dynamics(long B, const T* q, const T* qd, const T* qdd /* null: zero */, T gravity, T* tau);
  template <typename T> void crba(long B, const T* q, T* M);
  template <typename T> void minv(long B, const T* q, T* Minv);
  template <typename T>
  void forward_dynamics(long B, const T* q, const T* qd, const T* tau, T gravity, T* qdd);
  template <typename T>
  void inverse_dynamics_gradient(long B, const T* q, const T* qd, const T* qdd /* null: zero */, T gravity,
                                 T* dtau_dq, T* dtau_dqd);
  // Minv (B x nv x nv) too when not null (M⁻¹ is computed on the way)
  template <typename T>
  void forward_dynamics_gradient(long B, const T* q, const T* qd, const T* tau, T gravity, T* dqdd_dq,
                                 T* dqdd_dqd, T* Minv = nullptr);
  template <typename T>
  void integrator(long B, const T* q, const T* qd, const T* u, T dt, T gravity, int type, T* x);
  template <typename T>
  void integrator_gradient(long B, const T* q, const T* qd, const T* u, T dt, T gravity, int type, T* x, T* AB);

  // a registered operation (ops/registry.hpp, id: its index in ops::AllOps)
  // on call.B samples in the engine's dtype: the arrays of `call` hold T =
  // double ("float64") or float ("float32") values. No input is checked here
  // (ops::check_call), and frame and end-effector arguments arrive resolved
  // (ops::resolve_names: a body and its placement, as Handle::run passes
  // them); Handle::run does both. A failed sample and non-finite outputs
  // throw as the methods above do.
  void run_op(int op, const ops::OpCall& call);

  // the most packs (simd_width() samples each) one job of the thread pool takes: a batch of more runs
  // as several jobs, one after another. packs: 1 .. 2^24 - 1, the default (a batch of over 134
  // million float64 samples on AVX-512); else std::invalid_argument. For tests, which set it small
  // to run that path on a small batch; the results do not depend on it
  void set_max_job_packs(long packs);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace rbd
