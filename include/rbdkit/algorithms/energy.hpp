// rbdkit/algorithms/energy.hpp — kinetic, potential and mechanical energy,
// and the Coriolis matrix C(q, qd) in the Christoffel-consistent
// factorisation (Ṁ - 2C skew-symmetric) that Pinocchio's
// computeCoriolisMatrix computes, after Echeandia & Wensing, "Numerical
// methods to compute the Coriolis matrix and Christoffel symbols for
// rigid-body systems" (JCND 2021), in world coordinates.
//
//   T = ½ Σ v_iᵀ I_i v_i            (body velocities and inertias, any frame)
//   V = -Σ m_i g·c_i,  g = (0, 0, gravity), c_i the world centre of mass of body i
//
// Coriolis matrix. With world columns s, their rates ṡ = v_body × s, and per
// body the matrix B_i = ½ (v_i ×* I_i - I_i v_i×) + ½ (· ×* h_i) (h_i = I_i v_i),
// summed over subtrees into composites Ic_d, Bc_d, the entry of DoF a
// (body i) and DoF b (body k) on one branch is
//     C_ab = s_a · (Ic_d ṡ_b + Bc_d s_b),    d = the deeper of i and k
// and zero for bodies on different branches. C·qd + g = nonlinear effects.
// Mimic bodies add their terms into their target's column (Gᵀ C G).
#pragma once

#include "rbdkit/algorithms/kinematics.hpp"
#include "rbdkit/algorithms/rnea_derivatives.hpp"

namespace rbd {

// ------------------------------------------------------------------ energies

// T(q, qd) = ½ Σ v_i · I_i v_i, body frame.   writes w.X_parent, w.X_world, w.v
template <typename S> RBD_HD S kinetic_energy(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd) {
  forward_kinematics(m, w, q, qd);
  S T = S(0);
  for (int i = 0; i < m.nb; ++i) T += dot(w.v[i], m.body[i].I * w.v[i]);
  return S(0.5) * T;
}

// V(q) = -gravity Σ m_i z(c_i), c_i = X_world_i (h_i / m_i).   writes w.X_parent, w.X_world
template <typename S> RBD_HD S potential_energy(const ModelView<S>& m, Workspace<S>& w, const S* q, S gravity) {
  forward_kinematics(m, w, q, static_cast<const S*>(nullptr));
  S mz = S(0);
  for (int i = 0; i < m.nb; ++i) {
    const Inertia<S>& I = m.body[i].I;
    // world first moment m c = R h + m p; its z component
    mz += (w.X_world[i].R * I.h).z + I.m * w.X_world[i].p.z;
  }
  return -gravity * mz;
}

// ------------------------------------------------------------------ Coriolis

// forward pass, world frame: placements, columns s, velocities v, and per
// body the inertia Ic, momentum h = Ic v and B = v ×* Ic - Ic v×.
//   writes w.X_parent, w.X_world, w.S_world, w.v (world), w.Ic, w.h, w.B (per body)
template <typename S>
RBD_HD void momentum_forward_pass(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd) {
  place_joints(m, w.X_parent, q);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    // X_0i = X_0λ X_λi, s = X_0i S, v_i = v_λ + s qd
    placed_world(m, w, i);
    world_motion(m, w, i, qd, static_cast<const S*>(nullptr), S(0), false, false);
    const Motion<S>& v = w.v[i];
    // body inertia, momentum and inertia rate in the world frame
    w.Ic[i] = transform_inertia(w.X_world[i], b.I);
    w.h[i] = w.Ic[i] * v;
    w.B[i] = inertia_variation(w.Ic[i], v);
  }
}

// backward pass: composites Ic, h, B, and the Coriolis entries of every body
// pair on one branch, at the deeper body d (Bc = ½ (B + · ×* hc)):
//   columns of d, rows of d and its ancestors e:  C[e, d] = s_e · (Ic ṡ_d + Bc s_d)
//   rows of d, columns of its strict ancestors e: C[d, e] = (Ic s_d) · ṡ_e + (Bcᵀ s_d) · s_e,
//                                                 Bcᵀ s = ½ (Bᵀ s - s ×* hc)
// writes C (nv x nv, row-major); w.Ic, w.h, w.B become subtree sums
template <typename S> RBD_HD void coriolis_backward_pass(const ModelView<S>& m, Workspace<S>& w, S* C) {
  const int nv = m.nv;
  for (int k = 0; k < nv * nv; ++k) C[k] = S(0);
  for (int d = m.nb - 1; d >= 0; --d) {
    const BodyDesc<S>& bd = m.body[d];
    const Motion<S>* sd = w.S_world + 6 * d;
    const Inertia<S>& Ic = w.Ic[d];
    // column forces F = Ic ṡ + Bc s, and the row forces P = Ic s, Q = Bcᵀ s of d's DoFs
    Force<S> F[6], P[6], Q[6];
    for (int a = 0; a < bd.nv; ++a) {
      const Motion<S> sdot = cross(w.v[d], sd[a]);
      F[a] = Ic * sdot + S(0.5) * (w.B[d] * sd[a] + cross(sd[a], w.h[d]));
      P[a] = Ic * sd[a];
      Q[a] = S(0.5) * (w.B[d] * sd[a] - cross(sd[a], w.h[d]));  // Bᵀ s = B s (symmetric)
    }
    // rows of d and its ancestors, columns of d
    for (int e = d; e >= 0; e = m.body[e].parent) {
      const BodyDesc<S>& be = m.body[e];
      for (int r = 0; r < be.nv; ++r)
        for (int c = 0; c < bd.nv; ++c) C[(be.v_idx + r) * nv + bd.v_idx + c] += dot(w.S_world[6 * e + r], F[c]);
    }
    // rows of d, columns of its strict ancestors
    for (int e = bd.parent; e >= 0; e = m.body[e].parent) {
      const BodyDesc<S>& be = m.body[e];
      for (int c = 0; c < be.nv; ++c) {
        const Motion<S>& se = w.S_world[6 * e + c];
        const Motion<S> sedot = cross(w.v[e], se);
        for (int r = 0; r < bd.nv; ++r) C[(bd.v_idx + r) * nv + be.v_idx + c] += dot(sedot, P[r]) + dot(se, Q[r]);
      }
    }
    // subtree sums handed to the parent
    if (bd.parent >= 0) {
      w.Ic[bd.parent] += w.Ic[d];
      w.h[bd.parent] += w.h[d];
      w.B[bd.parent] += w.B[d];
    }
  }
}

// C(q, qd) (nv x nv, row-major), Pinocchio's computeCoriolisMatrix
template <typename S>
RBD_HD void coriolis_matrix(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, S* C) {
  momentum_forward_pass(m, w, q, qd);
  coriolis_backward_pass(m, w, C);
}

}  // namespace rbd
