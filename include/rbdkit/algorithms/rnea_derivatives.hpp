// rbdkit/algorithms/rnea_derivatives.hpp — analytical first derivatives of
// inverse dynamics, ∂tau/∂q and ∂tau/∂qd, in O(n·d) (d: tree depth), after
// Carpentier & Mansard, "Analytical derivatives of rigid body dynamics
// algorithms" (RSS 2018), in world coordinates (or, by default in rnea_derivatives,
// a free root's frame: world.hpp).
//
// In the world frame a tangent step δ on DoF k moves the whole subtree of k
// rigidly with the twist s_k δ. Every world quantity attached to that subtree
// then changes by s_k × (·), which cancels in tau_j = s_j·F_j for j in the
// subtree; what remains are the sensitivities of the DoF columns
//     dVdq_k = v_λ × s_k,   dAdq_k = a_λ × s_k + v_λ × dVdq_k,
//     dAdv_k = v_k × s_k + dVdq_k
// acting through the subtree composites Ic (inertia), Bc = Σ(v ×* I - I v×)
// and hc (momentum):
//     j in subtree(k):   ∂tau_j/∂q_k  = dAdq_k · Ic_j s_j + dVdq_k · Bt_j
//                        ∂tau_j/∂qd_k = dAdv_k · Ic_j s_j + s_k · Bt_j,
//                        Bt_j = Bc_jᵀ s_j - s_j ×* hc_j
//     j above k:         ∂tau_j/∂q_k  = s_j · (s_k ×* F_k + Ic_k dAdq_k + Bc_k dVdq_k + dVdq_k ×* hc_k)
//                        ∂tau_j/∂qd_k = s_j · (Ic_k dAdv_k + Bc_k s_k + s_k ×* hc_k)
// Derivatives are in the tangent space (q ← integrate(q, δ)); mimic bodies
// add their terms into their target's column (the reduced derivative).
#pragma once

#include "rbdkit/algorithms/world.hpp"

namespace rbd {

// body i's momentum, net force and inertia variation in the reference frame (world.hpp), from its
// inertia w.Ic, velocity and acceleration there.  writes w.h, w.f, w.B of body i
template <typename S>
RBD_HD void rnea_derivatives_body_terms(const ModelView<S>&, Workspace<S>& w, int i, const S* fext) {
  const Inertia<S>& oI = w.Ic[i];
  w.h[i] = oI * w.v[i];
  w.f[i] = oI * w.a[i] + cross(w.v[i], w.h[i]);
  if (fext) w.f[i] -= w.X_world[i].act(load_force(fext + 6 * i));
  w.B[i] = inertia_variation(oI, w.v[i]);
}

// forward pass: placements, subspace columns, velocities, accelerations, column sensitivities, and
// per-body inertia, momentum, force and B, in the reference frame (world.hpp: the world's when
// leave_world, else a free root's).
//   q (nq), qd (nv), qdd (nv or null), fext (nb x 6 body frame or null); placed:
//   w.X_parent, w.X_world, w.S_world and w.Ic (the body inertias) already hold q's
//   placement in that frame (minv_backward_pass leaves them so, given the same leave_world),
//   which is then not redone
//   writes w.X_parent, w.X_world, w.S_world, w.v, w.a (gravity included), w.dVdq,
//   w.dAdq, w.dAdv, w.Ic, w.h, w.f, w.B
template <typename S>
RBD_HD void rnea_derivatives_forward_pass(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd,
                                          const S* qdd, const S* fext, S gravity, bool placed,
                                          bool leave_world) {
  if (!placed) place_joints(m, w.X_parent, q);
  RBD_UNROLL
  for (int i = 0; i < m.nb; ++i) {
    // placement, subspace, velocity, acceleration, column sensitivities
    if (!placed) placed_world(m, w, i, true, leave_world);
    world_motion(m, w, i, qd, qdd, gravity, true, true, leave_world);
    if (!placed) w.Ic[i] = reference_inertia(m, w, i, leave_world);
    rnea_derivatives_body_terms(m, w, i, fext);
  }
}

// rnea_derivatives_forward_pass on a team (model/team.hpp): the placements (world_placements_team,
// unless placed) and each joint's own motion side by side, the velocity and acceleration chain on one
// thread (a few additions and a cross product per body), then each body's sensitivities and inertia
// terms side by side. The same values, each in the same order
template <typename S, typename Team>
RBD_HD void rnea_derivatives_forward_team(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q,
                                          const S* qd, const S* qdd, const S* fext, S gravity, bool placed,
                                          bool leave_world) {
  // vJ = s qd and aJ = s qdd, parked in w.v and w.a until the chain adds the parent's motion
  auto own_motion = [&](int i) { world_joint_motion(m, w, i, qd, qdd, true, w.v[i], w.a[i]); };
  if (placed) {
    t.each(m.nb, [&](long i) { own_motion(static_cast<int>(i)); });
  } else {
    world_placements_team(
        t, m, w, q, true,
        [&](int i) {
          w.Ic[i] = reference_inertia(m, w, i, leave_world);
          own_motion(i);
        },
        leave_world);
  }
  t.one([&] {  // v_i = v_λ + vJ, a_i = a_λ + aJ + v_i × vJ, parents first
    RBD_UNROLL
    for (int i = 0; i < m.nb; ++i) {
      Motion<S> vp, ap;
      parent_motion(m, w, i, gravity, true, vp, ap, leave_world);
      const Motion<S> vJ = w.v[i];
      w.v[i] = vp + vJ;
      w.a[i] = ap + w.a[i] + cross(w.v[i], vJ);
    }
  });
  t.each(m.nb, [&](long i_) {
    const int i = static_cast<int>(i_);
    Motion<S> vp, ap;
    parent_motion(m, w, i, gravity, true, vp, ap, leave_world);
    motion_sensitivities(m, w, i, vp, ap);
    rnea_derivatives_body_terms(m, w, i, fext);
  });
}

// subtree composites: w.Ic, w.h, w.f and w.B of each body become its subtree's
// sums (children before parents), what the derivative entries read
template <typename S> RBD_HD void rnea_derivatives_composites(const ModelView<S>& m, Workspace<S>& w) {
  RBD_UNROLL
  for (int i = m.nb - 1; i >= 0; --i) {
    const int p = m.body[i].parent;
    if (p < 0) continue;
    w.Ic[p] += w.Ic[i];
    w.h[p] += w.h[i];
    w.f[p] += w.f[i];
    w.B[p] += w.B[i];
  }
}

// the derivative entries that body i owns, after the composites: the rows of
// joint i in the columns of i and its ancestors, and the rows of i's strict
// ancestors in the columns of i (tau's entries of joint i too, when not null).
// Bodies own disjoint entries on a model without mimic joints, so they may
// run in any order, or side by side (rbdkit/cuda/team_kernels.cuh); a mimic body
// adds into its target's entries, so there they run one after another. Adds
// into dtau_dq, dtau_dqd (nv x nv, row-major) and tau (nv)
template <typename S>
RBD_HD void rnea_derivatives_body(const ModelView<S>& m, const Workspace<S>& w, int i, S* dtau_dq, S* dtau_dqd,
                                  S* tau) {
  const int nv = m.nv;
  const BodyDesc<S>& bi = m.body[i];
  const Motion<S>* si = w.S_world + 6 * i;
  // rows of joint i, columns of i and its ancestors k:
  //   ∂tau_i/∂q_k = dAdq_k · A_i + dVdq_k · Bt_i,  ∂tau_i/∂qd_k = dAdv_k · A_i + s_k · Bt_i
  Force<S> A[6], Bt[6];
  for (int a = 0; a < bi.nv; ++a) {
    A[a] = w.Ic[i] * si[a];
    Bt[a] = w.B[i] * si[a] - cross(si[a], w.h[i]);  // Bcᵀ s = Bc s (symmetric)
    if (tau) tau[bi.v_idx + a] += dot(si[a], w.f[i]);
  }
  for (int k = i; k >= 0; k = m.body[k].parent) {
    const BodyDesc<S>& bk = m.body[k];
    for (int a = 0; a < bi.nv; ++a)
      for (int c = 0; c < bk.nv; ++c) {
        const int r = (bi.v_idx + a) * nv + bk.v_idx + c;
        dtau_dq[r] += dot(w.dAdq[6 * k + c], A[a]) + dot(w.dVdq[6 * k + c], Bt[a]);
        dtau_dqd[r] += dot(w.dAdv[6 * k + c], A[a]) + dot(w.S_world[6 * k + c], Bt[a]);
      }
  }
  // rows of the strict ancestors j, columns of joint i:
  //   ∂tau_j/∂q_i = s_j · Psi_i,  ∂tau_j/∂qd_i = s_j · Phi_i
  if (bi.parent < 0) return;
  Force<S> Psi[6], Phi[6];
  for (int c = 0; c < bi.nv; ++c) {
    const Motion<S>& dv = w.dVdq[6 * i + c];
    Psi[c] = cross(si[c], w.f[i]) + w.Ic[i] * w.dAdq[6 * i + c] + w.B[i] * dv + cross(dv, w.h[i]);
    Phi[c] = w.Ic[i] * w.dAdv[6 * i + c] + w.B[i] * si[c] + cross(si[c], w.h[i]);
  }
  for (int j = bi.parent; j >= 0; j = m.body[j].parent) {
    const BodyDesc<S>& bj = m.body[j];
    for (int a = 0; a < bj.nv; ++a)
      for (int c = 0; c < bi.nv; ++c) {
        const int r = (bj.v_idx + a) * nv + bi.v_idx + c;
        dtau_dq[r] += dot(w.S_world[6 * j + a], Psi[c]);
        dtau_dqd[r] += dot(w.S_world[6 * j + a], Phi[c]);
      }
  }
}

// backward pass: subtree composites and the two derivative matrices.
//   writes dtau_dq, dtau_dqd (nv x nv, row-major), tau (nv, or null), and
//   turns w.Ic, w.h, w.f, w.B into subtree sums
template <typename S>
RBD_HD void rnea_derivatives_backward_pass(const ModelView<S>& m, Workspace<S>& w, S* dtau_dq, S* dtau_dqd,
                                           S* tau) {
  const int nv = m.nv;
  for (int k = 0; k < nv * nv; ++k) dtau_dq[k] = S(0), dtau_dqd[k] = S(0);
  if (tau)
    for (int k = 0; k < nv; ++k) tau[k] = S(0);
  rnea_derivatives_composites(m, w);
  RBD_UNROLL
  for (int i = m.nb - 1; i >= 0; --i) rnea_derivatives_body(m, w, i, dtau_dq, dtau_dqd, tau);
}

// ∂tau/∂q and ∂tau/∂qd (nv x nv each, row-major) of tau = ID(q, qd, qdd, f_ext);
// qdd and fext may be null (zero). tau (nv) is written too when not null.
// placed, leave_world: as rnea_derivatives_forward_pass's (here a tree with a free root is in the
// root's frame by default: the derivatives do not depend on the frame, and no lever arm there is
// longer than the robot)
template <typename S> RBD_FLATTEN
RBD_HD void rnea_derivatives(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* qdd,
                             const S* fext, S gravity, S* dtau_dq, S* dtau_dqd, S* tau = nullptr,
                             bool placed = false, bool leave_world = false) {
  rnea_derivatives_forward_pass(m, w, q, qd, qdd, fext, gravity, placed, leave_world);
  rnea_derivatives_backward_pass(m, w, dtau_dq, dtau_dqd, tau);
}

// rnea_derivatives on a team of threads (model/team.hpp; the GPU's team kernels), for a model without
// mimic joints: the forward pass split (rnea_derivatives_forward_team), the four composite sums side
// by side, then each body's entries side by side (bodies own disjoint entries there). The same
// results; tau is not computed. An InlineTeam runs the serial passes
template <typename S, typename Team>
RBD_HD void rnea_derivatives_team(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd,
                                  const S* qdd, const S* fext, S gravity, S* dtau_dq, S* dtau_dqd,
                                  bool placed = false, bool leave_world = false) {
  t.each(static_cast<long>(m.nv) * m.nv, [&](long k) { dtau_dq[k] = S(0), dtau_dqd[k] = S(0); });
  if constexpr (!Team::cooperative) {
    rnea_derivatives_forward_pass(m, w, q, qd, qdd, fext, gravity, placed, leave_world);
    rnea_derivatives_composites(m, w);
  } else {
    rnea_derivatives_forward_team(t, m, w, q, qd, qdd, fext, gravity, placed, leave_world);
    t.each(4, [&](long part) {  // the composites, each of the four sums on its own thread
      RBD_UNROLL
      for (int i = m.nb - 1; i >= 0; --i) {
        const int p = m.body[i].parent;
        if (p < 0) continue;
        if (part == 0) w.Ic[p] += w.Ic[i];
        else if (part == 1) w.h[p] += w.h[i];
        else if (part == 2) w.f[p] += w.f[i];
        else w.B[p] += w.B[i];
      }
    });
  }
  t.each(m.nb, [&](long i) {
    rnea_derivatives_body(m, w, static_cast<int>(i), dtau_dq, dtau_dqd, static_cast<S*>(nullptr));
  });
}

// per-body DoF columns (6 per body, as w.S_world) <-> an (nb x 6 x 6) array whose
// [b][r][a] is row r of column a of body b (zeros beyond the joint's nv): the
// per-pass helpers' layout
template <typename S> RBD_HD void store_dof_columns(const ModelView<S>& m, const Motion<S>* cols, S* out) {
  for (int b = 0; b < m.nb; ++b)
    for (int a = 0; a < 6; ++a) {
      S x[6];
      for (int r = 0; r < 6; ++r) x[r] = S(0);
      if (a < m.body[b].nv) store(cols[6 * b + a], x);
      for (int r = 0; r < 6; ++r) out[(b * 6 + r) * 6 + a] = x[r];
    }
}
template <typename S> RBD_HD void load_dof_columns(const ModelView<S>& m, const S* in, Motion<S>* cols) {
  for (int b = 0; b < m.nb; ++b)
    for (int a = 0; a < m.body[b].nv; ++a) {
      S x[6];
      for (int r = 0; r < 6; ++r) x[r] = in[(b * 6 + r) * 6 + a];
      cols[6 * b + a] = load_motion(x);
    }
}

}  // namespace rbd
