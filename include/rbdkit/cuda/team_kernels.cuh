// rbdkit/cuda/team_kernels.cuh — cooperative kernels: a team of threads (one
// block of kTeam) computes one sample, for the operations whose one-thread
// chain is long (issue 17; docs/cuda.md, "Team kernels"). One GPU thread takes
// 100 µs for iiwa's ∇FD and 1.6 ms for floating Atlas's, the dense product
// -M⁻¹ ∂ID alone 40 % and 70 % of it (cuda/stage_latency.cu on an H200,
// docs/gpu.md); a team splits that work across its threads.
//
// A team kernel is written as phases (model/team.hpp): "for each index this
// thread owns", ended by a barrier (Team::each), or one thread's serial pass
// (Team::one), or a phased pass on the first warp beside a serial one on the
// second (Team::beside).
// What a phase hands to the next goes through memory (the sample's work slice
// or its outputs); a local variable outside a phase must be the same on every
// thread (sizes, pointers, a flag read back after a barrier). The same source
// runs:
//   BlockTeam   (nvcc)  the block's threads, __syncthreads() between phases
//   SerialTeam  (interpret mode, RBDKIT_CUDA_INTERPRET=1)  a phase's indices
//               one after another, the last first: a phase that reads what an
//               earlier index of the same phase wrote gives a wrong result in
//               CI, as it would race on a GPU
// The algorithms are the family headers' own, written for a team where they
// are split (aba_derivatives_team, integrator_gradient_with, matmul on a
// team); on the CPU the same source runs on an InlineTeam. Each team
// operation (TeamOp<Op>) computes what the registry's Op::run computes, on a
// model without mimic joints (a mimic body adds into its target's entries,
// which would race); the engine runs the sample-per-thread kernel
// (kernels.cuh) for the others.
#pragma once

#include <stdexcept>
#include <string>

#include "rbdkit/cuda/kernels.cuh"
#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/algorithms/crba.hpp"
#include "rbdkit/model/team.hpp"
#include "rbdkit/plant/integrator_hessian.hpp"
#include "rbdkit/plant/costs.hpp"
#include "rbdkit/plant/integrators.hpp"

namespace rbd {
namespace cuda {

constexpr int kTeam = 64;  // threads per sample: two warps (Team::beside splits them)

// ---- the teams
// The first N threads of a block as a team: N = kTeam, the whole block (BlockTeam, __syncthreads()
// between phases), or 32, its first warp (WarpTeam, __syncwarp(): the team of BlockTeam::beside).
// extra: the team's own memory in the sample's work slice (TeamOp<Op>::extra_bytes, at its end)
template <int N> struct GpuTeam {
  static constexpr bool cooperative = true;
  static constexpr int threads = N;
  unsigned char* extra = nullptr;
  RBD_HD static void barrier() {
#if defined(__CUDA_ARCH__)
    if constexpr (N == 32) __syncwarp();
    else __syncthreads();
#endif
  }
  // every index below n: thread t takes t, t + N, ...
  template <typename F> RBD_HD void each(long n, F&& f) const {
#if defined(__CUDA_ARCH__)
    for (long k = threadIdx.x; k < n; k += N) f(k);
#else
    (void)n, (void)f;
#endif
    barrier();
  }
  template <typename F> RBD_HD void each2(long rows, long cols, F&& f) const {
    each(rows * cols, [&](long k) { f(k / cols, k % cols); });
  }
  template <typename F> RBD_HD void one(F&& f) const {
#if defined(__CUDA_ARCH__)
    if (threadIdx.x == 0) f();
#else
    (void)f;
#endif
    barrier();
  }
  // the block: f(sub) on the first warp, a team of its own, beside g() on the second warp's first thread
  template <typename F, typename G> RBD_HD void beside(F&& f, G&& g) const {
    static_assert(N == kTeam, "beside: a block's team splits into its first warp and a thread");
#if defined(__CUDA_ARCH__)
    if (threadIdx.x < 32) f(GpuTeam<32>{extra});
    else if (threadIdx.x == 32) g();
#else
    (void)f, (void)g;
#endif
    barrier();
  }
  // the block: whether x[0..n) are all finite, on every thread (a vote, and a barrier)
  template <typename T> RBD_HD bool all_finite(const T* x, long n) const {
    static_assert(N == kTeam, "all_finite: the block's vote");
#if defined(__CUDA_ARCH__)
    T acc = T(0);
    for (long k = threadIdx.x; k < n; k += N) acc += x[k] - x[k];
    return __syncthreads_and(acc == acc) != 0;
#else
    (void)x, (void)n;
    return false;
#endif
  }
};
using BlockTeam = GpuTeam<kTeam>;
using WarpTeam = GpuTeam<32>;

struct SerialTeam {
  static constexpr bool cooperative = true;
  static constexpr int threads = kTeam;  // (the block it stands for: the same tiles as there)
  unsigned char* extra = nullptr;
  template <typename F> void each(long n, F&& f) const {
    for (long k = n - 1; k >= 0; --k) f(k);
  }
  template <typename F> void each2(long rows, long cols, F&& f) const {
    each(rows * cols, [&](long k) { f(k / cols, k % cols); });
  }
  template <typename F> void one(F&& f) const { f(); }
  // (g first: g reading the team's results fails here, as it would race on a GPU; the team reading
  // g's would pass, which is why g writes only memory of its own)
  template <typename F, typename G> void beside(F&& f, G&& g) const { g(), f(*this); }
  template <typename T> bool all_finite(const T* x, long n) const { return cuda::all_finite(x, n); }
};

// ---- the team operations: TeamOp<Op>::run(team, m, w, a) computes Op::run's outputs, with
// team.extra: extra_bytes(nb, nv) bytes (a multiple of 16) after the workspace and the op's scratch.
// per_sm: up to how many samples per SM the engine's auto choice takes the team kernel on a small
// model (past it a sample per thread keeps every lane busy; cuda_engine.cpp, uses_team); wide_nv: from
// this nv on, auto takes the team at every B (0: never), where one thread's chain is too long for a
// sample per thread to catch up at any B; mujoco_form: whether the team splits the work in MuJoCo's
// output convention too (where it does not, auto keeps the sample kernel for such a call). TeamRule
// holds them
template <typename Op> struct TeamOp {
  static constexpr bool available = false;
};
// a team operation's rule for the engine (the members above); full_workspace: the team needs the full
// workspace where the op's own is linear, and the engine carves that one for a team launch
template <int PerSm, int WideNv, bool MujocoForm = false, bool FullWorkspace = false> struct TeamRule {
  static constexpr bool available = true;
  static constexpr int per_sm = PerSm;
  static constexpr int wide_nv = WideNv;
  static constexpr bool mujoco_form = MujocoForm;
  static constexpr bool full_workspace = FullWorkspace;
};

// ID and the per-body motion and forces: rnea_team (rnea.hpp), then the outputs an entry per index
// (the accelerations without gravity, a chain of rotations, on one thread)
template <> struct TeamOp<ops::InverseDynamics> : TeamRule<8, 0> {
  // (wide_nv 0: O(nb) work, floating Atlas's sample kernel led from B = 4096)
  template <typename T> RBD_HD static unsigned long extra_bytes(int, int) { return 0; }
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    rnea_team(t, m, w, a.in[0], a.in[1], a.in[2], a.in[4], a.real[3], a.out[0]);
    if (a.out[1] || a.out[3])
      t.each(m.nb, [&](long i) {
        if (a.out[1]) store(w.v[i], a.out[1] + 6 * i);
        if (a.out[3]) store(w.f[i], a.out[3] + 6 * i);
      });
    if (a.out[2]) {
      t.one([&] { remove_gravity(m, w, a.real[3], w.c); });  // (w.c is free after RNEA)
      t.each(m.nb, [&](long i) { store(w.c[i], a.out[2] + 6 * i); });
    }
    return true;
  }
};

// M: crba_team (crba.hpp), in world coordinates: the placements and body inertias an entry per index,
// the composites on one thread, then a column per index. per_sm and wide_nv as M⁻¹'s (no GPU
// measurement yet: CRBA's columns are lighter than M⁻¹'s, each walking its ancestors only)
template <> struct TeamOp<ops::Crba> : TeamRule<8, 16> {
  template <typename T> RBD_HD static unsigned long extra_bytes(int, int) { return 0; }
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    crba_team(t, m, w, a.in[0], a.out[0]);
    return true;
  }
};

// M⁻¹: minv_team (minv.hpp); extra: its flag
template <> struct TeamOp<ops::Minv> : TeamRule<8, 16> {
  template <typename T> RBD_HD static unsigned long extra_bytes(int, int) { return 16; }
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    int* ok = reinterpret_cast<int*>(t.extra);
    minv_team(t, m, w, a.in[0], a.choice[1] != 0, a.out[0], ok);
    return *ok;
  }
};

// FD through M⁻¹, qdd = M⁻¹ (u - c): forward_dynamics_team (minv.hpp), the bias c by RNEA on one
// thread beside minv_team on the first warp, then each row of the product. The same values as
// forward_dynamics (minv.hpp) where that runs the passes, to rounding where it factorises M. extra: forward_dynamics_team_bytes (RNEA's workspace, u - c, the flag)
template <> struct TeamOp<ops::ForwardDynamics> : TeamRule<8, 16> {
  template <typename T> RBD_HD static unsigned long extra_bytes(int nb, int nv) {
    return forward_dynamics_team_bytes<T>(nb, nv);
  }
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    return forward_dynamics_team(t, m, w, t.extra, a.in[0], a.in[1], a.in[2], a.in[3], a.real[4], a.out[0]);
  }
};

// ∂ID/∂q and ∂ID/∂qd: rnea_derivatives_team (rnea_derivatives.hpp)
template <> struct TeamOp<ops::InverseDynamicsGradient> : TeamRule<8, 16> {
  template <typename T> RBD_HD static unsigned long extra_bytes(int, int nv) {
    return workspace_array_bytes<T>(2ul * nv * nv);
  }
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    const int nv = m.nv, n2 = nv * nv;
    T* dq = a.out[1] ? a.out[1] : reinterpret_cast<T*>(t.extra);
    T* dv = a.out[2] ? a.out[2] : reinterpret_cast<T*>(t.extra) + n2;
    rnea_derivatives_team(t, m, w, a.in[0], a.in[1], a.in[2], a.in[4], a.real[3], dq, dv);
    if (a.out[0])  // dtau = [dtau_dq | dtau_dqd]
      t.each(2 * n2, [&](long k) {
        const int r = static_cast<int>(k / (2 * nv)), c = static_cast<int>(k % (2 * nv));
        a.out[0][k] = c < nv ? dq[r * nv + c] : dv[r * nv + c - nv];
      });
    return true;
  }
};

// ∂qdd/∂q and ∂qdd/∂qd = -M⁻¹ ∂ID/∂(q, qd) at qdd = FD: aba_derivatives_team (aba_derivatives.hpp)
template <> struct TeamOp<ops::ForwardDynamicsGradient> : TeamRule<8, 16> {
  template <typename T> RBD_HD static unsigned long extra_bytes(int nb, int nv) {
    return aba_derivatives_team_bytes<T>(nb, nv);
  }
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    if (!aba_derivatives_team(t, m, w, t.extra, a.in[0], a.in[1], a.in[2], a.in[3], a.real[4], a.out[2], a.out[0],
                              a.out[1]))
      return false;
    if (a.out[3]) t.each(m.nv * m.nv, [&](long k) { a.out[3][k] = w.dense[k]; });  // M⁻¹, when asked for
    return true;
  }
};

// the step's arguments: the integrator ops take (q, qd, u, dt, type, f_ext, gravity, convention), the
// plant ones (x, u, dt, type, f_ext, gravity, convention): the offset of every argument after qd
template <typename Op> RBD_HD constexpr int step_arg_offset() {
  constexpr int o = Op::spec.args[0].name[0] == 'x' && Op::spec.args[0].name[1] == '\0' ? 0 : 1;
  static_assert(Op::spec.n_args == 7 + o, "a step's arguments: (q, qd | x), u, dt, type, f_ext, gravity, convention");
  return o;
}

// the integrator step's value (integrator, plant_step; integrators.hpp), every scheme:
// integrator_step_with on the team, each stage's acceleration by forward_dynamics_team (FD through
// M⁻¹: the serial step's ABA to rounding), the stage updates and retractions on one thread. M⁻¹
// needs the full workspace where the op's own is linear: full_workspace, so the engine carves the
// full one for a team launch. MuJoCo's convention has no team form: where the team is asked for,
// the registry's kernel runs on one thread. extra: forward_dynamics_team's memory, a flag
template <typename Op> struct TeamStepValue : TeamRule<8, 16, false, true> {
  // (per_sm as FD's: the same work per stage, one to four stages)
  template <typename T> RBD_HD static unsigned long extra_bytes(int nb, int nv) {
    return forward_dynamics_team_bytes<T>(nb, nv) + 16;
  }
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    constexpr int o = step_arg_offset<Op>();
    int* ok = reinterpret_cast<int*>(t.extra + extra_bytes<T>(m.nb, m.nv) - 16);
    if (a.choice[6 + o] != kPinocchioConvention) {
      t.one([&] { *ok = Op::run(m, w, a); });
      return *ok;
    }
    const T* v = o ? a.in[1] : a.in[0] + m.nq;
    return integrator_step_with<PinocchioStep<T>>(m, w, a.choice[3 + o], a.in[0], v, a.in[1 + o], a.in[4 + o],
                                                  a.real[2 + o], a.real[5 + o], a.out[0], a.out[0] + m.nq, a.scratch,
                                                  t);
  }
};
template <> struct TeamOp<ops::Integrator> : TeamStepValue<ops::Integrator> {};
template <> struct TeamOp<ops::PlantStep> : TeamStepValue<ops::PlantStep> {};

// the integrator step and its gradient (integrators.hpp), every scheme, with or without ∂x⁺/∂f_ext
// (integrator_gradient, integrator_f_ext_gradient, plant_step_gradient):
// integrator_gradient_with on the team, each stage's ∇FD by aba_derivatives_team and the chain rule's
// products an entry per index. MuJoCo's convention has no team form: where the team is asked for
// (the engine's auto does not), the registry's kernel runs on one thread of the team
template <typename Op> struct TeamStep : TeamRule<32, 16> {
  // (per_sm: four ∇FD and their products per sample, more work to split)
  template <typename T> RBD_HD static unsigned long extra_bytes(int nb, int nv) {
    return aba_derivatives_team_bytes<T>(nb, nv) + 16;
  }
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    constexpr int o = step_arg_offset<Op>();
    int* ok = reinterpret_cast<int*>(t.extra + extra_bytes<T>(m.nb, m.nv) - 16);
    if (a.choice[6 + o] != kPinocchioConvention) {
      t.one([&] { *ok = Op::run(m, w, a); });
      return *ok;
    }
    constexpr bool with_fext = Op::spec.n_out == 3;
    const long own = with_fext ? integrator_fext_gradient_scratch_values(m.nq, m.nv, m.nb)
                               : integrator_gradient_scratch_values(m.nq, m.nv);
    T* x = a.out[0] ? a.out[0] : a.scratch + own;  // x⁺ and AB in the scratch when not asked for, as Op::run
    T* AB = a.out[1] ? a.out[1] : a.scratch + own + m.nq + m.nv;
    const T* v = o ? a.in[1] : a.in[0] + m.nq;
    return integrator_gradient_with<PinocchioStep<T>>(m, w, a.choice[3 + o], a.in[0], v, a.in[1 + o], a.in[4 + o],
                                                      a.real[2 + o], a.real[5 + o], x, x + m.nq, AB,
                                                      with_fext ? a.out[2] : static_cast<T*>(nullptr), a.scratch, t);
  }
};
template <> struct TeamOp<ops::IntegratorGradient> : TeamStep<ops::IntegratorGradient> {};
template <> struct TeamOp<ops::IntegratorFExtGradient> : TeamStep<ops::IntegratorFExtGradient> {};
template <> struct TeamOp<ops::PlantStepGradient> : TeamStep<ops::PlantStepGradient> {};

// the step's Hessian (integrator_hessian.hpp), every scheme: integrator_hessian_with on the team (each
// stage's ∇FD by aba_derivatives_team, IDSVA-SO and the retraction maps on one thread, FDSVA-SO's and
// the jets' products and sums an entry or a row per index); the reference form's correction on one
// thread. MuJoCo's convention has no team form: where the team is asked for, the registry's kernel
// runs on one thread (a mimic model never gets the team: the engine's uses_team). extra:
// aba_derivatives_team's memory, the team's products (integrator_hessian_team_values), a flag
template <> struct TeamOp<ops::PlantStepHessian> : TeamRule<32, 16> {
  // (per_sm as the step's gradient: the stages' work is more to split)
  template <typename T> RBD_HD static unsigned long extra_bytes(int nb, int nv) {
    return aba_derivatives_team_bytes<T>(nb, nv) + workspace_array_bytes<T>(integrator_hessian_team_values(nv)) + 16;
  }
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    int* ok = reinterpret_cast<int*>(t.extra + extra_bytes<T>(m.nb, m.nv) - 16);
    if (a.choice[5] != kPinocchioConvention) {
      t.one([&] { *ok = ops::PlantStepHessian::run(m, w, a); });
      return *ok;
    }
    T* team_tmp = reinterpret_cast<T*>(t.extra + aba_derivatives_team_bytes<T>(m.nb, m.nv));
    T* x = a.out[0] ? a.out[0] : a.scratch + integrator_hessian_scratch_values(m.nq, m.nv);  // (as Op::run)
    T* AB = a.out[1] ? a.out[1] : x + m.nq + m.nv;
    if (!integrator_hessian_with<PinocchioStep>(m, w, a.choice[3], a.in[0], a.in[0] + m.nq, a.in[1], a.real[2],
                                                a.real[4], x, x + m.nq, AB, a.out[2], a.scratch, t, team_tmp))
      return false;
    if (a.choice[6] == kReferenceForm) t.one([&] { step_hessian_reference_form(m, a.choice[5], AB, a.out[2]); });
    return true;
  }
};

// ---- the costs and barriers (plant/costs.hpp), in both conventions: the serial prefix (the log map,
// kinematics, ccrba and dccrba) and the value's sum on one thread, the gradient and the Hessian an
// entry per index. per_sm as ID's (no GPU measurement yet); wide_nv 16 where the Hessian is dense
// (O(nv²) entries, which the team writes coalesced and one thread a sample writes alone), 0 for
// the barriers' O(nv). extra: a flag (the failures of com_cost and momentum_cost)
struct TeamCost : TeamRule<8, 16, true> {
  template <typename T> RBD_HD static unsigned long extra_bytes(int, int) { return 16; }
  RBD_HD static int* flag(unsigned char* extra) { return reinterpret_cast<int*>(extra); }
};
template <> struct TeamOp<ops::QuadraticStateCost> : TeamCost {
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>&, const ops::OpArgs<T>& a) {
    quadratic_cost(t, m.nq + m.nv, a.in[0], a.in[1], a.in[2], a.out[0], a.out[1], a.out[2]);
    return true;
  }
};
template <> struct TeamOp<ops::QuadraticInputCost> : TeamCost {
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>&, const ops::OpArgs<T>& a) {
    quadratic_cost(t, m.nv, a.in[0], a.in[1], a.in[2], a.out[0], a.out[1], a.out[2]);
    return true;
  }
};
template <> struct TeamOp<ops::QuadraticStateCostTangent> : TeamCost {
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>&, const ops::OpArgs<T>& a) {
    quadratic_state_cost_tangent(t, m, a.in[0], a.in[1], a.in[2], a.out[0], a.out[1], a.out[2], a.scratch,
                                 a.choice[3]);
    return true;
  }
};
template <> struct TeamOp<ops::EePosCost> : TeamCost {
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    ee_pos_cost(t, m, w, a.in[0], a.in[1], a.in[2], a.choice[3], a.in[4], a.choice[5], a.out[0], a.out[1], a.out[2],
                a.scratch);
    return true;
  }
};
template <> struct TeamOp<ops::ComCost> : TeamCost {
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    return com_cost(t, m, w, a.in[0], a.in[1], a.in[2], a.choice[3], a.out[0], a.out[1], a.out[2], a.scratch,
                    flag(t.extra));
  }
};
template <> struct TeamOp<ops::MomentumCost> : TeamCost {
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>& w, const ops::OpArgs<T>& a) {
    return momentum_cost(t, m, w, a.in[0], a.in[1], a.in[2], a.in[3], a.choice[4], a.out[0], a.out[1], a.out[2],
                         a.scratch, flag(t.extra));
  }
};
// extra: each coordinate's term of the value (n <= nq <= nv + nb)
template <int Which> struct TeamOp<ops::JointBarrier<Which>> : TeamRule<8, 0, true> {
  template <typename T> RBD_HD static unsigned long extra_bytes(int nb, int nv) {
    return workspace_array_bytes<T>(nv + nb);
  }
  template <typename T, typename Team>
  RBD_HD static bool run(const Team& t, const ModelView<T>& m, Workspace<T>&, const ops::OpArgs<T>& a) {
    log_barrier(t, Which == 0 ? m.nq : m.nv, a.in[0], a.in[1], a.in[2], a.real[3], a.out[0], a.out[1], a.out[2],
                reinterpret_cast<T*>(t.extra));
    return true;
  }
};

// the team's extra bytes of Op (0 too where Op has no team kernel)
template <typename Op, typename T> RBD_HD unsigned long team_extra_bytes(int nb, int nv) {
  if constexpr (TeamOp<Op>::available) return TeamOp<Op>::template extra_bytes<T>(nb, nv);
  else return 0;
}

// sample s of Op by team t (every thread of it calls this): op_sample's arguments, checks and status.
// The work slice (c.work_bytes): the workspace, the op's scratch, the team's extra at its end
template <typename Op, typename T, typename Team>
RBD_HD void team_sample(Team t, const DeviceCall<T>& c, const ModelView<T>& m, long s, unsigned char* work) {
  constexpr int n_out = Op::spec.n_out;
  constexpr bool finite_outputs = Op::spec.outputs == ops::kFiniteOutputs;
  if (c.check_inputs && !inputs_ok<Op>(c, m, s)) {  // (every thread reads the same values)
    t.one([&] {
      c.status[s] = kSampleBadInput;
      *c.failed = c.call_id;
    });
    return;
  }
  Workspace<T> w = carve_workspace<T>(work, m.nb, m.nv, c.layout);
  const ops::OpArgs<T> a = sample_args(c, s, work);
  t.extra = work + c.work_bytes - team_extra_bytes<Op, T>(m.nb, m.nv);
  int status = kSampleOk;
  if (!TeamOp<Op>::run(t, m, w, a)) {
    status = kSampleFailed;
  } else if (finite_outputs) {
    for (int o = n_out - 1; o >= 0; --o)
      if (a.out[o] && !t.all_finite(a.out[o], c.out_values[o])) status = kSampleNonFinite + o;
  }
  t.one([&] {
    c.status[s] = status;
    if (status != kSampleOk) *c.failed = c.call_id;
  });
}

#if defined(__CUDACC__)
// a block per sample, over a grid-stride loop; dynamic shared memory: the sample's work slice when
// c.work_shared; Model: where the model comes from (kernels.cuh's CallModel)
template <typename Op, typename T, typename Model = CallModel>
__global__ void __launch_bounds__(kTeam) team_kernel(DeviceCall<T> c, const BodyDesc<T>* __restrict__ bodies) {
  extern __shared__ __align__(16) unsigned char shared_work[];
  const ModelView<T> m = Model::view(ModelView<T>{c.model.nb, c.model.nq, c.model.nv, c.model.has_mimic, bodies});
  if constexpr (TeamOp<Op>::available) {
    const BlockTeam t;
    for (long s = blockIdx.x; s < c.B; s += gridDim.x)
      team_sample<Op>(t, c, m, s, c.work_shared ? shared_work : c.work + static_cast<unsigned long>(s) * c.work_bytes);
  }
}
#endif

// Op's team launch in interpret mode: each block's samples, a team at a time
template <typename Op, typename T, typename Model = CallModel>
void interpret_team_op(const DeviceCall<T>& c, LaunchShape shape) {
  if constexpr (!TeamOp<Op>::available) {
    (void)c, (void)shape;
    throw std::logic_error(std::string(Op::spec.name) + ": a team launch of an operation without a team kernel");
  } else {
    const SerialTeam t;
    const ModelView<T> m = Model::view(c.model);
    emulate_launch(LaunchShape{shape.blocks, 1, shape.shared_bytes, shape.shared_limit},
                   [&](long b, int, unsigned char* shared) {
                     for (long s = b; s < c.B; s += shape.blocks)
                       team_sample<Op>(t, c, m, s,
                                       c.work_shared ? shared : c.work + static_cast<unsigned long>(s) * c.work_bytes);
                   });
  }
}

// what the engine knows of an operation's team kernel (per_sm 0: it has none)
struct TeamInfo {
  unsigned long extra = 0;  // TeamOp<Op>::extra_bytes
  int per_sm = 0, wide_nv = 0;
  bool mujoco_form = false, full_workspace = false;
};
template <typename Op, typename T> TeamInfo team_info(int nb, int nv) {
  if constexpr (TeamOp<Op>::available) {
    using R = TeamOp<Op>;
    return {R::template extra_bytes<T>(nb, nv), R::per_sm, R::wide_nv, R::mujoco_form, R::full_workspace};
  } else {
    (void)nb, (void)nv;
    return {};
  }
}
// per registered operation (ops::AllOps' order)
template <typename T, typename... Op> void team_infos(ops::OpList<Op...>, int nb, int nv, TeamInfo* out) {
  int k = 0;
  ((out[k++] = team_info<Op, T>(nb, nv)), ...);
}

}  // namespace cuda
}  // namespace rbd
