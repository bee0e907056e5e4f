// rbdkit/algorithms/crba.hpp — joint-space mass matrix by the composite
// rigid-body algorithm (Featherstone, RBDA §6.2, table 6.2).
//
//
// Mimic joints: a mimic body contributes mult·S to its target's column, so
// M accumulates every body pair's term into the (shared) columns; the
// result is Gᵀ M_full G for the reduced-coordinate map G.
#pragma once

#include "rbdkit/algorithms/world.hpp"

namespace rbd {

// Everything in world coordinates: each body inertia is moved to the world
// once, composites add without transforms, and M_ji = s_j · (Ic_i s_i) is a
// dot product per ancestor (no force is carried up the chain).

// forward pass: world placements, subspace columns, world body inertias
//   writes w.X_parent, w.X_world, w.S_world, w.Ic
template <typename S> RBD_HD void crba_forward_pass(const ModelView<S>& m, Workspace<S>& w, const S* q) {
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    world_placement(m, w, q, i);
    w.Ic[i] = transform_inertia(w.X_world[i], b.I);
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

// backward pass: F = Ic_i s_i, M_ji = s_jᵀ F for j = i and its ancestors,
// Ic_λ += Ic_i. writes M (nv x nv, row-major), w.Ic (subtree sums).
// Without mimic joints each (ancestor, descendant) pair of DoFs is met once,
// so both triangles are assigned; a mimic body adds into its target's columns.
template <typename S> RBD_HD void crba_backward_pass(const ModelView<S>& m, Workspace<S>& w, S* M) {
  const int nv = m.nv;
  const bool add = m.has_mimic;
  for (int k = 0; k < nv * nv; ++k) M[k] = S(0);
  for (int i = m.nb - 1; i >= 0; --i) {
    const BodyDesc<S>& bi = m.body[i];
    const Motion<S>* si = w.S_world + 6 * i;
    // one column F = Ic s per DoF of the joint, walked up the ancestors (one
    // DoF, the common case: F stays in registers)
    for (int k = 0; k < bi.nv; ++k) {
      const Force<S> F = w.Ic[i] * si[k];
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
    if (bi.parent >= 0) w.Ic[bi.parent] += w.Ic[i];
  }
}

// M(q), nv x nv row-major, symmetric
template <typename S> RBD_HD void crba(const ModelView<S>& m, Workspace<S>& w, const S* q, S* M) {
  crba_forward_pass(m, w, q);
  crba_backward_pass(m, w, M);
}

}  // namespace rbd
