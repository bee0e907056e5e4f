// rbdkit/algorithms/aba.hpp — forward dynamics qdd = FD(q, qd, tau, f_ext)
// by the articulated-body algorithm (Featherstone, RBDA §7.3, table 7.1),
// in body coordinates, O(n); on a small tree in double precision by M's
// tree-sparse factorisation (aba_factored, crba.hpp's mass_factor), faster there.
//
// Mimic joints couple coordinates across bodies, which the articulated-body
// recursion cannot absorb; mimic models take the dense path
// qdd = M⁻¹(tau - c) with a Cholesky solve (aba_dense).
#pragma once

#include "rbdkit/algorithms/crba.hpp"
#include "rbdkit/algorithms/dense.hpp"
#include "rbdkit/algorithms/rnea.hpp"

namespace rbd {

// pass 1: kinematics, velocity-product accelerations c_i, bias forces pA_i
//   writes w.X_parent, w.v, w.c, w.IA, w.f (= pA)
template <typename S>
RBD_HD void aba_forward_pass1(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* fext) {
  place_joints(m, w.X_parent, q);
  RBD_UNROLL
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    const Motion<S> vJ = joint_motion(b, qd + b.v_idx);
    w.v[i] = b.parent >= 0 ? w.X_parent[i].act_inv(w.v[b.parent]) + vJ : vJ;
    w.c[i] = cross(w.v[i], vJ);
    w.IA[i] = Mat6<S>::from_inertia(b.I);
    w.f[i] = cross(w.v[i], b.I * w.v[i]);
    if (fext) w.f[i] -= load_force(fext + 6 * i);
  }
}

// the joint-DoF quantities U = IA S, D⁻¹ = (Sᵀ U)⁻¹ for subspace columns Sc[0..n).
// false if D is singular: a joint that moves no mass (D = 0, or D at the
// rounding level of Σ_r IA_rr S_r², the size of its terms; pivot_positive).
template <typename S> RBD_HD bool joint_inertia(int n, const Motion<S>* Sc, const Mat6<S>& IA, Force<S>* U, S* Dinv) {
  for (int k = 0; k < n; ++k) U[k] = IA * Sc[k];
  if (n == 1) {
    const Motion<S>& s = Sc[0];
    const S D = dot(s, U[0]);
    const S scale = IA(0, 0) * s.lin.x * s.lin.x + IA(1, 1) * s.lin.y * s.lin.y + IA(2, 2) * s.lin.z * s.lin.z +
                    IA(3, 3) * s.ang.x * s.ang.x + IA(4, 4) * s.ang.y * s.ang.y + IA(5, 5) * s.ang.z * s.ang.z;
    if (!pivot_positive(D, scale)) return false;
    Dinv[0] = S(1) / D;
    return true;
  }
  S D[36];
  for (int k = 0; k < n; ++k)
    for (int l = 0; l < n; ++l) D[l * n + k] = dot(Sc[l], U[k]);
  return spd_inverse(D, n, Dinv);
}

// the same in body coordinates for body b. A revolute or prismatic joint
// about a frame axis e_k has S = ±mult·e_(3+k) or e_k, so U = IA S is a column
// of IA and D one of its diagonal entries; a free joint's S is the identity,
// so U is IA's columns and D is IA
template <typename S> RBD_HD bool aba_joint_inertia(const BodyDesc<S>& b, const Mat6<S>& IA, Force<S>* U, S* Dinv) {
  if (b.type == kFree) {
    S D[36];
    for (int k = 0; k < 36; ++k) D[k] = IA.m[k];
    for (int k = 0; k < 6; ++k)
      U[k] = {{IA(0, k), IA(1, k), IA(2, k)}, {IA(3, k), IA(4, k), IA(5, k)}};
    return spd_inverse(D, 6, Dinv);
  }
  S sk = S(0);
  const int c = joint_frame_column(b, sk);
  if (c >= 0) {
    U[0] = {{sk * IA(0, c), sk * IA(1, c), sk * IA(2, c)}, {sk * IA(3, c), sk * IA(4, c), sk * IA(5, c)}};
    const S D = sk * (sk * IA(c, c));  // sᵀ U
    if (!pivot_positive(D, IA(c, c) * (sk * sk))) return false;
    Dinv[0] = S(1) / D;
    return true;
  }
  Motion<S> Sc[6];
  for (int k = 0; k < b.nv; ++k) Sc[k] = joint_subspace_col(b, k);
  return joint_inertia(b.nv, Sc, IA, U, Dinv);
}

// out <- IA - U D⁻¹ Uᵀ = IA - Σ_k W_k U_kᵀ, W_k = Σ_l U_l D⁻¹(l, k) (n joint DoFs),
// or out += it with add. The result is symmetric: the 21 entries of the upper
// triangle are computed and each written to both places. Every array is
// indexed by constants once the loops over r and c unroll (registers on a
// GPU): W_k and U_k live one k at a time
template <typename S>
RBD_HD void articulated_update(int n, const Mat6<S>& IA, const Force<S>* U, const S* Dinv, bool add, Mat6<S>& out) {
  auto put = [&](int r, int c, const S& x) {
    if (add) {
      out(r, c) += x;
      if (c != r) out(c, r) += x;
    } else {
      out(r, c) = x;
      out(c, r) = x;
    }
  };
  if (n == 1) {  // the common case: W = U D⁻¹, one term per entry
    S u[6], wu[6];
    store(U[0], u);
    for (int r = 0; r < 6; ++r) wu[r] = u[r] * Dinv[0];
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) put(r, c, IA(r, c) - wu[r] * u[c]);
    return;
  }
  S x[6][6];
  for (int r = 0; r < 6; ++r)
    for (int c = r; c < 6; ++c) x[r][c] = IA(r, c);
  for (int k = 0; k < n; ++k) {
    S Wk[6] = {S(0), S(0), S(0), S(0), S(0), S(0)}, Uk[6];
    store(U[k], Uk);
    for (int l = 0; l < n; ++l) {
      S Ul[6];
      store(U[l], Ul);
      const S d = Dinv[l * n + k];
      for (int r = 0; r < 6; ++r) Wk[r] += Ul[r] * d;
    }
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) x[r][c] -= Wk[r] * Uk[c];
  }
  for (int r = 0; r < 6; ++r)
    for (int c = r; c < 6; ++c) put(r, c, x[r][c]);
}

// Ia = IA - U D⁻¹ Uᵀ: the articulated inertia seen through the joint
template <typename S> RBD_HD Mat6<S> articulated_residual(int n, const Mat6<S>& IA, const Force<S>* U, const S* Dinv) {
  Mat6<S> Ia;
  articulated_update(n, IA, U, Dinv, false, Ia);
  return Ia;
}

// IA_parent += IA - U D⁻¹ Uᵀ (one frame: the world-frame recursions), without
// forming the residual
template <typename S>
RBD_HD void add_articulated_residual(int n, const Mat6<S>& IA, const Force<S>* U, const S* Dinv, Mat6<S>& IA_parent) {
  articulated_update(n, IA, U, Dinv, true, IA_parent);
}

// IA_λ += X* (IA - U D⁻¹ Uᵀ) X⁻¹ : the articulated inertia handed to the parent
template <typename S>
RBD_HD void aba_project_inertia(const BodyDesc<S>& b, const Transform<S>& X, const Mat6<S>& IA, const Force<S>* U,
                                const S* Dinv, Mat6<S>& IA_parent) {
  IA_parent += transform_mat6(X, articulated_residual(b.nv, IA, U, Dinv));
}

// pass 2 (leaves to root): U, D⁻¹, u = tau - Sᵀ pA; articulated inertias and
// bias forces handed to the parent. writes w.U, w.Dinv, w.u, w.IA, w.f
template <typename S> RBD_HD bool aba_backward_pass(const ModelView<S>& m, Workspace<S>& w, const S* tau) {
  RBD_UNROLL
  for (int i = m.nb - 1; i >= 0; --i) {
    const BodyDesc<S>& b = m.body[i];
    Force<S>* U = w.U + 6 * i;
    S* Dinv = w.Dinv + 36 * i;
    if (!aba_joint_inertia(b, w.IA[i], U, Dinv)) return false;
    S sp[6];
    joint_project(b, w.f[i], sp);
    for (int k = 0; k < b.nv; ++k) w.u[b.v_idx + k] = tau[b.v_idx + k] - sp[k];
    if (b.parent < 0) continue;
    // pa = pA + Ia c + U D⁻¹ u, with Ia = IA - U D⁻¹ Uᵀ:  pa = pA + IA c + U D⁻¹ (u - Uᵀ c)
    Force<S> pa = w.f[i] + w.IA[i] * w.c[i];
    for (int k = 0; k < b.nv; ++k) {
      S coeff = S(0);
      for (int l = 0; l < b.nv; ++l)
        coeff += Dinv[k * b.nv + l] * (w.u[b.v_idx + l] - dot(w.c[i], U[l]));
      pa += coeff * U[k];
    }
    aba_project_inertia(b, w.X_parent[i], w.IA[i], U, Dinv, w.IA[b.parent]);
    w.f[b.parent] += w.X_parent[i].act(pa);
  }
  return true;
}

// pass 3 (root to leaves): a_i = X⁻¹ a_λ + c_i, qdd_i = D⁻¹(u - Uᵀ a_i), a_i += S qdd_i
//   writes w.a (gravity included), qdd (nv)
template <typename S> RBD_HD void aba_forward_pass2(const ModelView<S>& m, Workspace<S>& w, S gravity, S* qdd) {
  RBD_UNROLL
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    Motion<S> ap = Motion<S>::zero();
    if (b.parent >= 0) ap = w.a[b.parent];
    else ap.lin.z = -gravity;
    w.a[i] = w.X_parent[i].act_inv(ap) + w.c[i];
    const Force<S>* U = w.U + 6 * i;
    const S* Dinv = w.Dinv + 36 * i;
    S r[6];
    for (int k = 0; k < b.nv; ++k) r[k] = w.u[b.v_idx + k] - dot(w.a[i], U[k]);
    for (int k = 0; k < b.nv; ++k) {
      S acc = S(0);
      for (int l = 0; l < b.nv; ++l) acc += Dinv[k * b.nv + l] * r[l];
      qdd[b.v_idx + k] = acc;
    }
    w.a[i] += joint_motion(b, qdd + b.v_idx);
  }
}

// the first body, leaves to root, whose joint's articulated inertia D is
// singular at q (the test of aba_backward_pass and minv), or -1: names the
// joint once an algorithm has reported a mass matrix that is not positive
// definite. writes w.X_parent, w.IA, w.U, w.Dinv
template <typename S> RBD_HD int aba_singular_body(const ModelView<S>& m, Workspace<S>& w, const S* q) {
  place_joints(m, w.X_parent, q);
  for (int i = 0; i < m.nb; ++i) w.IA[i] = Mat6<S>::from_inertia(m.body[i].I);
  for (int i = m.nb - 1; i >= 0; --i) {
    const BodyDesc<S>& b = m.body[i];
    Force<S>* U = w.U + 6 * i;
    S* Dinv = w.Dinv + 36 * i;
    if (!aba_joint_inertia(b, w.IA[i], U, Dinv)) return i;
    if (b.parent >= 0) aba_project_inertia(b, w.X_parent[i], w.IA[i], U, Dinv, w.IA[b.parent]);
  }
  return -1;
}

// dense path for mimic models: qdd = M⁻¹ (tau - c) by Cholesky. false if M is singular.
template <typename S>
RBD_HD bool aba_dense(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* tau,
                      const S* fext, S gravity, S* qdd) {
  S* M = w.dense;
  crba(m, w, q, M);
  bias_residual(m, w, q, qd, tau, fext, gravity, qdd);
  if (!cholesky(M, m.nv)) return false;
  cholesky_solve(M, m.nv, qdd);
  return true;
}

// forward dynamics through M's tree-sparse factorisation (crba.hpp's mass_factor), for a small tree
// (minv_factored_pays) in a full workspace: the bias c by RNEA, which leaves the joint placements; M by
// CRBA on them (placed); M = Lᵀ D L; qdd = M⁻¹ (tau - c) by mass_factor_solve. On the iiwa, HyQ and
// fixed Atlas it took 0.76-0.83 of the three passes' time, on floating HyQ 0.9 (a compiled instance,
// docs/performance.md's tenth round). false where mass_factor refuses a pivot (qdd untouched): aba then
// runs the passes, whose verdict stands. M's lower tree pattern, then L, in w.dense2, tau - c and 1/D
// in w.dense, the DoF tree in w.so_i
template <typename S>
RBD_HD bool aba_factored(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* tau,
                         const S* fext, S gravity, S* qdd) {
  const int nv = m.nv;
  S* x = w.dense;  // tau - c, then qdd
  S* dinv = w.dense + nv;
  bias_residual(m, w, q, qd, tau, fext, gravity, x);
  if (!crba_factored(m, w, q, true, dinv, 1)) return false;
  mass_factor_solve(nv, w.so_i, w.so_i + nv, w.dense2, dinv, 1, x);
  for (int k = 0; k < nv; ++k) qdd[k] = x[k];
  return true;
}

// whether a scalar type computes in single precision: float, and a SIMD pack (simd.hpp's Pack<T, W>) or
// a dual number (dual.hpp) over float
template <typename S> struct single_precision : std::is_same<S, float> {};
template <template <class, int> class P, class T, int W> struct single_precision<P<T, W>> : single_precision<T> {};
template <template <class> class D, class T> struct single_precision<D<T>> : single_precision<T> {};

// qdd (nv) = FD(q, qd, tau, f_ext). fext may be null. Returns false if the
// articulated inertia of some joint is not positive definite (e.g. a chain
// of massless bodies), in which case qdd is undefined. The three passes of the
// articulated-body algorithm; on a small tree, in double precision and given a
// full workspace (aba_layout gives one there), M's factorisation (aba_factored),
// the same qdd to rounding. Not in float: forming M costs accuracy where M is
// ill-conditioned (the floating planar test model, cond(M) up to 2e4: 1.1e-4
// against float64, where the passes stay within the 1e-4 bound of the families
// that do not apply M⁻¹; M⁻¹, FD through it and ∇FD, bound at 2e-3 in float,
// factorise in either precision). aba_layout does not know the precision: a
// float caller gets the full workspace there too
template <typename S> RBD_FLATTEN
RBD_HD bool aba(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* tau, const S* fext,
                S gravity, S* qdd) {
  if (m.has_mimic) return aba_dense(m, w, q, qd, tau, fext, gravity, qdd);
  if constexpr (!single_precision<S>::value)
    if (w.dense2 && minv_factored_pays(m) && aba_factored(m, w, q, qd, tau, fext, gravity, qdd)) return true;
  aba_forward_pass1(m, w, q, qd, fext);
  if (!aba_backward_pass(m, w, tau)) return false;
  aba_forward_pass2(m, w, gravity, qdd);
  return true;
}

}  // namespace rbd
