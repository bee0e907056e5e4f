// rbdkit/algorithms/crba.hpp — joint-space mass matrix by the composite
// rigid-body algorithm (Featherstone, RBDA §6.2, table 6.2).
//
// In body coordinates (crba): each composite inertia is moved to its parent's
// frame once, X_λi* Ic_i X_λi⁻¹, and the columns F = Ic_i s of a subtree ride
// up with it, one force transform per level; M's entries are Sᵀ F in each
// body's own frame, a pick of one component for a joint about a frame axis.
// This is the least work per body (no world placement, no world inertia) and
// Pinocchio's layout: joint i's rows of M over its subtree's columns at once.
//
// The body-frame pass needs each subtree's coordinates contiguous (bodies in
// depth-first order: subtrees_contiguous); a model on the general path
// (ModelView::has_mimic: mimic joints, or a ModelBuilder's bodies added
// otherwise) takes crba_world.
//
// Mimic joints (crba_world): a mimic body contributes mult·S to its target's
// column, so M accumulates every body pair's term into the (shared) columns;
// the result is Gᵀ M_full G for the reduced-coordinate map G. That pass works
// in world coordinates, where each body's inertia is moved to the world once,
// composites add without transforms and M_ji = s_j · (Ic_i s_i) is a dot
// product per ancestor.
#pragma once

#include <type_traits>

#include "rbdkit/algorithms/dense.hpp"
#include "rbdkit/algorithms/world.hpp"

namespace rbd {

// ---- body coordinates (models off the general path: no mimic joints, subtrees contiguous)

#if defined(RBD_HOST_AVX)
// F_c <- X* F_c for the n columns F (n x 6 row-major) in double under AVX: f_lin' = R f_lin as R's
// columns scaled by f_lin's entries, f_ang' = R f_ang + p × f_lin' with the cross product from two
// lane rotations, each lane with Transform::act's operations in their order; about 17 instructions a
// column where the scalar form takes 42 operations and 12 moves. The stores: f_lin' with an idle
// fourth lane over f_ang's first entry (read already), then f_ang' as two entries and one
inline void crba_act_columns_avx(const Transform<double>& X, double* F, int n) {
  typedef double V __attribute__((vector_size(32)));
  typedef double V2 __attribute__((vector_size(16)));
  const double* R = X.R.m;
  const V c0 = {R[0], R[3], R[6], 0}, c1 = {R[1], R[4], R[7], 0}, c2 = {R[2], R[5], R[8], 0};
  const V p = {X.p.x, X.p.y, X.p.z, 0};
  const V p_yzx = __builtin_shufflevector(p, p, 1, 2, 0, 3), p_zxy = __builtin_shufflevector(p, p, 2, 0, 1, 3);
  for (int c = 0; c < n; ++c) {
    double* f = F + 6 * c;
    const V fl = (c0 * f[0] + c1 * f[1]) + c2 * f[2];
    const V fl_zxy = __builtin_shufflevector(fl, fl, 2, 0, 1, 3), fl_yzx = __builtin_shufflevector(fl, fl, 1, 2, 0, 3);
    const V fa = ((c0 * f[3] + c1 * f[4]) + c2 * f[5]) + (p_yzx * fl_zxy - p_zxy * fl_yzx);
    __builtin_memcpy(f, &fl, sizeof fl);
    const V2 fa01 = {fa[0], fa[1]};
    __builtin_memcpy(f + 3, &fa01, sizeof fa01);
    f[5] = fa[2];
  }
}
#endif

// which frame-axis form a rotation has: 3 K + ρ where R = P R_K(θ), a turn about frame axis K followed
// by a signed permutation P that takes axis K to axis ρ (a revolute joint about a frame axis under a
// placement of quarter turns, or of none: P = 1, ρ = K), read off R's exact zeros: column K and row ρ
// are zero but for R(ρ, K) = ±1, so that each other row has its two nonzeros in the two columns other
// than K. -1: none (a general rotation). z is tried first: most URDF joints turn about it, and R = 1,
// which every K fits, then reads as Form 8, the one form the device also compiles
template <typename S> RBD_HD_INLINE int frame_turn_form(const Mat3<S>& R) {
  for (int t = 0; t < 3; ++t) {
    const int k = t == 0 ? 2 : t - 1;  // z, x, y
    const int k1 = k == 2 ? 0 : k + 1, k2 = k == 0 ? 2 : k - 1;
    for (int rho = 0; rho < 3; ++rho) {
      const int r1 = rho == 2 ? 0 : rho + 1, r2 = rho == 0 ? 2 : rho - 1;
      if (R(rho, k1) == S(0) && R(rho, k2) == S(0) && R(r1, k) == S(0) && R(r2, k) == S(0)) return 3 * k + rho;
    }
  }
  return -1;
}

// F <- X* F for one column x[0..6) (its components l0 l1 l2 a0 a1 a2; or, V a vector, a column per
// lane) from X's R (row-major) and p as values of C (S, or S in every lane of V): with Transform::act's
// operations in their order (Form -1), or in R's frame-axis form Form = 3 K + ρ (frame_turn_form), each
// row but ρ two products and row ρ one, R(ρ, K) x_K: 26 operations a column where the general form
// takes 42, with the same values for finite columns up to the sign of a zero (the general form's sums
// (R_r0 x_0 + R_r1 x_1) + R_r2 x_2 add the same nonzero products in the same order, and exact zeros)
template <int Form, typename C, typename V>
RBD_HD_INLINE void crba_act_lanes(const C* R, const C& px, const C& py, const C& pz, V* x) {
  V l[3], a[3];
  if constexpr (Form < 0) {
    for (int r = 0; r < 3; ++r) {
      l[r] = (R[3 * r] * x[0] + R[3 * r + 1] * x[1]) + R[3 * r + 2] * x[2];
      a[r] = (R[3 * r] * x[3] + R[3 * r + 1] * x[4]) + R[3 * r + 2] * x[5];
    }
  } else {
    constexpr int K = Form / 3, rho = Form % 3;
    constexpr int c0 = K == 0 ? 1 : 0, c1 = K == 2 ? 1 : 2;  // the columns other than K, in order
    for (int r = 0; r < 3; ++r) {
      if (r == rho) {
        l[r] = R[3 * r + K] * x[K];
        a[r] = R[3 * r + K] * x[3 + K];
      } else {
        l[r] = R[3 * r + c0] * x[c0] + R[3 * r + c1] * x[c1];
        a[r] = R[3 * r + c0] * x[3 + c0] + R[3 * r + c1] * x[3 + c1];
      }
    }
  }
  x[0] = l[0], x[1] = l[1], x[2] = l[2];
  x[3] = a[0] + (py * l[2] - pz * l[1]), x[4] = a[1] + (pz * l[0] - px * l[2]);
  x[5] = a[2] + (px * l[1] - py * l[0]);
}

// f(std::integral_constant<int, Form>{}) with R's frame_turn_form (read from a real scalar's values;
// a pack or a dual number takes the general form, Form -1). On a device only Form 8 (a turn about z
// under no turn) has its own instance, which keeps the kernels' code small
template <typename S, typename F> RBD_HD_INLINE void with_frame_turn_form(const Mat3<S>& R, F&& f) {
  int form = -1;
  if constexpr (std::is_floating_point<S>::value) form = frame_turn_form(R);
  typedef std::integral_constant<int, -1> General;
#if defined(__CUDA_ARCH__)
  if (form == 8) return f(std::integral_constant<int, 8>{});
  return f(General{});
#else
  switch (form) {
    case 0: return f(std::integral_constant<int, 0>{});
    case 1: return f(std::integral_constant<int, 1>{});
    case 2: return f(std::integral_constant<int, 2>{});
    case 3: return f(std::integral_constant<int, 3>{});
    case 4: return f(std::integral_constant<int, 4>{});
    case 5: return f(std::integral_constant<int, 5>{});
    case 6: return f(std::integral_constant<int, 6>{});
    case 7: return f(std::integral_constant<int, 7>{});
    case 8: return f(std::integral_constant<int, 8>{});
    default: return f(General{});
  }
#endif
}

#if defined(RBD_HOST_LANES) && !defined(RBD_HOST_AVX) && defined(__SSE2__)
#define RBD_CRBA_COLUMN_PAIRS 1
// crba_act_columns in double on an x86-64 without AVX (the library's baseline, the benchmark's
// generic rows): two columns at a time, lane l of each 2-lane vector a component of column c + l, so
// that each lane runs the scalar form's operations in their order (crba_act_lanes: without fused
// multiply-adds the columns are the scalar loop's bit for bit) and an operation serves two columns:
// 42 vector operations and 24 moves for two columns where the scalar form takes 42 operations and 12
// moves for one
inline void crba_act_column_pairs(const Transform<double>& X, double* F, int n) {
  typedef double V __attribute__((vector_size(16)));
  const double* R = X.R.m;
  with_frame_turn_form(X.R, [&](auto form) {
    constexpr int Form = decltype(form)::value;
    int c = 0;
    if (n >= 2) {
      V r[9];  // R and p in both lanes, once for the subtree's columns
      for (int k = 0; k < 9; ++k) r[k] = V{R[k], R[k]};
      const V px = {X.p.x, X.p.x}, py = {X.p.y, X.p.y}, pz = {X.p.z, X.p.z};
      for (; c + 2 <= n; c += 2) {
        double* f = F + 6 * c;  // column c, then column c + 1
        V x[6];
        for (int k = 0; k < 6; ++k) x[k] = V{f[k], f[6 + k]};
        crba_act_lanes<Form>(r, px, py, pz, x);
        for (int k = 0; k < 6; ++k) f[k] = x[k][0], f[6 + k] = x[k][1];
      }
    }
    if (c < n) crba_act_lanes<Form>(R, X.p.x, X.p.y, X.p.z, F + 6 * c);
  });
}
#endif

// F_c <- X* F_c for the n columns F (n x 6 row-major), crba_act_lanes column by column, in R's
// frame-axis form where it has one (with_frame_turn_form: a revolute joint about a frame axis under a
// placement of quarter turns or of none; with the URDF reader's snap of near quarter turns every
// column transform of the iiwa and HyQ): 26 operations a column where the general transform takes 42.
// In double under AVX (crba_act_columns_avx) every column goes through 4-lane vectors instead, and on
// an x86-64 without AVX two columns at a time (crba_act_column_pairs)
template <typename S> RBD_HD void crba_act_columns(const Transform<S>& X, S* F, int n) {
#if defined(RBD_HOST_AVX)
  if constexpr (std::is_same<S, double>::value) return crba_act_columns_avx(X, F, n);
#elif defined(RBD_CRBA_COLUMN_PAIRS)
  if constexpr (std::is_same<S, double>::value) return crba_act_column_pairs(X, F, n);
#endif
  with_frame_turn_form(X.R, [&](auto form) {
    for (int c = 0; c < n; ++c) crba_act_lanes<decltype(form)::value>(X.R.m, X.p.x, X.p.y, X.p.z, F + 6 * c);
  });
}

// which of M's entries crba writes: both triangles (M whole: the entries of DoF pairs neither of
// which is the other's ancestor zeroed), the upper triangle (the strict lower one zeroed: the upper
// triangle is what Pinocchio's crba writes, and a Cholesky factorisation reads), or the lower
// triangle's tree pattern alone (the (DoF, ancestor DoF) pairs and the joints' own blocks; nothing
// zeroed: mass_factor reads and writes no other entry)
enum MassEntries { kMassFull, kMassUpper, kMassLowerPattern };

// writes M's rows of body i's DoFs over its subtree's columns [v_i, v_i + nv_subtree) from
// the columns F (F(c, k): component k of column c, each in body i's frame) into the upper triangle,
// and mirrored into the lower one (E: MassEntries, which of the two). Over the pass every entry of M
// that can be nonzero is assigned, off the diagonal once (the columns before v_i: by i's ancestors'
// rows); the others (neither in i's subtree nor its ancestors') stay as the pass found them.
// fc, sign: joint_frame_column(b, sign)
template <int E, typename S, typename Columns>
RBD_HD_INLINE void crba_store_rows_of(const ModelView<S>& m, int i, int fc, const S& sign, const Columns& F, S* M) {
  constexpr bool upper = E != kMassLowerPattern, lower = E != kMassUpper;
  const BodyDesc<S>& b = m.body[i];
  const int nv = m.nv, vi = b.v_idx, c_end = vi + b.nv_subtree;
  auto put = [&](int r, int c, const S& x) {  // M_rc = M_cr = x (r <= c)
    if (upper) M[r * nv + c] = x;
    if (lower) M[c * nv + r] = x;
  };
  if (fc >= 0) {  // S = sign·e_fc: Sᵀ F is one component
    for (int c = vi; c < c_end; ++c) put(vi, c, sign * F(c, fc));
  } else if (b.type == kFree) {  // S = 1: the rows are the columns F themselves
    for (int c = vi; c < vi + 6; ++c)  // the joint's own block: its upper triangle, mirrored
      for (int l = 0; l <= c - vi; ++l) put(vi + l, c, F(c, l));
    for (int c = vi + 6; c < c_end; ++c)
      for (int l = 0; l < 6; ++l) put(vi + l, c, F(c, l));
  } else {
    for (int c = vi; c < c_end; ++c) {
      S x[6];
      joint_project(b, Force<S>{{F(c, 0), F(c, 1), F(c, 2)}, {F(c, 3), F(c, 4), F(c, 5)}}, x);
      // the joint's own block: its upper triangle only (l <= c - vi), mirrored
      for (int l = 0; l < b.nv && vi + l <= c; ++l) put(vi + l, c, x[l]);
    }
  }
}
// the same, F nv x 6 row-major (column c at F + 6 c)
template <int E, typename S>
RBD_HD void crba_store_rows(const ModelView<S>& m, int i, int fc, const S& sign, const S* F, S* M) {
  crba_store_rows_of<E>(m, i, fc, sign, [F](int c, int k) { return F[6 * c + k]; }, M);
}

// body i's columns F_c = Ic s_c (c = v_i ..), each written by put(c, F_c): for a joint about a frame
// axis (fc >= 0: joint_frame_column(b, sign)) sign times a column of Ic, for a free joint Ic's six
// columns, no products; else Ic times each column of S
template <typename S, typename Put>
RBD_HD_INLINE void crba_joint_columns(const BodyDesc<S>& b, int fc, const S& sign, const Inertia<S>& Ic, Put&& put) {
  if (fc >= 0) put(b.v_idx, sign * Ic.column(fc));
  else if (b.type == kFree) for (int k = 0; k < 6; ++k) put(b.v_idx + k, Ic.column(k));
  else for (int k = 0; k < b.nv; ++k) put(b.v_idx + k, Ic * joint_subspace_col(b, k));
}

// backward pass, bodies last to first, on M zeroed first unless E (MassEntries) is the lower
// pattern (one contiguous fill: on a branched tree most of M is zero, and zeroing each row's columns
// past the subtree with their mirrored column took 6 % of Atlas's instructions, strided):
//   F_c = Ic_i s_c for body i's DoFs c               (its columns join the subtree's; picks from Ic
//                                                     for a frame-axis or free joint)
//   M[v_i.., subtree] = S_iᵀ F                        (crba_store_rows)
//   Ic_λ += X_λi* Ic_i X_λi⁻¹,  F_subtree <- X_λi* F  (both now in the parent's frame)
// reads w.X_parent; writes w.Ic (composites, body frames), w.F (nv x 6: the columns), M
template <int E, typename S> RBD_HD void crba_body_backward_pass(const ModelView<S>& m, Workspace<S>& w, S* M) {
  S* F = w.F;
  if (E != kMassLowerPattern)
    for (int k = 0; k < m.nv * m.nv; ++k) M[k] = S(0);
  RBD_UNROLL
  for (int i = m.nb - 1; i >= 0; --i) {
    const BodyDesc<S>& b = m.body[i];
    const int vi = b.v_idx, c_end = vi + b.nv_subtree;
    S sign;
    const int fc = joint_frame_column(b, sign);
    crba_joint_columns(b, fc, sign, w.Ic[i], [F](int c, const Force<S>& f) { store(f, F + 6 * c); });
    crba_store_rows<E>(m, i, fc, sign, F, M);
    if (b.parent >= 0) {
      const Transform<S>& X = w.X_parent[i];
      w.Ic[b.parent] += transform_inertia(X, w.Ic[i]);
      crba_act_columns(X, F + 6 * vi, c_end - vi);
    }
  }
}

// ---- world coordinates (the general path; crba_forward_pass also serves centroidal.hpp)

// forward pass: world placements, subspace columns, world body inertias
//   writes w.X_parent, w.X_world, w.S_world, w.Ic
template <typename S> RBD_HD void crba_forward_pass(const ModelView<S>& m, Workspace<S>& w, const S* q) {
  place_joints(m, w.X_parent, q);
  RBD_UNROLL
  for (int i = 0; i < m.nb; ++i) {
    placed_world(m, w, i);
    w.Ic[i] = transform_inertia(w.X_world[i], m.body[i].I);
  }
}

// M_ji for the DoFs of ancestor j against one column F = Ic_i s: s_jᵀ F, written
// to both triangles (add: accumulated, for mimic models). joint_project_in: a
// free joint's six products are one force transform, X_0j⁻¹ F
template <typename S>
RBD_HD void crba_store_ancestor(const ModelView<S>& m, Workspace<S>& w, int j, const Force<S>& F, int c, bool add,
                                S* M) {
  const BodyDesc<S>& bj = m.body[j];
  const int nv = m.nv;
  S x[6];
  joint_project_in(bj, w.X_world[j], w.S_world + 6 * j, F, x);
  for (int l = 0; l < bj.nv; ++l) {
    S& upper = M[(bj.v_idx + l) * nv + c];
    S& lower = M[c * nv + bj.v_idx + l];
    if (add) upper += x[l], lower += x[l];
    else upper = x[l], lower = x[l];
  }
}

// column c = v_i + k of M in world coordinates: F = Ic_i s_k with Ic_i body i's composite, M's entries
// of c against i's own DoFs l <= k and against every ancestor's DoFs, both triangles (add:
// accumulated, for mimic models). Without mimic joints a column writes only entries no other
// column writes (each (ancestor, descendant) pair of DoFs belongs to the descendant's column)
template <typename S>
RBD_HD void crba_world_column(const ModelView<S>& m, Workspace<S>& w, int i, int k, bool add, S* M) {
  const int nv = m.nv;
  const BodyDesc<S>& bi = m.body[i];
  const Motion<S>* si = w.S_world + 6 * i;
  const Force<S> F = w.Ic[i] * si[k];  // (one DoF, the common case: F stays in registers)
  const int c = bi.v_idx + k;
  // diagonal block: the joint's own DoFs l <= k (both triangles)
  for (int l = 0; l <= k; ++l) {
    const S x = dot(si[l], F);
    S& upper = M[(bi.v_idx + l) * nv + c];
    S& lower = M[c * nv + bi.v_idx + l];
    if (add) {
      upper += x;
      if (l != k) lower += x;
    } else {
      upper = x, lower = x;
    }
  }
  for (int j = bi.parent; j >= 0; j = m.body[j].parent) crba_store_ancestor(m, w, j, F, c, add, M);
}

// backward pass: F = Ic_i s_i, M_ji = s_jᵀ F for j = i and its ancestors (crba_world_column),
// Ic_λ += Ic_i. writes M (nv x nv, row-major), w.Ic (subtree sums).
// Without mimic joints each (ancestor, descendant) pair of DoFs is met once,
// so both triangles are assigned; a mimic body adds into its target's columns.
template <typename S> RBD_HD void crba_backward_pass(const ModelView<S>& m, Workspace<S>& w, S* M) {
  const int nv = m.nv;
  const bool add = m.has_mimic;
  for (int k = 0; k < nv * nv; ++k) M[k] = S(0);
  RBD_UNROLL
  for (int i = m.nb - 1; i >= 0; --i) {
    // one column per DoF of the joint, walked up the ancestors
    for (int k = 0; k < m.body[i].nv; ++k) crba_world_column(m, w, i, k, add, M);
    if (m.body[i].parent >= 0) w.Ic[m.body[i].parent] += w.Ic[i];
  }
}

// M in world coordinates (any model: mimic joints, any body order)
template <typename S> RBD_HD void crba_world(const ModelView<S>& m, Workspace<S>& w, const S* q, S* M) {
  crba_forward_pass(m, w, q);
  crba_backward_pass(m, w, M);
}

// M(q), nv x nv row-major, symmetric; E (MassEntries): M whole (the default), its upper triangle
// (zeros below) or its lower tree pattern. In body coordinates (writes w.X_parent, w.Ic, w.F), on the
// general path in world coordinates (crba_world: M whole, then the lower triangle zeroed for the
// upper). placed: w.X_parent already holds q's joint placements (rnea leaves them), which the
// body-frame pass then reads as they are
template <int E = kMassFull, typename S>
RBD_HD void crba(const ModelView<S>& m, Workspace<S>& w, const S* q, S* M, bool placed = false) {
  if (m.has_mimic) {
    crba_world(m, w, q, M);
    if (E == kMassUpper)
      for (int r = 1; r < m.nv; ++r)
        for (int c = 0; c < r; ++c) M[r * m.nv + c] = S(0);
    return;
  }
  if (!placed) place_joints(m, w.X_parent, q);
  RBD_UNROLL
  for (int i = 0; i < m.nb; ++i) w.Ic[i] = m.body[i].I;
  crba_body_backward_pass<E>(m, w, M);
}

// ---- M's tree-sparse factorisation (Featherstone, RBDA §6.5), for a small tree
//
// M = Lᵀ D L with L unit lower triangular, L_kj ≠ 0 only where j is an ancestor DoF of k (the
// DoF tree: a joint's DoFs in a chain under its parent's last), computed in place over M's lower
// triangle from the leaves up in O(Σ_k depth_k²):
//   for k = nv-1 .. 0:  D_k = H_kk;  for i ∈ anc(k):  a = H_ki / D_k,  H_ij -= a H_kj (j ∈ anc(i) ∪ {i}),  H_ki = a
// For a one-DoF joint D_k is its articulated inertia sᵀ IA s, the direct passes' D (for a multi-DoF
// joint, the pivots of the passes' D block). M⁻¹ (minv.hpp's minv_factored) and forward dynamics (aba,
// M x = tau - c by two sweeps over L and one over D) take it where it pays (minv_factored_pays).

// lambda[k]: DoF k's parent DoF (-1 under the world); run[k]: the first DoF of the chain of
// consecutive DoFs that ends at k (lambda[j] = j - 1 for j in (run[k], k]). A DoF's ancestors are then
// a few contiguous runs: [run[k], k], then [run[e], e] for e = lambda[run[k]], and so on up to the
// world (one run on a chain like the iiwa's). Bodies in depth-first order (no mimic joints)
template <typename S> RBD_HD constexpr void dof_tree(const ModelView<S>& m, int* lambda, int* run) {
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    const BodyDesc<S>* p = b.parent >= 0 ? &m.body[b.parent] : nullptr;
    int up = p ? p->v_idx + p->nv - 1 : -1;
    for (int k = b.v_idx; k < b.v_idx + b.nv; ++k) {
      lambda[k] = up;
      run[k] = up >= 0 && up == k - 1 ? run[up] : k;
      up = k;
    }
  }
}

// f(first, last) for each run of DoF k's ancestors and k itself (dof_tree), from k up
template <typename F> RBD_HD_INLINE void for_dof_path(const int* lambda, const int* run, int k, F&& f) {
  for (int e = k; e >= 0; e = lambda[run[e]]) f(run[e], e);
}

// the DoF tree as the factorisation walks it (mass_factor_with, minv.hpp's minv_of_factor_with), here from
// dof_tree's arrays at run time, a DoF an int; codegen/unrolled.hpp walks a robot's constant tree, a DoF
// an integral constant, with every loop bound known to the compiler
struct DofWalk {
  const int* lambda;
  const int* run;
  int n;  // nv
  RBD_HD_INLINE int parent(int k) const { return lambda[k]; }
  // f(j0, j1) for each run [j0, j1] of DoF e's path (e and its ancestors), from e up; none for e < 0
  template <class F> RBD_HD_INLINE void runs(int e, F&& f) const { for_dof_path(lambda, run, e, f); }
  // f(i) for each DoF i of e's path, nearest first
  template <class F> RBD_HD_INLINE void dofs(int e, F&& f) const {
    runs(e, [&](int i0, int i1) RBD_LAMBDA_INLINE {
      for (int i = i1; i >= i0; --i) f(i);
    });
  }
  // f(i) for each DoF i of e's path, root first: the runs from the root's down (each found by climbing
  // from e to the run below the last one visited; a path has few runs), each run in increasing order
  template <class F> RBD_HD_INLINE void dofs_from_root(int e, F&& f) const {
    if (e < 0) return;
    for (int above = -1; above != e;) {  // above: the last DoF visited (-1: none yet)
      int k = e;
      while (lambda[run[k]] != above) k = lambda[run[k]];
      for (int i = run[k]; i <= k; ++i) f(i);
      above = k;
    }
  }
  // f(k) for k = n-1 .. 0 while f returns true; false if one did not
  template <class F> RBD_HD_INLINE bool each_down(F&& f) const {
    for (int k = n - 1; k >= 0; --k)
      if (!f(k)) return false;
    return true;
  }
  // f(k) for k = 0 .. n-1
  template <class F> RBD_HD_INLINE void each_up(F&& f) const {
    for (int k = 0; k < n; ++k) f(k);
  }
};

// whether minv and aba take the factorisation: Σ_i nv_i · nv_subtree_i, the (ancestor DoF, DoF) pairs of the
// tree (L's nonzeros below the diagonal, plus the joints' own), at most 9 per DoF. Measured (-march=native
// harness, factored against the passes): iiwa 4 per DoF (375 against 582 ns), fixed HyQ 2 (432 against
// 972), fixed Atlas 5 (1960 against 2873), floating HyQ 7.3 (1110 against 1256), floating iiwa 8.2 (835
// against 884), floating Atlas 10.2 (3538 against 3250). O(nb): it runs on every call
template <typename S> RBD_HD bool minv_factored_pays(const ModelView<S>& m) {
  if (m.has_mimic) return false;
  long pairs = 0;
  for (int i = 0; i < m.nb; ++i) pairs += static_cast<long>(m.body[i].nv) * m.body[i].nv_subtree;
  return pairs <= 9L * m.nv;
}

// y[j] -= a x[j] for j in [j0, j1]: in host code RBD_HOST_VECTOR_BYTES at a time, then one by one (each
// entry's one operation either way; over a constant tree, codegen/unrolled.hpp, the bounds are constants)
template <typename S> RBD_HD_INLINE void sub_scaled_run(S* RBD_RESTRICT y, const S* RBD_RESTRICT x, S a, int j0, int j1) {
  int j = j0;
#if defined(RBD_HOST_LANES)
  if constexpr (std::is_same<S, double>::value) {
    typedef double V __attribute__((vector_size(RBD_HOST_VECTOR_BYTES)));
    constexpr int L = RBD_HOST_LANES;
    for (; j + L <= j1 + 1; j += L) {
      V xv, yv;
      __builtin_memcpy(&xv, x + j, sizeof xv);
      __builtin_memcpy(&yv, y + j, sizeof yv);
      yv -= a * xv;
      __builtin_memcpy(y + j, &yv, sizeof yv);
    }
  }
#endif
  for (; j <= j1; ++j) y[j] -= a * x[j];
}

// H (nv x nv, row-major, M from crba: its lower triangle) <- L below the diagonal, in place, leaves
// first; dinv[k·stride] <- 1/D_k. lambda, run: dof_tree's. Each pivot's scale first (in dinv):
// Σ_r Ic_rr s_r² of the joint's column s against its composite inertia (w.Ic, as crba leaves it), the
// size of the terms of M_kk = sᵀ Ic s, so that a rod turned about its own axis, whose M_kk is rounding
// noise, is singular as in the direct passes. false if some D_k is at the rounding level of its terms
// or below (pivot_positive): stricter than the passes' check on the articulated inertia (a light link
// under a coaxial joint carrying a heavy one has D_k far below sᵀ Ic s), so a caller then runs the
// passes, whose verdict stands. walk: the DoF tree (DofWalk)
template <typename S, typename Walk>
RBD_HD_INLINE bool mass_factor_with(const ModelView<S>& m, const Workspace<S>& w, const Walk& walk, S* H, S* dinv,
                                    int stride) {
  const int n = m.nv;
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    const Inertia<S>& Ic = w.Ic[i];
    for (int l = 0; l < b.nv; ++l) {
      const Motion<S> s = joint_subspace_col(b, l);
      dinv[(b.v_idx + l) * stride] = Ic.m * dot(s.lin, s.lin) + Ic.I(0, 0) * (s.ang.x * s.ang.x) +
                                     Ic.I(1, 1) * (s.ang.y * s.ang.y) + Ic.I(2, 2) * (s.ang.z * s.ang.z);
    }
  }
  // LTDL; each ancestor i of k (nearest first) takes H_i· -= a H_k· over its own path
  return walk.each_down([&](auto k) {
    const S dk = H[k * n + k];
    if (!pivot_positive(dk, dinv[k * stride])) return false;
    const S di = S(1) / dk;
    dinv[k * stride] = di;
    S* RBD_RESTRICT Hk = H + k * n;
    walk.dofs(walk.parent(k), [&](auto i) RBD_LAMBDA_INLINE {
      const S a = Hk[i] * di;
      S* RBD_RESTRICT Hi = H + i * n;
      walk.runs(i, [&](int j0, int j1) RBD_LAMBDA_INLINE { sub_scaled_run(Hi, Hk, a, j0, j1); });
      Hk[i] = a;
    });
    return true;
  });
}
// the same on dof_tree's arrays
template <typename S>
RBD_HD bool mass_factor(const ModelView<S>& m, const Workspace<S>& w, const int* lambda, const int* run, S* H,
                        S* dinv, int stride) {
  return mass_factor_with(m, w, DofWalk{lambda, run, m.nv}, H, dinv, stride);
}

// M(q)'s lower tree pattern by crba into w.dense2 (placed: as crba's; its other entries are left as
// they were), the DoF tree into w.so_i (lambda, then run: 2 nv ints), then mass_factor (1/D_k at
// dinv[k·stride]); false as mass_factor. Writes w.X_parent (unless placed), w.Ic (composites) and w.F
// as crba does
template <typename S>
RBD_HD bool crba_factored(const ModelView<S>& m, Workspace<S>& w, const S* q, bool placed, S* dinv, int stride) {
  crba<kMassLowerPattern>(m, w, q, w.dense2, placed);
  dof_tree(m, w.so_i, w.so_i + m.nv);
  return mass_factor(m, w, w.so_i, w.so_i + m.nv, w.dense2, dinv, stride);
}

// x (nv) <- M⁻¹ x = L⁻¹ D⁻¹ L⁻ᵀ x from mass_factor's L (in H) and 1/D (dinv, stride): x_i -= L_ki x_k
// for k's ancestors i, leaves first; x_k *= 1/D_k; x_k -= Σ_i L_ki x_i, root first
template <typename S>
RBD_HD void mass_factor_solve(int n, const int* lambda, const int* run, const S* H, const S* dinv, int stride,
                              S* x) {
  for (int k = n - 1; k >= 0; --k) {
    const S xk = x[k];
    const S* Hk = H + k * n;
    for_dof_path(lambda, run, lambda[k], [&](int i0, int i1) {
      for (int i = i0; i <= i1; ++i) x[i] -= Hk[i] * xk;
    });
  }
  for (int k = 0; k < n; ++k) x[k] *= dinv[k * stride];
  for (int k = 0; k < n; ++k) {
    S xk = x[k];
    const S* Hk = H + k * n;
    for_dof_path(lambda, run, lambda[k], [&](int i0, int i1) {
      for (int i = i0; i <= i1; ++i) xk -= Hk[i] * x[i];
    });
    x[k] = xk;
  }
}

// crba on a team of threads (model/team.hpp), for a model without mimic joints: crba_world's passes
// in the root's reference frame (world.hpp, as minv_team's). M zeroed (each); the placements,
// subspace columns and body inertias side by side (world_placements_team); the composites
// Ic_λ += Ic_i, children first, on one thread (a chain, as the placements are); then every column side by side
// (crba_world_column: a column writes only its own entries). An InlineTeam runs crba (body
// coordinates: the same M to rounding)
template <typename S, typename Team>
RBD_HD void crba_team(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q, S* M) {
  if constexpr (!Team::cooperative) {
    crba(m, w, q, M);
  } else {
    t.each(static_cast<long>(m.nv) * m.nv, [&](long k) { M[k] = S(0); });
    world_placements_team(
        t, m, w, q, true, [&](int i) { w.Ic[i] = reference_inertia(m, w, i, false); }, false);
    t.one([&] {
      RBD_UNROLL
      for (int i = m.nb - 1; i >= 0; --i)
        if (m.body[i].parent >= 0) w.Ic[m.body[i].parent] += w.Ic[i];
    });
    t.each(m.nv, [&](long c) {
      int i = 0;  // the body whose joint has DoF c
      while (i + 1 < m.nb && c >= m.body[i].v_idx + m.body[i].nv) ++i;
      crba_world_column(m, w, i, static_cast<int>(c) - m.body[i].v_idx, false, M);
    });
  }
}

}  // namespace rbd
