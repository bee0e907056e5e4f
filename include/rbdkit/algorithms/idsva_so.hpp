// rbdkit/algorithms/idsva_so.hpp — analytical second-order partial
// derivatives of inverse dynamics, tau = ID(q, qd, qdd), in O(N·d²)
// (N bodies, d tree depth), after Singh, Russell & Wensing, "Analytical
// second-order partial derivatives of rigid-body inverse dynamics" (IDSVA-SO,
// ICRA 2023), in this project's notation and frames.
//
// Outputs, each (nv x nv x nv) row-major, flat index (i·nv + j)·nv + k:
//   d2tau_dq2  [i, j, k] = ∂/∂q_k (∂tau_i/∂q_j)   (∂tau/∂q_j as inverse_dynamics_gradient)
//   d2tau_dqd2 [i, j, k] = ∂²tau_i / ∂qd_j ∂qd_k   (symmetric in j, k)
//   d2tau_dqdqd[i, j, k] = ∂²tau_i / ∂q_j ∂qd_k
//   dM_dq      [i, j, k] = ∂M_ij / ∂q_k            (= ∂²tau_i / ∂qdd_j ∂q_k)
// q derivatives are tangent: ∂/∂q_k is the derivative along q <- integrate(q, δ e_k).
// For j, k in one free-flyer or spherical joint these steps do not commute, and
// d2tau_dq2[i, j, k] - d2tau_dq2[i, k, j] = Σ_l ∂tau_i/∂q_l · c_l with
// c = [e_k, e_j] the Lie bracket of the two tangent directions; everywhere else
// d2tau_dq2 is symmetric in (j, k). This is what central differences of
// ∂tau/∂q through integrate give, and Pinocchio's ComputeRNEASecondOrderDerivatives.
//
// Derivation (docs/conventions.md). In world coordinates a tangent step on DoF
// k turns the subtree of k rigidly with the twist s_k: every column below
// changes by ∂s_l/∂q_k = s_k × s_l, every inertia by s_k ×* I - I s_k×. The
// joint forces tau_i = s_i · F_i (F_i: net force on the subtree of i) are
// polynomials in those world quantities, so the derivatives follow by the
// product rule; the rigid parts cancel in the pairings and leave the column
// sensitivities of the first-order algorithm (rnea_derivatives.hpp)
//     ψ̇_k = v_λ × s_k,   ψ̈_k = a_λ × s_k + v_λ × ψ̇_k,   σ_k = v_k × s_k + ψ̇_k
//     ∂ψ̇_j/∂q_k = s_k × ψ̇_j + ψ̇_k × s_j,  ∂ψ̈_j/∂q_k = s_k × ψ̈_j + ψ̈_k × s_j + 2 ψ̇_k × ψ̇_j  (k above j)
// acting through the composites Ic, Bc = Σ(v ×* I - I v×), hc, Fc of the
// deepest body c of the triple (i, j, k) (all three lie on one root path;
// otherwise the entry is zero). Every entry is a few dot products of
// per-(DoF, DoF) forces with the third DoF's columns.
//
// Two variants of the same recursion, equal to rounding:
//   idsva_so_world_frame: world-frame forward pass (gravity as the base
//     acceleration of the sweep), composites add without transforms;
//   idsva_so_body_frame: body-frame forward pass (RNEA's v, a, constant S and
//     inertias), composites carried to the parent by X*, and the ancestors'
//     columns brought into the body's frame along the path.
// Mimic bodies add their terms into their target's columns (the reduced
// tensors, every index contracted with G). No external forces.
#pragma once

#include "rbdkit/algorithms/rnea_derivatives.hpp"

namespace rbd {

// ---------------------------------------------------------------- the path
// Entry e of the path of body c (e < n): motions so_m[4e..4e+4) = s, ψ̇, ψ̈, σ,
// forces so_f[8e..8e+8), ints so_i[2e] = column, so_i[2e+1] = depth (0: a DoF
// of c, 1: of its parent, ...), all in one frame.

template <typename S>
RBD_HD void so_path_push(Workspace<S>& w, int& n, int col, int depth, const Motion<S>& s, const Motion<S>& psi,
                         const Motion<S>& psi2, const Motion<S>& sigma) {
  Motion<S>* cm = w.so_m + 4 * n;
  cm[0] = s;
  cm[1] = psi;
  cm[2] = psi2;
  cm[3] = sigma;
  w.so_i[2 * n] = col;
  w.so_i[2 * n + 1] = depth;
  ++n;
}

// ------------------------------------------------------------ one body's terms
// Every entry of the four tensors whose deepest body is c, from the n path
// entries (the first n_c of them c's own DoFs) and c's composites Ic, Bc, hc,
// Fc, all in one frame. Adds into the (nv x nv x nv) outputs.
//
// With d a DoF of c, x, i, j, k path DoFs ("above": depth > 0):
//   i = d (row of c):        d2q[d,j,k] = ψ̈_k·α_j + ψ̇_k·β_j for k at or above j (symmetric otherwise)
//   i above, d in a column:  d2q[i,d,k] = d2q[i,k,d] = ψ̈_k·a_i + ψ̇_k·b_i - [i above k] s_k·ρ_i
// with the per-DoF forces
//   α_x = s_x ×* Ic s_d,   ν_x = ψ̇_x ×* Ic s_d,   μ_x = Ic(s_d × ψ̇_x) - s_d ×* Ic ψ̇_x
//   β_x = ν_x + μ_x + s_x ×* (Bc s_d - s_d ×* hc),   γ_x = -s_d ×* Ic s_x
//   w_i = s_i × s_d,  a_i = Ic w_i + s_d ×* Ic s_i
//   b_i = Bc w_i - w_i ×* hc + s_d ×* (Bc s_i - s_i ×* hc) + ψ̇_d ×* Ic s_i + Ic(s_i × ψ̇_d) - s_i ×* Ic ψ̇_d
//   Φ_d = s_d ×* Fc + Ic ψ̈_d + Bc ψ̇_d + ψ̇_d ×* hc   (∂Fc/∂q_d),   ρ_i = s_i ×* Φ_d
//   Ω_d = Ic σ_d + Bc s_d + s_d ×* hc                 (∂Fc/∂qd_d),  ω_i = s_i ×* Ω_d
// and from the same forces (μ'_i = Ic(s_i × ψ̇_d) - s_i ×* Ic ψ̇_d, ν'_i = ψ̇_d ×* Ic s_i):
//   d2v[d,j,k]  = s_k·γ_j + s_j·γ_k + [k strictly above j] s_k·α_j
//   d2v[i,d,k]  = d2v[i,k,d] = s_k·(a_i - α_i) (k above c),  s_k·(Ic w_i - α_i) (k at c)
//   d2qv[d,j,k] = σ_k·α_j + s_k·β_j (k strictly above j),  s_k·(μ_j - ν_j) (otherwise)
//   d2qv[i,d,k] = σ_k·a_i + s_k·b_i (k above c),  s_k·(μ'_i - ν'_i + Bc w_i - w_i ×* hc) + σ_k·Ic w_i (k at c)
//   d2qv[i,k,d] = ψ̇_k·(a_i - α_i) - [i above k] s_k·ω_i  (k above c)
//   dM[i,k,d]   = s_k·a_i (i, k above c),   dM[i,d,k] = dM[d,i,k] = -s_k·α_i (k strictly below i)
// (dM is zero when i and j are both DoFs of c, or k is at or above both).
template <typename S>
RBD_HD void idsva_so_body_terms(Workspace<S>& w, int nv, int n_c, int n, const Inertia<S>& Ic, const InertiaRate<S>& Bc,
                                const Force<S>& hc, const Force<S>& Fc, S* d2q, S* d2v, S* d2qv, S* dM) {
  const Motion<S>* cm = w.so_m;
  Force<S>* cf = w.so_f;
  const int* ci = w.so_i;
  // products of every path DoF with the composites: Ic s, Ic ψ̇, Bc s, s ×* hc
  for (int e = 0; e < n; ++e) {
    cf[8 * e] = Ic * cm[4 * e];
    cf[8 * e + 1] = Ic * cm[4 * e + 1];
    cf[8 * e + 2] = Bc * cm[4 * e];
    cf[8 * e + 3] = cross(cm[4 * e], hc);
  }
  auto at = [nv](int i, int j, int k) { return (static_cast<long>(i) * nv + j) * nv + k; };
  for (int e = 0; e < n_c; ++e) {
    const Motion<S>& sd = cm[4 * e];
    const Motion<S>& psid = cm[4 * e + 1];
    const Force<S>& Isd = cf[8 * e];
    const Force<S>& Ipsid = cf[8 * e + 1];
    const Force<S> Bsd_sdh = cf[8 * e + 2] - cf[8 * e + 3];
    const int d = ci[2 * e];
    const Force<S> Phi = cross(sd, Fc) + Ic * cm[4 * e + 2] + Bc * psid + cross(psid, hc);
    const Force<S> Omg = Ic * cm[4 * e + 3] + cf[8 * e + 2] + cf[8 * e + 3];

    // per-DoF forces of the row d: α, β, μ - ν, γ
    for (int x = 0; x < n; ++x) {
      const Motion<S>& sx = cm[4 * x];
      const Motion<S>& psix = cm[4 * x + 1];
      const Force<S> alpha = cross(sx, Isd);
      const Force<S> nu = cross(psix, Isd);
      const Force<S> mu = Ic * cross(sd, psix) - cross(sd, cf[8 * x + 1]);
      cf[8 * x + 4] = alpha;
      cf[8 * x + 5] = nu + mu + cross(sx, Bsd_sdh);
      cf[8 * x + 6] = mu - nu;
      cf[8 * x + 7] = S(-1) * cross(sd, cf[8 * x]);
    }

    // row d: pairs (j, k) of path DoFs, k at or above j (path entries run
    // from c up, so k starts at the first DoF of j's joint)
    for (int j = 0, j0 = 0; j < n; ++j) {
      const int cj = ci[2 * j], dj = ci[2 * j + 1];
      if (j > 0 && ci[2 * j - 1] != dj) j0 = j;
      // local copies: the tensor stores below could alias the path arrays
      const Motion<S> sj = cm[4 * j];
      const Force<S> alpha = cf[8 * j + 4], beta = cf[8 * j + 5], mu_nu = cf[8 * j + 6], gamma = cf[8 * j + 7];
      for (int k = j0; k < n; ++k) {
        const Motion<S>* mk = cm + 4 * k;
        const int ck = ci[2 * k], dk = ci[2 * k + 1];
        const S qq = dot(mk[2], alpha) + dot(mk[1], beta);
        S vv = dot(mk[0], gamma) + dot(sj, cf[8 * k + 7]);
        d2q[at(d, cj, ck)] += qq;
        if (dk == dj) {  // one joint: the ordered pair as it comes
          d2qv[at(d, cj, ck)] += dot(mk[0], mu_nu);
          d2v[at(d, cj, ck)] += vv;
        } else {  // k strictly above j: both orders
          vv += dot(mk[0], alpha);
          d2q[at(d, ck, cj)] += qq;
          d2qv[at(d, cj, ck)] += dot(mk[3], alpha) + dot(mk[0], beta);
          d2qv[at(d, ck, cj)] += dot(sj, cf[8 * k + 6]);
          d2v[at(d, cj, ck)] += vv;
          d2v[at(d, ck, cj)] += vv;
        }
      }
    }

    // rows i above c, with d in a column
    for (int i = n_c; i < n; ++i) {
      const Motion<S> si = cm[4 * i];
      const Force<S>* fi = cf + 8 * i;
      const Force<S> alpha = fi[4];
      const int ri = ci[2 * i], di = ci[2 * i + 1];
      const Motion<S> wi = cross(si, sd);
      const Force<S> Iw = Ic * wi;
      const Force<S> nu = cross(psid, fi[0]);
      const Force<S> mu = Ic * cross(si, psid) - cross(si, Ipsid);
      const Force<S> Bw_wh = Bc * wi - cross(wi, hc);
      const Force<S> a = Iw + cross(sd, fi[0]);
      const Force<S> b = Bw_wh + cross(sd, fi[2] - fi[3]) + nu + mu;
      const Force<S> rho = cross(si, Phi);
      const Force<S> omg = cross(si, Omg);
      const Force<S> a_alpha = a - alpha;    // qv with q above, and qd (both above)
      const Force<S> Iw_alpha = Iw - alpha;  // qd, the other column at c
      const Force<S> qv_c = mu - nu + Bw_wh;  // qv, the qd column at c
      for (int k = 0; k < n; ++k) {
        const Motion<S>* mk = cm + 4 * k;
        const int ck = ci[2 * k], dk = ci[2 * k + 1];
        const bool i_above_k = di > dk;
        S qq = dot(mk[2], a) + dot(mk[1], b);
        if (i_above_k) qq -= dot(mk[0], rho);
        d2q[at(ri, d, ck)] += qq;
        if (dk > 0) {  // k above c: (d, k) and (k, d)
          d2q[at(ri, ck, d)] += qq;
          d2qv[at(ri, d, ck)] += dot(mk[3], a) + dot(mk[0], b);
          S qv = dot(mk[1], a_alpha);
          if (i_above_k) qv -= dot(mk[0], omg);
          d2qv[at(ri, ck, d)] += qv;
          const S vv = dot(mk[0], a_alpha);
          d2v[at(ri, d, ck)] += vv;
          d2v[at(ri, ck, d)] += vv;
          // ∂M_ik/∂q_d, both i and k above c
          dM[at(ri, ck, d)] += dot(mk[0], a);
        } else {  // k a DoF of c
          d2qv[at(ri, d, ck)] += dot(mk[0], qv_c) + dot(mk[3], Iw);
          d2v[at(ri, d, ck)] += dot(mk[0], Iw_alpha);
        }
        // ∂M_id/∂q_k = ∂M_di/∂q_k for k strictly below i
        if (i_above_k) {
          const S m = -dot(mk[0], alpha);
          dM[at(ri, d, ck)] += m;
          dM[at(d, ri, ck)] += m;
        }
      }
    }
  }
}

template <typename S> RBD_HD void so_zero(int nv, S* a, S* b, S* c, S* d) {
  const long n = static_cast<long>(nv) * nv * nv;
  for (long k = 0; k < n; ++k) a[k] = S(0), b[k] = S(0), c[k] = S(0), d[k] = S(0);
}

// ---------------------------------------------------------- world frame
// forward pass: rnea_derivatives_forward_pass (world v, a with -g, s, ψ̇, ψ̈, σ,
// and per-body Ic, h, f, B). backward pass: body by body from the leaves, the
// path gathered as it is (world frame), the body's terms, composites to the parent.
// Writes w.X_parent, w.X_world, w.S_world, w.v, w.a, w.dVdq, w.dAdq, w.dAdv, w.Ic, w.h, w.f, w.B, w.so_*.
template <typename S>
RBD_HD void idsva_so_world_frame(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* qdd,
                                 S gravity, S* d2tau_dq2, S* d2tau_dqd2, S* d2tau_dqdqd, S* dM_dq) {
  rnea_derivatives_forward_pass(m, w, q, qd, qdd, static_cast<const S*>(nullptr), gravity, false, true);
  so_zero(m.nv, d2tau_dq2, d2tau_dqd2, d2tau_dqdqd, dM_dq);
  for (int c = m.nb - 1; c >= 0; --c) {
    // the path from c to the root
    int n = 0, n_c = 0;
    for (int j = c, depth = 0; j >= 0; j = m.body[j].parent, ++depth) {
      const BodyDesc<S>& bj = m.body[j];
      for (int a = 0; a < bj.nv; ++a) {
        const int e = 6 * j + a;
        so_path_push(w, n, bj.v_idx + a, depth, w.S_world[e], w.dVdq[e], w.dAdq[e], w.dAdv[e]);
      }
      if (depth == 0) n_c = n;
    }
    idsva_so_body_terms(w, m.nv, n_c, n, w.Ic[c], w.B[c], w.h[c], w.f[c], d2tau_dq2, d2tau_dqd2, d2tau_dqdqd,
                        dM_dq);
    // subtree sums handed to the parent
    const int p = m.body[c].parent;
    if (p >= 0) {
      w.Ic[p] += w.Ic[c];
      w.h[p] += w.h[c];
      w.f[p] += w.f[c];
      w.B[p] += w.B[c];
    }
  }
}

// ----------------------------------------------------------- body frame
// forward pass in body coordinates (RNEA's recursion): X_λi, v_i, a_i (-g at
// the root), and per DoF, with S constant in the body and v_λ, a_λ the parent's
// motion seen in the body:  ψ̇ = v_λ × S,  ψ̈ = a_λ × S + v_λ × ψ̇,  σ = v_i × S + ψ̇;
// per body I (constant), h = I v, f = I a + v ×* h, B = v ×* I - I v×.
// Writes w.X_parent, w.v, w.a, and (in body coordinates) w.S_world, w.dVdq, w.dAdq, w.dAdv,
// w.Ic, w.h, w.f, w.B.
template <typename S>
RBD_HD void idsva_so_body_forward_pass(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* qdd,
                                       S gravity) {
  place_joints(m, w.X_parent, q);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    Motion<S> vp = Motion<S>::zero(), ap = Motion<S>::zero();
    if (b.parent >= 0) {
      vp = w.X_parent[i].act_inv(w.v[b.parent]);
      ap = w.X_parent[i].act_inv(w.a[b.parent]);
    } else {
      Motion<S> g = Motion<S>::zero();
      g.lin.z = -gravity;
      ap = w.X_parent[i].act_inv(g);
    }
    const Motion<S> vJ = joint_motion(b, qd + b.v_idx);
    w.v[i] = vp + vJ;
    w.a[i] = ap + cross(w.v[i], vJ);
    if (qdd) w.a[i] += joint_motion(b, qdd + b.v_idx);
    for (int k = 0; k < b.nv; ++k) {
      const int e = 6 * i + k;
      const Motion<S> s = joint_subspace_col(b, k);
      w.S_world[e] = s;
      w.dVdq[e] = cross(vp, s);
      w.dAdq[e] = cross(ap, s) + cross(vp, w.dVdq[e]);
      w.dAdv[e] = cross(w.v[i], s) + w.dVdq[e];
    }
    w.Ic[i] = b.I;
    w.h[i] = b.I * w.v[i];
    w.f[i] = b.I * w.a[i] + cross(w.v[i], w.h[i]);
    w.B[i] = inertia_variation(b.I, w.v[i]);
  }
}

// backward pass: body by body from the leaves, the ancestors' columns brought
// into the body's frame (X_r_c composed along the path), the body's terms,
// composites carried to the parent (Ic, B by X* · X⁻¹, h, f by X*).
template <typename S>
RBD_HD void idsva_so_body_frame(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* qdd,
                                S gravity, S* d2tau_dq2, S* d2tau_dqd2, S* d2tau_dqdqd, S* dM_dq) {
  idsva_so_body_forward_pass(m, w, q, qd, qdd, gravity);
  so_zero(m.nv, d2tau_dq2, d2tau_dqd2, d2tau_dqdqd, dM_dq);
  for (int c = m.nb - 1; c >= 0; --c) {
    // the path from c to the root, in c's frame: X_r_c = X_λr... X_λc_c
    int n = 0, n_c = 0;
    Transform<S> X_r_c = Transform<S>::identity();
    for (int j = c, child = -1, depth = 0; j >= 0; child = j, j = m.body[j].parent, ++depth) {
      const BodyDesc<S>& bj = m.body[j];
      if (child >= 0) X_r_c = w.X_parent[child] * X_r_c;  // X_j_c = X_j_child · X_child_c
      for (int a = 0; a < bj.nv; ++a) {
        const int e = 6 * j + a;
        if (depth == 0)
          so_path_push(w, n, bj.v_idx + a, depth, w.S_world[e], w.dVdq[e], w.dAdq[e], w.dAdv[e]);
        else
          so_path_push(w, n, bj.v_idx + a, depth, X_r_c.act_inv(w.S_world[e]), X_r_c.act_inv(w.dVdq[e]),
                       X_r_c.act_inv(w.dAdq[e]), X_r_c.act_inv(w.dAdv[e]));
      }
      if (depth == 0) n_c = n;
    }
    idsva_so_body_terms(w, m.nv, n_c, n, w.Ic[c], w.B[c], w.h[c], w.f[c], d2tau_dq2, d2tau_dqd2, d2tau_dqdqd,
                        dM_dq);
    const int p = m.body[c].parent;
    if (p >= 0) {
      const Transform<S>& X = w.X_parent[c];
      w.Ic[p] += transform_inertia(X, w.Ic[c]);
      w.h[p] += X.act(w.h[c]);
      w.f[p] += X.act(w.f[c]);
      w.B[p] += transform_rate(X, w.B[c]);
    }
  }
}

// a free-flyer root (floating base)
template <typename S> RBD_HD bool has_floating_root(const ModelView<S>& m) {
  for (int i = 0; i < m.nb; ++i)
    if (m.body[i].parent < 0 && m.body[i].type == kFree) return true;
  return false;
}

// both tensors families by the variant suited to the model: body frame for a
// fixed base, world frame for a floating base (an implementation choice)
template <typename S>
RBD_HD void idsva_so(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* qdd, S gravity,
                     S* d2tau_dq2, S* d2tau_dqd2, S* d2tau_dqdqd, S* dM_dq) {
  if (has_floating_root(m))
    idsva_so_world_frame(m, w, q, qd, qdd, gravity, d2tau_dq2, d2tau_dqd2, d2tau_dqdqd, dM_dq);
  else
    idsva_so_body_frame(m, w, q, qd, qdd, gravity, d2tau_dq2, d2tau_dqd2, d2tau_dqdqd, dM_dq);
}

}  // namespace rbd
