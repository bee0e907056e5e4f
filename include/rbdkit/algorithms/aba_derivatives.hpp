// rbdkit/algorithms/aba_derivatives.hpp — first derivatives of forward
// dynamics and the external-force sensitivities.
//
//   qdd = FD(q, qd, tau, f_ext)  satisfies  ID(q, qd, qdd, f_ext) = tau, so
//   ∂qdd/∂x = -M⁻¹ ∂ID/∂x |_(qdd = FD)     for x = q (tangent), qd
//   ∂tau/∂f_ext_b = -J_bᵀ,  ∂qdd/∂f_ext_b = M⁻¹ J_bᵀ   (J_b: body b's Jacobian, body frame)
#pragma once

#include "rbdkit/algorithms/aba.hpp"
#include "rbdkit/algorithms/minv.hpp"
#include "rbdkit/algorithms/rnea_derivatives.hpp"
#include "rbdkit/model/team.hpp"

namespace rbd {

// w.dense <- M⁻¹ (minv), or the Cholesky factor of M for mimic
// models; false if M is not PD
template <typename S> RBD_HD bool prepare_minv(const ModelView<S>& m, Workspace<S>& w, const S* q) {
  if (m.has_mimic) {
    crba(m, w, q, w.dense);
    return cholesky(w.dense, m.nv);
  }
  return minv(m, w, q, true, w.dense);
}

// D (nv x cols, row-major) <- -M⁻¹ D, after prepare_minv. Without mimic
// joints a dense product (dense.hpp's neg_matmul); with them, Cholesky solves
// column by column.
template <typename S> RBD_HD void apply_neg_minv(const ModelView<S>& m, Workspace<S>& w, S* D, int cols) {
  const int nv = m.nv;
  const S* Mi = w.dense;
  if (m.has_mimic) {
    S* tmp = w.dense + nv * nv;
    for (int c = 0; c < cols; ++c) {
      for (int r = 0; r < nv; ++r) tmp[r] = D[r * cols + c];
      cholesky_solve(Mi, nv, tmp);
      for (int r = 0; r < nv; ++r) D[r * cols + c] = -tmp[r];
    }
    return;
  }
  S* RBD_RESTRICT Dc = w.dense2;  // a copy of D (nv x cols, cols <= max(nv, 6))
  for (int k = 0; k < nv * cols; ++k) Dc[k] = D[k];
  neg_matmul(Mi, Dc, nv, cols, D);
}

// Dq, Dv (nv x nv each, row-major) <- -M⁻¹ Dq, -M⁻¹ Dv, after prepare_minv, for Dq = ∂ID/∂q and
// Dv = ∂ID/∂qd of a model without mimic joints: ∂tau_l/∂x_c vanishes unless l and c lie on one root
// path (rnea_derivatives leaves those entries exact zeros), about half of a floating humanoid's
// entries and three quarters of a fixed quadruped's. M⁻¹ is symmetric (w.dense, mirrored), so column
// c of M⁻¹ D is Σ_l D_lc M⁻¹_l· over the rows l on c's root paths, contiguous rows of M⁻¹, listed
// from the tree (a scan of D for its nonzeros took a sixth of the product on floating Atlas). Column
// c of both products runs at once (scaled_row_sums: each row of M⁻¹ loaded once for both). Each entry
// is neg_matmul's sum in its order without the exact zeros off the paths: the same number (to the
// sign of a zero). Tq = (M⁻¹ Dq)ᵀ goes to w.dense2, Tv to w.so_dense's third block and the gathered
// entries to its fourth (fdsva_so writes those only after aba_derivatives), then D <- -Tᵀ. Uses
// w.so_i (nv + nb ints: the rows of one column, each body's count of ancestor DoFs). aba_derivatives
// takes it when at most 2/3 of D can be nonzero (a chain like the iiwa's is dense, and
// apply_neg_minv's blocked product is then faster),
// in double and float only (a dual number's zero value may carry a derivative, a SIMD pack's zero is
// per lane). Out of line on the host: inlined into aba_derivatives's flattened body, the same
// products ran 2-3 % of ∇FD slower (floating HyQ and Atlas, a compiled instance).
template <typename S> RBD_HD bool tree_sparse_product_pays(const ModelView<S>& m) {
  if (m.has_mimic) return false;
  long nnz = 0;  // Σ over DoFs c of the DoFs on c's root paths: its ancestors' and its subtree's
  for (int i = 0; i < m.nb; ++i) {
    long above = 0;
    for (int j = m.body[i].parent; j >= 0; j = m.body[j].parent) above += m.body[j].nv;
    nnz += m.body[i].nv * (above + m.body[i].nv_subtree);
  }
  return 3 * nnz <= 2L * m.nv * m.nv;
}
template <typename S>
RBD_NOINLINE RBD_FLATTEN RBD_HD void neg_minv_times_tree_sparse(const ModelView<S>& m, Workspace<S>& w, S* Dq, S* Dv) {
  const int nv = m.nv;
  const long nn = static_cast<long>(nv) * nv;
  const S* Mi = w.dense;
  S* Tq = w.dense2;
  S* Tv = w.so_dense + 2 * nn;
  S* a = w.so_dense + 3 * nn;  // column c's entries in the listed rows (nv each)
  S* b = a + nv;
  int* rows = w.so_i;
  int* above = w.so_i + nv;  // per body, the DoFs of its ancestors
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& bi = m.body[i];
    // the rows of body i's columns, ascending: its ancestors' DoFs from the root, then its subtree's.
    // Bodies are depth-first (has_mimic false), so rows[0, above_i) still lists the ancestors' as they
    // wrote them (a body's at above_i, after its parent's): only the subtree's are written here
    const int p = bi.parent, n0 = p < 0 ? 0 : above[p] + m.body[p].nv, n = n0 + bi.nv_subtree;
    above[i] = n0;
    for (int k = 0; k < bi.nv_subtree; ++k) rows[n0 + k] = bi.v_idx + k;
    for (int c = bi.v_idx; c < bi.v_idx + bi.nv; ++c) {
      for (int j = 0; j < n; ++j) a[j] = Dq[rows[j] * nv + c], b[j] = Dv[rows[j] * nv + c];
      scaled_row_sums(Mi, a, b, nv, rows, n, Tq + c * nv, Tv + c * nv);
    }
  }
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < nv; ++c) Dq[r * nv + c] = -Tq[c * nv + r], Dv[r * nv + c] = -Tv[c * nv + r];
}

// Minv (nv x nv) <- M⁻¹, after prepare_minv: a copy of the inverse it
// left (the product -M⁻¹ (-1) would cost nv³), or the mimic path's solves
template <typename S> RBD_HD void copy_minv(const ModelView<S>& m, Workspace<S>& w, S* Minv) {
  const int nv = m.nv;
  if (!m.has_mimic) {
    for (int k = 0; k < nv * nv; ++k) Minv[k] = w.dense[k];
    return;
  }
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < nv; ++c) Minv[r * nv + c] = r == c ? S(-1) : S(0);
  apply_neg_minv(m, w, Minv, nv);
}

// qdd (nv), ∂qdd/∂q and ∂qdd/∂qd (nv x nv each). false if M is not PD.
// qdd = M⁻¹ (tau - c) with the bias c = ID(q, qd, 0, f_ext) (forward_dynamics): M⁻¹ is the one the
// derivative products need anyway, so qdd costs an RNEA and a product where ABA's three passes took
// about twice that. It agrees with ABA's (the aba operation, the integrators' step) to rounding, not
// bit for bit, as the team form's does (whose M⁻¹ is minv_column's, equal to the passes' to rounding).
// factored: forward_dynamics's (a compiled instance's own factorisation, codegen/unrolled.hpp)
template <typename S, typename Factored = FactoredMinv<S>> RBD_FLATTEN
RBD_HD bool aba_derivatives(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* tau,
                            const S* fext, S gravity, S* qdd, S* dqdd_dq, S* dqdd_dqd,
                            const Factored& factored = Factored{}) {
  // M⁻¹ first (forward_dynamics's, place): it leaves the placements and body inertias that the
  // derivative passes then reuse, in its frame (a free root's; the mimic path's CRBA leaves none)
  if (!forward_dynamics(m, w, q, qd, tau, fext, gravity, qdd, false, true, factored)) return false;
  rnea_derivatives(m, w, q, qd, qdd, fext, gravity, dqdd_dq, dqdd_dqd, static_cast<S*>(nullptr), !m.has_mimic);
  if constexpr (std::is_same<S, double>::value || std::is_same<S, float>::value) {
    if (tree_sparse_product_pays(m)) {
      neg_minv_times_tree_sparse(m, w, dqdd_dq, dqdd_dqd);
      return true;
    }
  }
  apply_neg_minv(m, w, dqdd_dq, m.nv);
  apply_neg_minv(m, w, dqdd_dqd, m.nv);
  return true;
}

// aba_derivatives on a team of threads (model/team.hpp; the GPU's team kernels, rbdkit/cuda/team_kernels.cuh),
// for a model without mimic joints:
//   - M⁻¹ on the first warp (minv_team) beside the bias c = RNEA(q, qd, 0, f_ext) on one thread, in a
//     workspace of its own (RNEA's, linear, in `extra`); then qdd = M⁻¹ (tau - c), a row per index
//     (forward_dynamics's qdd, as FD's team computes it);
//   - the derivative passes on M⁻¹'s placements (rnea_derivatives_team);
//   - the two products -M⁻¹ ∂ID in tiles (matmul_tiles; each entry's sum in aba_derivatives's order).
// qdd is M⁻¹ (tau - c), not ABA's: the two agree to rounding, not bit for bit, so a team's step gradient
// gives x⁺ to the last bits of the step's. On an H200, ABA on one thread took 26 µs of iiwa's 40 beside
// M⁻¹'s 17; M⁻¹ beside RNEA, then qdd's rows, take 19 (cuda/stage_latency.cu's team table, docs/gpu.md).
// M⁻¹ is left in w.dense as in aba_derivatives.
// extra: aba_derivatives_team_bytes(nb, nv) bytes (forward_dynamics_team's, then ∂ID and qdd); qdd may
// be null (extra holds it)
template <typename S> RBD_HD unsigned long aba_derivatives_team_bytes(int nb, int nv) {
  return forward_dynamics_team_bytes<S>(nb, nv) + workspace_array_bytes<S>(2ul * nv * nv + nv);
}
template <typename S, typename Team>
RBD_HD bool aba_derivatives_team(const Team& t, const ModelView<S>& m, Workspace<S>& w, unsigned char* extra,
                                 const S* q, const S* qd, const S* tau, const S* fext, S gravity, S* qdd,
                                 S* dqdd_dq, S* dqdd_dqd) {
  const int nv = m.nv, n2 = nv * nv;
  S* dq = reinterpret_cast<S*>(extra + forward_dynamics_team_bytes<S>(m.nb, nv));  // ∂ID/∂q
  S* dv = dq + n2;                                                                  // ∂ID/∂qd
  if (!qdd) qdd = dv + n2;
  const S* Minv = w.dense;
  if (!forward_dynamics_team(t, m, w, extra, q, qd, tau, fext, gravity, qdd)) return false;
  rnea_derivatives_team(t, m, w, q, qd, qdd, fext, gravity, dq, dv, true);  // on M⁻¹'s placements
  const S* D[2] = {dq, dv};
  S* out[2] = {dqdd_dq, dqdd_dqd};
  matmul_tiles(t, Team::threads, Minv, D, out, 2, nv, nv, nv, S(-1));
  return true;
}

// the generalized force that body-local wrenches f_ext act as: sign · J_bᵀ f_b
// summed over bodies, as the matrix of its entries, element [b][r][c] =
// sign · (J_b)[c][r] at Jt[b·body_stride + r·row_stride + c] (J_b: body b's
// Jacobian in its own frame, 6 x nv; a mimic body adds into its target's rows).
// writes w.X_parent, w.X_world, w.S_world
template <typename S>
RBD_HD void external_force_map(const ModelView<S>& m, Workspace<S>& w, const S* q, S sign, S* Jt, int body_stride,
                               int row_stride) {
  const int nv = m.nv, nb = m.nb;
  for (int bb = 0; bb < nb; ++bb)
    for (int r = 0; r < nv; ++r)
      for (int c = 0; c < 6; ++c) Jt[bb * body_stride + r * row_stride + c] = S(0);
  // world-frame subspace columns
  place_joints(m, w.X_parent, q);
  for (int i = 0; i < nb; ++i) placed_world(m, w, i);
  // column k of J_b (body frame) = X_0b⁻¹ s_k for k on b's support
  for (int bb = 0; bb < nb; ++bb) {
    S* Jb = Jt + bb * body_stride;
    for (int k = bb; k >= 0; k = m.body[k].parent) {
      const BodyDesc<S>& bk = m.body[k];
      for (int c = 0; c < bk.nv; ++c) {
        S col[6];
        store(w.X_world[bb].act_inv(w.S_world[6 * k + c]), col);
        for (int r = 0; r < 6; ++r) Jb[(bk.v_idx + c) * row_stride + r] += sign * col[r];
      }
    }
  }
}

// body Jacobians in body coordinates, transposed and negated:
// dtau_dfext (nb x nv x 6): [b][r][c] = ∂tau_r/∂f_ext_b[c] = -(J_b)[c][r];
// then dqdd_dfext (nb x nv x 6) = M⁻¹ J_bᵀ. writes w.X_parent, w.X_world, w.S_world (by
// external_force_map; then M⁻¹'s, where minv takes the direct passes)
template <typename S>
RBD_HD bool fext_derivatives(const ModelView<S>& m, Workspace<S>& w, const S* q, S* dtau_dfext, S* dqdd_dfext) {
  const int nv = m.nv, nb = m.nb;
  external_force_map(m, w, q, S(-1), dtau_dfext, nv * 6, 6);
  // M⁻¹ Jᵀ = -M⁻¹ (-Jᵀ), one body block (nv x 6) at a time
  for (int k = 0; k < nb * nv * 6; ++k) dqdd_dfext[k] = dtau_dfext[k];
  if (!prepare_minv(m, w, q)) return false;
  for (int bb = 0; bb < nb; ++bb) apply_neg_minv(m, w, dqdd_dfext + bb * nv * 6, 6);
  return true;
}

}  // namespace rbd
