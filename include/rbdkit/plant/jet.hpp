// rbdkit/plant/jet.hpp — the algebra of truncated second-order jets,
// as integrator_hessian.hpp carries them through the stages of a step.
//
// A jet of an n-vector y(z), z (N), at z = 0 is its value, D = ∂y/∂z (n x N)
// and H = ∂²y/∂z² (n x N x N), row-major: D[r·N + j], H[(r·N + j)·N + k].
// The operations here combine the H of jets: chain-rule products with a
// quadratic form (jet_add_quadratic_upper) or a linear map
// (jet_add_linear_upper), the symmetric completion (jet_mirror), and the unit
// jet of one input block (jet_unit_block).
#pragma once

#include "rbdkit/algorithms/fdsva_so.hpp"  // so_skippable

namespace rbd {

// ---------------------------------------------------------------- jet algebra
// Every H is symmetric in (j, k): the products below fill the upper triangle
// (k >= j) only, and jet_mirror completes a tensor once it is summed.

// H[i] += s · Yᵀ T[i] Y on k >= j: H[i, j, k] += s Σ_ab T[i, a, b] Y[a, j] Y[b, k]
// (T n x p x p, each T[i] symmetric; Y p x N; H n x N x N); tmp (p x N)
template <typename S>
RBD_HD void jet_add_quadratic_upper(int n, int p, int N, const S* T, const S* Y, S s, S* H, S* tmp) {
  const long NN = static_cast<long>(N) * N;
  for (int i = 0; i < n; ++i) {
    const S* Ti = T + static_cast<long>(i) * p * p;
    // tmp = T[i] Y
    bool any = false;
    for (long k = 0; k < static_cast<long>(p) * N; ++k) tmp[k] = S(0);
    for (int a = 0; a < p; ++a)
      for (int b = 0; b < p; ++b) {
        const S t = Ti[a * p + b];
        if (so_skippable(t)) continue;
        any = true;
        const S* yb = Y + static_cast<long>(b) * N;
        S* ta = tmp + static_cast<long>(a) * N;
        for (int k = 0; k < N; ++k) ta[k] += t * yb[k];
      }
    if (!any) continue;
    // H[i] += s Yᵀ tmp, k >= j
    S* Hi = H + i * NN;
    for (int a = 0; a < p; ++a) {
      const S* ta = tmp + static_cast<long>(a) * N;
      for (int j = 0; j < N; ++j) {
        const S y = Y[static_cast<long>(a) * N + j];
        if (so_skippable(y)) continue;
        const S sy = s * y;
        S* h = Hi + static_cast<long>(j) * N;
        for (int k = j; k < N; ++k) h[k] += sy * ta[k];
      }
    }
  }
}

// H[i] += s Σ_a F[i, a] Hin[a] on k >= j (F n x p, Hin p x N x N, H n x N x N);
// row j of every Hin[a] is reused across i while it is in cache
template <typename S> RBD_HD void jet_add_linear_upper(int n, int p, int N, const S* F, const S* Hin, S s, S* H) {
  const long NN = static_cast<long>(N) * N;
  for (int j = 0; j < N; ++j)
    for (int i = 0; i < n; ++i) {
      S* h = H + i * NN + static_cast<long>(j) * N;
      for (int a = 0; a < p; ++a) {
        const S f = F[i * p + a];
        if (so_skippable(f)) continue;
        const S sf = s * f;
        const S* src = Hin + a * NN + static_cast<long>(j) * N;
        for (int k = j; k < N; ++k) h[k] += sf * src[k];
      }
    }
}

// H[i, k, j] <- H[i, j, k] for k > j (n x N x N)
template <typename S> RBD_HD void jet_mirror(int n, int N, S* H) {
  for (int i = 0; i < n; ++i) {
    S* Hi = H + static_cast<long>(i) * N * N;
    for (int j = 0; j < N; ++j)
      for (int k = j + 1; k < N; ++k) Hi[k * N + j] = Hi[j * N + k];
  }
}

// D (n x N) <- the unit block: D[r, block·nv + r] = 1 (n = nv)
template <typename S> RBD_HD void jet_unit_block(int nv, int block, S* D) {
  const int N = 3 * nv;
  for (long k = 0; k < static_cast<long>(nv) * N; ++k) D[k] = S(0);
  for (int r = 0; r < nv; ++r) D[r * N + block * nv + r] = S(1);
}

}  // namespace rbd
