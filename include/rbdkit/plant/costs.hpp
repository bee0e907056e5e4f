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
#pragma once

#include "rbdkit/algorithms/centroidal.hpp"
#include "rbdkit/algorithms/kinematics.hpp"
#include "rbdkit/model/configuration.hpp"
#include "rbdkit/plant/mujoco_convention.hpp"

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

// --------------------------------------------------------- centroidal tracking costs
// q (and qd) in the convention's layout and frames; the tangent blocks along its ⊕.

// scratch values of ee_pos_cost: q in Pinocchio's layout (nq), the pose (6) and its gradient (6 x nv)
RBD_HD constexpr long ee_pos_cost_scratch(int nq, int nv) { return nq + 6 + 6L * nv; }

// ½ Σ W (p(q) - p_des)² for the point at `offset` (3, body frame; null: the
// origin) on `body` (W, p_des (3)): value, grad (NX), Gauss–Newton H (NX x NX)
// embedded as residual_cost_embedded's; the position rows of the end-effector
// pose gradient are the residual's Jacobian
template <typename S>
RBD_HD void ee_pos_cost(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* p_des, const S* W, int body,
                        const S* offset, int convention, S* value, S* grad, S* H, S* scratch) {
  const S* qp = q;
  S* pose = scratch + m.nq;
  S* G = pose + 6;
  if (convention == kMujocoConvention) {
    configuration_from_mujoco(m, q, scratch);
    qp = scratch;
  }
  const Vec3<S> o = offset ? Vec3<S>{offset[0], offset[1], offset[2]} : Vec3<S>::zero();
  forward_kinematics(m, w, qp, static_cast<const S*>(nullptr));
  end_effector_pose(w, body, o, pose);
  end_effector_pose_gradient(m, w, body, o, G);
  if (convention == kMujocoConvention) jacobian_cols_to_mujoco(m, q, G, 6);
  S r[3];
  for (int k = 0; k < 3; ++k) r[k] = pose[k] - p_des[k];
  *value = residual_cost_embedded(3, r, W, G, m.nq, m.nv, grad, H);
}

// scratch values of com_cost: q in Pinocchio's layout (nq), J_com (3 x nv)
RBD_HD constexpr long com_cost_scratch(int nq, int nv) { return nq + 3L * nv; }

// ½ Σ W (com(q) - p_des)² (W, p_des (3)): value, grad (NX), Gauss–Newton H (NX x NX)
// embedded as residual_cost_embedded's. false if the robot has no mass
template <typename S>
RBD_HD bool com_cost(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* p_des, const S* W, int convention,
                     S* value, S* grad, S* H, S* scratch) {
  const S* qp = q;
  S* J = scratch + m.nq;
  if (convention == kMujocoConvention) {
    configuration_from_mujoco(m, q, scratch);
    qp = scratch;
  }
  S c[3];
  if (!center_of_mass(m, w, qp, c) || !jacobian_com(m, w, qp, J)) return false;
  if (convention == kMujocoConvention) jacobian_cols_to_mujoco(m, q, J, 3);
  S r[3];
  for (int k = 0; k < 3; ++k) r[k] = c[k] - p_des[k];
  *value = residual_cost_embedded(3, r, W, J, m.nq, m.nv, grad, H);
  return true;
}

// scratch values of momentum_cost: q, qd in Pinocchio's layout and frames,
// A, h, dA, J = [Jq | Jv] (6 x 2nv), Jq
RBD_HD constexpr long momentum_cost_scratch(int nq, int nv) { return nq + 6 + 25L * nv + 6L * nv * nv; }

// ½ Σ W r² with r = A(q)·qd - h_des (W, h_des (6)): value, grad Jᵀ W r (2nv),
// Gauss–Newton H = Jᵀ W J (2nv x 2nv), J = [(∂A/∂q)·qd | A] in the tangent
// [δq | δqd]. MuJoCo convention: qd is rotated to Pinocchio's frames inside r,
// and J keeps that rotation's configuration dependence. false without mass
template <typename S>
RBD_HD bool momentum_cost(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* h_des, const S* W,
                          int convention, S* value, S* grad, S* H, S* scratch) {
  const int nv = m.nv, n2 = 2 * nv;
  S* qp = scratch;
  S* vp = qp + m.nq;
  S* A = vp + nv;
  S* h = A + 6 * nv;
  S* dA = h + 6;
  S* J = dA + 6 * nv * nv;
  S* Jq = J + 6 * n2;
  const S* qs = q;
  const S* vs = qd;
  if (convention == kMujocoConvention) {
    configuration_from_mujoco(m, q, qp);
    rotate_from_mujoco(m, q, qd, vp);  // qd in MuJoCo's frames -> Pinocchio's
    qs = qp;
    vs = vp;
  }
  if (!ccrba(m, w, qs, vs, A, h) || !dccrba(m, w, qs, Jq, dA)) return false;  // Jq: dccrba's copy of A
  // J = [(∂A/∂q) qd | A]: column k of the first block is Σ_j dA[r][j][k] qd_j
  for (int r = 0; r < 6; ++r)
    for (int k = 0; k < nv; ++k) {
      S acc = S(0);
      for (int j = 0; j < nv; ++j) acc += dA[(r * nv + j) * nv + k] * vs[j];
      J[r * n2 + k] = acc;
      J[r * n2 + nv + k] = A[r * nv + k];
    }
  if (convention == kMujocoConvention) {
    // MuJoCo tangent: Jq ← (Jq + A ∂v_pin/∂δq) Cᵀ, Jv ← A Cᵀ
    for (int r = 0; r < 6; ++r)
      for (int k = 0; k < nv; ++k) Jq[r * nv + k] = J[r * n2 + k];
    add_frame_dependence(m, vs, A, Jq, 6);
    jacobian_cols_to_mujoco(m, q, Jq, 6);
    jacobian_cols_to_mujoco(m, q, A, 6);
    for (int r = 0; r < 6; ++r)
      for (int k = 0; k < nv; ++k) J[r * n2 + k] = Jq[r * nv + k], J[r * n2 + nv + k] = A[r * nv + k];
  }
  S res[6];
  for (int r = 0; r < 6; ++r) res[r] = h[r] - h_des[r];
  S v = S(0);
  for (int r = 0; r < 6; ++r) v += S(0.5) * W[r] * res[r] * res[r];
  *value = v;
  for (int c = 0; c < n2; ++c) {
    S acc = S(0);
    for (int r = 0; r < 6; ++r) acc += J[r * n2 + c] * W[r] * res[r];
    grad[c] = acc;
    for (int c2 = 0; c2 < n2; ++c2) {
      S hh = S(0);
      for (int r = 0; r < 6; ++r) hh += J[r * n2 + c] * W[r] * J[r * n2 + c2];
      H[c * n2 + c2] = hh;
    }
  }
  return true;
}

// -mu Σ [log(x - lo) + log(hi - x)], skipping infinite bounds. grad (n), Hdiag (n).
// Outside the open interval the value is +inf and that coordinate's gradient
// and Hessian entries are NaN (a line search rejects the point; nothing is
// silently clipped). Branch-free (select), so that SIMD lanes may differ: an
// infinite bound gives d = inf, whose terms mu/d and mu/d² are exactly 0.
template <typename S>
RBD_HD S log_barrier(int n, const S* x, const S* lo, const S* hi, S mu, S* grad, S* Hdiag) {
  const double unbounded = 1.0 / 0.0;
  const S zero = S(0), inf = S(1) / S(0), nan = S(0) / S(0);
  S value = S(0);
  for (int i = 0; i < n; ++i) {
    const S d_lo = x[i] - lo[i], d_hi = hi[i] - x[i];
    // inside: min(d_lo, d_hi) > 0 (two infinite bounds: inf - inf is NaN, not < 0, so d_hi)
    const auto inside = lane_gt(select(lane_lt(d_lo - d_hi, 0.0), d_lo, d_hi), 0.0);
    value = value - select(lane_gt(lo[i], -unbounded), mu * slog(d_lo), zero);
    value = value - select(lane_lt(hi[i], unbounded), mu * slog(d_hi), zero);
    value = select(inside, value, inf);  // and inf from here on
    grad[i] = select(inside, zero - mu / d_lo + mu / d_hi, nan);
    Hdiag[i] = select(inside, zero + mu / (d_lo * d_lo) + mu / (d_hi * d_hi), nan);
  }
  return value;
}

}  // namespace rbd
