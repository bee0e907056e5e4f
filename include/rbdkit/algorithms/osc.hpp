// rbdkit/algorithms/osc.hpp — the operational-space inertia of an end-effector
// point (Khatib, "the operational space formulation", 1987):
//
//   Λ = (J M⁻¹ Jᵀ)⁻¹,   J (6 x nv) the kLocalWorldAligned Jacobian of the point
//
// in two passes: factor M = L Lᵀ once per configuration (CRBA, Cholesky), then
// per end effector Y = L⁻¹ Jᵀ, J M⁻¹ Jᵀ = Yᵀ Y and its 6 x 6 inverse. Dense
// Cholesky works for mimic models too (their reduced M has no tree sparsity).
#pragma once

#include "rbdkit/algorithms/crba.hpp"
#include "rbdkit/algorithms/dense.hpp"
#include "rbdkit/algorithms/kinematics.hpp"

namespace rbd {

// pass 1: w.dense[0, nv²) <- the Cholesky factor L of M(q) (lower triangle);
// also w.X_parent, w.X_world. false if M is not positive definite.
template <typename S> RBD_HD bool osc_factor_mass_matrix(const ModelView<S>& m, Workspace<S>& w, const S* q) {
  crba(m, w, q, w.dense);
  forward_kinematics(m, w, q, static_cast<const S*>(nullptr));
  return cholesky(w.dense, m.nv);
}

// Λ (6 x 6, row-major) = A⁻¹ for the symmetric positive semi-definite A (6 x 6,
// overwritten). false when A is singular: a zero diagonal entry, or a Cholesky
// pivot² below `tol` once A is scaled to unit diagonal (the pivots² are then
// sines² of the angles between each row of J and the span of the ones before,
// in the M⁻¹ metric: some direction is not reachable).
template <typename S> RBD_HD bool osc_inverse_6(S* A, S tol, S* Lambda) {
  S d[6];
  for (int i = 0; i < 6; ++i) {
    if (!all_lanes(lane_gt(A[i * 6 + i], 0.0))) return false;
    d[i] = S(1) / ssqrt(A[i * 6 + i]);
  }
  // C = D A D with unit diagonal, factored in place
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) A[r * 6 + c] = d[r] * A[r * 6 + c] * d[c];
  if (!cholesky(A, 6)) return false;
  for (int i = 0; i < 6; ++i)
    if (!all_lanes(lane_gt(A[i * 6 + i] * A[i * 6 + i] - tol, 0.0))) return false;
  // Λ = D C⁻¹ D, column by column
  for (int c = 0; c < 6; ++c) {
    S col[6];
    for (int r = 0; r < 6; ++r) col[r] = r == c ? S(1) : S(0);
    cholesky_solve(A, 6, col);
    for (int r = 0; r < 6; ++r) Lambda[r * 6 + c] = d[r] * col[r] * d[c];
  }
  return true;
}

// pass 2: Λ (6 x 6, row-major) of the point `offset` (body frame) on `body`,
// after osc_factor_mass_matrix. Scratch: w.F (6 x nv). false if J M⁻¹ Jᵀ is
// singular (fewer than 6 independent DoF reach the point).
template <typename S>
RBD_HD bool osc_inertia(const ModelView<S>& m, Workspace<S>& w, int body, const Vec3<S>& offset, S* Lambda) {
  const int nv = m.nv;
  const S* L = w.dense;
  S* Y = w.F;
  frame_jacobian(m, w, body, Transform<S>{Mat3<S>::identity(), offset}, kLocalWorldAligned, Y);
  // Y_r = L⁻¹ J_rᵀ by forward substitution, row by row
  for (int r = 0; r < 6; ++r) {
    S* y = Y + r * nv;
    for (int i = 0; i < nv; ++i) {
      S acc = y[i];
      for (int k = 0; k < i; ++k) acc -= L[i * nv + k] * y[k];
      y[i] = acc / L[i * nv + i];
    }
  }
  // A_rc = y_r · y_c = J_r M⁻¹ J_cᵀ
  S A[36];
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c <= r; ++c) {
      S acc = S(0);
      for (int i = 0; i < nv; ++i) acc += Y[r * nv + i] * Y[c * nv + i];
      A[r * 6 + c] = acc;
      A[c * 6 + r] = acc;
    }
  return osc_inverse_6(A, S(1e-10), Lambda);
}

}  // namespace rbd
