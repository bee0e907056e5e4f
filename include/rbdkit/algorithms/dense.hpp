// rbdkit/algorithms/dense.hpp — small dense kernels on row-major arrays:
// Cholesky factorisation, solve and inverse of a symmetric positive-definite
// matrix. Used for the joint-DoF blocks D = Sᵀ IA S (n ≤ 6) and the dense
// forward-dynamics path of mimic models (n = nv).
#pragma once

#include "rbdkit/spatial/config.hpp"

namespace rbd {

// the positive-definiteness test of a pivot d of a symmetric positive
// semi-definite matrix whose entries are of size `scale` (e.g. its diagonal
// before elimination): d must exceed the rounding of the scale, not just 0,
// so that a singular matrix (a joint that moves no mass: d = 0, or rounding
// noise of the scale, whose inverse is inf or huge) is reported as singular.
template <typename S> RBD_HD bool pivot_positive(const S& d, const S& scale) {
  return all_lanes(lane_gt(d - S(16 * Eps<S>::machine) * scale, 0));
}

// in place: A (n x n, SPD) -> L with A = L Lᵀ in the lower triangle.
// returns false if A is not positive definite (a pivot at the rounding
// level of its diagonal entry: pivot_positive).
template <typename S> RBD_HD bool cholesky(S* A, int n) {
  for (int j = 0; j < n; ++j) {
    S d = A[j * n + j];
    const S scale = d;
    for (int k = 0; k < j; ++k) d -= A[j * n + k] * A[j * n + k];
    if (!pivot_positive(d, scale)) return false;
    d = ssqrt(d);
    A[j * n + j] = d;
    for (int i = j + 1; i < n; ++i) {
      S s = A[i * n + j];
      for (int k = 0; k < j; ++k) s -= A[i * n + k] * A[j * n + k];
      A[i * n + j] = s / d;
    }
  }
  return true;
}

// solve L Lᵀ x = b in place (b <- x), L from cholesky()
template <typename S> RBD_HD void cholesky_solve(const S* L, int n, S* b) {
  for (int i = 0; i < n; ++i) {
    S s = b[i];
    for (int k = 0; k < i; ++k) s -= L[i * n + k] * b[k];
    b[i] = s / L[i * n + i];
  }
  for (int i = n - 1; i >= 0; --i) {
    S s = b[i];
    for (int k = i + 1; k < n; ++k) s -= L[k * n + i] * b[k];
    b[i] = s / L[i * n + i];
  }
}

// Ainv (n x n) = A⁻¹ for SPD A; A is overwritten by its factor. false if not PD.
// Row c of the symmetric inverse is the solution for the unit vector e_c.
template <typename S> RBD_HD bool spd_inverse(S* A, int n, S* Ainv) {
  if (!cholesky(A, n)) return false;
  for (int c = 0; c < n; ++c) {
    S* row = Ainv + c * n;
    for (int r = 0; r < n; ++r) row[r] = r == c ? S(1) : S(0);
    cholesky_solve(A, n, row);
  }
  return true;
}

}  // namespace rbd
