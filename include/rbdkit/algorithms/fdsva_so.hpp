// rbdkit/algorithms/fdsva_so.hpp — second-order partial derivatives of
// forward dynamics qdd = FD(q, qd, u), from IDSVA-SO and M⁻¹ (the FDSVA-SO
// relations of Singh, Russell & Wensing).
//
// Differentiating ID(q, qd, FD(q, qd, u)) = u twice, with every ID term taken
// at qdd = FD(q, qd, u), ∂qdd/∂q = -M⁻¹ ∂ID/∂q, ∂qdd/∂qd = -M⁻¹ ∂ID/∂qd,
// ∂qdd/∂u = M⁻¹ and ∂M/∂q_j = dM_dq[:, :, j]:
//   d2qdd_dq2  [:, j, k] = -M⁻¹ (d2tau_dq2[:, j, k] + ∂M/∂q_j ∂qdd/∂q_k + ∂M/∂q_k ∂qdd/∂q_j)
//   d2qdd_dqd2 [:, j, k] = -M⁻¹ d2tau_dqd2[:, j, k]
//   d2qdd_dqdqd[:, j, k] = -M⁻¹ (d2tau_dqdqd[:, j, k] + ∂M/∂q_j ∂qdd/∂qd_k)
//   d2qdd_dqdu [:, j, k] = -M⁻¹ ∂M/∂q_j M⁻¹[:, k]
// (∂qdd/∂q_k as a column; index order and the tangent convention as in
// idsva_so.hpp: [i, j, k], k the outer derivative). ∂²qdd/∂u², ∂²qdd/∂qd∂u
// are zero. Each output is (nv x nv x nv) row-major. O(nv⁴) for the products
// with M⁻¹ (the zero entries of ∂M/∂q are skipped).
#pragma once

#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/algorithms/idsva_so.hpp"

namespace rbd {

// an exact zero that may be skipped in a product (never for dual numbers,
// whose derivative part may be nonzero)
template <typename S> RBD_HD bool so_skippable(const S&) { return false; }
RBD_HD bool so_skippable(double x) { return x == 0.0; }
RBD_HD bool so_skippable(float x) { return x == 0.0f; }

// row j of R = Aᵀ G (nv): r[k] = Σ_m A[m][j] G[m][k], summed over m in order, A = one row i of
// ∂M/∂q (m, j), its zero entries skipped
template <typename S> RBD_HD void so_transpose_times_row(int nv, const S* A, const S* G, int j, S* r) {
  for (int k = 0; k < nv; ++k) r[k] = S(0);
  for (int mm = 0; mm < nv; ++mm) {
    const S a = A[mm * nv + j];
    if (so_skippable(a)) continue;
    const S* g = G + mm * nv;
    for (int k = 0; k < nv; ++k) r[k] += a * g[k];
  }
}
// R (nv x nv) = Aᵀ G, row by row (a team's FDSVA-SO computes the rows side by side)
template <typename S> RBD_HD void so_transpose_times(int nv, const S* A, const S* G, S* R) {
  for (int j = 0; j < nv; ++j) so_transpose_times_row(nv, A, G, j, R + j * nv);
}

// X (nv x nv², row i the flattened (j, k) slice) <- -M⁻¹ X, after
// prepare_minv (w.dense). Columns (j, k) that are exactly zero stay zero
// (pairs j, k on different branches: no triple on one root path); the others
// go through blk (nv x nv) up to nv at a time. Uses w.so_i for their indices.
template <typename S> RBD_HD void so_apply_neg_minv(const ModelView<S>& m, Workspace<S>& w, S* X, S* blk) {
  const int nv = m.nv;
  const long nn = static_cast<long>(nv) * nv;
  int* cols = w.so_i;  // (nv) the columns in blk
  int n = 0;
  for (long c = 0; c <= nn; ++c) {
    if (c < nn) {
      bool zero = true;
      for (int r = 0; r < nv && zero; ++r) zero = so_skippable(X[r * nn + c]);
      if (zero) continue;
      cols[n++] = static_cast<int>(c);
      if (n < nv) continue;
    }
    if (n == 0) continue;
    // blk (nv x n) <- the n columns, -M⁻¹ blk, back
    for (int r = 0; r < nv; ++r)
      for (int e = 0; e < n; ++e) blk[r * n + e] = X[r * nn + cols[e]];
    apply_neg_minv(m, w, blk, n);
    for (int r = 0; r < nv; ++r)
      for (int e = 0; e < n; ++e) X[r * nn + cols[e]] = blk[r * n + e];
    n = 0;
  }
}

// the second-order part of fdsva_so from its first order at the same point: qdd = FD(q, qd, u),
// Gq = ∂qdd/∂q and Gv = ∂qdd/∂qd (nv x nv), with w.dense as aba_derivatives leaves it (M⁻¹; a mimic
// model: M's Cholesky factor). The step Hessian (plant/integrator_hessian.hpp), which has the first
// order already, calls it directly. Uses w.so_dense past its first 2nv² values. Inlined: fdsva_so
// is then the one function it was (left a call, floating HyQ's rk4 step Hessian ran 10 % slower).
// On a cooperative team (a model without mimic joints): IDSVA-SO on one thread, then the products
// with ∂M/∂q a row (i, j) per index and those with -M⁻¹ a column per index, in team_blk (nv³
// values); each entry is summed in the order one thread sums it
template <typename S, typename Team = InlineTeam>
RBD_HD_INLINE void fdsva_so_second_order(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd,
                                         const S* qdd, S gravity, const S* Gq, const S* Gv, S* d2qdd_dq2,
                                         S* d2qdd_dqd2, S* d2qdd_dqdqd, S* d2qdd_dqdu, const Team& t = Team{},
                                         S* team_blk = nullptr) {
  const int nv = m.nv;
  const long nn = static_cast<long>(nv) * nv;
  S* Mi = w.so_dense + 2 * nn;  // M⁻¹
  (void)t, (void)team_blk;
  if constexpr (!Team::cooperative) {
    S* blk = Mi + nn;
    if (m.has_mimic) {
      for (int c = 0; c < nv; ++c) {
        S* row = Mi + c * nv;
        for (int r = 0; r < nv; ++r) row[r] = r == c ? S(1) : S(0);
        cholesky_solve(w.dense, nv, row);
      }
    } else {
      for (long k = 0; k < nn; ++k) Mi[k] = w.dense[k];
    }
    // second-order inverse dynamics at that acceleration; ∂M/∂q held in the last output for now
    S* dM = d2qdd_dqdu;
    idsva_so(m, w, q, qd, qdd, gravity, d2qdd_dq2, d2qdd_dqd2, d2qdd_dqdqd, dM);
    // the ∂M/∂q · ∂qdd terms, row by row
    for (int i = 0; i < nv; ++i) {
      const S* dMi = dM + i * nn;
      so_transpose_times(nv, dMi, Gq, blk);
      S* o = d2qdd_dq2 + i * nn;
      for (int j = 0; j < nv; ++j)
        for (int k = 0; k < nv; ++k) o[j * nv + k] += blk[j * nv + k] + blk[k * nv + j];
      so_transpose_times(nv, dMi, Gv, blk);
      o = d2qdd_dqdqd + i * nn;
      for (long k = 0; k < nn; ++k) o[k] += blk[k];
    }
    // ∂M/∂q_j M⁻¹, in place row by row
    for (int i = 0; i < nv; ++i) {
      so_transpose_times(nv, dM + i * nn, Mi, blk);
      for (long k = 0; k < nn; ++k) dM[i * nn + k] = blk[k];
    }
    // -M⁻¹ on the first index of all four
    so_apply_neg_minv(m, w, d2qdd_dq2, blk);
    so_apply_neg_minv(m, w, d2qdd_dqd2, blk);
    so_apply_neg_minv(m, w, d2qdd_dqdqd, blk);
    so_apply_neg_minv(m, w, d2qdd_dqdu, blk);
  } else {
    t.each(nn, [&](long k) { Mi[k] = w.dense[k]; });
    S* dM = d2qdd_dqdu;
    t.one([&] { idsva_so(m, w, q, qd, qdd, gravity, d2qdd_dq2, d2qdd_dqd2, d2qdd_dqdqd, dM); });
    // the blocks b_i = dM_iᵀ G of so_transpose_times a row (i, j) per index; each product's uses of b_i
    // in a phase after it (they read b_i's other rows)
    S* b = team_blk;
    auto block_row = [&](long i, long j, const S* G) {
      so_transpose_times_row(nv, dM + i * nn, G, static_cast<int>(j), b + i * nn + j * nv);
    };
    // the ∂M/∂q · ∂qdd terms
    t.each2(nv, nv, [&](long i, long j) { block_row(i, j, Gq); });
    t.each2(nv, nv, [&](long i, long j) {
      const S* bi = b + i * nn;
      S* o = d2qdd_dq2 + i * nn + j * nv;
      for (int k = 0; k < nv; ++k) o[k] += bi[j * nv + k] + bi[k * nv + j];
    });
    t.each2(nv, nv, [&](long i, long j) { block_row(i, j, Gv); });
    t.each2(nv, nv, [&](long i, long j) {
      for (int k = 0; k < nv; ++k) d2qdd_dqdqd[i * nn + j * nv + k] += b[i * nn + j * nv + k];
    });
    // ∂M/∂q_j M⁻¹, then in place (every row of dM_i is read for each row of b_i)
    t.each2(nv, nv, [&](long i, long j) { block_row(i, j, Mi); });
    t.each2(nv, nv, [&](long i, long j) {
      for (int k = 0; k < nv; ++k) dM[i * nn + j * nv + k] = b[i * nn + j * nv + k];
    });
    // -M⁻¹ on the first index of all four: column c of each (nv entries nn apart) through its own nv values
    S* X[4] = {d2qdd_dq2, d2qdd_dqd2, d2qdd_dqdqd, d2qdd_dqdu};
    for (S* Xt : X)
      t.each(nn, [&](long c) {
        bool zero = true;
        for (int r = 0; r < nv && zero; ++r) zero = so_skippable(Xt[r * nn + c]);
        if (zero) return;
        S* x = team_blk + c * nv;
        for (int r = 0; r < nv; ++r) x[r] = Xt[r * nn + c];
        for (int r = 0; r < nv; ++r) {
          S acc = S(0);
          for (int k = 0; k < nv; ++k) acc += w.dense[r * nv + k] * x[k];
          Xt[r * nn + c] = -acc;
        }
      });
  }
}

// the four (nv x nv x nv) tensors above; qdd (nv) too when not null. Uses
// w.so_dense; false if M is not positive definite.
template <typename S>
RBD_HD bool fdsva_so(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* u, S gravity,
                     S* d2qdd_dq2, S* d2qdd_dqd2, S* d2qdd_dqdqd, S* d2qdd_dqdu, S* qdd_out = nullptr) {
  const int nv = m.nv;
  const long nn = static_cast<long>(nv) * nv;
  S* Gq = w.so_dense;       // ∂qdd/∂q
  S* Gv = Gq + nn;          // ∂qdd/∂qd
  S* qdd = Gv + 3 * nn;     // (after M⁻¹ and a block: fdsva_so_second_order's)
  // first order at qdd = FD(q, qd, u); w.dense keeps M⁻¹ (mimic models: the Cholesky factor of M)
  if (!aba_derivatives(m, w, q, qd, u, static_cast<const S*>(nullptr), gravity, qdd, Gq, Gv)) return false;
  fdsva_so_second_order(m, w, q, qd, qdd, gravity, Gq, Gv, d2qdd_dq2, d2qdd_dqd2, d2qdd_dqdqd, d2qdd_dqdu);
  if (qdd_out)
    for (int k = 0; k < nv; ++k) qdd_out[k] = qdd[k];
  return true;
}

}  // namespace rbd
