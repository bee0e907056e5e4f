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
// interpret-mode emulation: src/cuda/team_kernels.cuh) or run inline;
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

// ---- the tree level by level: the bodies at one depth (BodyDesc::depth) side by side, a level per
// phase. A chain through the tree (a body's pose from its parent's, a parent's articulated inertia
// from its children's) takes as many phases as the tree has levels, not bodies: floating Atlas's 31
// bodies are 11 levels, floating HyQ's 13 are 4.
// levels_split: whether a team walks a model so. Not on one thread (InlineTeam), not where the levels
// are not given (ModelView::levels 0), and not on a chain such as iiwa, whose levels are its bodies:
// there one thread's loop saves the barriers.
template <typename Team, typename Model> RBD_HD bool levels_split(const Team&, const Model& m) {
  return Team::cooperative && m.levels > 0 && m.levels < m.nb;
}
// f(i) for every body, the root's level first: a body's parent is done before it
template <typename Team, typename Model, typename F> RBD_HD void each_level_down(const Team& t, const Model& m, F&& f) {
  for (int level = 0; level < m.levels; ++level)
    t.each(m.nb, [&](long i) {
      if (m.body[i].depth == level) f(static_cast<int>(i));
    });
}
// f(i) for every body, the deepest level first: a body's children are done before it
template <typename Team, typename Model, typename F> RBD_HD void each_level_up(const Team& t, const Model& m, F&& f) {
  for (int level = m.levels - 1; level >= 0; --level)
    t.each(m.nb, [&](long i) {
      if (m.body[i].depth == level) f(static_cast<int>(i));
    });
}
// g(j) for every child j of body i, the last first: the order in which a serial pass over the bodies,
// the last first, adds each child into its parent (so a parent that gathers its children's terms sums
// them in that pass's order). Bodies come after their parents (BodyDesc)
template <typename Model, typename G> RBD_HD void each_child_last_first(const Model& m, int i, G&& g) {
  for (int j = m.nb - 1; j > i; --j)
    if (m.body[j].parent == i) g(j);
}

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

// the tile side for an r x c product on a team of `threads`: 4 where that still gives every thread a
// tile, else 2 (iiwa's 7 x 7: 16 tiles of 2 x 2 rather than 4 of 4 x 4)
RBD_HD int team_tile_side(int r, int c, int threads) {
  return ((r + 3) / 4) * ((c + 3) / 4) >= threads ? 4 : 2;
}

// the tiles of `count` products C_p = sign · A B_p (A: r x n, each B_p: n x c, each C_p: r x c, row-major,
// strides as their widths) in one phase of a cooperative team, a tile per index
template <typename Team, typename S>
RBD_HD void matmul_tiles(const Team& t, int threads, const S* A, const S* const* B, S* const* C, int count, int r,
                         int n, int c, S sign) {
  const int side = team_tile_side(r, c * count, threads);
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
