// rbdkit/plant/costs.hpp — the plant layer's running costs and log
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
//
// Each is written for a team (model/team.hpp), for the GPU's team kernels
// (cuda/team_kernels.cuh): the serial prefix (the log map, kinematics, ccrba
// and dccrba) and the value's sum on one thread, then the gradient and the
// Hessian an entry per index (adjacent threads, adjacent entries), each sum in
// the serial order. The signatures without a team run it on an InlineTeam.
#pragma once

#include "rbdkit/algorithms/centroidal.hpp"
#include "rbdkit/algorithms/kinematics.hpp"
#include "rbdkit/model/configuration.hpp"
#include "rbdkit/model/team.hpp"
#include "rbdkit/plant/mujoco_convention.hpp"

namespace rbd {

// x (n) = 0
template <typename Team, typename S> RBD_HD void fill_zero(const Team& t, long n, S* x) {
  t.each(n, [&](long k) { x[k] = S(0); });
}

// H (n x n, row-major) = diag(d)
template <typename Team, typename S> RBD_HD void diagonal_matrix(const Team& t, int n, const S* d, S* H) {
  fill_zero(t, static_cast<long>(n) * n, H);
  t.each(n, [&](long i) { H[i * n + i] = d[i]; });
}

// g (n) = Aᵀ (w ⊙ r) for A (m x n, row stride lda), w and r (m): g[c] = Σ_i A[i][c] w[i] r[i], i from 0 up
template <typename Team, typename S>
RBD_HD void weighted_transpose_times(const Team& t, int m, int n, const S* A, int lda, const S* w, const S* r, S* g) {
  t.each(n, [&](long c) {
    S acc = S(0);
    for (int i = 0; i < m; ++i) acc += A[i * lda + c] * w[i] * r[i];
    g[c] = acc;
  });
}

// G (n x n, row stride ldg) = Aᵀ diag(w) A for A (m x n, row stride lda): G[c][c2] = Σ_i A[i][c] w[i] A[i][c2],
// i from 0 up (the Gauss–Newton Hessian of a weighted residual with Jacobian A)
template <typename Team, typename S>
RBD_HD void weighted_gram(const Team& t, int m, int n, const S* A, int lda, const S* w, S* G, int ldg) {
  t.each2(n, n, [&](long c, long c2) {
    const S* Ac = A + c;
    const S* Ac2 = A + c2;
    S acc = S(0);
    for (int i = 0; i < m; ++i) acc += Ac[i * lda] * w[i] * Ac2[i * lda];
    G[c * ldg + c2] = acc;
  });
}

// *value = ½ Σ Q_i (x_i - x_des_i)²; grad Q ⊙ (x - x_des) (n); H = diag(Q) (n x n)
template <typename Team, typename S>
RBD_HD void quadratic_cost(const Team& t, int n, const S* x, const S* x_des, const S* Q, S* value, S* grad, S* H) {
  t.one([&] {
    S v = S(0);
    for (int i = 0; i < n; ++i) {
      const S e = x[i] - x_des[i];
      v += S(0.5) * Q[i] * e * e;
    }
    *value = v;
  });
  t.each(n, [&](long i) { grad[i] = Q[i] * (x[i] - x_des[i]); });
  diagonal_matrix(t, n, Q, H);
}
template <typename S> RBD_HD S quadratic_cost(int n, const S* x, const S* x_des, const S* Q, S* grad, S* H) {
  S value;
  quadratic_cost(InlineTeam{}, n, x, x_des, Q, &value, grad, H);
  return value;
}

// *value = ½ eᵀ diag(Q) e for the log-map error e = [difference(q_des, q); qd - qd_des];
// x, x_des (nq + nv), Q (2nv); grad (2nv), H (2nv x 2nv); scratch nv x nv + nv.
// convention: OutputConvention (the MuJoCo one uses mj_difference)
template <typename Team, typename S>
RBD_HD void quadratic_state_cost_tangent(const Team& t, const ModelView<S>& m, const S* x, const S* x_des, const S* Q,
                                         S* value, S* grad, S* H, S* scratch, int convention) {
  const int nq = m.nq, nv = m.nv, n2 = 2 * nv;
  S* J = scratch;            // ∂difference(q_des, q)/∂q (nv x nv)
  S* e = scratch + nv * nv;  // configuration error (nv)
  t.one([&] {
    if (convention == kMujocoConvention) {
      mj_difference(m, x_des, x, e);
      mj_ddifference(m, x_des, x, 1, J);
    } else {
      difference(m, x_des, x, e);
      ddifference(m, x_des, x, 1, J);
    }
    S v = S(0);
    for (int i = 0; i < nv; ++i) v += S(0.5) * Q[i] * e[i] * e[i];
    for (int i = 0; i < nv; ++i) {
      const S ev = x[nq + i] - x_des[nq + i];
      v += S(0.5) * Q[nv + i] * ev * ev;
    }
    *value = v;
  });
  // configuration block: Jᵀ Q e and Jᵀ Q J; velocity block: Q ⊙ (qd - qd_des) and diag(Q)
  fill_zero(t, static_cast<long>(n2) * n2, H);
  weighted_transpose_times(t, nv, nv, J, nv, Q, e, grad);
  t.each(nv, [&](long i) {
    grad[nv + i] = Q[nv + i] * (x[nq + i] - x_des[nq + i]);
    H[(nv + i) * n2 + nv + i] = Q[nv + i];
  });
  weighted_gram(t, nv, nv, J, nv, Q, H, n2);
}
template <typename S>
RBD_HD S quadratic_state_cost_tangent(const ModelView<S>& m, const S* x, const S* x_des, const S* Q, S* grad, S* H,
                                      S* scratch, int convention = kPinocchioConvention) {
  S value;
  quadratic_state_cost_tangent(InlineTeam{}, m, x, x_des, Q, &value, grad, H, scratch, convention);
  return value;
}

// Gauss–Newton cost *value = ½ rᵀ W r of a residual r (m) with Jacobian Jr (m x nv, row-major)
// on the tangent δq; grad and H in the embedded NX layout described above
template <typename Team, typename S>
RBD_HD void residual_cost_embedded(const Team& t, int m, const S* r, const S* W, const S* Jr, int nq, int nv,
                                   S* value, S* grad, S* H) {
  const int nx = nq + nv;
  t.one([&] {
    S v = S(0);
    for (int i = 0; i < m; ++i) v += S(0.5) * W[i] * r[i] * r[i];
    *value = v;
  });
  fill_zero(t, nx, grad);
  fill_zero(t, static_cast<long>(nx) * nx, H);
  weighted_transpose_times(t, m, nv, Jr, nv, W, r, grad);
  weighted_gram(t, m, nv, Jr, nv, W, H, nx);
}

// --------------------------------------------------------- centroidal tracking costs
// q (and qd) in the convention's layout and frames; the tangent blocks along its ⊕.

// scratch values of ee_pos_cost: q in Pinocchio's layout (nq), the pose (6) and its gradient (6 x nv)
RBD_HD constexpr long ee_pos_cost_scratch(int nq, int nv) { return nq + 6 + 6L * nv; }

// ½ Σ W (p(q) - p_des)² for the point at `offset` (3, body frame; null: the
// origin) on `body` (W, p_des (3)): value, grad (NX), Gauss–Newton H (NX x NX)
// embedded as residual_cost_embedded's; the position rows of the end-effector
// pose gradient are the residual's Jacobian
template <typename Team, typename S>
RBD_HD void ee_pos_cost(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q, const S* p_des,
                        const S* W, int body, const S* offset, int convention, S* value, S* grad, S* H, S* scratch) {
  S* pose = scratch + m.nq;  // (its first three entries become the residual)
  S* G = pose + 6;
  t.one([&] {
    const S* qp = q;
    if (convention == kMujocoConvention) {
      configuration_from_mujoco(m, q, scratch);
      qp = scratch;
    }
    const Vec3<S> o = offset ? Vec3<S>{offset[0], offset[1], offset[2]} : Vec3<S>::zero();
    forward_kinematics(m, w, qp, static_cast<const S*>(nullptr));
    end_effector_pose(w, body, o, pose);
    end_effector_pose_gradient(m, w, body, o, G);
    if (convention == kMujocoConvention) jacobian_cols_to_mujoco(m, q, G, 6);
    for (int k = 0; k < 3; ++k) pose[k] = pose[k] - p_des[k];
  });
  residual_cost_embedded(t, 3, pose, W, G, m.nq, m.nv, value, grad, H);
}
template <typename S>
RBD_HD void ee_pos_cost(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* p_des, const S* W, int body,
                        const S* offset, int convention, S* value, S* grad, S* H, S* scratch) {
  ee_pos_cost(InlineTeam{}, m, w, q, p_des, W, body, offset, convention, value, grad, H, scratch);
}

// scratch values of com_cost: q in Pinocchio's layout (nq), the residual (3), J_com (3 x nv)
RBD_HD constexpr long com_cost_scratch(int nq, int nv) { return nq + 3 + 3L * nv; }

// ½ Σ W (com(q) - p_des)² (W, p_des (3)): value, grad (NX), Gauss–Newton H (NX x NX)
// embedded as residual_cost_embedded's. false if the robot has no mass (*ok: the
// flag every thread of a team reads)
template <typename Team, typename S>
RBD_HD bool com_cost(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q, const S* p_des, const S* W,
                     int convention, S* value, S* grad, S* H, S* scratch, int* ok) {
  S* r = scratch + m.nq;
  S* J = r + 3;
  t.one([&] {
    const S* qp = q;
    if (convention == kMujocoConvention) {
      configuration_from_mujoco(m, q, scratch);
      qp = scratch;
    }
    S c[3];
    *ok = center_of_mass(m, w, qp, c) && jacobian_com(m, w, qp, J);
    if (!*ok) return;
    if (convention == kMujocoConvention) jacobian_cols_to_mujoco(m, q, J, 3);
    for (int k = 0; k < 3; ++k) r[k] = c[k] - p_des[k];
  });
  if (!*ok) return false;
  residual_cost_embedded(t, 3, r, W, J, m.nq, m.nv, value, grad, H);
  return true;
}
template <typename S>
RBD_HD bool com_cost(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* p_des, const S* W, int convention,
                     S* value, S* grad, S* H, S* scratch) {
  int ok = 0;
  return com_cost(InlineTeam{}, m, w, q, p_des, W, convention, value, grad, H, scratch, &ok);
}

// scratch values of momentum_cost: q, qd in Pinocchio's layout and frames,
// A, h (then the residual), dA, J = [Jq | Jv] (6 x 2nv), Jq
RBD_HD constexpr long momentum_cost_scratch(int nq, int nv) { return nq + 6 + 25L * nv + 6L * nv * nv; }

// ½ Σ W r² with r = A(q)·qd - h_des (W, h_des (6)): value, grad Jᵀ W r (2nv),
// Gauss–Newton H = Jᵀ W J (2nv x 2nv), J = [(∂A/∂q)·qd | A] in the tangent
// [δq | δqd]. MuJoCo convention: qd is rotated to Pinocchio's frames inside r,
// and J keeps that rotation's configuration dependence. false without mass
// (*ok: the flag every thread of a team reads)
template <typename Team, typename S>
RBD_HD bool momentum_cost(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd,
                          const S* h_des, const S* W, int convention, S* value, S* grad, S* H, S* scratch, int* ok) {
  const int nv = m.nv, n2 = 2 * nv;
  const bool mujoco = convention == kMujocoConvention;
  S* qp = scratch;
  S* vp = qp + m.nq;
  S* A = vp + nv;
  S* h = A + 6 * nv;  // (then the residual r)
  S* dA = h + 6;
  S* J = dA + 6 * nv * nv;
  S* Jq = J + 6 * n2;
  const S* qs = mujoco ? qp : q;  // q and qd in Pinocchio's frames
  const S* vs = mujoco ? vp : qd;
  t.one([&] {
    if (mujoco) {
      configuration_from_mujoco(m, q, qp);
      rotate_from_mujoco(m, q, qd, vp);  // qd in MuJoCo's frames -> Pinocchio's
    }
    *ok = ccrba(m, w, qs, vs, A, h) && dccrba(m, w, qs, Jq, dA);  // Jq: dccrba's copy of A
  });
  if (!*ok) return false;
  // J = [(∂A/∂q) qd | A]: column k of the first block is Σ_j dA[r][j][k] qd_j
  t.each2(6, nv, [&](long r, long k) {
    S acc = S(0);
    for (int j = 0; j < nv; ++j) acc += dA[(r * nv + j) * nv + k] * vs[j];
    J[r * n2 + k] = acc;
    J[r * n2 + nv + k] = A[r * nv + k];
  });
  if (mujoco)
    t.one([&] {
      // MuJoCo tangent: Jq ← (Jq + A ∂v_pin/∂δq) Cᵀ, Jv ← A Cᵀ
      for (int r = 0; r < 6; ++r)
        for (int k = 0; k < nv; ++k) Jq[r * nv + k] = J[r * n2 + k];
      add_frame_dependence(m, vs, A, Jq, 6);
      jacobian_cols_to_mujoco(m, q, Jq, 6);
      jacobian_cols_to_mujoco(m, q, A, 6);
      for (int r = 0; r < 6; ++r)
        for (int k = 0; k < nv; ++k) J[r * n2 + k] = Jq[r * nv + k], J[r * n2 + nv + k] = A[r * nv + k];
    });
  t.one([&] {
    S v = S(0);
    for (int r = 0; r < 6; ++r) {
      h[r] = h[r] - h_des[r];
      v += S(0.5) * W[r] * h[r] * h[r];
    }
    *value = v;
  });
  weighted_transpose_times(t, 6, n2, J, n2, W, h, grad);
  weighted_gram(t, 6, n2, J, n2, W, H, n2);
  return true;
}
template <typename S>
RBD_HD bool momentum_cost(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* h_des, const S* W,
                          int convention, S* value, S* grad, S* H, S* scratch) {
  int ok = 0;
  return momentum_cost(InlineTeam{}, m, w, q, qd, h_des, W, convention, value, grad, H, scratch, &ok);
}

// *value = -mu Σ [log(x - lo) + log(hi - x)], skipping infinite bounds. grad (n), Hdiag (n).
// Outside the open interval the value is +inf and that coordinate's gradient
// and Hessian entries are NaN (a line search rejects the point; nothing is
// silently clipped). Branch-free (select), so that SIMD lanes may differ: an
// infinite bound gives d = inf, whose terms mu/d and mu/d² are exactly 0.
// On a cooperative team a coordinate per index, each one's term of the sum in
// terms (n), summed in order on one thread
template <typename Team, typename S>
RBD_HD void log_barrier(const Team& t, int n, const S* x, const S* lo, const S* hi, S mu, S* value, S* grad, S* Hdiag,
                        S* terms) {
  const double unbounded = 1.0 / 0.0;
  const S zero = S(0), inf = S(1) / S(0), nan = S(0) / S(0);
  // coordinate i: its gradient and Hessian entries, and its term mu [log(x - lo) + log(hi - x)]
  // (-inf outside, which makes the value +inf from there on)
  auto coordinate = [&](int i) {
    const S d_lo = x[i] - lo[i], d_hi = hi[i] - x[i];
    // inside: min(d_lo, d_hi) > 0 (two infinite bounds: inf - inf is NaN, not < 0, so d_hi)
    const auto inside = lane_gt(select(lane_lt(d_lo - d_hi, 0.0), d_lo, d_hi), 0.0);
    grad[i] = select(inside, zero - mu / d_lo + mu / d_hi, nan);
    Hdiag[i] = select(inside, zero + mu / (d_lo * d_lo) + mu / (d_hi * d_hi), nan);
    const S logs = select(lane_gt(lo[i], -unbounded), mu * slog(d_lo), zero) +
                   select(lane_lt(hi[i], unbounded), mu * slog(d_hi), zero);
    return select(inside, logs, zero - inf);
  };
  if constexpr (!Team::cooperative) {
    S v = zero;
    for (int i = 0; i < n; ++i) v = v - coordinate(i);
    *value = v;
  } else {
    t.each(n, [&](long i) { terms[i] = coordinate(static_cast<int>(i)); });
    t.one([&] {
      S v = zero;
      for (int i = 0; i < n; ++i) v = v - terms[i];
      *value = v;
    });
  }
}
template <typename S>
RBD_HD S log_barrier(int n, const S* x, const S* lo, const S* hi, S mu, S* grad, S* Hdiag) {
  S value;
  log_barrier(InlineTeam{}, n, x, lo, hi, mu, &value, grad, Hdiag, static_cast<S*>(nullptr));
  return value;
}

}  // namespace rbd
