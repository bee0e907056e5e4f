// rbdkit/algorithms/regressor.hpp — the dynamics as linear maps of the
// inertial parameters π (inertial-parameter regressors).
//
// π stacks 10 parameters per body, in body order, Pinocchio's
// dynamic-parameter order, all in the body frame:
//     π_b = [m, m·c_x, m·c_y, m·c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz]
// with I the rotational inertia about the body-frame origin (Inertia{m, h, I}).
//
//   tau = Y(q, qd, qdd)·π                    Y (nv x 10 nb)
//   ∂tau/∂x_c = dY_dx[c]·π                    dY_dx (2nv x nv x 10 nb), x = [q (tangent); qd]
//   ∂qdd/∂π = -M⁻¹·Y(q, qd, FD(q, qd, u))     (nv x 10 nb)
//   T = y_T·π,  V = y_V·π                      (10 nb)
//
// World coordinates throughout, as in rnea_derivatives.hpp. The world
// inertia oI_b = X_0b* I_b X_0b⁻¹ is linear in π_b, so with e_p the unit
// parameter vector, body b's net world force f_b = oI_b a_b + v_b ×* oI_b v_b
// is Σ_p π_bp f_b(e_p), and
//     Y[j, 10b + p] = s_j · f_b(e_p)      for every DoF j supporting b,
// one dot product per (body, parameter, supporting DoF): O(10·n·d).
//
// The gradient: ∂tau/∂x is linear in π too, and its column for (b, p) is
// the rnea_derivatives backward pass of a model in which only body b carries
// the inertia e_p. Its subtree composites (inertia Ic, momentum hc, force
// Fc, inertia rate Bc) then equal body b's own world quantities on b's
// support and vanish elsewhere, so only the (row, column) pairs inside b's
// support receive terms: O(d²) per (b, p) after one shared forward pass,
// O(10·n·d²) in all (plus clearing the dense output).
#pragma once

#include "rbdkit/algorithms/aba_derivatives.hpp"

namespace rbd {

// ------------------------------------------------------- parameters <-> Inertia
// π_b (10) -> Inertia{m, h, I}
template <typename S> RBD_HD Inertia<S> inertia_from_parameters(const S* pi) {
  Inertia<S> I;
  I.m = pi[0];
  I.h = {pi[1], pi[2], pi[3]};
  I.I = {{pi[4], pi[5], pi[7], pi[5], pi[6], pi[8], pi[7], pi[8], pi[9]}};
  return I;
}

// Inertia{m, h, I} -> π_b (10)
template <typename S> RBD_HD void inertia_to_parameters(const Inertia<S>& I, S* pi) {
  pi[0] = I.m;
  pi[1] = I.h.x; pi[2] = I.h.y; pi[3] = I.h.z;
  pi[4] = I.I(0, 0); pi[5] = I.I(0, 1); pi[6] = I.I(1, 1);
  pi[7] = I.I(0, 2); pi[8] = I.I(1, 2); pi[9] = I.I(2, 2);
}

// the inertia of the unit parameter vector e_p (p in 0..9)
template <typename S> RBD_HD Inertia<S> unit_inertia(int p) {
  S pi[10];
  for (int k = 0; k < 10; ++k) pi[k] = S(0);
  pi[p] = S(1);
  return inertia_from_parameters(pi);
}

// B·m for B = v ×* I - I v× (spatial.hpp's inertia_variation), without forming B
template <typename S> RBD_HD Force<S> inertia_rate(const Inertia<S>& I, const Motion<S>& v, const Motion<S>& m) {
  return cross(v, I * m) - I * cross(v, m);
}

// ------------------------------------------------------------- forward pass
// world placements, subspace columns, velocities and accelerations (gravity
// included); with sens, also the column sensitivities of rnea_derivatives
//   q (nq), qd (nv), qdd (nv or null: zero)
//   writes w.X_parent, w.X_world, w.S_world, w.v, w.a (world frame) [, w.dVdq, w.dAdq, w.dAdv]
template <typename S>
RBD_HD void regressor_forward_pass(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* qdd,
                                   S gravity, bool sens) {
  place_joints(m, w.X_parent, q);
  for (int i = 0; i < m.nb; ++i) {
    placed_world(m, w, i);
    world_motion(m, w, i, qd, qdd, gravity, true, sens);
  }
}

// ----------------------------------------------------------------- regressor
// backward pass: Y[j, 10b + p] = s_j · f_b(e_p) for the DoFs j supporting b,
// f_b(e_p) formed in the body frame (sparse unit inertia) and moved to the world.
//   reads w.X_world, w.S_world, w.v, w.a; writes Y (nv x 10 nb, row-major)
template <typename S> RBD_HD void regressor_backward_pass(const ModelView<S>& m, Workspace<S>& w, S* Y) {
  const int nv = m.nv, np = 10 * m.nb;
  for (int k = 0; k < nv * np; ++k) Y[k] = S(0);
  for (int b = 0; b < m.nb; ++b) {
    const Transform<S>& Xw = w.X_world[b];
    const Motion<S> v = Xw.act_inv(w.v[b]), a = Xw.act_inv(w.a[b]);  // body frame
    for (int p = 0; p < 10; ++p) {
      // net world force of body b carrying the unit parameter e_p
      const Inertia<S> I = unit_inertia<S>(p);
      const Force<S> f = Xw.act(I * a + cross(v, I * v));
      // its joint forces on b's support
      for (int j = b; j >= 0; j = m.body[j].parent) {
        const BodyDesc<S>& bj = m.body[j];
        for (int k = 0; k < bj.nv; ++k) Y[(bj.v_idx + k) * np + 10 * b + p] += dot(w.S_world[6 * j + k], f);
      }
    }
  }
}

// Y (nv x 10 nb, row-major) with tau = Y·π = ID(q, qd, qdd) for the model's π;
// qdd may be null (zero)
template <typename S>
RBD_HD void inverse_dynamics_regressor(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* qdd,
                                       S gravity, S* Y) {
  regressor_forward_pass(m, w, q, qd, qdd, gravity, false);
  regressor_backward_pass(m, w, Y);
}

// ------------------------------------------------------- regressor gradient
// backward pass of the gradient, one (b, p) column at a time: the
// rnea_derivatives backward pass with the composites of body b alone,
// restricted to b's support (see the file comment). With i, j, k on b's
// support, A_i = oI s_i, Bt_i = B s_i - s_i ×* h (B symmetric):
//   rows i, columns k above-or-at i:  dq += dAdq_k·A_i + dVdq_k·Bt_i,  dqd += dAdv_k·A_i + s_k·Bt_i
//   rows j above i, columns i:        dq += s_j·Psi_i,  dqd += s_j·Phi_i
//     Psi_i = s_i ×* f + oI dAdq_i + B dVdq_i + dVdq_i ×* h,  Phi_i = oI dAdv_i + B s_i + s_i ×* h
// reads the forward pass with sens; writes dY (2nv x nv x 10 nb): [c][r][col] =
// ∂Y[r][col]/∂x_c, and Y (nv x 10 nb) when not null
template <typename S>
RBD_HD void regressor_gradient_backward_pass(const ModelView<S>& m, Workspace<S>& w, S* dY, S* Y) {
  const int nv = m.nv, np = 10 * m.nb;
  const long plane = static_cast<long>(nv) * np;  // one x_c
  for (long k = 0; k < 2 * nv * plane; ++k) dY[k] = S(0);
  if (Y)
    for (long k = 0; k < plane; ++k) Y[k] = S(0);
  S* dq = dY;               // [c][r][col], c < nv: ∂/∂q_c
  S* dqd = dY + nv * plane;  // ∂/∂qd_c
  for (int b = 0; b < m.nb; ++b) {
    const Motion<S>& vb = w.v[b];
    for (int p = 0; p < 10; ++p) {
      const int col = 10 * b + p;
      // body b's world inertia, momentum and net force for π_b = e_p
      const Inertia<S> oI = transform_inertia(w.X_world[b], unit_inertia<S>(p));
      const Force<S> h = oI * vb;
      const Force<S> f = oI * w.a[b] + cross(vb, h);
      for (int i = b; i >= 0; i = m.body[i].parent) {
        const BodyDesc<S>& bi = m.body[i];
        const Motion<S>* si = w.S_world + 6 * i;
        // rows of joint i, columns of i and its ancestors k
        for (int a = 0; a < bi.nv; ++a) {
          const int r = bi.v_idx + a;
          const Force<S> A = oI * si[a];
          const Force<S> Bt = inertia_rate(oI, vb, si[a]) - cross(si[a], h);
          if (Y) Y[r * np + col] += dot(si[a], f);
          for (int k = i; k >= 0; k = m.body[k].parent) {
            const BodyDesc<S>& bk = m.body[k];
            for (int c = 0; c < bk.nv; ++c) {
              const long o = (bk.v_idx + c) * plane + r * np + col;
              dq[o] += dot(w.dAdq[6 * k + c], A) + dot(w.dVdq[6 * k + c], Bt);
              dqd[o] += dot(w.dAdv[6 * k + c], A) + dot(w.S_world[6 * k + c], Bt);
            }
          }
        }
        // rows of the strict ancestors j, columns of joint i
        if (bi.parent < 0) continue;
        for (int c = 0; c < bi.nv; ++c) {
          const Motion<S>& dv = w.dVdq[6 * i + c];
          const Force<S> Psi = cross(si[c], f) + oI * w.dAdq[6 * i + c] + inertia_rate(oI, vb, dv) + cross(dv, h);
          const Force<S> Phi = oI * w.dAdv[6 * i + c] + inertia_rate(oI, vb, si[c]) + cross(si[c], h);
          for (int j = bi.parent; j >= 0; j = m.body[j].parent) {
            const BodyDesc<S>& bj = m.body[j];
            for (int a = 0; a < bj.nv; ++a) {
              const long o = (bi.v_idx + c) * plane + (bj.v_idx + a) * np + col;
              dq[o] += dot(w.S_world[6 * j + a], Psi);
              dqd[o] += dot(w.S_world[6 * j + a], Phi);
            }
          }
        }
      }
    }
  }
}

// dY (2nv x nv x 10 nb): dY[c]·π = ∂tau/∂x_c, x = [q (tangent); qd], of
// tau = ID(q, qd, qdd); Y (nv x 10 nb) too when not null. qdd may be null.
template <typename S>
RBD_HD void inverse_dynamics_regressor_gradient(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd,
                                                const S* qdd, S gravity, S* dY, S* Y = nullptr) {
  regressor_forward_pass(m, w, q, qd, qdd, gravity, true);
  regressor_gradient_backward_pass(m, w, dY, Y);
}

// ------------------------------------------------- forward-dynamics gradient
// D (nv x cols, row-major) <- -M⁻¹ D for any number of columns, after
// prepare_minv: apply_neg_minv on blocks of at most max(nv, 6) columns
// (the size of its scratch w.dense2)
template <typename S> RBD_HD void apply_neg_minv_wide(const ModelView<S>& m, Workspace<S>& w, S* D, int cols) {
  if (m.has_mimic) {  // Cholesky solves, one column at a time
    apply_neg_minv(m, w, D, cols);
    return;
  }
  const int nv = m.nv, cap = nv > 6 ? nv : 6;
  const S* Mi = w.dense;
  S* Dc = w.dense2;
  for (int c0 = 0; c0 < cols; c0 += cap) {
    const int cw = cols - c0 < cap ? cols - c0 : cap;
    // copy the block, then out_r = -Σ_k Mi_rk D_k
    for (int r = 0; r < nv; ++r)
      for (int c = 0; c < cw; ++c) Dc[r * cw + c] = D[r * cols + c0 + c];
    for (int r = 0; r < nv; ++r) {
      S* out = D + r * cols + c0;
      for (int c = 0; c < cw; ++c) out[c] = S(0);
      for (int k = 0; k < nv; ++k) {
        const S a = -Mi[r * nv + k];
        const S* row = Dc + k * cw;
        for (int c = 0; c < cw; ++c) out[c] += a * row[c];
      }
    }
  }
}

// ∂qdd/∂π = -M⁻¹ Y(q, qd, qdd) (nv x 10 nb) at qdd = FD(q, qd, u), which is
// written to qdd (nv). false if M is not positive definite.
template <typename S>
RBD_HD bool forward_dynamics_parameter_gradient(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd,
                                                const S* u, S gravity, S* qdd, S* dqdd_dpi) {
  if (!aba(m, w, q, qd, u, static_cast<const S*>(nullptr), gravity, qdd)) return false;
  inverse_dynamics_regressor(m, w, q, qd, qdd, gravity, dqdd_dpi);
  if (!prepare_minv(m, w, q)) return false;
  apply_neg_minv_wide(m, w, dqdd_dpi, 10 * m.nb);
  return true;
}

// ---------------------------------------------------------- energy regressors
// kinetic energy T = Σ_b ½ v_bᵀ I_b v_b = y·π, with v_b = (v, ω) the body
// velocity in the body frame:
//   y_b = ½ [v·v, 2 (v × ω), ω_x², 2 ω_x ω_y, ω_y², 2 ω_x ω_z, 2 ω_y ω_z, ω_z²]
//   writes w.X_parent, w.v (body frame), y (10 nb)
template <typename S>
RBD_HD void kinetic_energy_regressor(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, S* y) {
  const S half = S(0.5);
  place_joints(m, w.X_parent, q);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    // body velocity: v_i = X⁻¹ v_λ + S qd
    const Motion<S> vJ = joint_motion(b, qd + b.v_idx);
    w.v[i] = b.parent >= 0 ? w.X_parent[i].act_inv(w.v[b.parent]) + vJ : vJ;
    const Vec3<S>& v = w.v[i].lin;
    const Vec3<S>& om = w.v[i].ang;
    const Vec3<S> vxw = cross(v, om);
    S* o = y + 10 * i;
    o[0] = half * dot(v, v);
    o[1] = vxw.x; o[2] = vxw.y; o[3] = vxw.z;
    o[4] = half * om.x * om.x; o[5] = om.x * om.y; o[6] = half * om.y * om.y;
    o[7] = om.x * om.z; o[8] = om.y * om.z; o[9] = half * om.z * om.z;
  }
}

// potential energy V = -Σ_b g·(m_b p_b + R_b h_b) = y·π with g = (0, 0, gravity),
// X_world_b = (R_b, p_b): Pinocchio's convention (zero at the world origin)
//   y_b = -gravity [p_b.z, R_b(2, 0), R_b(2, 1), R_b(2, 2), 0, 0, 0, 0, 0, 0]
//   writes w.X_parent, w.X_world, y (10 nb)
template <typename S>
RBD_HD void potential_energy_regressor(const ModelView<S>& m, Workspace<S>& w, const S* q, S gravity, S* y) {
  place_joints(m, w.X_parent, q);
  for (int i = 0; i < m.nb; ++i) {
    placed_world(m, w, i, false);
    const Transform<S>& X = w.X_world[i];
    S* o = y + 10 * i;
    o[0] = -gravity * X.p.z;
    for (int k = 0; k < 3; ++k) o[1 + k] = -gravity * X.R(2, k);
    for (int k = 4; k < 10; ++k) o[k] = S(0);
  }
}

}  // namespace rbd
