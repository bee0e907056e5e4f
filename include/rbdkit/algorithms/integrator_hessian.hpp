// rbdkit/algorithms/integrator_hessian.hpp — the second-order sensitivity of
// one integrator step (integrators.hpp), what a DDP solver consumes.
//
// Definition. z = [δq; δv; δu] (N = 3nv) perturbs the input as
// q = q0 ⊕ δq, v = v0 + δv, u = u0 + δu; the output is read in the chart at
// the nominal output x⁺(0) = (q⁺, v⁺):
//   ψ(z) = [difference(q⁺(0), q⁺(z)); v⁺(z) - v⁺(0)]           (2nv)
//   AB[i, j]   = ∂ψ_i/∂z_j           (2nv x N, = integrator_gradient)
//   H[i, j, k] = ∂²ψ_i/∂z_j∂z_k       (2nv x N x N, symmetric in j, k)
// so that x⁺(z) = x⁺(0) ⊕ (AB z + ½ H[z, z] + O(|z|³)).
//
// Method: second-order jets (value, D = ∂/∂z (n x N), H = ∂²/∂z² (n x N x N))
// carried through the stages of the scheme, built from two small steps:
//   retraction_jet    a stage configuration q_s = (q0 ⊕ δq) ⊕ w(z), read as
//                     ξ = difference(q̄_s, q_s) in the exponential chart at
//                     its nominal value, from the jet of the step w: first
//                     derivatives dintegrate, second derivatives of
//                     g(δq, w) per free-flyer / spherical joint by nested dual
//                     numbers through integrate/difference (zero elsewhere);
//   acceleration_jet  a_s = FD(q̄_s ⊕ ξ, v_s, u): the first derivatives of
//                     forward dynamics and FDSVA-SO's second derivatives
//                     (fdsva_so.hpp; q-q symmetrised, which is the Hessian in
//                     the exponential chart; ∂²a/∂v∂u = ∂²a/∂u² = 0) composed
//                     with the input jets by the chain rule.
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

// second derivatives of ξ = g(δq, w) = difference(q̄, (q0 ⊕ δq) ⊕ w) for one
// free-flyer (d = 6, nq 7) or spherical (d = 3, nq 4) joint, at δq = 0 and the
// given w (q̄ = q0 ⊕ w): G[i, a, c] = ∂²ξ_i/∂x_a∂x_c, x = [δq; w] (d x 2d x 2d).
// Exact (nested dual numbers through integrate and difference).
template <typename S>
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
      integrate(jm, q0d, x, qa);
      integrate(jm, qa, x + d, qb);
      difference(jm, qbd, qb, out);
      for (int i = 0; i < d; ++i) {
        const S h = out[i].d.d;
        G[(i * 2 * d + a) * 2 * d + c] = h;
        G[(i * 2 * d + c) * 2 * d + a] = h;
      }
    }
}

// scratch values of retraction_jet
RBD_HD long retraction_jet_scratch_values(int nv) { return 2L * nv * nv + 6 * 12 * 12 + 2L * 12 * 3 * nv; }

// The jet of a stage configuration q_s = (q0 ⊕ δq) ⊕ w(z), given the jet of
// the step w: value w (nv), Dw (nv x N) and Hw = hw_scale · Hw_src
// (nv x N x N; null: zero). Writes q̄ = q0 ⊕ w (nq) and the jet of
// ξ = difference(q̄, q_s): Dxi (nv x N), Hxi (nv x N x N).
template <typename S>
RBD_HD void retraction_jet(const ModelView<S>& m, const S* q0, const S* w, const S* Dw, const S* Hw_src,
                           S hw_scale, S* qbar, S* Dxi, S* Hxi, S* scratch) {
  const int nv = m.nv, N = 3 * nv;
  const long nn = static_cast<long>(nv) * nv, NN = static_cast<long>(N) * N;
  S* Gq = scratch;   // ∂(q0 ⊕ w)/∂q0 (nv x nv)
  S* Gw = Gq + nn;   // ∂(q0 ⊕ w)/∂w (nv x nv)
  S* G2 = Gw + nn;   // one joint's second derivatives (d x 2d x 2d)
  S* J = G2 + 6 * 12 * 12;  // one joint's [δq; w] rows of the jet (2d x N)
  S* tmp = J + 12L * N;     // (2d x N)
  integrate(m, q0, w, qbar);
  // first order: Dxi = Gq [I 0 0] + Gw Dw
  dintegrate(m, q0, w, 0, Gq);
  dintegrate(m, q0, w, 1, Gw);
  matmul(Gw, Dw, Dxi, nv, nv, N);
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < nv; ++c) Dxi[r * N + c] += Gq[r * nv + c];
  // second order: Gw Hw, then the curvature of the retraction per joint
  for (long k = 0; k < nv * NN; ++k) Hxi[k] = S(0);
  if (Hw_src) jet_add_linear_upper(nv, nv, N, Gw, Hw_src, hw_scale, Hxi);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic || (b.type != kFree && b.type != kSpherical)) continue;
    const int d = b.type == kFree ? 6 : 3, o = b.v_idx;
    joint_retraction_hessian(b.type, q0 + b.q_idx, w + o, qbar + b.q_idx, G2);
    for (int r = 0; r < d; ++r)
      for (int c = 0; c < N; ++c) {
        J[r * N + c] = c == o + r ? S(1) : S(0);
        J[(d + r) * N + c] = Dw[(o + r) * N + c];
      }
    jet_add_quadratic_upper(d, 2 * d, N, G2, J, S(1), Hxi + o * NN, tmp);
  }
  jet_mirror(nv, N, Hxi);
}

// ---------------------------------------------------------------- acceleration jet

// scratch values of acceleration_jet
RBD_HD long acceleration_jet_scratch_values(int nv) {
  const long nn = static_cast<long>(nv) * nv;
  return 3 * nn + 8 * nn * nv + 12 * nn;
}

// The jet of a = FD(q̄ ⊕ ξ, v, u + δu) from the jets of ξ (Dq, Hq) and of v
// (Dv, Hv); Hq, Hv may be null (zero). Writes a (nv), Da (nv x N),
// Ha (nv x N x N). Uses w (aba_derivatives, fdsva_so); false if M is not PD.
template <typename S>
RBD_HD bool acceleration_jet(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* v, const S* u, S gravity,
                             const S* Dq, const S* Hq, const S* Dv, const S* Hv, S* a, S* Da, S* Ha, S* scratch) {
  const int nv = m.nv, N = 3 * nv, p = 2 * nv;
  const long nn = static_cast<long>(nv) * nv, NN = static_cast<long>(N) * N;
  S* Fq = scratch;        // ∂a/∂q (nv x nv)
  S* Fv = Fq + nn;        // ∂a/∂v
  S* Mi = Fv + nn;        // ∂a/∂u = M⁻¹
  S* Aqq = Mi + nn;       // ∂²a/∂q∂q (nv x nv x nv, iterated)
  S* Avv = Aqq + nn * nv; // ∂²a/∂v∂v
  S* Aqv = Avv + nn * nv; // ∂²a/∂q∂v
  S* Aqu = Aqv + nn * nv; // ∂²a/∂q∂u
  S* T = Aqu + nn * nv;   // per row i the Hessian in (ξ, v) (nv x 2nv x 2nv)
  S* Y = T + 4 * nn * nv; // [Dq; Dv] (2nv x N)
  S* tmp = Y + 6 * nn;    // (2nv x N)
  // first order; aba_derivatives leaves M⁻¹ (mimic: its Cholesky factor) in w.dense
  if (!aba_derivatives(m, w, q, v, u, static_cast<const S*>(nullptr), gravity, a, Fq, Fv)) return false;
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < nv; ++c) Mi[r * nv + c] = r == c ? S(-1) : S(0);
  apply_neg_minv(m, w, Mi, nv);
  // Da = Fq Dq + Fv Dv + [0 0 M⁻¹]
  matmul(Fq, Dq, Da, nv, nv, N);
  matmul(Fv, Dv, tmp, nv, nv, N);
  for (long k = 0; k < nv * static_cast<long>(N); ++k) Da[k] += tmp[k];
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < nv; ++c) Da[r * N + 2 * nv + c] += Mi[r * nv + c];
  // second order: Ha = Yᵀ T Y + (the q-u terms) + Fq Hq + Fv Hv, T = [[sym Aqq, Aqv], [Aqvᵀ, Avv]]
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
  return true;
}

// ---------------------------------------------------------------- the step

// scratch values (of type S) of integrator_hessian
RBD_HD long integrator_hessian_scratch_values(int nq, int nv) {
  const long N = 3L * nv, Dm = nv * N, T = Dm * N;
  const long r = retraction_jet_scratch_values(nv), a = acceleration_jet_scratch_values(nv);
  return nq + 5L * nv + 6 * Dm + 4 * T + (r > a ? r : a);
}

// x⁺ (q_next (nq), v_next (nv)), AB (2nv x N) and H (2nv x N x N) as defined
// at the top of this file. false if M is not positive definite at a stage.
template <typename S>
RBD_HD bool integrator_hessian(const ModelView<S>& m, Workspace<S>& w, int type, const S* q, const S* v,
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
  if (!acceleration_jet(m, w, q, v, u, gravity, Dxi, static_cast<const S*>(nullptr), Dv,
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
    retraction_jet(m, q, step, Dw, type == kEuler ? static_cast<const S*>(nullptr) : Ha, hs, q_next, Dxi,
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
    retraction_jet(m, q, step, Dw, hv_zero ? static_cast<const S*>(nullptr) : Hv, c, qs, Dxi, Hxi, sub);
    // velocity from the preceding stage's acceleration jet
    for (int k = 0; k < nv; ++k) vs[k] = v[k] + c * as[k];
    jet_unit_block(nv, 1, Dv);
    for (long k = 0; k < Dm; ++k) Dv[k] += c * Da[k];
    for (long k = 0; k < T; ++k) Hv[k] = c * Ha[k];
    hv_zero = false;
    if (!acceleration_jet(m, w, qs, vs, u, gravity, Dxi, Hxi, Dv, Hv, as, Da, Ha, sub)) return false;
    for (int k = 0; k < nv; ++k) vsum[k] += b * vs[k], asum[k] += b * as[k];
    for (long k = 0; k < Dm; ++k) Dvsum[k] += b * Dv[k], Dasum[k] += b * Da[k];
    for (long k = 0; k < T; ++k) Hv_next[k] += b * Hv[k], Hasum[k] += b * Ha[k];
  }
  // q⁺ = q ⊕ dt Σ b v_s (its H from Σ b Hv_s, held in Hv_next), v⁺ = v + dt Σ b a_s
  for (int k = 0; k < nv; ++k) step[k] = dt * vsum[k], v_next[k] = v[k] + dt * asum[k];
  for (long k = 0; k < Dm; ++k) Dw[k] = dt * Dvsum[k];
  retraction_jet(m, q, step, Dw, Hv_next, dt, q_next, Dxi, Hq_next, sub);
  for (long k = 0; k < T; ++k) Hv_next[k] = dt * Hasum[k];
  for (long k = 0; k < Dm; ++k) AB[k] = Dxi[k], AB[Dm + k] = dt * Dasum[k];
  for (int r = 0; r < nv; ++r) AB[Dm + r * N + nv + r] += S(1);
  return true;
}

}  // namespace rbd
