// rbdkit/algorithms/minv.hpp — the inverse mass matrix M⁻¹(q), two ways:
//   - minv_passes: directly in O(n²), by running the articulated-body recursion
//     on the unit torque columns (Carpentier, "Analytical inverse of the joint
//     space inertia matrix", 2018), below;
//   - minv_factored: CRBA, then M's tree-sparse factorisation (further down),
//     which costs less on small and branched trees.
// minv, the operation, picks one per model (minv_factored_pays).
//
// The direct passes:
//   backward:  F_i = ∂pA_i/∂tau              (subtree columns)
//              Minv_i· = D⁻¹ (e_i - Sᵀ F_i)     (rows of joint i, subtree columns)
//              F_λ += F_i + U_i Minv_i·
//   forward:   P_i = ∂a_i/∂tau                (columns ≥ v_idx)
//              Minv_i· -= D⁻¹ Uᵀ P_λ,  P_i = P_λ + S_i Minv_i·
//
// Everything is in one inertial frame, the world's or a free root's (world.hpp's
// reference frame): the articulated inertias pass to the parent without a
// congruence transform, and the O(n²) column work is dot products and axpys (no
// column is ever transformed). Since a column of
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
#include "rbdkit/algorithms/world.hpp"

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

// U = IA S and D⁻¹ for body b's joint, IA and the subspace columns Sw in minv's frame (the world's or
// a free root's). A free root needs no U (it hands nothing to a parent and has no P_λ to project) and
// its D = Sᵀ IA S is IA seen from its own frame: IA itself in the root's frame, else (S = X_0b as a
// 6 x 6) one congruence transform, about 200 multiplies where U and D take 432. false if D is not
// positive definite
template <typename S>
RBD_HD bool minv_joint_inertia(const BodyDesc<S>& b, const Transform<S>& X_world, const Motion<S>* Sw,
                               const Mat6<S>& IA, Force<S>* U, S* Dinv, bool leave_world) {
  if (b.type == kFree && b.parent < 0) {
    if (in_root_frame(b, leave_world)) {
      S D[36];
      for (int k = 0; k < 36; ++k) D[k] = IA.m[k];
      return spd_inverse(D, 6, Dinv);
    }
    Mat6<S> D = transform_mat6(X_world.inverse(), IA);
    return spd_inverse(D.m, 6, Dinv);
  }
  return joint_inertia(b.nv, Sw, IA, U, Dinv);
}

// ---- the column work of a one-DoF body, over a run of columns [c0, c1) at once. The passes keep F
// (backward) and each body's P (forward) as 6 x nv, row r of every column contiguous, so a body's
// work over its columns is six streams read and written side by side, one row of M⁻¹ with them.
// minv_columns calls body(c, lane) for each column c, or for a vector of columns at a time (lane: a
// GCC/clang vector of RBD_HOST_VECTOR_BYTES, then of 16 bytes) in host code that nvcc does not see, in
// double and float; lanes_load/lanes_store move one lane's worth. Each column's operations are the
// same, in the same order, on either path.
template <typename T, typename S> RBD_HD T lanes_load(const S* p) {
  if constexpr (std::is_same<T, S>::value) {
    return *p;
  } else {
    T v;
    __builtin_memcpy(&v, p, sizeof(T));
    return v;
  }
}
template <typename T, typename S> RBD_HD void lanes_store(S* p, const T& v) {
  if constexpr (std::is_same<T, S>::value) *p = v;
  else __builtin_memcpy(p, &v, sizeof(T));
}
template <typename S, typename Body> RBD_HD_INLINE void minv_columns(int c0, int c1, const Body& body) {
  int c = c0;
#if (defined(__GNUC__) || defined(__clang__)) && !defined(__CUDACC__)
  if constexpr (std::is_same<S, double>::value || std::is_same<S, float>::value) {
#if RBD_HOST_VECTOR_BYTES >= 32
    typedef S V32 __attribute__((vector_size(32)));
    for (; c + int(32 / sizeof(S)) <= c1; c += 32 / sizeof(S)) body(c, V32{});
#endif
    typedef S V __attribute__((vector_size(16)));
    constexpr int L = 16 / sizeof(S);
    for (; c + L <= c1; c += L) body(c, V{});
  }
#endif
  for (; c < c1; ++c) body(c, S(0));
}

// row[c] = nd (sᵀ F_c) for c in [c0, c1): a one-DoF body's row of M⁻¹ over its descendants' columns
// (nd = -D⁻¹; F 6 x nv)
template <typename S>
RBD_HD void minv_row_from_columns(const Motion<S>& sw, S nd, const S* RBD_RESTRICT F, int nv, int c0, int c1,
                                  S* RBD_RESTRICT row) {
  const S s0 = sw.lin.x, s1 = sw.lin.y, s2 = sw.lin.z, s3 = sw.ang.x, s4 = sw.ang.y, s5 = sw.ang.z;
  minv_columns<S>(c0, c1, [=](int c, auto lane) {
    using T = decltype(lane);
    const T f0 = lanes_load<T>(F + c), f1 = lanes_load<T>(F + nv + c), f2 = lanes_load<T>(F + 2 * nv + c);
    const T f3 = lanes_load<T>(F + 3 * nv + c), f4 = lanes_load<T>(F + 4 * nv + c), f5 = lanes_load<T>(F + 5 * nv + c);
    lanes_store(row + c, T(nd * ((s0 * f0 + s1 * f1 + s2 * f2) + (s3 * f3 + s4 * f4 + s5 * f5))));
  });
}

// F_c += row[c] u for c in [c0, c1) (F 6 x nv): the subtree's columns handed to the parent
template <typename S>
RBD_HD void minv_columns_add(const Force<S>& u, const S* RBD_RESTRICT row, int nv, int c0, int c1,
                             S* RBD_RESTRICT F) {
  const S u0 = u.lin.x, u1 = u.lin.y, u2 = u.lin.z, u3 = u.ang.x, u4 = u.ang.y, u5 = u.ang.z;
  minv_columns<S>(c0, c1, [=](int c, auto lane) {
    using T = decltype(lane);
    const T x = lanes_load<T>(row + c);
    lanes_store(F + c, T(lanes_load<T>(F + c) + x * u0));
    lanes_store(F + nv + c, T(lanes_load<T>(F + nv + c) + x * u1));
    lanes_store(F + 2 * nv + c, T(lanes_load<T>(F + 2 * nv + c) + x * u2));
    lanes_store(F + 3 * nv + c, T(lanes_load<T>(F + 3 * nv + c) + x * u3));
    lanes_store(F + 4 * nv + c, T(lanes_load<T>(F + 4 * nv + c) + x * u4));
    lanes_store(F + 5 * nv + c, T(lanes_load<T>(F + 5 * nv + c) + x * u5));
  });
}

// the forward step of a one-DoF body over columns [c0, c1):
//   row[c] -= d (uᵀ P_λ,c),  P_c = P_λ,c + row[c] s       (Pp = P_λ, 6 x nv; null at a root: P_c = row[c] s)
template <typename S>
RBD_HD void minv_forward_row(const Force<S>& u, const Motion<S>& sw, S d, const S* RBD_RESTRICT Pp, int nv, int c0,
                             int c1, S* RBD_RESTRICT row, S* RBD_RESTRICT P) {
  const S s0 = sw.lin.x, s1 = sw.lin.y, s2 = sw.lin.z, s3 = sw.ang.x, s4 = sw.ang.y, s5 = sw.ang.z;
  if (!Pp) {
    minv_columns<S>(c0, c1, [=](int c, auto lane) {
      using T = decltype(lane);
      const T x = lanes_load<T>(row + c);
      lanes_store(P + c, T(x * s0)), lanes_store(P + nv + c, T(x * s1)), lanes_store(P + 2 * nv + c, T(x * s2));
      lanes_store(P + 3 * nv + c, T(x * s3)), lanes_store(P + 4 * nv + c, T(x * s4));
      lanes_store(P + 5 * nv + c, T(x * s5));
    });
    return;
  }
  const S u0 = u.lin.x, u1 = u.lin.y, u2 = u.lin.z, u3 = u.ang.x, u4 = u.ang.y, u5 = u.ang.z;
  minv_columns<S>(c0, c1, [=](int c, auto lane) {
    using T = decltype(lane);
    const T p0 = lanes_load<T>(Pp + c), p1 = lanes_load<T>(Pp + nv + c), p2 = lanes_load<T>(Pp + 2 * nv + c);
    const T p3 = lanes_load<T>(Pp + 3 * nv + c), p4 = lanes_load<T>(Pp + 4 * nv + c), p5 = lanes_load<T>(Pp + 5 * nv + c);
    const T x = lanes_load<T>(row + c) - d * ((p0 * u0 + p1 * u1 + p2 * u2) + (p3 * u3 + p4 * u4 + p5 * u5));
    lanes_store(row + c, x);
    lanes_store(P + c, T(p0 + x * s0)), lanes_store(P + nv + c, T(p1 + x * s1));
    lanes_store(P + 2 * nv + c, T(p2 + x * s2)), lanes_store(P + 3 * nv + c, T(p3 + x * s3));
    lanes_store(P + 4 * nv + c, T(p4 + x * s4)), lanes_store(P + 5 * nv + c, T(p5 + x * s5));
  });
}

// out_r[c] = Σ_k A(r, k) in_k[c] for c in [c0, c1) and r < 6 (k from 0 in order): a 6 x 6 applied to
// columns kept as six rows (in's row k at in + k·is, out's row r at out + r·os). A free root's column
// work: its rows of M⁻¹ from F, its P from those rows
template <typename S>
RBD_HD void mat6_times_rows(const Mat6<S>& A, const S* RBD_RESTRICT in, int is, int c0, int c1, S* RBD_RESTRICT out,
                            int os) {
  minv_columns<S>(c0, c1, [=](int c, auto lane) {
    using T = decltype(lane);
    T x[6];
    for (int k = 0; k < 6; ++k) x[k] = lanes_load<T>(in + k * is + c);
    for (int r = 0; r < 6; ++r) {
      T acc = A(r, 0) * x[0];
      for (int k = 1; k < 6; ++k) acc = acc + A(r, k) * x[k];
      lanes_store(out + r * os + c, acc);
    }
  });
}

// backward pass: articulated inertias, D⁻¹, the subtree rows of M⁻¹.
// writes w.X_parent, w.X_world, w.Ic (the body inertias), w.IA, w.U (not a free root's), w.Dinv,
// w.S_world, w.F (6 x nv), Minv (upper part), in the reference frame (world.hpp): the world's when
// leave_world, else a tree with a free root in its root's frame (M⁻¹ does not depend on the frame, and
// the root's S is then the identity: no change of frame for its D, its rows or its P). The derivative
// passes reuse the placements and inertias in the same frame. false if some D is not positive definite.
template <typename S>
RBD_HD bool minv_backward_pass(const ModelView<S>& m, Workspace<S>& w, const S* q, S* Minv, bool leave_world = false) {
  const int nv = m.nv;
  // body placements X_0i, articulated inertias start as the body inertias
  place_joints(m, w.X_parent, q);
  RBD_UNROLL
  for (int i = 0; i < m.nb; ++i) {
    placed_world(m, w, i, false, leave_world);
    w.Ic[i] = reference_inertia(m, w, i, leave_world);
    w.IA[i] = Mat6<S>::from_inertia(w.Ic[i]);
  }
  for (int k = 0; k < nv * nv; ++k) Minv[k] = S(0);
  S* F = w.F;  // 6 x nv: the columns of F_i, row r of every column at r·nv
  for (int k = 0; k < 6 * nv; ++k) F[k] = S(0);
  RBD_UNROLL
  for (int i = m.nb - 1; i >= 0; --i) {
    const BodyDesc<S>& b = m.body[i];
    const int vi = b.v_idx, ni = b.nv, c_end = b.v_idx + b.nv_subtree;
    Force<S>* U = w.U + 6 * i;
    Motion<S>* Sw = w.S_world + 6 * i;
    S* Dinv = w.Dinv + 36 * i;
    // U = IA S, D⁻¹, and IA_λ += IA - U D⁻¹ Uᵀ
    const bool own = in_root_frame(b, leave_world);
    if (own) {
      for (int k = 0; k < 6; ++k) {
        S e[6] = {S(0), S(0), S(0), S(0), S(0), S(0)};
        e[k] = S(1);
        Sw[k] = load_motion(e);
      }
    } else {
      for (int k = 0; k < ni; ++k) Sw[k] = joint_subspace_col_in(b, w.X_world[i], k);
    }
    if (!minv_joint_inertia(b, w.X_world[i], Sw, w.IA[i], U, Dinv, leave_world)) return false;
    if (b.parent >= 0) add_articulated_residual(ni, w.IA[i], U, Dinv, w.IA[b.parent]);
    // a one-DoF body (the common case: a scalar D⁻¹): its own entry D⁻¹, its descendants' columns
    // -D⁻¹ Sᵀ F, then F_λ = F_i + U Minv_i· over the subtree columns (in place)
    if (ni == 1) {
      Minv[vi * nv + vi] = Dinv[0];
      minv_row_from_columns(Sw[0], -Dinv[0], F, nv, vi + 1, c_end, Minv + vi * nv);
      if (b.parent >= 0) minv_columns_add(U[0], Minv + vi * nv, nv, vi, c_end, F);
      continue;
    }
    // otherwise the same with D⁻¹ a matrix: own block D⁻¹, descendants' columns -D⁻¹ Sᵀ F
    for (int k = 0; k < ni; ++k)
      for (int l = 0; l < ni; ++l) Minv[(vi + k) * nv + vi + l] = Dinv[k * ni + l];
    if (b.type == kFree && b.parent < 0) {  // -D⁻¹ X_0b⁻¹ F as one 6 x 6 on the rows of F
      Mat6<S> G;
      if (own) {  // S = 1: -D⁻¹
        for (int k = 0; k < 36; ++k) G.m[k] = -Dinv[k];
      } else {
        for (int k = 0; k < 6; ++k) {  // column k of the force transform X_0b⁻¹, then of -D⁻¹ times it
          S e[6] = {S(0), S(0), S(0), S(0), S(0), S(0)}, xk[6];
          e[k] = S(1);
          store(w.X_world[i].act_inv(load_force(e)), xk);
          neg_dinv_times<6>(Dinv, xk, &G(0, k), 6);
        }
      }
      mat6_times_rows(G, F, nv, vi + 6, c_end, Minv + vi * nv, nv);
    } else {
      for (int c = vi + ni; c < c_end; ++c) {
        S sf[6];
        joint_project_in(b, w.X_world[i], Sw, Force<S>{load3(F + c, nv), load3(F + 3 * nv + c, nv)}, sf);
        if (ni == 6) neg_dinv_times<6>(Dinv, sf, Minv + vi * nv + c, nv);  // a free joint: fixed-size loops
        else neg_dinv_times(ni, Dinv, sf, Minv + vi * nv + c, nv);
      }
    }
    if (b.parent < 0) continue;
    for (int c = vi; c < c_end; ++c) {  // F_λ = F_i + U Minv_i·
      Force<S> fc{load3(F + c, nv), load3(F + 3 * nv + c, nv)};
      for (int k = 0; k < ni; ++k) fc += Minv[(vi + k) * nv + c] * U[k];
      store3(fc.lin, F + c, nv), store3(fc.ang, F + 3 * nv + c, nv);
    }
  }
  return true;
}

// body i's forward step in column c >= v_idx: Minv_i,c -= D⁻¹ Uᵀ P_λ,c, P_i,c = P_λ,c + S Minv_i,c (the
// root has no P_λ). P and Pp point at column c of body i's and its parent's P (Pp null at a root), the
// column's six entries rs apart. reads w.U, w.S_world (the reference frame), w.Dinv; writes column c of P and
// of Minv
template <typename S>
RBD_HD void minv_forward_step(const ModelView<S>& m, Workspace<S>& w, int i, int c, S* Minv, S* P, const S* Pp,
                              int rs) {
  const int nv = m.nv;
  const BodyDesc<S>& b = m.body[i];
  const int vi = b.v_idx, ni = b.nv;
  const Force<S>* U = w.U + 6 * i;
  const Motion<S>* Sw = w.S_world + 6 * i;
  const S* Dinv = w.Dinv + 36 * i;
  Motion<S> pc = Motion<S>::zero();
  if (Pp) pc = {load3(Pp, rs), load3(Pp + 3 * rs, rs)};
  if (ni == 1 && Pp) {  // one DoF: a scalar D⁻¹, one U and one S
    S& x = Minv[vi * nv + c];
    x -= Dinv[0] * dot(pc, U[0]);
    pc += x * Sw[0];
  } else {
    if (Pp) {
      S up[6];
      for (int l = 0; l < ni; ++l) up[l] = dot(pc, U[l]);
      for (int k = 0; k < ni; ++k) {
        S acc = S(0);
        for (int l = 0; l < ni; ++l) acc += Dinv[k * ni + l] * up[l];
        Minv[(vi + k) * nv + c] -= acc;
      }
    }
    for (int k = 0; k < ni; ++k) pc += Minv[(vi + k) * nv + c] * Sw[k];
  }
  store3(pc.lin, P, rs), store3(pc.ang, P + 3 * rs, rs);
}

// forward pass over columns ≥ v_idx, parents first: minv_forward_step's work, each body's P_i as
// 6 x nv (w.P + 6 nv i; a one-DoF body's columns at once, minv_forward_row). leave_world: as the
// backward pass was given
template <typename S>
RBD_HD void minv_forward_pass(const ModelView<S>& m, Workspace<S>& w, S* Minv, bool leave_world = false) {
  const int nv = m.nv;
  RBD_UNROLL
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    const int vi = b.v_idx, ni = b.nv;
    const Force<S>* U = w.U + 6 * i;
    const Motion<S>* Sw = w.S_world + 6 * i;
    const S* Dinv = w.Dinv + 36 * i;
    S* P = w.P + 6 * nv * i;
    const S* Pp = b.parent >= 0 ? w.P + 6 * nv * b.parent : nullptr;
    if (ni == 1) {
      minv_forward_row(U[0], Sw[0], Dinv[0], Pp, nv, vi, nv, Minv + vi * nv, P);
      continue;
    }
    if (in_root_frame(b, leave_world)) {  // S = 1: P is its six rows of M⁻¹
      for (int r = 0; r < 6; ++r)
        for (int c = vi; c < nv; ++c) P[r * nv + c] = Minv[(vi + r) * nv + c];
      continue;
    }
    if (!Pp && ni == 6) {  // a free root: P = S Minv_i· as one 6 x 6 (S's columns) on its six rows
      Mat6<S> Sm;
      for (int k = 0; k < 6; ++k) {
        S sk[6];
        store(Sw[k], sk);
        for (int r = 0; r < 6; ++r) Sm(r, k) = sk[r];
      }
      mat6_times_rows(Sm, Minv + vi * nv, nv, vi, nv, P, nv);
      continue;
    }
    for (int c = vi; c < nv; ++c) minv_forward_step(m, w, i, c, Minv, P + c, Pp ? Pp + c : nullptr, nv);
  }
}

// column c of M⁻¹ (its upper part and its joint blocks), after the articulated inertias (w.U, w.Dinv,
// w.S_world, w.X_world): minv_backward_pass's column work for c (the bodies whose subtree holds c,
// children first; F's column c in a local, w.F untouched) then minv_forward_pass's (the bodies with
// v_idx <= c, parents first). Column c reads and writes only column c of Minv and of w.P (here each
// body's P is nv x 6, a column's six entries together), so columns may run side by side (minv_team). Below the diagonal, only c's own joint block is written (the
// rest is zero until the mirror). The same values as the two passes
template <typename S> RBD_HD void minv_column(const ModelView<S>& m, Workspace<S>& w, int c, S* Minv) {
  const int nv = m.nv;
  for (int r = 0; r < nv; ++r) Minv[r * nv + c] = S(0);
  Force<S> fc = Force<S>::zero();  // F's column c
  RBD_UNROLL
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
  RBD_UNROLL
  for (int i = 0; i < m.nb; ++i)  // parents first
    if (m.body[i].v_idx <= c) {
      const int p = m.body[i].parent;
      minv_forward_step(m, w, i, c, Minv, w.P + 6 * nv * i + 6 * c, p >= 0 ? w.P + 6 * nv * p + 6 * c : nullptr, 1);
    }
}

// minv on a team of threads (model/team.hpp), for a model without mimic joints: the placements and
// body inertias side by side (world_placements_team, in minv_backward_pass's frame), the articulated
// inertias U, D⁻¹ (the only chain: IA_λ += IA - U D⁻¹ Uᵀ, children first) on one thread, then every
// column side by side (minv_column), then the lower triangle (mirrored when dense, else zero). The
// same values as minv (to the signs of zeros; leave_world as minv's). ok: where the team writes
// whether every D was positive definite (read it after the team's next barrier). An InlineTeam runs
// minv
template <typename S, typename Team>
RBD_HD void minv_team(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q, bool dense, S* Minv,
                      int* ok, bool leave_world = false) {
  if constexpr (!Team::cooperative) {
    *ok = minv_passes(m, w, q, dense, Minv, leave_world);
  } else {
    const int nv = m.nv;
    world_placements_team(
        t, m, w, q, true,
        [&](int i) {
          w.Ic[i] = reference_inertia(m, w, i, leave_world);
          w.IA[i] = Mat6<S>::from_inertia(w.Ic[i]);
        },
        leave_world);
    t.one([&] {
      *ok = 1;
      RBD_UNROLL
      for (int i = m.nb - 1; i >= 0; --i) {
        const BodyDesc<S>& b = m.body[i];
        Force<S>* U = w.U + 6 * i;
        S* Dinv = w.Dinv + 36 * i;
        if (!minv_joint_inertia(b, w.X_world[i], w.S_world + 6 * i, w.IA[i], U, Dinv, leave_world)) *ok = 0;
        else if (b.parent >= 0) add_articulated_residual(b.nv, w.IA[i], U, Dinv, w.IA[b.parent]);
      }
    });
    t.each(nv, [&](long c) { minv_column(m, w, static_cast<int>(c), Minv); });
    t.each2(nv, nv, [&](long r, long c) {
      if (r > c) Minv[r * nv + c] = dense ? Minv[c * nv + r] : S(0);
    });
  }
}

// ---- M⁻¹ through M's tree-sparse factorisation (crba.hpp's mass_factor), for a small tree
//
// Z = M⁻¹ from L Z = D⁻¹ L⁻ᵀ (unit upper L⁻ᵀ), row by row from the root:
//   Z_rc = -Σ_{j ∈ anc(r)} L_rj Z_jc  (c < r),   Z_rr = 1/D_r - Σ_{j ∈ anc(r)} L_rj Z_rj
// where every Z_jc is known by then (j, c < r: row j's own, or row c's mirrored). Columns outside r's
// root subtree are zero (M is block diagonal over the trees under the world). Each row's off-diagonal
// part is sums over contiguous runs. CRBA plus this took 0.45-0.7 of the direct passes' time on the
// iiwa, HyQ and fixed Atlas, 0.9 on floating HyQ and iiwa, 1.1 on floating Atlas (minv_factored_pays;
// docs/performance.md's ninth round).

// zr[c] = -Σ_j Hr[j] Z[j·n + c] for c in [c0, c1), over the DoFs j that ancestors(f) visits (f(j) for
// each, in its order): a row of M⁻¹ below its diagonal from its ancestors' rows. In host code that
// nvcc does not see, for double and float, four vectors of columns (RBD_HOST_VECTOR_BYTES each) per
// walk over the ancestors; the rest by minv_columns. Each entry summed in the same order
template <typename S, typename Ancestors>
RBD_HD_INLINE void minv_factored_row(const S* Hr, const S* RBD_RESTRICT Z, int n, int c0, int c1, S* RBD_RESTRICT zr,
                                     const Ancestors& ancestors) {
  int c = c0;
#if (defined(__GNUC__) || defined(__clang__)) && !defined(__CUDACC__)
  if constexpr (std::is_same<S, double>::value || std::is_same<S, float>::value) {
    typedef S V __attribute__((vector_size(RBD_HOST_VECTOR_BYTES)));
    constexpr int L = RBD_HOST_VECTOR_BYTES / sizeof(S);
    for (; c + 4 * L <= c1; c += 4 * L) {
      V acc[4] = {V{}, V{}, V{}, V{}};
      ancestors([&](int j) RBD_LAMBDA_INLINE {
        const S l = Hr[j];
        for (int k = 0; k < 4; ++k) acc[k] -= l * lanes_load<V>(Z + j * n + c + k * L);
      });
      for (int k = 0; k < 4; ++k) lanes_store(zr + c + k * L, acc[k]);
    }
  }
#endif
  minv_columns<S>(c, c1, [&](int cc, auto lane) RBD_LAMBDA_INLINE {
    using T = decltype(lane);
    T acc = lane;  // (zero)
    ancestors([&](int j) RBD_LAMBDA_INLINE { acc = acc - Hr[j] * lanes_load<T>(Z + j * n + cc); });
    lanes_store(zr + cc, acc);
  });
}

// minv_factored after its crba: from M's lower tree pattern in w.dense2 and the composites in w.Ic (as
// crba<kMassLowerPattern> leaves them), M's factor in place over w.dense2 (mass_factor_with), then M⁻¹'s
// rows, root first (Minv: as minv_factored's; false as there). walk: the DoF tree (crba.hpp's DofWalk)
template <typename S, typename Walk>
RBD_HD_INLINE bool minv_of_factor_with(const ModelView<S>& m, Workspace<S>& w, const Walk& walk, bool dense, S* Minv) {
  const int n = m.nv;
  const S* H = w.dense2;
  for (int k = 0; k < n * n; ++k) Minv[k] = S(0);
  if (!mass_factor_with(m, w, walk, w.dense2, Minv, n + 1)) return false;  // 1/D_k on Minv's diagonal
  // Z = M⁻¹, rows from the root; row r over [c0, r) accumulated over r's ancestors in registers
  walk.each_up([&](auto r) {
    int c0 = r;  // the first DoF of r's path
    walk.runs(r, [&](int j0, int) RBD_LAMBDA_INLINE { c0 = j0; });
    S* RBD_RESTRICT zr = Minv + r * n;
    const S* Hr = H + r * n;
    // f(j) for r's ancestors, root first (none at a root): the parent's row, the newest, enters each sum last
    auto ancestors = [&](auto&& f) RBD_LAMBDA_INLINE { walk.dofs_from_root(walk.parent(r), f); };
    minv_factored_row(Hr, Minv, n, c0, r, zr, ancestors);
    S d = zr[r];
    ancestors([&](int j) RBD_LAMBDA_INLINE { d -= Hr[j] * zr[j]; });
    zr[r] = d;
    for (int c = c0; c < r; ++c) Minv[c * n + r] = zr[c];
  });
  if (!dense)
    for (int r = 1; r < n; ++r)
      for (int c = 0; c < r; ++c) Minv[r * n + c] = S(0);
  return true;
}
// the same with the DoF tree from dof_tree, into w.so_i (2 nv ints)
template <typename S>
RBD_HD bool minv_of_mass_pattern(const ModelView<S>& m, Workspace<S>& w, bool dense, S* Minv) {
  dof_tree(m, w.so_i, w.so_i + m.nv);
  return minv_of_factor_with(m, w, DofWalk{w.so_i, w.so_i + m.nv, m.nv}, dense, Minv);
}

// Minv = M⁻¹ by crba and its factorisation (mass_factor), for a model without mimic joints (bodies
// depth-first: minv_factored_pays is false otherwise); the upper triangle, and the lower mirrored when
// dense. M's lower tree pattern (crba<kMassLowerPattern>), then its factor, in w.dense2 (its other
// entries stale), the DoF tree in w.so_i (2 nv ints); writes w.X_parent (placed: as crba's), w.Ic
// (composites) and w.F as crba does, not minv_backward_pass's placements. false where mass_factor
// refuses a pivot (stricter than the passes' check): minv then runs the passes, whose verdict stands
template <typename S> RBD_HD bool minv_factored(const ModelView<S>& m, Workspace<S>& w, const S* q, bool dense,
                                                S* Minv, bool placed = false) {
  crba<kMassLowerPattern>(m, w, q, w.dense2, placed);
  return minv_of_mass_pattern(m, w, dense, Minv);
}

// M⁻¹(q) by the direct passes, nv x nv row-major. dense: mirror the upper triangle into the lower;
// otherwise the strict lower triangle is zero. leave_world: the passes in world coordinates, else a
// tree with a free root in its root's frame (minv_backward_pass, world.hpp); they leave their
// placements and inertias in w for the derivative passes (forward_dynamics, aba_derivatives). false if
// M is not PD.
template <typename S>
RBD_HD bool minv_passes(const ModelView<S>& m, Workspace<S>& w, const S* q, bool dense, S* Minv,
                        bool leave_world = false) {
  const int nv = m.nv;
  if (m.has_mimic) {
    S* M = w.dense;
    crba(m, w, q, M);
    if (!spd_inverse(M, nv, Minv)) return false;
  } else {
    if (!minv_backward_pass(m, w, q, Minv, leave_world)) return false;
    minv_forward_pass(m, w, Minv, leave_world);
  }
  for (int r = 1; r < nv; ++r)
    for (int c = 0; c < r; ++c) Minv[r * nv + c] = dense ? Minv[c * nv + r] : S(0);
  return true;
}

// M⁻¹(q), nv x nv row-major (the minv operation): by M's factorisation where that pays
// (minv_factored_pays: small and branched trees), else, or where the factorisation's stricter pivot
// check fails, by the direct passes (minv_passes; leave_world as there). dense: mirror the upper
// triangle into the lower; otherwise the strict lower triangle is zero. Either way the same matrix to
// rounding. false if M is not PD (the passes' check).
template <typename S> RBD_FLATTEN
RBD_HD bool minv(const ModelView<S>& m, Workspace<S>& w, const S* q, bool dense, S* Minv, bool leave_world = false) {
  if (minv_factored_pays(m) && minv_factored(m, w, q, dense, Minv)) return true;
  return minv_passes(m, w, q, dense, Minv, leave_world);
}

// forward_dynamics's M⁻¹ by the factorisation, dense, into Minv (its w.dense): minv_factored where that pays
// (minv_factored_pays), on the joint placements the bias's RNEA left (crba's placed). false: it does not
// pay, or the pivot check refused, and forward_dynamics runs the passes. A compiled instance passes its
// own (codegen/unrolled.hpp's Unrolled::Factored: this CRBA body by body)
template <typename S> struct FactoredMinv {
  RBD_HD bool operator()(const ModelView<S>& m, Workspace<S>& w, const S* q, S* Minv) const {
    return minv_factored_pays(m) && minv_factored(m, w, q, true, Minv, true);
  }
};

// qdd = M⁻¹ (tau - c(q, qd, f_ext)): forward dynamics through the inverse.
// writes w.dense (M⁻¹ in its first nv² entries; with mimic joints M's Cholesky
// factor) and qdd (nv). M⁻¹ as minv takes it: by M's factorisation where that pays (factored), else
// by the direct passes. leave_world: as minv's. place: also leave in w the reference frame's
// placements, subspace columns and body inertias that the derivative passes reuse
// (rnea_derivatives's placed; w.X_parent, w.X_world, w.S_world, w.Ic), as the passes do anyway; after
// the factorisation one more pass writes them (reference_placements), with no joint placed again
template <typename S, typename Factored = FactoredMinv<S>> RBD_FLATTEN
RBD_HD bool forward_dynamics(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* tau,
                             const S* fext, S gravity, S* qdd, bool leave_world = false, bool place = false,
                             const Factored& factored = Factored{}) {
  const int nv = m.nv;
  S* r = w.dense + nv * nv + nv;  // residual tau - c
  bias_residual(m, w, q, qd, tau, fext, gravity, r);
  S* Mi = w.dense;
  if (m.has_mimic) {
    crba(m, w, q, Mi);
    if (!cholesky(Mi, nv)) return false;
    for (int k = 0; k < nv; ++k) qdd[k] = r[k];
    cholesky_solve(Mi, nv, qdd);
    return true;
  }
  if (factored(m, w, q, Mi)) {
    if (place) reference_placements(m, w, leave_world);
  } else if (!minv_passes(m, w, q, true, Mi, leave_world)) {
    return false;
  }
  matvec(InlineTeam{}, Mi, r, qdd, nv, nv);
  return true;
}

// forward_dynamics on a team of threads (model/team.hpp), for a model without mimic joints: M⁻¹ on
// the first warp (minv_team, into w.dense: w the full workspace) beside the bias c = RNEA(q, qd, 0,
// f_ext) on one thread, in a linear workspace of its own; then qdd = M⁻¹ (tau - c), a row per index.
// The same values as forward_dynamics where that runs the passes, the same to rounding where it
// factorises M (minv_factored_pays). extra: forward_dynamics_team_bytes(nb, nv) bytes (RNEA's
// workspace, tau - c, a flag); false, on every thread, where a D is not positive definite
template <typename S> RBD_HD unsigned long forward_dynamics_team_bytes(int nb, int nv) {
  return workspace_bytes<S>(nb, nv, kLinearWorkspace) + workspace_array_bytes<S>(nv) + 16;
}
template <typename S, typename Team>
RBD_HD bool forward_dynamics_team(const Team& t, const ModelView<S>& m, Workspace<S>& w, unsigned char* extra,
                                  const S* q, const S* qd, const S* tau, const S* fext, S gravity, S* qdd) {
  const int nv = m.nv;
  Workspace<S> wr = carve_workspace<S>(extra, m.nb, nv, kLinearWorkspace);
  S* r = reinterpret_cast<S*>(extra + workspace_bytes<S>(m.nb, nv, kLinearWorkspace));  // tau - c
  int* ok = reinterpret_cast<int*>(extra + forward_dynamics_team_bytes<S>(m.nb, nv) - 16);
  t.beside([&](const auto& sub) { minv_team(sub, m, w, q, true, w.dense, ok); },
           [&] {
             rnea(m, wr, q, qd, static_cast<const S*>(nullptr), fext, gravity, r);
             for (int k = 0; k < nv; ++k) r[k] = tau[k] - r[k];
           });
  if (!*ok) return false;  // (read after the barrier: the same on every thread)
  matvec(t, w.dense, r, qdd, nv, nv);
  return true;
}

}  // namespace rbd
