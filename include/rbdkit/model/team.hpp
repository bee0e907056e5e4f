// rbdkit/model/team.hpp — the threads that compute one sample together.
//
// An algorithm written for a team takes it as a template parameter and
// splits its work into phases, each ended by a barrier:
//   t.each(n, f)     f(k) for every index k below n, spread over the team
//   t.each2(r, c, f) f(i, j) for every i below r and j below c (a matrix's entries)
//   t.one(f)         f() on one thread (a serial pass)
//   t.beside(f, g)   f(sub) on part of the team, a team of its own whose
//                    phases end at that part's barrier, beside the serial
//                    pass g() on one other thread
// What a phase hands to the next goes through memory; a local variable
// outside a phase must be the same on every thread. Team::cooperative says
// whether phases really are split (the GPU's team kernels, and their
// interpret-mode emulation: rbdkit/cuda/team_kernels.cuh) or run inline;
// Team::threads how many threads share a phase.
//
// InlineTeam is one thread running every phase in order, with no barrier:
// the serial code of the CPU, of its engine's SIMD packs and of the
// sample-per-thread kernels, unchanged by being written for a team.
#pragma once

#include "rbdkit/spatial/config.hpp"

namespace rbd {

struct InlineTeam {
  static constexpr bool cooperative = false;
  static constexpr int threads = 1;
  template <typename F> RBD_HD void each(long n, F&& f) const {
    for (long k = 0; k < n; ++k) f(k);
  }
  template <typename F> RBD_HD void each2(long rows, long cols, F&& f) const {
    for (long i = 0; i < rows; ++i)
      for (long j = 0; j < cols; ++j) f(i, j);
  }
  template <typename F> RBD_HD void one(F&& f) const { f(); }
  template <typename F, typename G> RBD_HD void beside(F&& f, G&& g) const { f(*this), g(); }
};

// C (r x c) = A (r x n) B (n x c), row-major, C aliasing neither: one
// thread's row-by-row accumulation, or tiles of entries on a cooperative team
// (matmul_tile). Each entry sums over n in the same order either way
template <typename S> RBD_HD void matmul(const S* A, const S* B, S* C, int r, int n, int c) {
  for (int i = 0; i < r; ++i) {
    S* Ci = C + i * c;
    for (int j = 0; j < c; ++j) Ci[j] = S(0);
    for (int k = 0; k < n; ++k) {
      const S a = A[i * n + k];
      const S* Bk = B + k * c;
      for (int j = 0; j < c; ++j) Ci[j] += a * Bk[j];
    }
  }
}

// y (r) = A (r x n) x, row-major, y aliasing neither: a row per index on a cooperative team, in order
// on an InlineTeam, each entry summed over n from 0 up either way (M⁻¹ (tau - c): forward dynamics
// through M⁻¹, minv.hpp, and its team forms)
template <typename Team, typename S> RBD_HD void matvec(const Team& t, const S* A, const S* x, S* y, int r, int n) {
  t.each(r, [&](long i) {
    S acc = S(0);
    for (int k = 0; k < n; ++k) acc += A[i * n + k] * x[k];
    y[i] = acc;
  });
}

// one R x R tile of C = sign · A B (A: r x n with row stride lda, B: n x c with stride ldb, C: stride
// ldc), rows i0.. and columns j0.., each entry summed over k from 0 up (the order of the plain
// product). A tile reads R entries of A and R of B per k for R² multiply-adds, where an entry per
// thread reads two for one, and its R² sums are independent (a GPU thread's chain of dependent
// adds is R² times shorter). Edge tiles clamp their reads to the last row or column and store only
// what lies inside
template <int R, typename S>
RBD_HD void matmul_tile(const S* A, int lda, const S* B, int ldb, S* C, int ldc, int r, int n, int c, int i0,
                        int j0, S sign) {
  int ri[R], cj[R];
  for (int a = 0; a < R; ++a) ri[a] = (i0 + a < r ? i0 + a : r - 1) * lda, cj[a] = j0 + a < c ? j0 + a : c - 1;
  S acc[R][R];
  for (int a = 0; a < R; ++a)
    for (int b = 0; b < R; ++b) acc[a][b] = S(0);
  for (int k = 0; k < n; ++k) {
    S x[R], y[R];
    for (int a = 0; a < R; ++a) x[a] = A[ri[a] + k], y[a] = B[k * ldb + cj[a]];
    for (int a = 0; a < R; ++a)
      for (int b = 0; b < R; ++b) acc[a][b] += x[a] * y[b];
  }
  for (int a = 0; a < R && i0 + a < r; ++a)
    for (int b = 0; b < R && j0 + b < c; ++b) C[(i0 + a) * ldc + j0 + b] = sign * acc[a][b];
}

// the tile side for `count` r x c products on a team of `threads`: 4 where that still gives every
// thread a tile, else 2 (iiwa's two 7 x 7: 32 tiles of 2 x 2 rather than 8 of 4 x 4)
RBD_HD int team_tile_side(int r, int c, int count, int threads) {
  return ((r + 3) / 4) * ((c + 3) / 4) * count >= threads ? 4 : 2;
}

// the tiles of `count` products C_p = sign · A B_p (A: r x n, each B_p: n x c, each C_p: r x c, row-major,
// strides as their widths) in one phase of a cooperative team, a tile per index
template <typename Team, typename S>
RBD_HD void matmul_tiles(const Team& t, int threads, const S* A, const S* const* B, S* const* C, int count, int r,
                         int n, int c, S sign) {
  const int side = team_tile_side(r, c, count, threads);
  const int tr = (r + side - 1) / side, tc = (c + side - 1) / side;
  t.each(static_cast<long>(count) * tr * tc, [&](long e) {
    const int p = static_cast<int>(e / (tr * tc)), k = static_cast<int>(e % (tr * tc));
    const int i0 = k / tc * side, j0 = k % tc * side;
    if (side == 4) matmul_tile<4>(A, n, B[p], c, C[p], c, r, n, c, i0, j0, sign);
    else matmul_tile<2>(A, n, B[p], c, C[p], c, r, n, c, i0, j0, sign);
  });
}

template <typename Team, typename S> RBD_HD void matmul(const Team& t, const S* A, const S* B, S* C, int r, int n, int c) {
  if constexpr (!Team::cooperative) {
    matmul(A, B, C, r, n, c);
  } else {
    matmul_tiles(t, Team::threads, A, &B, &C, 1, r, n, c, S(1));
  }
}

}  // namespace rbd
