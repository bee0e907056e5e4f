// rbdkit/algorithms/costs.hpp — the plant layer's running costs and log
// barriers: value, gradient and Hessian per knot point.
//
// Weights are diagonal and given as vectors. Shapes (NX = nq + nv):
//   quadratic_state_cost        x, x_des, Q (NX)    -> grad (NX), H (NX x NX), exact, ambient coordinates
//   quadratic_state_cost_tangent x, x_des (NX), Q (2nv) -> grad (2nv), H (2nv x 2nv):
//                                 e = [difference(q_des, q); qd - qd_des], grad Jᵀ Q e,
//                                 Gauss–Newton Hessian Jᵀ Q J, J = diag(∂difference/∂q, 1)
//   quadratic_input_cost        u, u_des, R (nv)    -> grad (nv), H (nv x nv), exact
//   position tracking (end effector, CoM): r = p(q) - p_des (3), W (3):
//                                 grad (NX), H (NX x NX) Gauss–Newton, tangent blocks embedded:
//                                 entries [0, nv) are the tangent δq, [nq, NX) the velocities,
//                                 [nv, nq) (the extra quaternion coordinates) stay zero
//   log barriers                -mu Σ [log(x - lower) + log(upper - x)] over finite bounds;
//                                 grad and the Hessian diagonal (same width as x)
// In the MuJoCo convention (mujoco_convention.hpp) x is [qpos; qvel], the log
// map is MuJoCo's ⊖ and the tangent blocks are along MuJoCo's ⊕.
#pragma once

#include "mujoco_convention.hpp"
#include "../configuration.hpp"

namespace rbd {

// ½ Σ Q_i (x_i - x_des_i)²; grad Q ⊙ (x - x_des); H = diag(Q) (n x n, row-major)
template <typename S>
RBD_HD S quadratic_cost(int n, const S* x, const S* x_des, const S* Q, S* grad, S* H) {
  S value = S(0);
  for (int i = 0; i < n; ++i) {
    const S e = x[i] - x_des[i];
    value += S(0.5) * Q[i] * e * e;
    grad[i] = Q[i] * e;
  }
  for (int i = 0; i < n * n; ++i) H[i] = S(0);
  for (int i = 0; i < n; ++i) H[i * n + i] = Q[i];
  return value;
}

// ½ eᵀ diag(Q) e for the log-map error e = [difference(q_des, q); qd - qd_des];
// x, x_des (nq + nv), Q (2nv); grad (2nv), H (2nv x 2nv); scratch nv x nv + nv.
// convention: OutputConvention (the MuJoCo one uses mj_difference)
template <typename S>
RBD_HD S quadratic_state_cost_tangent(const ModelView<S>& m, const S* x, const S* x_des, const S* Q, S* grad, S* H,
                                      S* scratch, int convention = kPinocchioConvention) {
  const int nq = m.nq, nv = m.nv, n2 = 2 * nv;
  S* J = scratch;        // ∂difference(q_des, q)/∂q (nv x nv)
  S* e = scratch + nv * nv;  // configuration error (nv)
  if (convention == kMujocoConvention) {
    mj_difference(m, x_des, x, e);
    mj_ddifference(m, x_des, x, 1, J);
  } else {
    difference(m, x_des, x, e);
    ddifference(m, x_des, x, 1, J);
  }
  S value = S(0);
  for (int i = 0; i < nv; ++i) value += S(0.5) * Q[i] * e[i] * e[i];
  for (int i = 0; i < nv; ++i) {
    const S ev = x[nq + i] - x_des[nq + i];
    value += S(0.5) * Q[nv + i] * ev * ev;
    grad[nv + i] = Q[nv + i] * ev;
  }
  for (int k = 0; k < n2 * n2; ++k) H[k] = S(0);
  // configuration block: Jᵀ Q e and Jᵀ Q J
  for (int c = 0; c < nv; ++c) {
    S g = S(0);
    for (int i = 0; i < nv; ++i) g += J[i * nv + c] * Q[i] * e[i];
    grad[c] = g;
    for (int c2 = 0; c2 < nv; ++c2) {
      S h = S(0);
      for (int i = 0; i < nv; ++i) h += J[i * nv + c] * Q[i] * J[i * nv + c2];
      H[c * n2 + c2] = h;
    }
  }
  for (int i = 0; i < nv; ++i) H[(nv + i) * n2 + nv + i] = Q[nv + i];
  return value;
}

// Gauss–Newton cost ½ rᵀ W r of a residual r (m) with Jacobian Jr (m x nv, row-major)
// on the tangent δq; grad and H in the embedded NX layout described above
template <typename S>
RBD_HD S residual_cost_embedded(int m, const S* r, const S* W, const S* Jr, int nq, int nv, S* grad, S* H) {
  const int nx = nq + nv;
  S value = S(0);
  for (int i = 0; i < m; ++i) value += S(0.5) * W[i] * r[i] * r[i];
  for (int k = 0; k < nx; ++k) grad[k] = S(0);
  for (int k = 0; k < nx * nx; ++k) H[k] = S(0);
  for (int c = 0; c < nv; ++c) {
    S g = S(0);
    for (int i = 0; i < m; ++i) g += Jr[i * nv + c] * W[i] * r[i];
    grad[c] = g;
    for (int c2 = 0; c2 < nv; ++c2) {
      S h = S(0);
      for (int i = 0; i < m; ++i) h += Jr[i * nv + c] * W[i] * Jr[i * nv + c2];
      H[c * nx + c2] = h;
    }
  }
  return value;
}

// -mu Σ [log(x - lo) + log(hi - x)], skipping infinite bounds. grad (n), Hdiag (n).
// Outside the open interval the value is +inf and that coordinate's gradient
// and Hessian entries are NaN (a line search rejects the point; nothing is
// silently clipped).
template <typename S>
RBD_HD S log_barrier(int n, const S* x, const S* lo, const S* hi, S mu, S* grad, S* Hdiag) {
  S value = S(0);
  const S inf = S(1) / S(0);
  for (int i = 0; i < n; ++i) {
    S g = S(0), h = S(0);
    bool outside = false;
    if (lo[i] > -inf) {
      const S d = x[i] - lo[i];
      if (!(d > S(0))) outside = true;
      else value -= mu * slog(d), g -= mu / d, h += mu / (d * d);
    }
    if (hi[i] < inf) {
      const S d = hi[i] - x[i];
      if (!(d > S(0))) outside = true;
      else value -= mu * slog(d), g += mu / d, h += mu / (d * d);
    }
    if (outside) {
      value = inf;
      g = S(0) / S(0);
      h = g;
    }
    grad[i] = g;
    Hdiag[i] = h;
  }
  return value;
}

}  // namespace rbd
