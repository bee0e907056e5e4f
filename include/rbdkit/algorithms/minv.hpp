// rbdkit/algorithms/minv.hpp — the inverse mass matrix M⁻¹(q), computed
// directly in O(n²) by running the articulated-body recursion on the unit
// torque columns (Carpentier, "Analytical inverse of the joint space inertia
// matrix", 2018), never by factorising M.
//
//   backward:  F_i = ∂pA_i/∂tau            (6 x nv per body, subtree columns)
//              Minv_i· = D⁻¹ (e_i - Sᵀ F_i)   (rows of joint i, subtree columns)
//   forward:   P_i = ∂a_i/∂tau              (6 x nv per body, columns ≥ v_idx)
//              Minv_i· -= D⁻¹ Uᵀ X⁻¹ P_λ
//
// Only the upper triangle (columns ≥ the row's joint) is computed; the lower
// triangle is mirrored when a dense result is asked for. Mimic models take
// the dense path (Cholesky inverse of M).
#pragma once

#include "aba.hpp"

namespace rbd {

// columns of a 6 x nv sensitivity block, stored row-major (6 rows of nv)
template <typename S> RBD_HD Force<S> load_col_force(const S* B, int nv, int c) {
  return {{B[c], B[nv + c], B[2 * nv + c]}, {B[3 * nv + c], B[4 * nv + c], B[5 * nv + c]}};
}
template <typename S> RBD_HD Motion<S> load_col_motion(const S* B, int nv, int c) {
  return {{B[c], B[nv + c], B[2 * nv + c]}, {B[3 * nv + c], B[4 * nv + c], B[5 * nv + c]}};
}
template <typename S, typename V> RBD_HD void store_col(const V& x, S* B, int nv, int c) {
  B[c] = x.lin.x; B[nv + c] = x.lin.y; B[2 * nv + c] = x.lin.z;
  B[3 * nv + c] = x.ang.x; B[4 * nv + c] = x.ang.y; B[5 * nv + c] = x.ang.z;
}

// backward pass: articulated inertias, D⁻¹, the subtree rows of M⁻¹ and F.
// writes w.X, w.IA, w.U, w.Dinv, w.F, Minv (upper part). false if not PD.
template <typename S> RBD_HD bool minv_backward_pass(const ModelView<S>& m, Workspace<S>& w, const S* q, S* Minv) {
  const int nv = m.nv;
  for (int k = 0; k < nv * nv; ++k) Minv[k] = S(0);
  for (int k = 0; k < 6 * nv * m.nb; ++k) w.F[k] = S(0);
  for (int i = 0; i < m.nb; ++i) {
    w.X[i] = body_transform(m.body[i], q);
    w.IA[i] = Mat6<S>::from_inertia(m.body[i].I);
  }
  for (int i = m.nb - 1; i >= 0; --i) {
    const BodyDesc<S>& b = m.body[i];
    const int vi = b.v_idx, ni = b.nv, c_end = b.v_idx + b.nv_subtree;
    Force<S>* U = w.U + 6 * i;
    S* Dinv = w.Dinv + 36 * i;
    S* F = w.F + 6 * nv * i;
    if (!aba_joint_inertia(b, w.IA[i], U, Dinv)) return false;
    // own block: D⁻¹
    for (int k = 0; k < ni; ++k)
      for (int l = 0; l < ni; ++l) Minv[(vi + k) * nv + vi + l] = Dinv[k * ni + l];
    // descendants' columns: -D⁻¹ Sᵀ F
    for (int c = vi + ni; c < c_end; ++c) {
      S sf[6];
      joint_project(b, load_col_force(F, nv, c), sf);
      for (int k = 0; k < ni; ++k) {
        S acc = S(0);
        for (int l = 0; l < ni; ++l) acc -= Dinv[k * ni + l] * sf[l];
        Minv[(vi + k) * nv + c] = acc;
      }
    }
    if (b.parent < 0) continue;
    // F_i += U Minv_i· ; F_λ += X* F_i over the subtree columns
    S* Fp = w.F + 6 * nv * b.parent;
    for (int c = vi; c < c_end; ++c) {
      Force<S> fc = load_col_force(F, nv, c);
      for (int k = 0; k < ni; ++k) fc += Minv[(vi + k) * nv + c] * U[k];
      const Force<S> fp = load_col_force(Fp, nv, c) + w.X[i].act(fc);
      store_col(fp, Fp, nv, c);
    }
    aba_project_inertia(b, w.X[i], w.IA[i], U, Dinv, w.IA[b.parent]);
  }
  return true;
}

// forward pass: P_i = X⁻¹ P_λ, Minv_i· -= D⁻¹ Uᵀ P_i, P_i += S Minv_i·
// over columns ≥ v_idx. writes w.P, Minv (upper part)
template <typename S> RBD_HD void minv_forward_pass(const ModelView<S>& m, Workspace<S>& w, S* Minv) {
  const int nv = m.nv;
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    const int vi = b.v_idx, ni = b.nv;
    const Force<S>* U = w.U + 6 * i;
    const S* Dinv = w.Dinv + 36 * i;
    S* P = w.P + 6 * nv * i;
    const S* Pp = b.parent >= 0 ? w.P + 6 * nv * b.parent : nullptr;
    for (int c = vi; c < nv; ++c) {
      Motion<S> pc = Motion<S>::zero();
      if (Pp) {
        pc = w.X[i].act_inv(load_col_motion(Pp, nv, c));
        S up[6];
        for (int l = 0; l < ni; ++l) up[l] = dot(pc, U[l]);
        for (int k = 0; k < ni; ++k) {
          S acc = S(0);
          for (int l = 0; l < ni; ++l) acc += Dinv[k * ni + l] * up[l];
          Minv[(vi + k) * nv + c] -= acc;
        }
      }
      S x[6];
      for (int k = 0; k < ni; ++k) x[k] = Minv[(vi + k) * nv + c];
      pc += joint_motion(b, x);
      store_col(pc, P, nv, c);
    }
  }
}

// M⁻¹(q), nv x nv row-major. dense: mirror the upper triangle into the lower;
// otherwise the strict lower triangle is zero. false if M is not PD.
template <typename S> RBD_HD bool minv(const ModelView<S>& m, Workspace<S>& w, const S* q, bool dense, S* Minv) {
  const int nv = m.nv;
  if (m.has_mimic) {
    S* M = w.dense;
    crba(m, w, q, M);
    if (!spd_inverse(M, nv, Minv)) return false;
  } else {
    if (!minv_backward_pass(m, w, q, Minv)) return false;
    minv_forward_pass(m, w, Minv);
  }
  for (int r = 1; r < nv; ++r)
    for (int c = 0; c < r; ++c) Minv[r * nv + c] = dense ? Minv[c * nv + r] : S(0);
  return true;
}

// qdd = M⁻¹ (tau - c(q, qd, f_ext)): forward dynamics through the inverse.
// writes w.dense (M⁻¹ in its first nv² entries) and qdd (nv).
template <typename S>
RBD_HD bool forward_dynamics(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* tau,
                             const S* fext, S gravity, S* qdd) {
  const int nv = m.nv;
  S* r = w.dense + nv * nv + nv;  // residual tau - c
  rnea(m, w, q, qd, static_cast<const S*>(nullptr), fext, gravity, r);
  for (int k = 0; k < nv; ++k) r[k] = tau[k] - r[k];
  S* Mi = w.dense;
  if (m.has_mimic) {
    crba(m, w, q, Mi);
    if (!cholesky(Mi, nv)) return false;
    for (int k = 0; k < nv; ++k) qdd[k] = r[k];
    cholesky_solve(Mi, nv, qdd);
    return true;
  }
  if (!minv(m, w, q, true, Mi)) return false;
  for (int row = 0; row < nv; ++row) {
    S acc = S(0);
    for (int c = 0; c < nv; ++c) acc += Mi[row * nv + c] * r[c];
    qdd[row] = acc;
  }
  return true;
}

}  // namespace rbd
