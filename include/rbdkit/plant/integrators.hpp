// rbdkit/plant/integrators.hpp — one time step x⁺ = f(x, u) of the
// forward dynamics, x = (q, v), and its tangent-space Jacobian [A | B].
//
//   euler                  q⁺ = q ⊕ dt v,                    v⁺ = v + dt a(q, v)
//   semi_implicit_euler    v⁺ = v + dt a(q, v),              q⁺ = q ⊕ dt v⁺
//   constant_acceleration  q⁺ = q ⊕ (dt v + ½ dt² a),        v⁺ = v + dt a
//   midpoint, trapezoidal (explicit Heun), rk4: full-state stages. Stage s
//   retracts from the initial configuration with the preceding stage's
//   velocity, q_s = q ⊕ c_s dt v_(s-1), v_s = v + c_s dt a_(s-1),
//   a_s = FD(q_s, v_s, u); then q⁺ = q ⊕ dt Σ b_s v_s, v⁺ = v + dt Σ b_s a_s.
//
// u and the body-local external forces stay constant over the step. The
// Jacobian follows the stages by the chain rule: forward-dynamics gradients
// at each stage and the Lie-group Jacobians of ⊕ (configuration.hpp).
// Tangent columns: [δq (nv) | δv (nv) | δu (nv)]; rows [δq⁺ (nv) | δv⁺ (nv)].
// integrator_fext_gradient adds the columns of the external forces, δf (6 nb):
// each stage applies them as a generalized force at its own configuration.
//
// The stage loop is written once over a convention policy (the coordinates
// the step runs in): PinocchioStep (integrate/difference, body-frame v) or
// MujocoStep (mujoco_convention.hpp: MuJoCo's qpos/qvel, ⊕ and frames). The
// entry points take the convention as a trailing code (OutputConvention).
#pragma once

#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/model/configuration.hpp"
#include "rbdkit/model/team.hpp"
#include "rbdkit/plant/mujoco_convention.hpp"

namespace rbd {

enum IntegratorType : int {
  kEuler = 0,
  kSemiImplicitEuler = 1,
  kMidpoint = 2,
  kRK4 = 3,
  kTrapezoidal = 4,       // explicit two-stage Heun
  kConstantAcceleration = 5,
};

// the explicit stage tables: stages, c_s (offset of stage s), b_s (weights)
struct Tableau {
  int stages;
  double c[4];
  double b[4];
};
RBD_HD Tableau tableau(int type) {
  switch (type) {
    case kMidpoint: return {2, {0.0, 0.5, 0.0, 0.0}, {0.0, 1.0, 0.0, 0.0}};
    case kTrapezoidal: return {2, {0.0, 1.0, 0.0, 0.0}, {0.5, 0.5, 0.0, 0.0}};
    case kRK4: return {4, {0.0, 0.5, 0.5, 1.0}, {1.0 / 6, 1.0 / 3, 1.0 / 3, 1.0 / 6}};
    default: return {1, {0.0, 0.0, 0.0, 0.0}, {1.0, 0.0, 0.0, 0.0}};
  }
}

// ---- conventions: retraction ⊕ (its inverse ⊖) with its Jacobians, and the acceleration
// a(q, v, u) = d/dt v with ∂a/∂δq, ∂a/∂v, ∂a/∂u (nv x nv each)

// Pinocchio's: integrate (SE(3)/SO(3) exponential), body-frame velocities
template <typename S> struct PinocchioStep {
  RBD_HD static void retract(const ModelView<S>& m, const S* q, const S* d, S* out) { integrate(m, q, d, out); }
  RBD_HD static void difference(const ModelView<S>& m, const S* q0, const S* q1, S* out) {
    rbd::difference(m, q0, q1, out);
  }
  RBD_HD static void dretract(const ModelView<S>& m, const S* q, const S* d, int arg, S* J) {
    dintegrate(m, q, d, arg, J);
  }
  RBD_HD static bool acceleration(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* v, const S* u,
                                  const S* fext, S gravity, S* a, S*) {
    return aba(m, w, q, v, u, fext, gravity, a);
  }
  // the same on a team: a cooperative one (a model without mimic joints) runs FD through M⁻¹
  // (forward_dynamics_team, in t.extra; w the full workspace), the serial ABA's a to rounding
  template <typename Team>
  RBD_HD static bool acceleration(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q, const S* v,
                                  const S* u, const S* fext, S gravity, S* a, S* scratch) {
    if constexpr (!Team::cooperative) return acceleration(m, w, q, v, u, fext, gravity, a, scratch);
    else return forward_dynamics_team(t, m, w, t.extra, q, v, u, fext, gravity, a);
  }
  RBD_HD static bool acceleration_derivatives(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* v,
                                              const S* u, const S* fext, S gravity, S* a, S* Fq, S* Fv, S* Fu, S*) {
    if (!aba_derivatives(m, w, q, v, u, fext, gravity, a, Fq, Fv)) return false;
    copy_minv(m, w, Fu);  // ∂a/∂u = M⁻¹, which aba_derivatives left in w
    return true;
  }
  // the same on a team: a cooperative one (a model without mimic joints) splits ∇FD
  // (aba_derivatives_team, in t.extra) and the copy of M⁻¹
  template <typename Team>
  RBD_HD static bool acceleration_derivatives(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q,
                                              const S* v, const S* u, const S* fext, S gravity, S* a, S* Fq, S* Fv,
                                              S* Fu, S* scratch) {
    if constexpr (!Team::cooperative) {
      return acceleration_derivatives(m, w, q, v, u, fext, gravity, a, Fq, Fv, Fu, scratch);
    } else {
      if (!aba_derivatives_team(t, m, w, t.extra, q, v, u, fext, gravity, a, Fq, Fv)) return false;
      t.each(static_cast<long>(m.nv) * m.nv, [&](long k) { Fu[k] = w.dense[k]; });
      return true;
    }
  }
  // the generalized force the body-local wrenches f_ext act as, J_f = ∂u/∂f = [J_0ᵀ … J_(nb-1)ᵀ]
  // (nv x 6nb) at q (so ∂a/∂f = Fu J_f)
  RBD_HD static void force_map(const ModelView<S>& m, Workspace<S>& w, const S* q, S* Jf, S*) {
    external_force_map(m, w, q, S(1), Jf, 6, 6 * m.nb);
  }
};

// MuJoCo's: mj_integratePos, qvel = [ṗ world; ω body] on free joints
template <typename S> struct MujocoStep {
  RBD_HD static void retract(const ModelView<S>& m, const S* q, const S* d, S* out) { mj_integrate(m, q, d, out); }
  RBD_HD static void difference(const ModelView<S>& m, const S* q0, const S* q1, S* out) {
    mj_difference(m, q0, q1, out);
  }
  RBD_HD static void dretract(const ModelView<S>& m, const S* q, const S* d, int arg, S* J) {
    mj_dintegrate(m, q, d, arg, J);
  }
  RBD_HD static bool acceleration(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* v, const S* u,
                                  const S* fext, S gravity, S* a, S* scratch) {
    return mujoco_acceleration(m, w, q, v, u, fext, gravity, a, scratch);
  }
  template <typename Team>
  RBD_HD static bool acceleration(const Team&, const ModelView<S>& m, Workspace<S>& w, const S* q, const S* v,
                                  const S* u, const S* fext, S gravity, S* a, S* scratch) {
    static_assert(!Team::cooperative, "MuJoCo's convention has no team form");
    return acceleration(m, w, q, v, u, fext, gravity, a, scratch);
  }
  RBD_HD static bool acceleration_derivatives(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* v,
                                              const S* u, const S* fext, S gravity, S* a, S* Fq, S* Fv, S* Fu,
                                              S* scratch) {
    return mujoco_acceleration_derivatives(m, w, q, v, u, fext, gravity, a, Fq, Fv, Fu, scratch);
  }
  // (one thread: the team kernels run MuJoCo's convention serially, rbdkit/cuda/team_kernels.cuh)
  template <typename Team>
  RBD_HD static bool acceleration_derivatives(const Team&, const ModelView<S>& m, Workspace<S>& w, const S* q,
                                              const S* v, const S* u, const S* fext, S gravity, S* a, S* Fq, S* Fv,
                                              S* Fu, S* scratch) {
    static_assert(!Team::cooperative, "MuJoCo's convention has no team form");
    return acceleration_derivatives(m, w, q, v, u, fext, gravity, a, Fq, Fv, Fu, scratch);
  }
  // J_f in MuJoCo's generalized forces, u_mj = C u_pin: the free joints' linear rows turned into the
  // world (scratch: nq values)
  RBD_HD static void force_map(const ModelView<S>& m, Workspace<S>& w, const S* q_mj, S* Jf, S* scratch) {
    S* q = scratch;  // (nq) Pinocchio configuration
    configuration_from_mujoco(m, q_mj, q);
    external_force_map(m, w, q, S(1), Jf, 6, 6 * m.nb);
    rows_to_mujoco(m, q_mj, Jf, 6 * m.nb);
  }
};

// scratch values (of type S) for one step, and for a step with its gradient (either convention)
RBD_HD long integrator_scratch_values(int nq, int nv) {
  return nq + 5L * nv + mujoco_acceleration_scratch_values(nq, nv);
}
RBD_HD long integrator_gradient_scratch_values(int nq, int nv) {
  return integrator_scratch_values(nq, nv) + 29L * nv * nv;
}
// and for a step with its gradient and ∂x⁺/∂f_ext: eight derivative blocks 6nb
// columns wider, and the stage's force map J_f (nv x 6nb)
RBD_HD long integrator_fext_gradient_scratch_values(int nq, int nv, int nb) {
  return integrator_gradient_scratch_values(nq, nv) + 9L * nv * 6 * nb;
}

// x⁺ = (q⁺ (nq), v⁺ (nv)) written to q_next, v_next, in the coordinates of
// the convention Conv. false if M is not PD. Written for a team (model/team.hpp):
// one thread (InlineTeam, the default), or a GPU team kernel's threads, which
// split each stage's acceleration (Conv::acceleration on the team); the stage
// updates and retractions, O(nv), stay on one thread
template <typename Conv, typename S, typename Team = InlineTeam>
RBD_HD bool integrator_step_with(const ModelView<S>& m, Workspace<S>& w, int type, const S* q, const S* v,
                                 const S* u, const S* fext, S dt, S gravity, S* q_next, S* v_next, S* scratch,
                                 const Team& t = Team{}) {
  const int nq = m.nq, nv = m.nv;
  S* qs = scratch;             // stage configuration (nq)
  S* vs = qs + nq;             // stage velocity (nv)
  S* as = vs + nv;             // stage acceleration (nv)
  S* vsum = as + nv;           // Σ b_s v_s (nv)
  S* asum = vsum + nv;         // Σ b_s a_s (nv)
  S* step = asum + nv;         // tangent step (nv)
  S* cs = step + nv;           // the convention's scratch
  if (type == kEuler || type == kSemiImplicitEuler || type == kConstantAcceleration) {
    if (!Conv::acceleration(t, m, w, q, v, u, fext, gravity, as, cs)) return false;
    t.one([&] {
      for (int k = 0; k < nv; ++k) v_next[k] = v[k] + dt * as[k];
      for (int k = 0; k < nv; ++k)
        step[k] = type == kEuler ? dt * v[k]
                : type == kSemiImplicitEuler ? dt * v_next[k]
                : dt * v[k] + S(0.5) * dt * dt * as[k];
      Conv::retract(m, q, step, q_next);
    });
    return true;
  }
  // full-state explicit stages
  const Tableau T = tableau(type);
  for (int s = 0; s < T.stages; ++s) {
    // stage state from the initial one with the preceding stage's rates
    t.one([&] {
      if (s == 0) {
        for (int k = 0; k < nv; ++k) vsum[k] = S(0), asum[k] = S(0);
        for (int k = 0; k < nq; ++k) qs[k] = q[k];
        for (int k = 0; k < nv; ++k) vs[k] = v[k];
      } else {
        const S c = S(T.c[s]) * dt;
        for (int k = 0; k < nv; ++k) step[k] = c * vs[k];
        for (int k = 0; k < nv; ++k) vs[k] = v[k] + c * as[k];
        Conv::retract(m, q, step, qs);
      }
    });
    if (!Conv::acceleration(t, m, w, qs, vs, u, fext, gravity, as, cs)) return false;
    t.one([&] {
      for (int k = 0; k < nv; ++k) vsum[k] += S(T.b[s]) * vs[k], asum[k] += S(T.b[s]) * as[k];
    });
  }
  t.one([&] {
    for (int k = 0; k < nv; ++k) step[k] = dt * vsum[k], v_next[k] = v[k] + dt * asum[k];
    Conv::retract(m, q, step, q_next);
  });
  return true;
}

// the step in the given convention (OutputConvention; default Pinocchio's)
template <typename S>
RBD_HD bool integrator_step(const ModelView<S>& m, Workspace<S>& w, int type, const S* q, const S* v, const S* u,
                            const S* fext, S dt, S gravity, S* q_next, S* v_next, S* scratch,
                            int convention = kPinocchioConvention) {
  if (convention == kMujocoConvention)
    return integrator_step_with<MujocoStep<S>>(m, w, type, q, v, u, fext, dt, gravity, q_next, v_next, scratch);
  return integrator_step_with<PinocchioStep<S>>(m, w, type, q, v, u, fext, dt, gravity, q_next, v_next, scratch);
}

// x⁺ and AB = ∂x⁺/∂(x, u) (2nv x 3nv, row-major) in the tangent of the
// convention Conv; with dX_df (2nv x 6nb, may be null) also ∂x⁺/∂f_ext,
// column 6b + c for component c of body b's wrench. false if M is not PD.
// The derivatives are carried as nv x nc blocks, columns [δq | δv | δu | δf]
// (nc = 3nv, or 3nv + 6nb with dX_df); f_ext enters each stage as the force
// it acts as, Fu J_f(q_s) (Conv::force_map), the only input whose map
// depends on the stage's configuration. The δf columns do not change the
// others: every product computes each column on its own.
// Written for a team (model/team.hpp): one thread (InlineTeam, the default)
// or a GPU team kernel's threads, which split each stage's ∇FD and every
// elementwise pass and product; the retractions and their Jacobians stay on
// one thread. Both give the same results.
template <typename Conv, typename S, typename Team = InlineTeam>
RBD_HD bool integrator_gradient_with(const ModelView<S>& m, Workspace<S>& w, int type, const S* q, const S* v,
                                     const S* u, const S* fext, S dt, S gravity, S* q_next, S* v_next, S* AB,
                                     S* dX_df, S* scratch, const Team& t = Team{}) {
  const int nq = m.nq, nv = m.nv, n3 = 3 * nv, nf = dX_df ? 6 * m.nb : 0, nc = n3 + nf;
  const long nn = static_cast<long>(nv) * nv, nd = static_cast<long>(nv) * nc;
  S* qs = scratch;
  S* vs = qs + nq;
  S* as = vs + nv;
  S* vsum = as + nv;
  S* asum = vsum + nv;
  S* step = asum + nv;
  S* cs = step + nv;  // the convention's scratch
  S* mat = scratch + integrator_scratch_values(nq, nv);
  // per stage: ∂q_s, ∂v_s, ∂a_s with respect to [δq | δv | δu (| δf)] (nv x nc each)
  S* Dq = mat;            // nv x nc
  S* Dv = Dq + nd;        // nv x nc
  S* Da = Dv + nd;        // nv x nc
  S* Dvsum = Da + nd;     // nv x nc
  S* Dasum = Dvsum + nd;
  S* Dstep = Dasum + nd;
  S* Fq = Dstep + nd;      // ∂a/∂q at the stage (nv x nv)
  S* Fv = Fq + nn;         // ∂a/∂v
  S* Jq = Fv + nn;         // dIntegrate/dq
  S* Jv = Jq + nn;         // dIntegrate/dv
  S* T1 = Jv + nn;         // nv x nc temporaries
  S* T2 = T1 + nd;
  S* Fu = T2 + nd;         // ∂a/∂u at the stage (nv x nv)
  S* Jf = Fu + nn;         // the force f_ext acts as, ∂u/∂f at the stage (nv x nf)

  // the stage derivatives of the acceleration: Da = Fq Dq + Fv Dv + [0 0 Fu Fu J_f]
  auto stage_acceleration = [&](const S* qq, const S* vv) -> bool {
    if (!Conv::acceleration_derivatives(t, m, w, qq, vv, u, fext, gravity, as, Fq, Fv, Fu, cs)) return false;
    matmul(t, Fq, Dq, Da, nv, nv, nc);
    matmul(t, Fv, Dv, T1, nv, nv, nc);
    t.each(nd, [&](long k) { Da[k] += T1[k]; });
    t.each2(nv, nv, [&](long r, long c) { Da[r * nc + 2 * nv + c] += Fu[r * nv + c]; });
    if (nf) {
      t.one([&] { Conv::force_map(m, w, qq, Jf, cs); });
      matmul(t, Fu, Jf, T1, nv, nv, nf);
      t.each2(nv, nf, [&](long r, long c) { Da[r * nc + n3 + c] += T1[r * nf + c]; });
    }
    return true;
  };
  // ∂(q ⊕ w) for a step w with derivative Dw: Jq [1 0 0] + Jv Dw, written to out
  auto retract_derivative = [&](const S* w_step, const S* Dw, S* out) {
    t.one([&] {
      Conv::dretract(m, q, w_step, 0, Jq);
      Conv::dretract(m, q, w_step, 1, Jv);
    });
    matmul(t, Jv, Dw, out, nv, nv, nc);
    t.each2(nv, nv, [&](long r, long c) { out[r * nc + c] += Jq[r * nv + c]; });
  };
  auto identity_block = [&](S* D, int block) {
    t.each(nd, [&](long k) { D[k] = S(0); });
    t.each(nv, [&](long r) { D[r * nc + block * nv + r] = S(1); });
  };
  // rows r of ∂q⁺ (Dq_next) and ∂v⁺ (Dv_next): AB's columns and dX_df's
  auto write_outputs = [&](const S* Dq_next, const S* Dv_next) {
    t.each2(nv, n3, [&](long r, long c) {
      AB[r * n3 + c] = Dq_next[r * nc + c];
      AB[(nv + r) * n3 + c] = Dv_next[r * nc + c];
    });
    t.each2(nv, nf, [&](long r, long c) {
      dX_df[r * nf + c] = Dq_next[r * nc + n3 + c];
      dX_df[(nv + r) * nf + c] = Dv_next[r * nc + n3 + c];
    });
  };

  // stage 1 (every scheme): q, v, a(q, v)
  identity_block(Dq, 0);
  identity_block(Dv, 1);
  if (!stage_acceleration(q, v)) return false;

  if (type == kEuler || type == kSemiImplicitEuler || type == kConstantAcceleration) {
    // v⁺ = v + dt a; ∂v⁺ - ∂v
    t.each(nv, [&](long k) { v_next[k] = v[k] + dt * as[k]; });
    t.each(nd, [&](long k) { Dstep[k] = dt * Da[k]; });
    t.each(nv, [&](long r) { Dstep[r * nc + nv + r] += S(1); });
    // step w and ∂w
    t.each(nv, [&](long k) {
      step[k] = type == kEuler ? dt * v[k]
              : type == kSemiImplicitEuler ? dt * v_next[k]
              : dt * v[k] + S(0.5) * dt * dt * as[k];
    });
    if (type == kEuler) {
      t.each(nd, [&](long k) { T2[k] = dt * Dv[k]; });
    } else if (type == kSemiImplicitEuler) {
      t.each(nd, [&](long k) { T2[k] = dt * Dstep[k]; });
    } else {
      t.each(nd, [&](long k) { T2[k] = dt * Dv[k] + S(0.5) * dt * dt * Da[k]; });
    }
    t.one([&] { Conv::retract(m, q, step, q_next); });
    retract_derivative(step, T2, T1);
    write_outputs(T1, Dstep);
    return true;
  }

  // full-state stages
  const Tableau T = tableau(type);
  t.each(nv, [&](long k) { vsum[k] = S(T.b[0]) * v[k], asum[k] = S(T.b[0]) * as[k], vs[k] = v[k]; });
  t.each(nd, [&](long k) { Dvsum[k] = S(T.b[0]) * Dv[k], Dasum[k] = S(T.b[0]) * Da[k]; });
  for (int s = 1; s < T.stages; ++s) {
    const S c = S(T.c[s]) * dt;
    // q_s = q ⊕ c v_(s-1), v_s = v + c a_(s-1)
    t.each(nv, [&](long k) { step[k] = c * vs[k]; });
    t.each(nd, [&](long k) { T2[k] = c * Dv[k]; });
    t.one([&] { Conv::retract(m, q, step, qs); });
    retract_derivative(step, T2, Dq);
    t.each(nv, [&](long k) { vs[k] = v[k] + c * as[k]; });
    t.each(nd, [&](long k) { Dv[k] = c * Da[k]; });
    t.each(nv, [&](long r) { Dv[r * nc + nv + r] += S(1); });
    if (!stage_acceleration(qs, vs)) return false;
    const S b = S(T.b[s]);
    t.each(nv, [&](long k) { vsum[k] += b * vs[k], asum[k] += b * as[k]; });
    t.each(nd, [&](long k) { Dvsum[k] += b * Dv[k], Dasum[k] += b * Da[k]; });
  }
  // q⁺ = q ⊕ dt Σ b v_s, v⁺ = v + dt Σ b a_s
  t.each(nv, [&](long k) { step[k] = dt * vsum[k], v_next[k] = v[k] + dt * asum[k]; });
  t.each(nd, [&](long k) { T2[k] = dt * Dvsum[k]; });
  t.one([&] { Conv::retract(m, q, step, q_next); });
  retract_derivative(step, T2, T1);
  t.each2(nv, nc, [&](long r, long c) { Dv[r * nc + c] = dt * Dasum[r * nc + c] + (c == nv + r ? S(1) : S(0)); });
  write_outputs(T1, Dv);
  return true;
}

// the step and its gradient in the given convention (OutputConvention; default Pinocchio's)
template <typename S>
RBD_HD bool integrator_gradient(const ModelView<S>& m, Workspace<S>& w, int type, const S* q, const S* v,
                                const S* u, const S* fext, S dt, S gravity, S* q_next, S* v_next, S* AB,
                                S* scratch, int convention = kPinocchioConvention) {
  if (convention == kMujocoConvention)
    return integrator_gradient_with<MujocoStep<S>>(m, w, type, q, v, u, fext, dt, gravity, q_next, v_next, AB,
                                                   static_cast<S*>(nullptr), scratch);
  return integrator_gradient_with<PinocchioStep<S>>(m, w, type, q, v, u, fext, dt, gravity, q_next, v_next, AB,
                                                    static_cast<S*>(nullptr), scratch);
}

// the step, its gradient AB and dX_df = ∂x⁺/∂f_ext (2nv x 6nb, row-major: column 6b + c
// for component c of body b's wrench, body frame), in the given convention;
// scratch: integrator_fext_gradient_scratch_values(nq, nv, nb)
template <typename S>
RBD_HD bool integrator_fext_gradient(const ModelView<S>& m, Workspace<S>& w, int type, const S* q, const S* v,
                                      const S* u, const S* fext, S dt, S gravity, S* q_next, S* v_next, S* AB,
                                      S* dX_df, S* scratch, int convention = kPinocchioConvention) {
  if (convention == kMujocoConvention)
    return integrator_gradient_with<MujocoStep<S>>(m, w, type, q, v, u, fext, dt, gravity, q_next, v_next, AB,
                                                   dX_df, scratch);
  return integrator_gradient_with<PinocchioStep<S>>(m, w, type, q, v, u, fext, dt, gravity, q_next, v_next, AB,
                                                    dX_df, scratch);
}

}  // namespace rbd
