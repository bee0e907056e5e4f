// rbdkit/plant/jet.hpp — the algebra of truncated second-order jets,
// as integrator_hessian.hpp carries them through the stages of a step.
//
// A jet of an n-vector y(z), z (N), at z = 0 is its value, D = ∂y/∂z (n x N)
// and H = ∂²y/∂z² (n x N x N), row-major: D[r·N + j], H[(r·N + j)·N + k].
// The operations here combine the H of jets: chain-rule products with a
// quadratic form (jet_add_quadratic_upper) or a linear map
// (jet_add_linear_upper), the symmetric completion (jet_mirror), and the unit
// jet of one input block (jet_unit_block). Each takes a team (model/team.hpp)
// first: an InlineTeam runs the loops as written, a cooperative team splits
// them into phases over independent entries, each entry summed in the same
// order, so either gives the same numbers (to the sign of a zero).
#pragma once

#include "rbdkit/algorithms/fdsva_so.hpp"  // so_skippable
#include "rbdkit/model/team.hpp"

namespace rbd {

// ---------------------------------------------------------------- jet algebra
// Every H is symmetric in (j, k): the products below fill the upper triangle
// (k >= j) only, and jet_mirror completes a tensor once it is summed.

// y[k] += a x[k] for k0 <= k < n, x and y disjoint (said once, so that the loops below vectorise the
// same wherever they are inlined)
template <typename S>
RBD_HD_INLINE void jet_axpy(long k0, long n, S a, const S* RBD_RESTRICT x, S* RBD_RESTRICT y) {
  for (long k = k0; k < n; ++k) y[k] += a * x[k];
}

// H[i] += s · Yᵀ T[i] Y on k >= j: H[i, j, k] += s Σ_ab T[i, a, b] Y[a, j] Y[b, k]
// (T n x p x p, each T[i] symmetric; Y p x N; H n x N x N). One thread forms T[i] Y in tmp (p x N
// values) and adds Yᵀ tmp row by row of Y, i after i (skipping a T[i] = 0); a cooperative team forms
// every T[i] Y in tmp (n x p x N values; a row (i, a) per index), then H's rows (i, j), adding the
// products by a T[i] = 0 too (the same sums but for the sign of a zero)
template <typename Team, typename S>
RBD_HD void jet_add_quadratic_upper(const Team& t, int n, int p, int N, const S* T, const S* Y, S s, S* H, S* tmp) {
  const long NN = static_cast<long>(N) * N, pN = static_cast<long>(p) * N;
  (void)t;
  if constexpr (!Team::cooperative) {
    for (int i = 0; i < n; ++i) {
      const S* Ti = T + static_cast<long>(i) * p * p;
      // tmp = T[i] Y
      bool any = false;
      for (long k = 0; k < pN; ++k) tmp[k] = S(0);
      for (int a = 0; a < p; ++a)
        for (int b = 0; b < p; ++b) {
          const S x = Ti[a * p + b];
          if (so_skippable(x)) continue;
          any = true;
          jet_axpy(0, N, x, Y + static_cast<long>(b) * N, tmp + static_cast<long>(a) * N);
        }
      if (!any) continue;
      // H[i] += s Yᵀ tmp, k >= j
      S* Hi = H + i * NN;
      for (int a = 0; a < p; ++a) {
        const S* ta = tmp + static_cast<long>(a) * N;
        for (int j = 0; j < N; ++j) {
          const S y = Y[static_cast<long>(a) * N + j];
          if (so_skippable(y)) continue;
          jet_axpy(j, N, s * y, ta, Hi + static_cast<long>(j) * N);
        }
      }
    }
  } else {  // tmp_i = T[i] Y for every i, a row (i, a) per index; then H's rows (i, j), each summed over a in order
    t.each(static_cast<long>(n) * p, [&](long e) {
      const long i = e / p, a = e % p;
      const S* Ti = T + i * p * p;
      S* ta = tmp + i * pN + a * N;
      for (int k = 0; k < N; ++k) ta[k] = S(0);
      for (int b = 0; b < p; ++b) {
        const S x = Ti[a * p + b];
        if (so_skippable(x)) continue;
        jet_axpy(0, N, x, Y + static_cast<long>(b) * N, ta);
      }
    });
    t.each(static_cast<long>(n) * N, [&](long e) {
      const long i = e / N, j = e % N;
      S* h = H + i * NN + j * N;
      for (int a = 0; a < p; ++a) {
        const S y = Y[static_cast<long>(a) * N + j];
        if (so_skippable(y)) continue;
        jet_axpy(j, N, s * y, tmp + i * pN + static_cast<long>(a) * N, h);
      }
    });
  }
}

// H[i] += s Σ_a F[i, a] Hin[a] on k >= j (F n x p, Hin p x N x N, H n x N x N); one thread takes
// row j of every Hin[a] across i while it is in cache, a cooperative team a row (j, i) per index
template <typename Team, typename S>
RBD_HD void jet_add_linear_upper(const Team& t, int n, int p, int N, const S* F, const S* Hin, S s, S* H) {
  const long NN = static_cast<long>(N) * N;
  t.each2(N, n, [&](long j, long i) {
    S* h = H + i * NN + j * N;
    for (int a = 0; a < p; ++a) {
      const S f = F[i * p + a];
      if (so_skippable(f)) continue;
      jet_axpy(j, N, s * f, Hin + a * NN + j * N, h);
    }
  });
}

// H[i, k, j] <- H[i, j, k] for k > j (n x N x N)
template <typename Team, typename S> RBD_HD void jet_mirror(const Team& t, int n, int N, S* H) {
  t.each2(n, N, [&](long i, long j) {
    S* Hi = H + i * N * N;
    for (long k = j + 1; k < N; ++k) Hi[k * N + j] = Hi[j * N + k];
  });
}

// D (n x N) <- the unit block: D[r, block·nv + r] = 1 (n = nv)
template <typename Team, typename S> RBD_HD void jet_unit_block(const Team& t, int nv, int block, S* D) {
  const int N = 3 * nv;
  t.each(static_cast<long>(nv) * N, [&](long k) { D[k] = S(0); });
  t.each(nv, [&](long r) { D[r * N + block * nv + r] = S(1); });
}

}  // namespace rbd
