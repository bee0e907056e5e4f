// rbdkit/algorithms/minv.hpp — the inverse mass matrix M⁻¹(q), computed
// directly in O(n²) by running the articulated-body recursion on the unit
// torque columns (Carpentier, "Analytical inverse of the joint space inertia
// matrix", 2018), never by factorising M.
//
//   backward:  F_i = ∂pA_i/∂tau              (subtree columns)
//              Minv_i· = D⁻¹ (e_i - Sᵀ F_i)     (rows of joint i, subtree columns)
//              F_λ += F_i + U_i Minv_i·
//   forward:   P_i = ∂a_i/∂tau                (columns ≥ v_idx)
//              Minv_i· -= D⁻¹ Uᵀ P_λ,  P_i = P_λ + S_i Minv_i·
//
// Everything is in world coordinates: the articulated inertias pass to the
// parent without a congruence transform, and the O(n²) column work is dot
// products and axpys (no column is ever transformed). Since a column of
// subtree(i) only ever receives contributions from inside that subtree, one
// shared 6 x nv array holds every F_i.
//
// Only the upper triangle (columns ≥ the row's joint) is computed; the lower
// triangle is mirrored when a dense result is asked for. The passes need each
// subtree's columns contiguous (subtrees_contiguous); models on the general path
// (ModelView::has_mimic: mimic joints, or bodies not added depth-first) take the
// dense path (Cholesky inverse of M).
#pragma once

#include "rbdkit/algorithms/aba.hpp"

namespace rbd {

// out[k·stride] = -Σ_l D⁻¹(k, l) x_l for k < n; the n = N form has fixed-size loops
template <int N, typename S> RBD_HD void neg_dinv_times(const S* Dinv, const S* x, S* out, int stride) {
  for (int k = 0; k < N; ++k) {
    S acc = S(0);
    for (int l = 0; l < N; ++l) acc -= Dinv[k * N + l] * x[l];
    out[k * stride] = acc;
  }
}
template <typename S> RBD_HD void neg_dinv_times(int n, const S* Dinv, const S* x, S* out, int stride) {
  for (int k = 0; k < n; ++k) {
    S acc = S(0);
    for (int l = 0; l < n; ++l) acc -= Dinv[k * n + l] * x[l];
    out[k * stride] = acc;
  }
}

// U = IA S and D⁻¹ for body b's joint, IA and the subspace columns Sw in world coordinates (minv's
// passes). A free root needs no U (it hands nothing to a parent and has no P_λ to project) and its
// D = Sᵀ IA S, with S = X_0b as a 6 x 6, is IA seen from its own frame: one congruence transform,
// about 200 multiplies where U and D take 432. false if D is not positive definite
template <typename S>
RBD_HD bool minv_joint_inertia(const BodyDesc<S>& b, const Transform<S>& X_world, const Motion<S>* Sw,
                               const Mat6<S>& IA, Force<S>* U, S* Dinv) {
  if (b.type == kFree && b.parent < 0) {
    Mat6<S> D = transform_mat6(X_world.inverse(), IA);
    return spd_inverse(D.m, 6, Dinv);
  }
  return joint_inertia(b.nv, Sw, IA, U, Dinv);
}

// backward pass: articulated inertias, D⁻¹, the subtree rows of M⁻¹.
// writes w.X_parent, w.X_world, w.Ic (the world body inertias), w.IA, w.U (world
// frame), w.Dinv, w.S_world, w.F (nv x 6), Minv (upper part). false if some D
// is not positive definite.
template <typename S> RBD_HD bool minv_backward_pass(const ModelView<S>& m, Workspace<S>& w, const S* q, S* Minv) {
  const int nv = m.nv;
  // body placements X_0i, articulated inertias start as the body inertias (world frame)
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    world_placement(m, w, q, i, false);
    w.Ic[i] = transform_inertia(w.X_world[i], b.I);
    w.IA[i] = Mat6<S>::from_inertia(w.Ic[i]);
  }
  for (int k = 0; k < nv * nv; ++k) Minv[k] = S(0);
  for (int k = 0; k < 6 * nv; ++k) w.F[k] = S(0);
  for (int i = m.nb - 1; i >= 0; --i) {
    const BodyDesc<S>& b = m.body[i];
    const int vi = b.v_idx, ni = b.nv, c_end = b.v_idx + b.nv_subtree;
    Force<S>* U = w.U + 6 * i;
    Motion<S>* Sw = w.S_world + 6 * i;
    S* Dinv = w.Dinv + 36 * i;
    // U = IA S, D⁻¹, and IA_λ += IA - U D⁻¹ Uᵀ
    for (int k = 0; k < ni; ++k) Sw[k] = joint_subspace_col_in(b, w.X_world[i], k);
    if (!minv_joint_inertia(b, w.X_world[i], Sw, w.IA[i], U, Dinv)) return false;
    if (b.parent >= 0) add_articulated_residual(ni, w.IA[i], U, Dinv, w.IA[b.parent]);
    // own block: D⁻¹
    for (int k = 0; k < ni; ++k)
      for (int l = 0; l < ni; ++l) Minv[(vi + k) * nv + vi + l] = Dinv[k * ni + l];
    // descendants' columns: -D⁻¹ Sᵀ F (one DoF, the common case: a scalar D⁻¹)
    if (ni == 1) {
      for (int c = vi + 1; c < c_end; ++c) Minv[vi * nv + c] = -Dinv[0] * dot(Sw[0], load_force(w.F + 6 * c));
    } else
    for (int c = vi + ni; c < c_end; ++c) {
      S sf[6];
      joint_project_in(b, w.X_world[i], Sw, load_force(w.F + 6 * c), sf);
      if (ni == 6) neg_dinv_times<6>(Dinv, sf, Minv + vi * nv + c, nv);  // a free joint: fixed-size loops
      else neg_dinv_times(ni, Dinv, sf, Minv + vi * nv + c, nv);
    }
    // F_λ = F_i + U Minv_i· over the subtree columns (in place)
    if (b.parent < 0) continue;
    for (int c = vi; c < c_end; ++c) {
      Force<S> fc = load_force(w.F + 6 * c);
      for (int k = 0; k < ni; ++k) fc += Minv[(vi + k) * nv + c] * U[k];
      store(fc, w.F + 6 * c);
    }
  }
  return true;
}

// body i's forward step in column c >= v_idx: Minv_i,c -= D⁻¹ Uᵀ P_λ,c, P_i,c = P_λ,c + S Minv_i,c (the
// root has no P_λ).  reads w.U, w.S_world (world frame), w.Dinv, the parent's w.P; writes body i's
// column c of w.P (nb x nv x 6) and of Minv
template <typename S> RBD_HD void minv_forward_step(const ModelView<S>& m, Workspace<S>& w, int i, int c, S* Minv) {
  const int nv = m.nv;
  const BodyDesc<S>& b = m.body[i];
  const int vi = b.v_idx, ni = b.nv;
  const Force<S>* U = w.U + 6 * i;
  const Motion<S>* Sw = w.S_world + 6 * i;
  const S* Dinv = w.Dinv + 36 * i;
  S* P = w.P + 6 * nv * i + 6 * c;
  const S* Pp = b.parent >= 0 ? w.P + 6 * nv * b.parent + 6 * c : nullptr;
  if (ni == 1 && Pp) {  // one DoF: a scalar D⁻¹, one U and one S
    Motion<S> pc = load_motion(Pp);
    S& x = Minv[vi * nv + c];
    x -= Dinv[0] * dot(pc, U[0]);
    pc += x * Sw[0];
    store(pc, P);
    return;
  }
  Motion<S> pc = Motion<S>::zero();
  if (Pp) {
    pc = load_motion(Pp);
    S up[6];
    for (int l = 0; l < ni; ++l) up[l] = dot(pc, U[l]);
    for (int k = 0; k < ni; ++k) {
      S acc = S(0);
      for (int l = 0; l < ni; ++l) acc += Dinv[k * ni + l] * up[l];
      Minv[(vi + k) * nv + c] -= acc;
    }
  }
  for (int k = 0; k < ni; ++k) pc += Minv[(vi + k) * nv + c] * Sw[k];
  store(pc, P);
}

// forward pass over columns ≥ v_idx (minv_forward_step), parents first
template <typename S> RBD_HD void minv_forward_pass(const ModelView<S>& m, Workspace<S>& w, S* Minv) {
  for (int i = 0; i < m.nb; ++i)
    for (int c = m.body[i].v_idx; c < m.nv; ++c) minv_forward_step(m, w, i, c, Minv);
}

// column c of M⁻¹ (its upper part and its joint blocks), after the articulated inertias (w.U, w.Dinv,
// w.S_world, w.X_world): minv_backward_pass's column work for c (the bodies whose subtree holds c,
// children first; F's column c in a local, w.F untouched) then minv_forward_pass's (the bodies with
// v_idx <= c, parents first). Column c reads and writes only column c of Minv and of w.P, so columns
// may run side by side (minv_team). Below the diagonal, only c's own joint block is written (the
// rest is zero until the mirror). The same values as the two passes
template <typename S> RBD_HD void minv_column(const ModelView<S>& m, Workspace<S>& w, int c, S* Minv) {
  const int nv = m.nv;
  for (int r = 0; r < nv; ++r) Minv[r * nv + c] = S(0);
  Force<S> fc = Force<S>::zero();  // F's column c
  for (int i = m.nb - 1; i >= 0; --i) {
    const BodyDesc<S>& b = m.body[i];
    const int vi = b.v_idx, ni = b.nv;
    if (c < vi || c >= vi + b.nv_subtree) continue;
    const Force<S>* U = w.U + 6 * i;
    const Motion<S>* Sw = w.S_world + 6 * i;
    const S* Dinv = w.Dinv + 36 * i;
    if (c < vi + ni) {  // own block: D⁻¹
      for (int k = 0; k < ni; ++k) Minv[(vi + k) * nv + c] = Dinv[k * ni + c - vi];
    } else if (ni == 1) {  // a descendant's column: -D⁻¹ Sᵀ F
      Minv[vi * nv + c] = -Dinv[0] * dot(Sw[0], fc);
    } else {
      S sf[6];
      joint_project_in(b, w.X_world[i], Sw, fc, sf);
      if (ni == 6) neg_dinv_times<6>(Dinv, sf, Minv + vi * nv + c, nv);
      else neg_dinv_times(ni, Dinv, sf, Minv + vi * nv + c, nv);
    }
    if (b.parent < 0) continue;
    for (int k = 0; k < ni; ++k) fc += Minv[(vi + k) * nv + c] * U[k];
  }
  for (int i = 0; i < m.nb; ++i)  // parents first
    if (m.body[i].v_idx <= c) minv_forward_step(m, w, i, c, Minv);
}

// minv on a team of threads (model/team.hpp), for a model without mimic joints: the placements and
// body inertias side by side (world_placements_team), the articulated inertias U, D⁻¹ (the only chain:
// IA_λ += IA - U D⁻¹ Uᵀ, children first) on one thread, then every column side by side (minv_column),
// then the lower triangle (mirrored when dense, else zero). The same values as minv. ok: where the
// team writes whether every D was positive definite (read it after the team's next barrier). An
// InlineTeam runs minv
template <typename S, typename Team>
RBD_HD void minv_team(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q, bool dense, S* Minv,
                      int* ok) {
  if constexpr (!Team::cooperative) {
    *ok = minv(m, w, q, dense, Minv);
  } else {
    const int nv = m.nv;
    world_placements_team(t, m, w, q, true, [&](int i) {
      w.Ic[i] = transform_inertia(w.X_world[i], m.body[i].I);
      w.IA[i] = Mat6<S>::from_inertia(w.Ic[i]);
    });
    t.one([&] {
      *ok = 1;
      for (int i = m.nb - 1; i >= 0; --i) {
        const BodyDesc<S>& b = m.body[i];
        Force<S>* U = w.U + 6 * i;
        S* Dinv = w.Dinv + 36 * i;
        if (!minv_joint_inertia(b, w.X_world[i], w.S_world + 6 * i, w.IA[i], U, Dinv)) *ok = 0;
        else if (b.parent >= 0) add_articulated_residual(b.nv, w.IA[i], U, Dinv, w.IA[b.parent]);
      }
    });
    t.each(nv, [&](long c) { minv_column(m, w, static_cast<int>(c), Minv); });
    t.each2(nv, nv, [&](long r, long c) {
      if (r > c) Minv[r * nv + c] = dense ? Minv[c * nv + r] : S(0);
    });
  }
}

// M⁻¹(q), nv x nv row-major. dense: mirror the upper triangle into the lower;
// otherwise the strict lower triangle is zero. false if M is not PD.
template <typename S> RBD_HD bool minv(const ModelView<S>& m, Workspace<S>& w, const S* q, bool dense, S* Minv) {
  const int nv = m.nv;
  if (m.has_mimic) {
    S* M = w.dense;
    crba(m, w, q, M);
    if (!spd_inverse(M, nv, Minv)) return false;
  } else {
    if (!minv_backward_pass(m, w, q, Minv)) return false;
    minv_forward_pass(m, w, Minv);
  }
  for (int r = 1; r < nv; ++r)
    for (int c = 0; c < r; ++c) Minv[r * nv + c] = dense ? Minv[c * nv + r] : S(0);
  return true;
}

// qdd = M⁻¹ (tau - c(q, qd, f_ext)): forward dynamics through the inverse.
// writes w.dense (M⁻¹ in its first nv² entries) and qdd (nv).
template <typename S>
RBD_HD bool forward_dynamics(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* tau,
                             const S* fext, S gravity, S* qdd) {
  const int nv = m.nv;
  S* r = w.dense + nv * nv + nv;  // residual tau - c
  rnea(m, w, q, qd, static_cast<const S*>(nullptr), fext, gravity, r);
  for (int k = 0; k < nv; ++k) r[k] = tau[k] - r[k];
  S* Mi = w.dense;
  if (m.has_mimic) {
    crba(m, w, q, Mi);
    if (!cholesky(Mi, nv)) return false;
    for (int k = 0; k < nv; ++k) qdd[k] = r[k];
    cholesky_solve(Mi, nv, qdd);
    return true;
  }
  if (!minv(m, w, q, true, Mi)) return false;
  for (int row = 0; row < nv; ++row) {
    S acc = S(0);
    for (int c = 0; c < nv; ++c) acc += Mi[row * nv + c] * r[c];
    qdd[row] = acc;
  }
  return true;
}

}  // namespace rbd
