// rbdkit/algorithms/integrator_hessian.hpp — the second-order sensitivity of
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
#pragma once

#include "../dual.hpp"
#include "fdsva_so.hpp"
#include "integrators.hpp"

namespace rbd {

// ---------------------------------------------------------------- jet algebra
// Every H is symmetric in (j, k): the products below fill the upper triangle
// (k >= j) only, and jet_mirror completes a tensor once it is summed.

// H[i] += s · Yᵀ T[i] Y on k >= j: H[i, j, k] += s Σ_ab T[i, a, b] Y[a, j] Y[b, k]
// (T n x p x p, each T[i] symmetric; Y p x N; H n x N x N); tmp (p x N)
template <typename S>
RBD_HD void jet_add_quadratic_upper(int n, int p, int N, const S* T, const S* Y, S s, S* H, S* tmp) {
  const long NN = static_cast<long>(N) * N;
  for (int i = 0; i < n; ++i) {
    const S* Ti = T + static_cast<long>(i) * p * p;
    // tmp = T[i] Y
    bool any = false;
    for (long k = 0; k < static_cast<long>(p) * N; ++k) tmp[k] = S(0);
    for (int a = 0; a < p; ++a)
      for (int b = 0; b < p; ++b) {
        const S t = Ti[a * p + b];
        if (so_skippable(t)) continue;
        any = true;
        const S* yb = Y + static_cast<long>(b) * N;
        S* ta = tmp + static_cast<long>(a) * N;
        for (int k = 0; k < N; ++k) ta[k] += t * yb[k];
      }
    if (!any) continue;
    // H[i] += s Yᵀ tmp, k >= j
    S* Hi = H + i * NN;
    for (int a = 0; a < p; ++a) {
      const S* ta = tmp + static_cast<long>(a) * N;
      for (int j = 0; j < N; ++j) {
        const S y = Y[static_cast<long>(a) * N + j];
        if (so_skippable(y)) continue;
        const S sy = s * y;
        S* h = Hi + static_cast<long>(j) * N;
        for (int k = j; k < N; ++k) h[k] += sy * ta[k];
      }
    }
  }
}

// H[i] += s Σ_a F[i, a] Hin[a] on k >= j (F n x p, Hin p x N x N, H n x N x N);
// row j of every Hin[a] is reused across i while it is in cache
template <typename S> RBD_HD void jet_add_linear_upper(int n, int p, int N, const S* F, const S* Hin, S s, S* H) {
  const long NN = static_cast<long>(N) * N;
  for (int j = 0; j < N; ++j)
    for (int i = 0; i < n; ++i) {
      S* h = H + i * NN + static_cast<long>(j) * N;
      for (int a = 0; a < p; ++a) {
        const S f = F[i * p + a];
        if (so_skippable(f)) continue;
        const S sf = s * f;
        const S* src = Hin + a * NN + static_cast<long>(j) * N;
        for (int k = j; k < N; ++k) h[k] += sf * src[k];
      }
    }
}

// H[i, k, j] <- H[i, j, k] for k > j (n x N x N)
template <typename S> RBD_HD void jet_mirror(int n, int N, S* H) {
  for (int i = 0; i < n; ++i) {
    S* Hi = H + static_cast<long>(i) * N * N;
    for (int j = 0; j < N; ++j)
      for (int k = j + 1; k < N; ++k) Hi[k * N + j] = Hi[j * N + k];
  }
}

// D (n x N) <- the unit block: D[r, block·nv + r] = 1 (n = nv)
template <typename S> RBD_HD void jet_unit_block(int nv, int block, S* D) {
  const int N = 3 * nv;
  for (long k = 0; k < static_cast<long>(nv) * N; ++k) D[k] = S(0);
  for (int r = 0; r < nv; ++r) D[r * N + block * nv + r] = S(1);
}

// ---------------------------------------------------------------- retraction jet

// the part of joint b whose retraction is curved, as a joint type with its q
// and v offsets; false where ⊕ is flat (additive). Pinocchio: the free flyer
// (SE(3)) and spherical joints whole
template <typename S>
RBD_HD bool curved_part(PinocchioStep<S>, const BodyDesc<S>& b, int& type, int& qo, int& vo) {
  if (b.mimic || (b.type != kFree && b.type != kSpherical)) return false;
  type = b.type, qo = b.q_idx, vo = b.v_idx;
  return true;
}
// MuJoCo: the quaternion of free and ball joints (a free position is additive)
template <typename S>
RBD_HD bool curved_part(MujocoStep<S>, const BodyDesc<S>& b, int& type, int& qo, int& vo) {
  if (b.mimic || (b.type != kFree && b.type != kSpherical)) return false;
  const int r = b.type == kFree ? 3 : 0;
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
  const int d = type == kFree ? 6 : 3, nqj = type == kFree ? 7 : 4;
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

// The jet of a stage configuration q_s = (q0 ⊕ δq) ⊕ w(z) in Conv's ⊕, given
// the jet of the step w: value w (nv), Dw (nv x N) and Hw = hw_scale · Hw_src
// (nv x N x N; null: zero). Writes q̄ = q0 ⊕ w (nq) and the jet of
// ξ = q_s ⊖ q̄: Dxi (nv x N), Hxi (nv x N x N).
template <template <typename> class Conv, typename S>
RBD_HD void retraction_jet(const ModelView<S>& m, const S* q0, const S* w, const S* Dw, const S* Hw_src,
                           S hw_scale, S* qbar, S* Dxi, S* Hxi, S* scratch) {
  const int nv = m.nv, N = 3 * nv;
  const long nn = static_cast<long>(nv) * nv, NN = static_cast<long>(N) * N;
  S* Gq = scratch;   // ∂(q0 ⊕ w)/∂q0 (nv x nv)
  S* Gw = Gq + nn;   // ∂(q0 ⊕ w)/∂w (nv x nv)
  S* G2 = Gw + nn;   // one joint part's second derivatives (d x 2d x 2d)
  S* J = G2 + 6 * 12 * 12;  // one joint part's [δq; w] rows of the jet (2d x N)
  S* tmp = J + 12L * N;     // (2d x N)
  Conv<S>::retract(m, q0, w, qbar);
  // first order: Dxi = Gq [I 0 0] + Gw Dw
  Conv<S>::dretract(m, q0, w, 0, Gq);
  Conv<S>::dretract(m, q0, w, 1, Gw);
  matmul(Gw, Dw, Dxi, nv, nv, N);
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < nv; ++c) Dxi[r * N + c] += Gq[r * nv + c];
  // second order: Gw Hw, then the curvature of the retraction per curved part
  for (long k = 0; k < nv * NN; ++k) Hxi[k] = S(0);
  if (Hw_src) jet_add_linear_upper(nv, nv, N, Gw, Hw_src, hw_scale, Hxi);
  for (int i = 0; i < m.nb; ++i) {
    int type = 0, qo = 0, o = 0;
    if (!curved_part(Conv<S>{}, m.body[i], type, qo, o)) continue;
    const int d = type == kFree ? 6 : 3;
    joint_retraction_hessian<Conv>(type, q0 + qo, w + o, qbar + qo, G2);
    for (int r = 0; r < d; ++r)
      for (int c = 0; c < N; ++c) {
        J[r * N + c] = c == o + r ? S(1) : S(0);
        J[(d + r) * N + c] = Dw[(o + r) * N + c];
      }
    jet_add_quadratic_upper(d, 2 * d, N, G2, J, S(1), Hxi + o * NN, tmp);
  }
  jet_mirror(nv, N, Hxi);
}

// ---------------------------------------------------------------- acceleration tensors

// The derivatives of a = FD(q ⊕ ξ, v, u) at ξ = 0 that the jets compose:
// Fq = ∂a/∂ξ, Fv = ∂a/∂v, Fu = ∂a/∂u = M⁻¹ (nv x nv each); T (nv x 2nv x 2nv)
// per row i the symmetric Hessian in (ξ, v); Aqu = ∂²a/∂ξ∂u (nv x nv x nv,
// [(i·nv + b)·nv + c]); ∂²a/∂v∂u = ∂²a/∂u² = 0. Uses w (aba_derivatives,
// fdsva_so) and 3nv³ scratch values. false if M is not PD.
template <typename S>
RBD_HD bool acceleration_tensors(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* v, const S* u,
                                 S gravity, S* a, S* Fq, S* Fv, S* Fu, S* T, S* Aqu, S* scratch) {
  const int nv = m.nv, p = 2 * nv;
  const long nn = static_cast<long>(nv) * nv;
  S* Aqq = scratch;        // ∂²a/∂q∂q (nv x nv x nv, iterated)
  S* Avv = Aqq + nn * nv;  // ∂²a/∂v∂v
  S* Aqv = Avv + nn * nv;  // ∂²a/∂q∂v
  // first order; aba_derivatives leaves M⁻¹ (mimic: its Cholesky factor) in w.dense
  if (!aba_derivatives(m, w, q, v, u, static_cast<const S*>(nullptr), gravity, a, Fq, Fv)) return false;
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < nv; ++c) Fu[r * nv + c] = r == c ? S(-1) : S(0);
  apply_neg_minv(m, w, Fu, nv);
  // second order: T = [[sym Aqq, Aqv], [Aqvᵀ, Avv]]
  if (!fdsva_so(m, w, q, v, u, gravity, Aqq, Avv, Aqv, Aqu)) return false;
  for (int i = 0; i < nv; ++i) {
    const long o = static_cast<long>(i) * nn;
    S* Ti = T + static_cast<long>(i) * p * p;
    for (int r = 0; r < nv; ++r)
      for (int c = 0; c < nv; ++c) {
        Ti[r * p + c] = S(0.5) * (Aqq[o + r * nv + c] + Aqq[o + c * nv + r]);
        Ti[r * p + nv + c] = Aqv[o + r * nv + c];
        Ti[(nv + c) * p + r] = Aqv[o + r * nv + c];
        Ti[(nv + r) * p + nv + c] = Avv[o + r * nv + c];
      }
  }
  return true;
}

// The jet of a from its tensors (acceleration_tensors) and the jets of ξ
// (Dq, Hq) and v (Dv, Hv), u's jet being [0 0 I]; Hq, Hv may be null (zero).
// Writes Da (nv x N), Ha (nv x N x N); scratch 12nv² values.
template <typename S>
RBD_HD void compose_acceleration_jet(int nv, const S* Fq, const S* Fv, const S* Fu, const S* T, const S* Aqu,
                                     const S* Dq, const S* Hq, const S* Dv, const S* Hv, S* Da, S* Ha, S* scratch) {
  const int N = 3 * nv, p = 2 * nv;
  const long nn = static_cast<long>(nv) * nv, NN = static_cast<long>(N) * N;
  S* Y = scratch;       // [Dq; Dv] (2nv x N)
  S* tmp = Y + 6 * nn;  // (2nv x N)
  // Da = Fq Dq + Fv Dv + [0 0 Fu]
  matmul(Fq, Dq, Da, nv, nv, N);
  matmul(Fv, Dv, tmp, nv, nv, N);
  for (long k = 0; k < nv * static_cast<long>(N); ++k) Da[k] += tmp[k];
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < nv; ++c) Da[r * N + 2 * nv + c] += Fu[r * nv + c];
  // Ha = Yᵀ T Y + (the q-u terms) + Fq Hq + Fv Hv
  for (long k = 0; k < nv * static_cast<long>(N); ++k) Y[k] = Dq[k], Y[nv * static_cast<long>(N) + k] = Dv[k];
  for (long k = 0; k < nv * NN; ++k) Ha[k] = S(0);
  jet_add_quadratic_upper(nv, p, N, T, Y, S(1), Ha, tmp);
  // Du = [0 0 I]: Ha[i, j, 2nv + c] and Ha[i, 2nv + c, j] += Σ_b Aqu[i, b, c] Dq[b, j]
  for (int i = 0; i < nv; ++i)
    for (int b = 0; b < nv; ++b) {
      const S* t = Aqu + (static_cast<long>(i) * nv + b) * nv;
      S* Hi = Ha + i * NN;
      for (int j = 0; j < N; ++j) {
        const S d = Dq[b * N + j];
        if (so_skippable(d)) continue;
        for (int c = 0; c < nv; ++c) {
          const S x = d * t[c];
          Hi[static_cast<long>(j) * N + 2 * nv + c] += x;
          Hi[static_cast<long>(2 * nv + c) * N + j] += x;
        }
      }
    }
  if (Hq) jet_add_linear_upper(nv, nv, N, Fq, Hq, S(1), Ha);
  if (Hv) jet_add_linear_upper(nv, nv, N, Fv, Hv, S(1), Ha);
  jet_mirror(nv, N, Ha);
}

// ---------------------------------------------------------------- the tensors in MuJoCo coordinates
// Per free joint (v offset o, R its rotation at the stage, θ = ξ[o+3..o+5]),
// with x = [ξ; v; u] (3nv) in MuJoCo coordinates and y the same in ours:
//   ξ_lin = V(θ)⁻¹ Rᵀ ξ_mj,lin   (SE(3) log of (Exp θ, Rᵀ δp)),  ξ_ang = θ
//   v_lin = Exp(-θ) Rᵀ v_mj,lin,  u_lin = Exp(-θ) Rᵀ u_mj,lin,  angular parts equal
// then a_mj,lin = R Exp(θ) (a_lin + ω × v_lin), a_mj,ang = a_ang. The input
// map's Jacobian Φ and second derivatives (at θ = 0, vl = v_lin, ul = u_lin):
//   ∂ξ_lin/∂ξ_mj,lin = Rᵀ;  ∂v_lin/∂θ = [vl]×, ∂v_lin/∂v_mj,lin = Rᵀ (u alike)
//   ∂²ξ_lin/∂ξ_mj,lin_a∂θ_b = -½ e_b × r_a                  (r_a = Rᵀ e_a)
//   ∂²v_lin/∂θ_b∂θ_c = ½ (e_b × (e_c × vl) + e_c × (e_b × vl)),
//   ∂²v_lin/∂θ_b∂v_mj,lin_a = -e_b × r_a                    (u alike)
// so that F_mj = F Φ and A_mj[i] = Φᵀ A[i] Φ + Σ_c F[i, c] ∂²y_c on the input
// side; the output map then adds its own first and second derivatives.

// scratch values of tensors_to_mujoco
RBD_HD long tensors_to_mujoco_scratch_values(int nv) { return 27L * nv * nv + 9L * nv; }

// row i of (T, Aqu) as the full symmetric Hessian over x = [ξ; v; u] (3nv x 3nv), and back
template <typename S> RBD_HD void tensor_row_unpack(int nv, const S* T, const S* Aqu, int i, S* Mf) {
  const int p = 2 * nv, n3 = 3 * nv;
  const S* Ti = T + static_cast<long>(i) * p * p;
  const S* Ai = Aqu + static_cast<long>(i) * nv * nv;
  for (int r = 0; r < n3; ++r)
    for (int c = 0; c < n3; ++c) {
      S x = S(0);
      if (r < p && c < p) x = Ti[r * p + c];
      else if (r < nv && c >= p) x = Ai[r * nv + c - p];
      else if (c < nv && r >= p) x = Ai[c * nv + r - p];
      Mf[static_cast<long>(r) * n3 + c] = x;
    }
}
template <typename S> RBD_HD void tensor_row_pack(int nv, const S* Mf, int i, S* T, S* Aqu) {
  const int p = 2 * nv, n3 = 3 * nv;
  S* Ti = T + static_cast<long>(i) * p * p;
  S* Ai = Aqu + static_cast<long>(i) * nv * nv;
  for (int r = 0; r < p; ++r)
    for (int c = 0; c < p; ++c) Ti[r * p + c] = Mf[static_cast<long>(r) * n3 + c];
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < nv; ++c) Ai[r * nv + c] = Mf[static_cast<long>(r) * n3 + p + c];
}

template <typename S> RBD_HD Vec3<S> load3(const S* z, long st) { return {z[0], z[st], z[2 * st]}; }
template <typename S> RBD_HD void store3(const Vec3<S>& a, S* z, long st) { z[0] = a.x, z[st] = a.y, z[2 * st] = a.z; }
// the symmetric pair (j, k), (k, j) of a full (n3 x n3) matrix += x
template <typename S> RBD_HD void add_sym(S* Mf, int n3, int j, int k, S x) {
  Mf[static_cast<long>(j) * n3 + k] += x;
  if (j != k) Mf[static_cast<long>(k) * n3 + j] += x;
}

// z <- Φᵀ z on one free joint's entries of a line z over x (its ξ, v, u parts
// at zq, zv, zu, stride st): z_θ += z_vlin × vl + z_ulin × ul, then the
// ξ_lin, v_lin and u_lin parts <- R (·)
template <typename S>
RBD_HD void free_input_transpose(int o, const Mat3<S>& R, const Vec3<S>& vl, const Vec3<S>& ul, S* zq, S* zv,
                                 S* zu, long st) {
  const Vec3<S> zvl = load3(zv + o * st, st), zul = load3(zu + o * st, st);
  store3(load3(zq + (o + 3) * st, st) + cross(zvl, vl) + cross(zul, ul), zq + (o + 3) * st, st);
  store3(R * load3(zq + o * st, st), zq + o * st, st);
  store3(R * zvl, zv + o * st, st);
  store3(R * zul, zu + o * st, st);
}

// The tensors of a (acceleration_tensors at the converted point q, v, u in
// our coordinates) -> those of a_mj in MuJoCo coordinates at q_mj, in place:
// a (nv), Fq, Fv, Fu, T, Aqu. A no-op without free joints.
template <typename S>
RBD_HD void tensors_to_mujoco(const ModelView<S>& m, const S* q_mj, const S* v, const S* u, S* a, S* Fq, S* Fv,
                              S* Fu, S* T, S* Aqu, S* scratch) {
  const int nv = m.nv, n3 = 3 * nv;
  const long nn3 = static_cast<long>(n3) * n3;
  bool any = false;
  for (int i = 0; i < m.nb; ++i) any = any || (!m.body[i].mimic && m.body[i].type == kFree);
  if (!any) return;
  S* Mf = scratch;         // three full Hessians (3 x 3nv x 3nv)
  S* Ds = Mf + 3 * nn3;    // ∂s (3 x 3nv)
  const Vec3<S> E[3] = {{S(1), S(0), S(0)}, {S(0), S(1), S(0)}, {S(0), S(0), S(1)}};

  // input side, row by row: A[i] <- Φᵀ A[i] Φ + Σ_c F[i, c] ∂²y_c, then F[i] <- F[i] Φ
  for (int i = 0; i < nv; ++i) {
    tensor_row_unpack(nv, T, Aqu, i, Mf);
    for (int j = 0; j < m.nb; ++j) {
      const BodyDesc<S>& b = m.body[j];
      if (b.mimic || b.type != kFree) continue;
      const int o = b.v_idx;
      const Mat3<S> R = free_rotation_mj(b, q_mj);
      const Vec3<S> vl = load3(v + o, 1), ul = load3(u + o, 1);
      // Φᵀ on the rows, then on the columns
      for (int c = 0; c < n3; ++c)
        free_input_transpose(o, R, vl, ul, Mf + c, Mf + nv * n3 + c, Mf + 2 * nv * n3 + c, n3);
      for (int r = 0; r < n3; ++r) {
        S* z = Mf + r * n3;
        free_input_transpose(o, R, vl, ul, z, z + nv, z + 2 * nv, 1);
      }
      // the input map's second derivatives weighted by row i of F (ours)
      const Vec3<S> wq = load3(Fq + i * nv + o, 1), wv = load3(Fv + i * nv + o, 1), wu = load3(Fu + i * nv + o, 1);
      for (int ia = 0; ia < 3; ++ia) {
        const Vec3<S> ra = {R(ia, 0), R(ia, 1), R(ia, 2)};
        const Vec3<S> cq = S(-0.5) * cross(ra, wq), cv = S(-1) * cross(ra, wv), cu = S(-1) * cross(ra, wu);
        for (int ib = 0; ib < 3; ++ib) {
          add_sym(Mf, n3, o + ia, o + 3 + ib, cq[ib]);
          add_sym(Mf, n3, nv + o + ia, o + 3 + ib, cv[ib]);
          add_sym(Mf, n3, 2 * nv + o + ia, o + 3 + ib, cu[ib]);
        }
      }
      const S dv = dot(wv, vl), du = dot(wu, ul);
      for (int ib = 0; ib < 3; ++ib)
        for (int ic = 0; ic < 3; ++ic) {
          const S x = S(0.5) * (wv[ic] * vl[ib] + wv[ib] * vl[ic] + wu[ic] * ul[ib] + wu[ib] * ul[ic]) -
                      (ib == ic ? dv + du : S(0));
          Mf[static_cast<long>(o + 3 + ib) * n3 + o + 3 + ic] += x;
        }
      free_input_transpose(o, R, vl, ul, Fq + i * nv, Fv + i * nv, Fu + i * nv, 1);
    }
    tensor_row_pack(nv, Mf, i, T, Aqu);
  }

  // output side per free joint: rows o..o+2 <- R Exp(θ) s, s = a_lin + ω × v_lin
  for (int j = 0; j < m.nb; ++j) {
    const BodyDesc<S>& b = m.body[j];
    if (b.mimic || b.type != kFree) continue;
    const int o = b.v_idx;
    const Mat3<S> R = free_rotation_mj(b, q_mj);
    const Vec3<S> vl = load3(v + o, 1), om = load3(v + o + 3, 1);
    const Vec3<S> s = load3(a + o, 1) + cross(om, vl);
    // value, the rows' jets of s: ∂s = F_mj[lin rows] + ∂(ω × v_lin)
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < nv; ++k) {
        Ds[r * n3 + k] = Fq[(o + r) * nv + k];
        Ds[r * n3 + nv + k] = Fv[(o + r) * nv + k];
        Ds[r * n3 + 2 * nv + k] = Fu[(o + r) * nv + k];
      }
      tensor_row_unpack(nv, T, Aqu, o + r, Mf + r * nn3);
    }
    auto add3 = [&](int jj, int kk, const Vec3<S>& x) {  // the three rows' (jj, kk) and (kk, jj) += x
      for (int r = 0; r < 3; ++r) add_sym(Mf + r * nn3, n3, jj, kk, x[r]);
    };
    for (int ib = 0; ib < 3; ++ib) {
      const Vec3<S> ra = {R(ib, 0), R(ib, 1), R(ib, 2)};  // r_a for a = ib
      store3(load3(Ds + o + 3 + ib, n3) + cross(om, cross(vl, E[ib])), Ds + o + 3 + ib, n3);
      store3(load3(Ds + nv + o + 3 + ib, n3) + cross(E[ib], vl), Ds + nv + o + 3 + ib, n3);
      store3(load3(Ds + nv + o + ib, n3) + cross(om, ra), Ds + nv + o + ib, n3);
    }
    for (int ib = 0; ib < 3; ++ib)
      for (int ic = 0; ic < 3; ++ic) {
        const Vec3<S> ra = {R(ic, 0), R(ic, 1), R(ic, 2)};  // a = ic
        add3(nv + o + 3 + ib, o + 3 + ic, cross(E[ib], cross(vl, E[ic])));   // ω-θ
        add3(nv + o + 3 + ib, nv + o + ic, cross(E[ib], ra));                // ω-v_lin
        add3(o + 3 + ib, nv + o + ic, S(-1) * cross(om, cross(E[ib], ra)));  // θ-v_lin
        if (ic >= ib) {  // θ-θ: ω × ∂²v_lin
          const Vec3<S> Q = S(0.5) * (cross(E[ib], cross(E[ic], vl)) + cross(E[ic], cross(E[ib], vl)));
          add3(o + 3 + ib, o + 3 + ic, cross(om, Q));
        }
      }
    // R Exp(θ) s: θ-θ, θ-x terms with ∂s, then ∂ gets e_b × s on the θ columns
    for (int ib = 0; ib < 3; ++ib) {
      for (int ic = ib; ic < 3; ++ic)
        add3(o + 3 + ib, o + 3 + ic,
             S(0.5) * (cross(E[ib], cross(E[ic], s)) + cross(E[ic], cross(E[ib], s))));
      for (int k = 0; k < n3; ++k) {
        const Vec3<S> x = cross(E[ib], load3(Ds + k, n3));
        for (int r = 0; r < 3; ++r) {
          Mf[r * nn3 + static_cast<long>(o + 3 + ib) * n3 + k] += x[r];
          Mf[r * nn3 + static_cast<long>(k) * n3 + o + 3 + ib] += x[r];
        }
      }
    }
    for (int ib = 0; ib < 3; ++ib) store3(load3(Ds + o + 3 + ib, n3) + cross(E[ib], s), Ds + o + 3 + ib, n3);
    // rotate the three rows by R and write them back
    for (long k = 0; k < nn3; ++k) store3(R * load3(Mf + k, nn3), Mf + k, nn3);
    for (int k = 0; k < n3; ++k) store3(R * load3(Ds + k, n3), Ds + k, n3);
    store3(R * s, a + o, 1);
    for (int r = 0; r < 3; ++r) {
      tensor_row_pack(nv, Mf + r * nn3, o + r, T, Aqu);
      for (int k = 0; k < nv; ++k) {
        Fq[(o + r) * nv + k] = Ds[r * n3 + k];
        Fv[(o + r) * nv + k] = Ds[r * n3 + nv + k];
        Fu[(o + r) * nv + k] = Ds[r * n3 + 2 * nv + k];
      }
    }
  }
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
template <typename S>
RBD_HD bool acceleration_jet(PinocchioStep<S>, const ModelView<S>& m, Workspace<S>& w, const S* q, const S* v,
                             const S* u, S gravity, const S* Dq, const S* Hq, const S* Dv, const S* Hv, S* a, S* Da,
                             S* Ha, S* scratch) {
  const int nv = m.nv;
  const long nn = static_cast<long>(nv) * nv;
  S* Fq = scratch;          // ∂a/∂ξ (nv x nv)
  S* Fv = Fq + nn;          // ∂a/∂v
  S* Fu = Fv + nn;          // ∂a/∂u
  S* T = Fu + nn;           // (nv x 2nv x 2nv)
  S* Aqu = T + 4 * nn * nv; // (nv x nv x nv)
  S* work = Aqu + nn * nv + m.nq + 2L * nv;
  if (!acceleration_tensors(m, w, q, v, u, gravity, a, Fq, Fv, Fu, T, Aqu, work)) return false;
  compose_acceleration_jet(nv, Fq, Fv, Fu, T, Aqu, Dq, Hq, Dv, Hv, Da, Ha, work);
  return true;
}

// MuJoCo coordinates: q (MuJoCo layout), v, u in MuJoCo's frames
template <typename S>
RBD_HD bool acceleration_jet(MujocoStep<S>, const ModelView<S>& m, Workspace<S>& w, const S* q_mj, const S* v_mj,
                             const S* u_mj, S gravity, const S* Dq, const S* Hq, const S* Dv, const S* Hv, S* a, S* Da,
                             S* Ha, S* scratch) {
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
// (PinocchioStep or MujocoStep). false if M is not PD at a stage.
template <template <typename> class Conv, typename S>
RBD_HD bool integrator_hessian_with(const ModelView<S>& m, Workspace<S>& w, int type, const S* q, const S* v,
                                    const S* u, S dt, S gravity, S* q_next, S* v_next, S* AB, S* H, S* scratch) {
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
  jet_unit_block(nv, 0, Dxi);
  jet_unit_block(nv, 1, Dv);
  if (!acceleration_jet(Conv<S>{}, m, w, q, v, u, gravity, Dxi, static_cast<const S*>(nullptr), Dv,
                        static_cast<const S*>(nullptr), as, Da, Ha, sub))
    return false;

  if (type == kEuler || type == kSemiImplicitEuler || type == kConstantAcceleration) {
    // v⁺ = v + dt a
    for (int k = 0; k < nv; ++k) v_next[k] = v[k] + dt * as[k];
    for (long k = 0; k < Dm; ++k) Dvsum[k] = Dv[k] + dt * Da[k];  // ∂v⁺
    for (long k = 0; k < T; ++k) Hv_next[k] = dt * Ha[k];
    // q⁺ = q ⊕ w: euler w = dt v, semi-implicit w = dt v⁺, constant acceleration w = dt v + ½ dt² a
    S hs = S(0);
    if (type == kEuler) {
      for (int k = 0; k < nv; ++k) step[k] = dt * v[k];
      for (long k = 0; k < Dm; ++k) Dw[k] = dt * Dv[k];
    } else if (type == kSemiImplicitEuler) {
      for (int k = 0; k < nv; ++k) step[k] = dt * v_next[k];
      for (long k = 0; k < Dm; ++k) Dw[k] = dt * Dvsum[k];
      hs = dt * dt;
    } else {
      for (int k = 0; k < nv; ++k) step[k] = dt * v[k] + S(0.5) * dt * dt * as[k];
      for (long k = 0; k < Dm; ++k) Dw[k] = dt * Dv[k] + S(0.5) * dt * dt * Da[k];
      hs = S(0.5) * dt * dt;
    }
    retraction_jet<Conv>(m, q, step, Dw, type == kEuler ? static_cast<const S*>(nullptr) : Ha, hs, q_next, Dxi,
                   Hq_next, sub);
    for (long k = 0; k < Dm; ++k) AB[k] = Dxi[k], AB[Dm + k] = Dvsum[k];
    return true;
  }

  // full-state stages: q_s = q ⊕ c dt v_(s-1), v_s = v + c dt a_(s-1)
  const Tableau tb = tableau(type);
  S b0 = S(tb.b[0]);
  for (int k = 0; k < nv; ++k) vsum[k] = b0 * v[k], asum[k] = b0 * as[k], vs[k] = v[k];
  for (long k = 0; k < Dm; ++k) Dvsum[k] = b0 * Dv[k], Dasum[k] = b0 * Da[k];
  for (long k = 0; k < T; ++k) Hasum[k] = b0 * Ha[k];  // Σ b_s Hv_s is kept in Hv_next
  for (long k = 0; k < T; ++k) Hv_next[k] = S(0);
  bool hv_zero = true;  // Hv of the preceding stage is zero (stage 1)
  for (int s = 1; s < tb.stages; ++s) {
    const S c = S(tb.c[s]) * dt, b = S(tb.b[s]);
    // configuration from the preceding stage's velocity jet
    for (int k = 0; k < nv; ++k) step[k] = c * vs[k];
    for (long k = 0; k < Dm; ++k) Dw[k] = c * Dv[k];
    retraction_jet<Conv>(m, q, step, Dw, hv_zero ? static_cast<const S*>(nullptr) : Hv, c, qs, Dxi, Hxi, sub);
    // velocity from the preceding stage's acceleration jet
    for (int k = 0; k < nv; ++k) vs[k] = v[k] + c * as[k];
    jet_unit_block(nv, 1, Dv);
    for (long k = 0; k < Dm; ++k) Dv[k] += c * Da[k];
    for (long k = 0; k < T; ++k) Hv[k] = c * Ha[k];
    hv_zero = false;
    if (!acceleration_jet(Conv<S>{}, m, w, qs, vs, u, gravity, Dxi, Hxi, Dv, Hv, as, Da, Ha, sub)) return false;
    for (int k = 0; k < nv; ++k) vsum[k] += b * vs[k], asum[k] += b * as[k];
    for (long k = 0; k < Dm; ++k) Dvsum[k] += b * Dv[k], Dasum[k] += b * Da[k];
    for (long k = 0; k < T; ++k) Hv_next[k] += b * Hv[k], Hasum[k] += b * Ha[k];
  }
  // q⁺ = q ⊕ dt Σ b v_s (its H from Σ b Hv_s, held in Hv_next), v⁺ = v + dt Σ b a_s
  for (int k = 0; k < nv; ++k) step[k] = dt * vsum[k], v_next[k] = v[k] + dt * asum[k];
  for (long k = 0; k < Dm; ++k) Dw[k] = dt * Dvsum[k];
  retraction_jet<Conv>(m, q, step, Dw, Hv_next, dt, q_next, Dxi, Hq_next, sub);
  for (long k = 0; k < T; ++k) Hv_next[k] = dt * Hasum[k];
  for (long k = 0; k < Dm; ++k) AB[k] = Dxi[k], AB[Dm + k] = dt * Dasum[k];
  for (int r = 0; r < nv; ++r) AB[Dm + r * N + nv + r] += S(1);
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
