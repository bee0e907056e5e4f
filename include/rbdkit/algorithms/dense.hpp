// rbdkit/algorithms/dense.hpp — small dense kernels on row-major arrays:
// Cholesky factorisation, solve and inverse of a symmetric positive-definite
// matrix. Used for the joint-DoF blocks D = Sᵀ IA S (n ≤ 6) and the dense
// forward-dynamics path of mimic models (n = nv).
#pragma once

#include <type_traits>

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
    const S dinv = S(1) / d;  // one division per column
    for (int i = j + 1; i < n; ++i) {
      S s = A[i * n + j];
      for (int k = 0; k < j; ++k) s -= A[i * n + k] * A[j * n + k];
      A[i * n + j] = s * dinv;
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

// Ainv (n x n) = A⁻¹ for SPD A, as L⁻ᵀ L⁻¹ (LAPACK's potri); A is overwritten by its factor L.
// false if not PD.
//   X = L⁻¹ (lower, in Ainv's lower triangle):  X_ii = 1/L_ii,  X_ij = -X_ii Σ_{k=j..i-1} L_ik X_kj
//   A⁻¹_rc = Σ_{k>=c} X_kr X_kc  for c >= r, rows in order (entry (r, c) reads X's rows >= c; the
//   diagonal X_rr is last read by entry (r, r) itself), then mirrored into the lower triangle.
// n divisions and about n³/3 multiplies, where solving for the n unit columns took n² divisions.
template <typename S> RBD_HD bool spd_inverse(S* A, int n, S* Ainv) {
  if (!cholesky(A, n)) return false;
  for (int i = 0; i < n; ++i) {
    const S xi = S(1) / A[i * n + i];
    Ainv[i * n + i] = xi;
    for (int j = 0; j < i; ++j) {
      S s = S(0);
      for (int k = j; k < i; ++k) s += A[i * n + k] * Ainv[k * n + j];
      Ainv[i * n + j] = -(s * xi);
    }
  }
  for (int r = 0; r < n; ++r)
    for (int c = r; c < n; ++c) {
      S s = S(0);
      for (int k = c; k < n; ++k) s += Ainv[k * n + r] * Ainv[k * n + c];
      Ainv[r * n + c] = s;
    }
  for (int r = 1; r < n; ++r)
    for (int c = 0; c < r; ++c) Ainv[r * n + c] = Ainv[c * n + r];
  return true;
}

// out (n x cols) = -A B, A (n x n) and B (n x cols) row-major, out not
// overlapping either. Every entry is summed over k = 0..n-1 in order from 0
// and negated at the end, so the result is the same on every path below.
//
// In host code that nvcc does not see, for double and float: register blocks
// of 2 rows x 4 vectors (GCC/clang vector extensions, 16-byte vectors, so
// 2 x 8 doubles or 2 x 16 floats: SSE2 with no -march; 32-byte vectors first
// where the compiler targets AVX, RBD_HOST_VECTOR_BYTES), whose accumulators
// stay in registers over k. Left to itself the compiler vectorises the k loop
// as a reduction instead, which costs twice the instructions. Elsewhere
// (CUDA sources, SIMD packs, dual numbers): the plain triple loop, the same
// operations in the same order.
template <typename S> RBD_HD void neg_matmul_plain(const S* A, const S* B, int n, int cols, S* out) {
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < cols; ++c) {
      S acc = S(0);
      for (int k = 0; k < n; ++k) acc += A[r * n + k] * B[k * cols + c];
      out[r * cols + c] = -acc;
    }
}

#if (defined(__GNUC__) || defined(__clang__)) && !defined(__CUDACC__)
namespace detail {
// rows [r, r + R) x columns [c, c + NV·L) of out = -A B, NV vectors of L lanes (Bytes bytes) per row
template <typename S, int R, int NV, int Bytes>
inline void neg_matmul_block(const S* RBD_RESTRICT A, const S* RBD_RESTRICT B, int n, int cols, int r, int c,
                             S* RBD_RESTRICT out) {
  typedef S V __attribute__((vector_size(Bytes)));
  constexpr int L = Bytes / sizeof(S);
  V acc[R][NV];
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < NV; ++j) acc[i][j] = V{} ;
  for (int k = 0; k < n; ++k) {
    V b[NV];
    for (int j = 0; j < NV; ++j) __builtin_memcpy(&b[j], B + k * cols + c + j * L, sizeof(V));
    for (int i = 0; i < R; ++i) {
      const S a = A[(r + i) * n + k];
      for (int j = 0; j < NV; ++j) acc[i][j] += a * b[j];
    }
  }
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < NV; ++j) {
      const V o = -acc[i][j];
      __builtin_memcpy(out + (r + i) * cols + c + j * L, &o, sizeof(V));
    }
}

template <typename S, int R>
inline void neg_matmul_rows(const S* RBD_RESTRICT A, const S* RBD_RESTRICT B, int n, int cols, int r,
                            S* RBD_RESTRICT out) {
  constexpr int L = 16 / sizeof(S), W = RBD_HOST_VECTOR_BYTES / sizeof(S);
  int c = 0;
  for (; c + 4 * W <= cols; c += 4 * W) neg_matmul_block<S, R, 4, RBD_HOST_VECTOR_BYTES>(A, B, n, cols, r, c, out);
  for (; c + W <= cols; c += W) neg_matmul_block<S, R, 1, RBD_HOST_VECTOR_BYTES>(A, B, n, cols, r, c, out);
  if constexpr (W > L)
    for (; c + L <= cols; c += L) neg_matmul_block<S, R, 1, 16>(A, B, n, cols, r, c, out);
  for (; c < cols; ++c)
    for (int i = r; i < r + R; ++i) {
      S acc = S(0);
      for (int k = 0; k < n; ++k) acc += A[i * n + k] * B[k * cols + c];
      out[i * cols + c] = -acc;
    }
}
}  // namespace detail
#endif

template <typename S> RBD_HD void neg_matmul(const S* RBD_RESTRICT A, const S* RBD_RESTRICT B, int n, int cols,
                                             S* RBD_RESTRICT out) {
#if (defined(__GNUC__) || defined(__clang__)) && !defined(__CUDACC__)
  if constexpr (std::is_same<S, double>::value || std::is_same<S, float>::value) {
    int r = 0;
    for (; r + 2 <= n; r += 2) detail::neg_matmul_rows<S, 2>(A, B, n, cols, r, out);
    if (r < n) detail::neg_matmul_rows<S, 1>(A, B, n, cols, r, out);
    return;
  }
#endif
  neg_matmul_plain(A, B, n, cols, out);
}

// two columns of Bᵀ A (of B A for a symmetric B, as M⁻¹) whose nonzeros lie in the same `count`
// listed rows of B (n x n, row-major): out_a[r] = Σ_j a[j] B[rows[j]·n + r] and out_b[r] likewise
// with b, for r < n, where a[j] and b[j] are the two columns' entries in row rows[j], gathered.
// Each entry is summed from 0 in the list's order, so with the zero terms of a dense product left
// out it is that product's number. Each row of B is loaded once for both columns. Host double and
// float: register blocks of 4, 2 and 1 vectors per column (RBD_HOST_VECTOR_BYTES: 32 bytes where
// the compiler targets AVX, else 16), then one 16-byte vector, then the plain loop for the tail;
// elsewhere the plain loop (from entry r0).
template <typename S>
RBD_HD void scaled_row_sums_plain(const S* B, const S* a, const S* b, int n, const int* rows, int count, S* out_a,
                                  S* out_b, int r0 = 0) {
  for (int r = r0; r < n; ++r) {
    S sa = S(0), sb = S(0);
    for (int j = 0; j < count; ++j) {
      const S x = B[rows[j] * n + r];
      sa += a[j] * x;
      sb += b[j] * x;
    }
    out_a[r] = sa;
    out_b[r] = sb;
  }
}

#if (defined(__GNUC__) || defined(__clang__)) && !defined(__CUDACC__)
namespace detail {
// entries [r, r + NV·L) of scaled_row_sums, NV vectors of L lanes per column
template <typename S, int NV, int Bytes>
inline void scaled_row_sums_block(const S* RBD_RESTRICT B, const S* RBD_RESTRICT a, const S* RBD_RESTRICT b,
                                  int n, const int* RBD_RESTRICT rows, int count, int r, S* RBD_RESTRICT out_a,
                                  S* RBD_RESTRICT out_b) {
  typedef S V __attribute__((vector_size(Bytes)));
  constexpr int L = Bytes / sizeof(S);
  V acc_a[NV], acc_b[NV];
  for (int v = 0; v < NV; ++v) acc_a[v] = V{}, acc_b[v] = V{};
  for (int j = 0; j < count; ++j) {
    const S sa = a[j], sb = b[j];
    const S* Bj = B + rows[j] * n + r;
    for (int v = 0; v < NV; ++v) {
      V x;
      __builtin_memcpy(&x, Bj + v * L, sizeof(V));
      acc_a[v] += sa * x;
      acc_b[v] += sb * x;
    }
  }
  for (int v = 0; v < NV; ++v) {
    __builtin_memcpy(out_a + r + v * L, &acc_a[v], sizeof(V));
    __builtin_memcpy(out_b + r + v * L, &acc_b[v], sizeof(V));
  }
}
}  // namespace detail
#endif

template <typename S>
RBD_HD void scaled_row_sums(const S* RBD_RESTRICT B, const S* RBD_RESTRICT a, const S* RBD_RESTRICT b, int n,
                            const int* RBD_RESTRICT rows, int count, S* RBD_RESTRICT out_a, S* RBD_RESTRICT out_b) {
#if (defined(__GNUC__) || defined(__clang__)) && !defined(__CUDACC__)
  if constexpr (std::is_same<S, double>::value || std::is_same<S, float>::value) {
    constexpr int VB = RBD_HOST_VECTOR_BYTES, W = VB / sizeof(S), L = 16 / sizeof(S);
    int r = 0;
    for (; r + 4 * W <= n; r += 4 * W) detail::scaled_row_sums_block<S, 4, VB>(B, a, b, n, rows, count, r, out_a, out_b);
    if (r + 2 * W <= n) detail::scaled_row_sums_block<S, 2, VB>(B, a, b, n, rows, count, r, out_a, out_b), r += 2 * W;
    if (r + W <= n) detail::scaled_row_sums_block<S, 1, VB>(B, a, b, n, rows, count, r, out_a, out_b), r += W;
    if constexpr (W > L)
      if (r + L <= n) detail::scaled_row_sums_block<S, 1, 16>(B, a, b, n, rows, count, r, out_a, out_b), r += L;
    scaled_row_sums_plain(B, a, b, n, rows, count, out_a, out_b, r);
    return;
  }
#endif
  scaled_row_sums_plain(B, a, b, n, rows, count, out_a, out_b);
}

}  // namespace rbd
