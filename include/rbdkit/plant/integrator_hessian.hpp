// rbdkit/plant/integrator_hessian.hpp — the second-order sensitivity of
// one integrator step (integrators.hpp), what a DDP solver consumes.
//
// Definition. z = [δq; δv; δu] (N = 3nv) perturbs the input as
// q = q0 ⊕ δq, v = v0 + δv, u = u0 + δu; the output is read in the chart at
// the nominal output x⁺(0) = (q⁺, v⁺):
//   ψ(z) = [q⁺(z) ⊖ q⁺(0); v⁺(z) - v⁺(0)]                    (2nv)
//   AB[i, j]   = ∂ψ_i/∂z_j           (2nv x N, = integrator_gradient)
//   H[i, j, k] = ∂²ψ_i/∂z_j∂z_k       (2nv x N x N, symmetric in j, k)
// so that x⁺(z) = x⁺(0) ⊕ (AB z + ½ H[z, z] + O(|z|³)). ⊕, ⊖ and the
// coordinates of q, v, u and the accelerations are those of the convention
// policy Conv (integrators.hpp): PinocchioStep (integrate / difference,
// body-frame v) or MujocoStep (mj_integrate / mj_difference, qvel =
// [ṗ world; ω body] on free joints; mujoco_convention.hpp).
//
// Method: second-order jets (value, D = ∂/∂z (n x N), H = ∂²/∂z² (n x N x N))
// carried through the stages of the scheme (one driver for both policies),
// built from two small steps:
//   retraction_jet    a stage configuration q_s = (q0 ⊕ δq) ⊕ w(z), read as
//                     ξ = q_s ⊖ q̄_s in the chart at its nominal value, from
//                     the jet of the step w: first derivatives by Conv's
//                     dretract, second derivatives of g(δq, w) per curved
//                     joint part by nested dual numbers through Conv's ⊕ / ⊖
//                     (Pinocchio: free flyer, spherical; MuJoCo: the
//                     quaternions of free and ball joints, the free position
//                     being additive); zero elsewhere;
//   acceleration_jet  a_s = a(q̄_s ⊕ ξ, v_s, u): the derivative tensors of a
//                     (first derivatives of forward dynamics, FDSVA-SO's
//                     second derivatives, fdsva_so.hpp; q-q symmetrised,
//                     which is the Hessian in the exponential chart;
//                     ∂²a/∂v∂u = ∂²a/∂u² = 0) composed with the input jets by
//                     the chain rule. In MuJoCo coordinates the tensors are
//                     Pinocchio's at the converted point carried exactly
//                     (closed form) through the free-joint conversion maps:
//                     inputs (ξ_mj, v_mj, u_mj) -> (ξ, v, u), output
//                     (θ, v, a) -> a_mj = R (a_lin + ω × v_lin).
// Velocities and the step sums are linear in the jets. No external forces.
// Jets are row-major: D[r·N + j], H[(r·N + j)·N + k].
// Files: the jet algebra is jet.hpp, the tensors' conversion to MuJoCo
// coordinates mujoco_tensors.hpp; this header holds the stage jets (retraction,
// acceleration) and the step.
#pragma once

#include "rbdkit/algorithms/fdsva_so.hpp"
#include "rbdkit/plant/integrators.hpp"
#include "rbdkit/plant/jet.hpp"
#include "rbdkit/plant/mujoco_tensors.hpp"
#include "rbdkit/spatial/dual.hpp"

namespace rbd {

// ---------------------------------------------------------------- retraction jet

// the part of joint b whose retraction is curved, as a joint type with its q
// and v offsets; false where ⊕ is flat (additive). Pinocchio: the free flyer
// (SE(3)) and spherical joints whole
template <typename S>
RBD_HD bool curved_part(PinocchioStep<S>, const BodyDesc<S>& b, int& type, int& qo, int& vo) {
  if (quat_offset(b) < 0) return false;
  type = b.type, qo = b.q_idx, vo = b.v_idx;
  return true;
}
// MuJoCo: the quaternion of free and ball joints (a free position is additive)
template <typename S>
RBD_HD bool curved_part(MujocoStep<S>, const BodyDesc<S>& b, int& type, int& qo, int& vo) {
  if (quat_offset(b) < 0) return false;
  const int r = joint_rot(b.type);
  type = kSpherical, qo = b.q_idx + r, vo = b.v_idx + r;
  return true;
}

// second derivatives of ξ = g(δq, w) = ((q0 ⊕ δq) ⊕ w) ⊖ q̄ for one curved
// part (type kFree: d = 6, nq 7; kSpherical: d = 3, nq 4) in Conv's ⊕ / ⊖, at
// δq = 0 and the given w (q̄ = q0 ⊕ w): G[i, a, c] = ∂²ξ_i/∂x_a∂x_c,
// x = [δq; w] (d x 2d x 2d). Exact (nested dual numbers).
template <template <typename> class Conv, typename S>
RBD_HD void joint_retraction_hessian(int type, const S* q0, const S* w, const S* qbar, S* G) {
  using D1 = Dual<S>;
  using D2 = Dual<D1>;
  const int d = joint_nv(type), nqj = joint_nq(type);
  BodyDesc<D2> b{};
  b.parent = -1;
  b.type = type;
  b.nq = nqj;
  b.nv = d;
  b.mimic = 0;
  const ModelView<D2> jm = {1, nqj, d, 0, &b};
  D2 q0d[7], qbd[7], qa[7], qb[7], x[12], out[6];
  for (int k = 0; k < nqj; ++k) q0d[k] = D2(D1(q0[k])), qbd[k] = D2(D1(qbar[k]));
  for (int a = 0; a < 2 * d; ++a)
    for (int c = a; c < 2 * d; ++c) {
      // x = x̄ + ε₁ e_a + ε₂ e_c: the ε₁ε₂ part of ξ is ∂²ξ/∂x_a∂x_c
      for (int k = 0; k < 2 * d; ++k) {
        const S xv = k < d ? S(0) : w[k - d];
        x[k] = D2(D1(xv, k == a ? S(1) : S(0)), D1(k == c ? S(1) : S(0)));
      }
      Conv<D2>::retract(jm, q0d, x, qa);
      Conv<D2>::retract(jm, qa, x + d, qb);
      Conv<D2>::difference(jm, qbd, qb, out);
      for (int i = 0; i < d; ++i) {
        const S h = out[i].d.d;
        G[(i * 2 * d + a) * 2 * d + c] = h;
        G[(i * 2 * d + c) * 2 * d + a] = h;
      }
    }
}

// scratch values of retraction_jet
RBD_HD long retraction_jet_scratch_values(int nv) { return 2L * nv * nv + 6 * 12 * 12 + 2L * 12 * 3 * nv; }

// a cooperative team's memory for the step Hessian beside its scratch, in values, the largest of
// its uses one after another: jet_add_quadratic_upper's products T[i] Y of every row i at once
// (n x p x N: compose_acceleration_jet's nv x 2nv x N, a curved part's at most 6 x 12 x N) and
// FDSVA-SO's blocks (nv³: fdsva_so_second_order)
RBD_HD long integrator_hessian_team_values(int nv) {
  const long N = 3L * nv, compose = 2L * nv * nv * N, retraction = 72L * N, fdsva = 1L * nv * nv * nv;
  const long m = compose > retraction ? compose : retraction;
  return m > fdsva ? m : fdsva;
}

// The jet of a stage configuration q_s = (q0 ⊕ δq) ⊕ w(z) in Conv's ⊕, given
// the jet of the step w: value w (nv), Dw (nv x N) and Hw = hw_scale · Hw_src
// (nv x N x N; null: zero). Writes q̄ = q0 ⊕ w (nq) and the jet of
// ξ = q_s ⊖ q̄: Dxi (nv x N), Hxi (nv x N x N). On team t (model/team.hpp):
// the maps and each curved part's second derivatives on one thread, the
// products side by side; team_tmp: a cooperative team's products
// (integrator_hessian_team_values; unused by one thread)
template <template <typename> class Conv, typename S, typename Team = InlineTeam>
RBD_HD void retraction_jet(const ModelView<S>& m, const S* q0, const S* w, const S* Dw, const S* Hw_src,
                           S hw_scale, S* qbar, S* Dxi, S* Hxi, S* scratch, const Team& t = Team{},
                           S* team_tmp = nullptr) {
  const int nv = m.nv, N = 3 * nv;
  const long nn = static_cast<long>(nv) * nv, NN = static_cast<long>(N) * N;
  S* Gq = scratch;   // ∂(q0 ⊕ w)/∂q0 (nv x nv)
  S* Gw = Gq + nn;   // ∂(q0 ⊕ w)/∂w (nv x nv)
  S* G2 = Gw + nn;   // one joint part's second derivatives (d x 2d x 2d)
  S* J = G2 + 6 * 12 * 12;  // one joint part's [δq; w] rows of the jet (2d x N)
  S* tmp = Team::cooperative ? team_tmp : J + 12L * N;  // (2d x N; a team's: d x 2d x N)
  t.one([&] {
    Conv<S>::retract(m, q0, w, qbar);
    Conv<S>::dretract(m, q0, w, 0, Gq);
    Conv<S>::dretract(m, q0, w, 1, Gw);
  });
  // first order: Dxi = Gq [I 0 0] + Gw Dw
  matmul(t, Gw, Dw, Dxi, nv, nv, N);
  t.each2(nv, nv, [&](long r, long c) { Dxi[r * N + c] += Gq[r * nv + c]; });
  // second order: Gw Hw, then the curvature of the retraction per curved part
  t.each(nv * NN, [&](long k) { Hxi[k] = S(0); });
  if (Hw_src) jet_add_linear_upper(t, nv, nv, N, Gw, Hw_src, hw_scale, Hxi);
  for (int i = 0; i < m.nb; ++i) {
    int type = 0, qo = 0, o = 0;
    if (!curved_part(Conv<S>{}, m.body[i], type, qo, o)) continue;
    const int d = joint_nv(type);
    t.one([&] { joint_retraction_hessian<Conv>(type, q0 + qo, w + o, qbar + qo, G2); });
    t.each2(d, N, [&](long r, long c) {
      J[r * N + c] = c == o + r ? S(1) : S(0);
      J[(d + r) * N + c] = Dw[(o + r) * N + c];
    });
    jet_add_quadratic_upper(t, d, 2 * d, N, G2, J, S(1), Hxi + o * NN, tmp);
  }
  jet_mirror(t, nv, N, Hxi);
}

// ---------------------------------------------------------------- acceleration tensors

// The derivatives of a = FD(q ⊕ ξ, v, u) at ξ = 0 that the jets compose:
// Fq = ∂a/∂ξ, Fv = ∂a/∂v, Fu = ∂a/∂u = M⁻¹ (nv x nv each); T (nv x 2nv x 2nv)
// per row i the symmetric Hessian in (ξ, v); Aqu = ∂²a/∂ξ∂u (nv x nv x nv,
// [(i·nv + b)·nv + c]); ∂²a/∂v∂u = ∂²a/∂u² = 0. Uses w (aba_derivatives,
// fdsva_so_second_order) and 3nv³ scratch values. false if M is not PD. On team t: the
// first order by PinocchioStep's (aba_derivatives_team on a cooperative team,
// in t.extra), FDSVA-SO's second order on that first order (fdsva_so_second_order:
// not forming ∇FD again; on a team in team_tmp, integrator_hessian_team_values),
// T's rows side by side
template <typename S, typename Team = InlineTeam>
RBD_HD bool acceleration_tensors(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* v, const S* u,
                                 S gravity, S* a, S* Fq, S* Fv, S* Fu, S* T, S* Aqu, S* scratch,
                                 const Team& t = Team{}, S* team_tmp = nullptr) {
  const int nv = m.nv, p = 2 * nv;
  const long nn = static_cast<long>(nv) * nv;
  S* Aqq = scratch;        // ∂²a/∂q∂q (nv x nv x nv, iterated)
  S* Avv = Aqq + nn * nv;  // ∂²a/∂v∂v
  S* Aqv = Avv + nn * nv;  // ∂²a/∂q∂v
  // first order; it leaves M⁻¹ (mimic: its Cholesky factor) in w.dense
  if (!PinocchioStep<S>::acceleration_derivatives(t, m, w, q, v, u, static_cast<const S*>(nullptr), gravity, a, Fq,
                                                  Fv, Fu, static_cast<S*>(nullptr)))
    return false;
  // second order: T = [[sym Aqq, Aqv], [Aqvᵀ, Avv]]
  fdsva_so_second_order(m, w, q, v, a, gravity, Fq, Fv, Aqq, Avv, Aqv, Aqu, t, team_tmp);
  t.each(nv, [&](long i) {
    const long o = i * nn;
    S* Ti = T + i * p * p;
    for (int r = 0; r < nv; ++r)
      for (int c = 0; c < nv; ++c) {
        Ti[r * p + c] = S(0.5) * (Aqq[o + r * nv + c] + Aqq[o + c * nv + r]);
        Ti[r * p + nv + c] = Aqv[o + r * nv + c];
        Ti[(nv + c) * p + r] = Aqv[o + r * nv + c];
        Ti[(nv + r) * p + nv + c] = Avv[o + r * nv + c];
      }
  });
  return true;
}

// The jet of a from its tensors (acceleration_tensors) and the jets of ξ
// (Dq, Hq) and v (Dv, Hv), u's jet being [0 0 I]; Hq, Hv may be null (zero).
// Writes Da (nv x N), Ha (nv x N x N); scratch 12nv² values; on team t, as
// retraction_jet (team_tmp: a cooperative team's products). Out of line on the
// host (RBD_NOINLINE)
template <typename S, typename Team = InlineTeam>
RBD_NOINLINE RBD_HD void compose_acceleration_jet(int nv, const S* Fq, const S* Fv, const S* Fu, const S* T,
                                                  const S* Aqu, const S* Dq, const S* Hq, const S* Dv, const S* Hv,
                                                  S* Da, S* Ha, S* scratch, const Team& t = Team{},
                                                  S* team_tmp = nullptr) {
  const int N = 3 * nv, p = 2 * nv;
  const long nn = static_cast<long>(nv) * nv, NN = static_cast<long>(N) * N, Dm = nv * static_cast<long>(N);
  S* Y = scratch;       // [Dq; Dv] (2nv x N)
  S* tmp = Y + 6 * nn;  // (2nv x N)
  // Da = Fq Dq + Fv Dv + [0 0 Fu]
  matmul(t, Fq, Dq, Da, nv, nv, N);
  matmul(t, Fv, Dv, tmp, nv, nv, N);
  t.each(Dm, [&](long k) { Da[k] += tmp[k]; });
  t.each2(nv, nv, [&](long r, long c) { Da[r * N + 2 * nv + c] += Fu[r * nv + c]; });
  // Ha = Yᵀ T Y + (the q-u terms) + Fq Hq + Fv Hv
  t.each(Dm, [&](long k) { Y[k] = Dq[k], Y[Dm + k] = Dv[k]; });
  t.each(nv * NN, [&](long k) { Ha[k] = S(0); });
  jet_add_quadratic_upper(t, nv, p, N, T, Y, S(1), Ha, Team::cooperative ? team_tmp : tmp);
  // Du = [0 0 I]: Ha[i, j, 2nv + c] and Ha[i, 2nv + c, j] += Σ_b Aqu[i, b, c] Dq[b, j] (a row i per index)
  t.each(nv, [&](long i) {
    S* Hi = Ha + i * NN;
    for (int b = 0; b < nv; ++b) {
      const S* a = Aqu + (i * nv + b) * nv;
      for (int j = 0; j < N; ++j) {
        const S d = Dq[b * N + j];
        if (so_skippable(d)) continue;
        for (int c = 0; c < nv; ++c) {
          const S x = d * a[c];
          Hi[static_cast<long>(j) * N + 2 * nv + c] += x;
          Hi[static_cast<long>(2 * nv + c) * N + j] += x;
        }
      }
    }
  });
  if (Hq) jet_add_linear_upper(t, nv, nv, N, Fq, Hq, S(1), Ha);
  if (Hv) jet_add_linear_upper(t, nv, nv, N, Fv, Hv, S(1), Ha);
  jet_mirror(t, nv, N, Ha);
}

// ---------------------------------------------------------------- acceleration jet

// scratch values of acceleration_jet (either convention)
RBD_HD long acceleration_jet_scratch_values(int nq, int nv) {
  const long nn = static_cast<long>(nv) * nv;
  long work = 3 * nn * nv;  // acceleration_tensors
  if (12 * nn > work) work = 12 * nn;  // compose_acceleration_jet
  if (tensors_to_mujoco_scratch_values(nv) > work) work = tensors_to_mujoco_scratch_values(nv);
  return 3 * nn + 5 * nn * nv + nq + 2L * nv + work;
}

// The jet of a_s = a(q̄ ⊕ ξ, v, u + δu) in the convention of the tag from the
// jets of ξ (Dq, Hq) and of v (Dv, Hv); Hq, Hv may be null (zero). Writes
// a (nv), Da (nv x N), Ha (nv x N x N). Uses w; false if M is not PD.
// On team t, as acceleration_tensors and compose_acceleration_jet (team_tmp: a cooperative team's
// memory, integrator_hessian_team_values; MuJoCo's coordinates on one thread only)
template <typename S, typename Team = InlineTeam>
RBD_HD bool acceleration_jet(PinocchioStep<S>, const ModelView<S>& m, Workspace<S>& w, const S* q, const S* v,
                             const S* u, S gravity, const S* Dq, const S* Hq, const S* Dv, const S* Hv, S* a, S* Da,
                             S* Ha, S* scratch, const Team& t = Team{}, S* team_tmp = nullptr) {
  const int nv = m.nv;
  const long nn = static_cast<long>(nv) * nv;
  S* Fq = scratch;          // ∂a/∂ξ (nv x nv)
  S* Fv = Fq + nn;          // ∂a/∂v
  S* Fu = Fv + nn;          // ∂a/∂u
  S* T = Fu + nn;           // (nv x 2nv x 2nv)
  S* Aqu = T + 4 * nn * nv; // (nv x nv x nv)
  S* work = Aqu + nn * nv + m.nq + 2L * nv;
  if (!acceleration_tensors(m, w, q, v, u, gravity, a, Fq, Fv, Fu, T, Aqu, work, t, team_tmp)) return false;
  compose_acceleration_jet(nv, Fq, Fv, Fu, T, Aqu, Dq, Hq, Dv, Hv, Da, Ha, work, t, team_tmp);
  return true;
}

// MuJoCo coordinates: q (MuJoCo layout), v, u in MuJoCo's frames
template <typename S, typename Team = InlineTeam>
RBD_HD bool acceleration_jet(MujocoStep<S>, const ModelView<S>& m, Workspace<S>& w, const S* q_mj, const S* v_mj,
                             const S* u_mj, S gravity, const S* Dq, const S* Hq, const S* Dv, const S* Hv, S* a, S* Da,
                             S* Ha, S* scratch, const Team& = Team{}, S* = nullptr) {
  static_assert(!Team::cooperative, "MuJoCo's coordinates have no team form of the step Hessian");
  const int nv = m.nv;
  const long nn = static_cast<long>(nv) * nv;
  S* Fq = scratch;
  S* Fv = Fq + nn;
  S* Fu = Fv + nn;
  S* T = Fu + nn;
  S* Aqu = T + 4 * nn * nv;
  S* q = Aqu + nn * nv;  // the point in our coordinates: q (nq), v (nv), u (nv)
  S* v = q + m.nq;
  S* u = v + nv;
  S* work = u + nv;
  configuration_from_mujoco(m, q_mj, q);
  rotate_from_mujoco(m, q_mj, v_mj, v);
  rotate_from_mujoco(m, q_mj, u_mj, u);
  if (!acceleration_tensors(m, w, q, v, u, gravity, a, Fq, Fv, Fu, T, Aqu, work)) return false;
  tensors_to_mujoco(m, q_mj, v, u, a, Fq, Fv, Fu, T, Aqu, work);
  compose_acceleration_jet(nv, Fq, Fv, Fu, T, Aqu, Dq, Hq, Dv, Hv, Da, Ha, work);
  return true;
}

// ---------------------------------------------------------------- the step

// scratch values (of type S) of integrator_hessian (either convention)
RBD_HD long integrator_hessian_scratch_values(int nq, int nv) {
  const long N = 3L * nv, Dm = nv * N, T = Dm * N;
  const long r = retraction_jet_scratch_values(nv), a = acceleration_jet_scratch_values(nq, nv);
  return nq + 5L * nv + 6 * Dm + 4 * T + (r > a ? r : a);
}

// x⁺ (q_next (nq), v_next (nv)), AB (2nv x N) and H (2nv x N x N) as defined
// at the top of this file, in the coordinates of the policy Conv
// (PinocchioStep or MujocoStep). false if M is not PD at a stage. On team t
// (model/team.hpp; a cooperative one in Pinocchio's coordinates, on a model
// without mimic joints): each stage's first derivatives by
// aba_derivatives_team (in t.extra), IDSVA-SO and the retraction maps on one
// thread, FDSVA-SO's and the jets' products and sums side by side; team_tmp:
// integrator_hessian_team_values(nv) values (unused by one thread)
template <template <typename> class Conv, typename S, typename Team = InlineTeam>
RBD_HD bool integrator_hessian_with(const ModelView<S>& m, Workspace<S>& w, int type, const S* q, const S* v,
                                    const S* u, S dt, S gravity, S* q_next, S* v_next, S* AB, S* H, S* scratch,
                                    const Team& t = Team{}, S* team_tmp = nullptr) {
  const int nq = m.nq, nv = m.nv, N = 3 * nv;
  const long Dm = static_cast<long>(nv) * N, T = Dm * N;
  S* qs = scratch;        // stage configuration (nq)
  S* vs = qs + nq;        // stage velocity (nv)
  S* as = vs + nv;        // stage acceleration (nv)
  S* vsum = as + nv;      // Σ b_s v_s
  S* asum = vsum + nv;    // Σ b_s a_s
  S* step = asum + nv;    // retraction step w (nv)
  S* Dxi = step + nv;    // jets: D (nv x N) ...
  S* Dv = Dxi + Dm;
  S* Da = Dv + Dm;
  S* Dvsum = Da + Dm;
  S* Dasum = Dvsum + Dm;
  S* Dw = Dasum + Dm;
  S* Hxi = Dw + Dm;       // ... and H (nv x N x N)
  S* Hv = Hxi + T;
  S* Ha = Hv + T;
  S* Hasum = Ha + T;
  S* sub = Hasum + T;     // retraction_jet / acceleration_jet scratch
  S* Hq_next = H;         // output rows
  S* Hv_next = H + T;

  // stage 1 (every scheme): ξ = δq, v = v0 + δv, a(q, v, u)
  jet_unit_block(t, nv, 0, Dxi);
  jet_unit_block(t, nv, 1, Dv);
  if (!acceleration_jet(Conv<S>{}, m, w, q, v, u, gravity, Dxi, static_cast<const S*>(nullptr), Dv,
                        static_cast<const S*>(nullptr), as, Da, Ha, sub, t, team_tmp))
    return false;

  if (type == kEuler || type == kSemiImplicitEuler || type == kConstantAcceleration) {
    // v⁺ = v + dt a
    t.each(nv, [&](long k) { v_next[k] = v[k] + dt * as[k]; });
    t.each(Dm, [&](long k) { Dvsum[k] = Dv[k] + dt * Da[k]; });  // ∂v⁺
    t.each(T, [&](long k) { Hv_next[k] = dt * Ha[k]; });
    // q⁺ = q ⊕ w: euler w = dt v, semi-implicit w = dt v⁺, constant acceleration w = dt v + ½ dt² a
    S hs = S(0);
    if (type == kEuler) {
      t.each(nv, [&](long k) { step[k] = dt * v[k]; });
      t.each(Dm, [&](long k) { Dw[k] = dt * Dv[k]; });
    } else if (type == kSemiImplicitEuler) {
      t.each(nv, [&](long k) { step[k] = dt * v_next[k]; });
      t.each(Dm, [&](long k) { Dw[k] = dt * Dvsum[k]; });
      hs = dt * dt;
    } else {
      t.each(nv, [&](long k) { step[k] = dt * v[k] + S(0.5) * dt * dt * as[k]; });
      t.each(Dm, [&](long k) { Dw[k] = dt * Dv[k] + S(0.5) * dt * dt * Da[k]; });
      hs = S(0.5) * dt * dt;
    }
    retraction_jet<Conv>(m, q, step, Dw, type == kEuler ? static_cast<const S*>(nullptr) : Ha, hs, q_next, Dxi,
                         Hq_next, sub, t, team_tmp);
    t.each(Dm, [&](long k) { AB[k] = Dxi[k], AB[Dm + k] = Dvsum[k]; });
    return true;
  }

  // full-state stages: q_s = q ⊕ c dt v_(s-1), v_s = v + c dt a_(s-1)
  const Tableau tb = tableau(type);
  S b0 = S(tb.b[0]);
  t.each(nv, [&](long k) { vsum[k] = b0 * v[k], asum[k] = b0 * as[k], vs[k] = v[k]; });
  t.each(Dm, [&](long k) { Dvsum[k] = b0 * Dv[k], Dasum[k] = b0 * Da[k]; });
  t.each(T, [&](long k) { Hasum[k] = b0 * Ha[k], Hv_next[k] = S(0); });  // Σ b_s Hv_s is kept in Hv_next
  bool hv_zero = true;  // Hv of the preceding stage is zero (stage 1)
  for (int s = 1; s < tb.stages; ++s) {
    const S c = S(tb.c[s]) * dt, b = S(tb.b[s]);
    // configuration from the preceding stage's velocity jet
    t.each(nv, [&](long k) { step[k] = c * vs[k]; });
    t.each(Dm, [&](long k) { Dw[k] = c * Dv[k]; });
    retraction_jet<Conv>(m, q, step, Dw, hv_zero ? static_cast<const S*>(nullptr) : Hv, c, qs, Dxi, Hxi, sub, t,
                         team_tmp);
    // velocity from the preceding stage's acceleration jet
    t.each(nv, [&](long k) { vs[k] = v[k] + c * as[k]; });
    jet_unit_block(t, nv, 1, Dv);
    t.each(Dm, [&](long k) { Dv[k] += c * Da[k]; });
    t.each(T, [&](long k) { Hv[k] = c * Ha[k]; });
    hv_zero = false;
    if (!acceleration_jet(Conv<S>{}, m, w, qs, vs, u, gravity, Dxi, Hxi, Dv, Hv, as, Da, Ha, sub, t, team_tmp))
      return false;
    t.each(nv, [&](long k) { vsum[k] += b * vs[k], asum[k] += b * as[k]; });
    t.each(Dm, [&](long k) { Dvsum[k] += b * Dv[k], Dasum[k] += b * Da[k]; });
    t.each(T, [&](long k) { Hv_next[k] += b * Hv[k], Hasum[k] += b * Ha[k]; });
  }
  // q⁺ = q ⊕ dt Σ b v_s (its H from Σ b Hv_s, held in Hv_next), v⁺ = v + dt Σ b a_s
  t.each(nv, [&](long k) { step[k] = dt * vsum[k], v_next[k] = v[k] + dt * asum[k]; });
  t.each(Dm, [&](long k) { Dw[k] = dt * Dvsum[k]; });
  retraction_jet<Conv>(m, q, step, Dw, Hv_next, dt, q_next, Dxi, Hq_next, sub, t, team_tmp);
  t.each(T, [&](long k) { Hv_next[k] = dt * Hasum[k]; });
  t.each(Dm, [&](long k) { AB[k] = Dxi[k], AB[Dm + k] = dt * Dasum[k]; });
  t.each(nv, [&](long r) { AB[Dm + r * N + nv + r] += S(1); });
  return true;
}

// the step Hessian in the given convention (OutputConvention; default Pinocchio's)
template <typename S>
RBD_HD bool integrator_hessian(const ModelView<S>& m, Workspace<S>& w, int type, const S* q, const S* v,
                               const S* u, S dt, S gravity, S* q_next, S* v_next, S* AB, S* H, S* scratch,
                               int convention = kPinocchioConvention) {
  if (convention == kMujocoConvention)
    return integrator_hessian_with<MujocoStep>(m, w, type, q, v, u, dt, gravity, q_next, v_next, AB, H, scratch);
  return integrator_hessian_with<PinocchioStep>(m, w, type, q, v, u, dt, gravity, q_next, v_next, AB, H, scratch);
}

}  // namespace rbd
