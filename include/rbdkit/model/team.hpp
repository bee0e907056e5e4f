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
// interpret-mode emulation: src/cuda/team_kernels.cuh) or run inline.
//
// InlineTeam is one thread running every phase in order, with no barrier:
// the serial code of the CPU, of its engine's SIMD packs and of the
// sample-per-thread kernels, unchanged by being written for a team.
#pragma once

#include "rbdkit/spatial/config.hpp"

namespace rbd {

struct InlineTeam {
  static constexpr bool cooperative = false;
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
// thread's row-by-row accumulation, or one entry per index on a cooperative
// team (each entry sums over n in the same order either way)
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
template <typename Team, typename S> RBD_HD void matmul(const Team& t, const S* A, const S* B, S* C, int r, int n, int c) {
  if constexpr (!Team::cooperative) {
    matmul(A, B, C, r, n, c);
  } else {
    t.each(static_cast<long>(r) * c, [&](long e) {
      const int i = static_cast<int>(e / c), j = static_cast<int>(e % c);
      S acc = S(0);
      for (int k = 0; k < n; ++k) acc += A[i * n + k] * B[k * c + j];
      C[e] = acc;
    });
  }
}

}  // namespace rbd
