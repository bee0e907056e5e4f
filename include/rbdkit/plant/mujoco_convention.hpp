// rbdkit/plant/mujoco_convention.hpp — the MuJoCo output convention:
// MuJoCo's qpos/qvel layout and frames, its retraction (mj_integratePos /
// mj_differentiatePos) with the tangent Jacobians, and the forward dynamics
// in MuJoCo coordinates with its first derivatives (chain rule through
// aba_derivatives). The integrators run on these through MujocoStep.
//
// Layout and frames (R: the rotation of a free joint's quaternion):
//   free joint   qpos [p (3), quaternion w x y z], qvel [ṗ (3); ω (3)]:
//                ṗ = R v_lin is the rate of the position coordinates (the world
//                frame for a root free joint), ω stays in the body frame;
//                generalized force [f (3); τ (3)] with f = R f_body, τ body frame;
//                acceleration d/dt qvel: p̈ = R (a_lin + ω × v_lin), ω̇ as ours
//   ball joint   quaternion w x y z, ω body frame (as ours)
//   other joints unchanged. A model without free or ball joints is unchanged.
//
// Retraction q ⊕ δ (nv): free position p + δp (world, additive), quaternion
// r ⊗ exp(δθ) (body frame), ball the same, others additive; q1 ⊖ q0 its
// inverse. Tangent derivatives of a function of the state are taken along
// this ⊕ (as mjd_transitionFD's A and B).
//
// Relation to the Pinocchio tangent at the same configuration: a MuJoCo
// perturbation δ (nv) is, to first order, the Pinocchio perturbation Cᵀ δ with
// C = blockdiag(R, I3) on each free joint, identity elsewhere; likewise
// v_pin = Cᵀ v_mj, u_pin = Cᵀ u_mj and a_mj = C a_pin + b with
// b = [R (ω × v_lin); 0] per free joint.
#pragma once

#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/model/configuration.hpp"

namespace rbd {

enum OutputConvention : int {
  kPinocchioConvention = 0,
  kMujocoConvention = 1,
};

// ---- layout

// (MuJoCo's quaternion order, load_quat_wxyz / store_quat_wxyz, and quat_offset: joint_types.hpp)

// q_pin (nq, quaternions x y z w) -> q_mj (nq, w x y z); in place allowed
template <typename S> RBD_HD void configuration_to_mujoco(const ModelView<S>& m, const S* q_pin, S* q_mj) {
  for (int k = 0; k < m.nq; ++k) q_mj[k] = q_pin[k];
  for (int i = 0; i < m.nb; ++i) {
    const int o = quat_offset(m.body[i]);
    if (o >= 0) store_quat_wxyz(load_quat(q_pin + o), q_mj + o);
  }
}
// q_mj (nq) -> q_pin (nq); in place allowed
template <typename S> RBD_HD void configuration_from_mujoco(const ModelView<S>& m, const S* q_mj, S* q_pin) {
  for (int k = 0; k < m.nq; ++k) q_pin[k] = q_mj[k];
  for (int i = 0; i < m.nb; ++i) {
    const int o = quat_offset(m.body[i]);
    if (o >= 0) store_quat(load_quat_wxyz(q_mj + o), q_pin + o);
  }
}

// R of the free joint of body b at a MuJoCo configuration
template <typename S> RBD_HD Mat3<S> free_rotation_mj(const BodyDesc<S>& b, const S* q_mj) {
  return to_matrix(load_quat_wxyz(q_mj + b.q_idx + 3));
}

// ---- frames: x (nv) -> y (nv), in place allowed; q_mj (nq) in MuJoCo layout

// C x: free-joint linear parts rotated body -> world (velocities, forces)
template <typename S> RBD_HD void rotate_to_mujoco(const ModelView<S>& m, const S* q_mj, const S* x, S* y) {
  for (int k = 0; k < m.nv; ++k) y[k] = x[k];
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic || b.type != kFree) continue;
    const int o = b.v_idx;
    const Vec3<S> r = free_rotation_mj(b, q_mj) * Vec3<S>{x[o], x[o + 1], x[o + 2]};
    y[o] = r.x; y[o + 1] = r.y; y[o + 2] = r.z;
  }
}
// Cᵀ x: free-joint linear parts rotated world -> body
template <typename S> RBD_HD void rotate_from_mujoco(const ModelView<S>& m, const S* q_mj, const S* x, S* y) {
  for (int k = 0; k < m.nv; ++k) y[k] = x[k];
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic || b.type != kFree) continue;
    const int o = b.v_idx;
    const Vec3<S> r = mul_t(free_rotation_mj(b, q_mj), Vec3<S>{x[o], x[o + 1], x[o + 2]});
    y[o] = r.x; y[o + 1] = r.y; y[o + 2] = r.z;
  }
}
// a_mj = C a_pin + b: the time derivative of qvel from our acceleration a_pin
// at velocity v_pin (both nv, Pinocchio frames); a_mj may alias a_pin
template <typename S>
RBD_HD void acceleration_to_mujoco(const ModelView<S>& m, const S* q_mj, const S* v_pin, const S* a_pin, S* a_mj) {
  for (int k = 0; k < m.nv; ++k) a_mj[k] = a_pin[k];
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic || b.type != kFree) continue;
    const int o = b.v_idx;
    const Vec3<S> lin = {v_pin[o], v_pin[o + 1], v_pin[o + 2]};
    const Vec3<S> w = {v_pin[o + 3], v_pin[o + 4], v_pin[o + 5]};
    const Vec3<S> r = free_rotation_mj(b, q_mj) * (Vec3<S>{a_pin[o], a_pin[o + 1], a_pin[o + 2]} + cross(w, lin));
    a_mj[o] = r.x; a_mj[o + 1] = r.y; a_mj[o + 2] = r.z;
  }
}

// ---- retraction (MuJoCo coordinates)

// each joint's retraction is its type's mj_* (joint_types.hpp)

// q ⊕ v (mj_integratePos with unit step): q (nq), v (nv) -> out (nq)
template <typename S> RBD_HD void mj_integrate(const ModelView<S>& m, const S* q, const S* v, S* out) {
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    visit_joint(b.type, [&](auto J) { J.mj_integrate(q + b.q_idx, v + b.v_idx, out + b.q_idx); });
  }
}

// q1 ⊖ q0 (mj_differentiatePos with unit step): q0, q1 (nq) -> out (nv), q0 ⊕ out = q1
template <typename S> RBD_HD void mj_difference(const ModelView<S>& m, const S* q0, const S* q1, S* out) {
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    visit_joint(b.type, [&](auto J) { J.mj_difference(q0 + b.q_idx, q1 + b.q_idx, out + b.v_idx); });
  }
}

// arg 0: ∂(q ⊕ v)/∂q, arg 1: ∂(q ⊕ v)/∂v, in the MuJoCo tangent. J (nv x nv), block diagonal
template <typename S> RBD_HD void mj_dintegrate(const ModelView<S>& m, const S* q, const S* v, int arg, S* J) {
  (void)q;
  const int nv = m.nv;
  for (int k = 0; k < nv * nv; ++k) J[k] = S(0);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    const int o = b.v_idx;
    visit_joint(b.type, [&](auto JT) { JT.mj_dintegrate(v + o, arg, J + o * nv + o, nv); });
  }
}

// arg 0: ∂(q1 ⊖ q0)/∂q0, arg 1: ∂(q1 ⊖ q0)/∂q1, MuJoCo tangent. J (nv x nv), block diagonal
template <typename S> RBD_HD void mj_ddifference(const ModelView<S>& m, const S* q0, const S* q1, int arg, S* J) {
  const int nv = m.nv;
  for (int k = 0; k < nv * nv; ++k) J[k] = S(0);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    const int o = b.v_idx;
    visit_joint(b.type, [&](auto JT) { JT.mj_ddifference(q0 + b.q_idx, q1 + b.q_idx, arg, J + o * nv + o, nv); });
  }
}

// ---- forward dynamics in MuJoCo coordinates

// scratch values (of type S) of mujoco_acceleration / mujoco_acceleration_derivatives
RBD_HD long mujoco_acceleration_scratch_values(int nq, int nv) { return nq + 3L * nv; }

// a_mj = d/dt qvel at (q_mj, v_mj) under the generalized force u_mj (MuJoCo
// frames) and body-local fext (nb x 6, may be null). false if M is not PD
template <typename S>
RBD_HD bool mujoco_acceleration(const ModelView<S>& m, Workspace<S>& w, const S* q_mj, const S* v_mj, const S* u_mj,
                                const S* fext, S gravity, S* a_mj, S* scratch) {
  S* q = scratch;        // (nq) Pinocchio configuration
  S* v = q + m.nq;       // (nv) Pinocchio velocity
  S* u = v + m.nv;       // (nv) Pinocchio generalized force
  S* a = u + m.nv;       // (nv) Pinocchio acceleration
  configuration_from_mujoco(m, q_mj, q);
  rotate_from_mujoco(m, q_mj, v_mj, v);
  rotate_from_mujoco(m, q_mj, u_mj, u);
  if (!aba(m, w, q, v, u, fext, gravity, a)) return false;
  acceleration_to_mujoco(m, q_mj, v, a, a_mj);
  return true;
}

// rows r0..r0+2 of an (nv x cols) matrix: F ← R F
template <typename S> RBD_HD void rotate_rows(const Mat3<S>& R, S* F, int r0, int cols) {
  for (int c = 0; c < cols; ++c) {
    const Vec3<S> x = R * Vec3<S>{F[r0 * cols + c], F[(r0 + 1) * cols + c], F[(r0 + 2) * cols + c]};
    F[r0 * cols + c] = x.x; F[(r0 + 1) * cols + c] = x.y; F[(r0 + 2) * cols + c] = x.z;
  }
}
// columns c0..c0+2 of an (rows x nv) matrix: F ← F Rᵀ
template <typename S> RBD_HD void rotate_cols_t(const Mat3<S>& R, S* F, int c0, int rows, int nv) {
  for (int r = 0; r < rows; ++r) {
    S* f = F + r * nv + c0;
    const Vec3<S> x = R * Vec3<S>{f[0], f[1], f[2]};  // (F Rᵀ) row = R · row
    f[0] = x.x; f[1] = x.y; f[2] = x.z;
  }
}
// (rows x nv) block: F[:, c0:c0+3] += G[:, g0:g0+3] K, K (3 x 3)
template <typename S> RBD_HD void add_cols_times(const S* G, int g0, const Mat3<S>& K, S* F, int c0, int rows, int nv) {
  for (int r = 0; r < rows; ++r) {
    const S* g = G + r * nv + g0;
    for (int c = 0; c < 3; ++c) F[r * nv + c0 + c] += g[0] * K(0, c) + g[1] * K(1, c) + g[2] * K(2, c);
  }
}

// J (rows x nv) taken along the Pinocchio tangent -> along the MuJoCo tangent
// at the same configuration: J ← J Cᵀ (free-joint linear columns)
template <typename S> RBD_HD void jacobian_cols_to_mujoco(const ModelView<S>& m, const S* q_mj, S* J, int rows) {
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic || b.type != kFree) continue;
    rotate_cols_t(free_rotation_mj(b, q_mj), J, b.v_idx, rows, m.nv);
  }
}
// F (nv x cols) whose rows are Pinocchio generalized forces or velocities -> MuJoCo's
// at the same configuration: F ← C F (free-joint linear rows)
template <typename S> RBD_HD void rows_to_mujoco(const ModelView<S>& m, const S* q_mj, S* F, int cols) {
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic || b.type != kFree) continue;
    rotate_rows(free_rotation_mj(b, q_mj), F, b.v_idx, cols);
  }
}
// the configuration dependence of x_pin = Cᵀ x_mj at fixed x_mj (a velocity or
// force; x_pin (nv) in Pinocchio frames): for F = ∂y/∂x_pin (rows x nv),
// Jq (rows x nv) += F ∂x_pin/∂δq, i.e. on each free joint's angle columns
// Jq[:, θ] += F[:, lin] [x_lin]×
template <typename S>
RBD_HD void add_frame_dependence(const ModelView<S>& m, const S* x_pin, const S* F, S* Jq, int rows) {
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic || b.type != kFree) continue;
    const int o = b.v_idx;
    add_cols_times(F, o, skew(Vec3<S>{x_pin[o], x_pin[o + 1], x_pin[o + 2]}), Jq, o + 3, rows, m.nv);
  }
}

// a_mj and its derivatives in MuJoCo coordinates: Fq = ∂a/∂δq (tangent ⊕ above),
// Fv = ∂a/∂v, Fu = ∂a/∂u, each (nv x nv, row-major). false if M is not PD.
//   Fq = C (F_q Cᵀ + F_v V + M⁻¹ U) + ∂(C a_pin + b)/∂δq,   Fv = C F_v Cᵀ + ∂b/∂v,   Fu = C M⁻¹ Cᵀ
// with V = ∂v_pin/∂δθ = [v_lin]×, U = ∂u_pin/∂δθ = [f_lin]× on each free joint
template <typename S>
RBD_HD bool mujoco_acceleration_derivatives(const ModelView<S>& m, Workspace<S>& w, const S* q_mj, const S* v_mj,
                                            const S* u_mj, const S* fext, S gravity, S* a_mj, S* Fq, S* Fv, S* Fu,
                                            S* scratch) {
  const int nv = m.nv;
  S* q = scratch;
  S* v = q + m.nq;
  S* u = v + nv;
  S* a = u + nv;
  configuration_from_mujoco(m, q_mj, q);
  rotate_from_mujoco(m, q_mj, v_mj, v);
  rotate_from_mujoco(m, q_mj, u_mj, u);
  // Pinocchio-frame derivatives; aba_derivatives leaves M⁻¹ (or its factor) in w
  if (!aba_derivatives(m, w, q, v, u, fext, gravity, a, Fq, Fv)) return false;
  copy_minv(m, w, Fu);  // M⁻¹
  acceleration_to_mujoco(m, q_mj, v, a, a_mj);
  // the input conversions' configuration dependence, then Cᵀ on the columns
  add_frame_dependence(m, v, Fv, Fq, nv);
  add_frame_dependence(m, u, Fu, Fq, nv);
  jacobian_cols_to_mujoco(m, q_mj, Fq, nv);
  jacobian_cols_to_mujoco(m, q_mj, Fv, nv);
  jacobian_cols_to_mujoco(m, q_mj, Fu, nv);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic || b.type != kFree) continue;
    const int o = b.v_idx;
    // C on the rows
    const Mat3<S> R = free_rotation_mj(b, q_mj);
    rotate_rows(R, Fq, o, nv);
    rotate_rows(R, Fv, o, nv);
    rotate_rows(R, Fu, o, nv);
    // the output conversion's own derivatives: a_mj,lin = R (a_lin + ω × v_lin)
    const Vec3<S> lin = {v[o], v[o + 1], v[o + 2]};
    const Vec3<S> om = {v[o + 3], v[o + 4], v[o + 5]};
    const Mat3<S> Wl = skew(lin), Wo = skew(om);
    // ∂/∂δθ at fixed qvel: -R [a_lin]× (from R) + R [v_lin]× [ω]× (from ω_world × ṗ)
    const Vec3<S> al = Vec3<S>{a[o], a[o + 1], a[o + 2]};
    const Mat3<S> dth = R * (Wl * Wo - skew(al));
    const Mat3<S> dvl = R * Wo * transpose(R);  // ∂/∂ṗ
    const Mat3<S> dom = S(-1) * (R * Wl);       // ∂/∂ω
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        Fq[(o + r) * nv + o + 3 + c] += dth(r, c);
        Fv[(o + r) * nv + o + c] += dvl(r, c);
        Fv[(o + r) * nv + o + 3 + c] += dom(r, c);
      }
  }
  return true;
}

}  // namespace rbd
