// rbdkit/algorithms/crba.hpp — joint-space mass matrix by the composite
// rigid-body algorithm (Featherstone, RBDA §6.2, table 6.2).
//
// Mimic joints: a mimic body contributes mult·S to its target's column, so
// M accumulates every body pair's term into the (shared) columns; the
// result is Gᵀ M_full G for the reduced-coordinate map G.
#pragma once

#include "../workspace.hpp"

namespace rbd {

// forward pass: body transforms and composite inertias initialised
template <typename S> RBD_HD void crba_forward_pass(const ModelView<S>& m, Workspace<S>& w, const S* q) {
  for (int i = 0; i < m.nb; ++i) {
    w.X[i] = body_transform(m.body[i], q);
    w.Ic[i] = m.body[i].I;
  }
}

// backward pass: F = Ic_i S_i carried up the support chain, M (nv x nv, row-major)
template <typename S> RBD_HD void crba_backward_pass(const ModelView<S>& m, Workspace<S>& w, S* M) {
  const int nv = m.nv;
  for (int k = 0; k < nv * nv; ++k) M[k] = S(0);
  for (int i = m.nb - 1; i >= 0; --i) {
    const BodyDesc<S>& bi = m.body[i];
    // F_k = Ic_i S_k for each DoF k of joint i
    Force<S> F[6];
    for (int k = 0; k < bi.nv; ++k) F[k] = w.Ic[i] * joint_subspace_col(bi, k);
    // diagonal block: M_ii = S_iᵀ F
    for (int k = 0; k < bi.nv; ++k) {
      S col[6];
      joint_project(bi, F[k], col);
      for (int l = 0; l < bi.nv; ++l) M[(bi.v_idx + l) * nv + bi.v_idx + k] += col[l];
    }
    // off-diagonal blocks: walk to the root, M_ji = S_jᵀ X F (and its transpose)
    int j = i;
    while (m.body[j].parent >= 0) {
      for (int k = 0; k < bi.nv; ++k) F[k] = w.X[j].act(F[k]);
      j = m.body[j].parent;
      const BodyDesc<S>& bj = m.body[j];
      for (int k = 0; k < bi.nv; ++k) {
        S col[6];
        joint_project(bj, F[k], col);
        for (int l = 0; l < bj.nv; ++l) {
          M[(bj.v_idx + l) * nv + bi.v_idx + k] += col[l];
          M[(bi.v_idx + k) * nv + bj.v_idx + l] += col[l];
        }
      }
    }
    // composite inertia: Ic_λ += X* Ic_i X⁻¹
    if (bi.parent >= 0) w.Ic[bi.parent] += transform_inertia(w.X[i], w.Ic[i]);
  }
}

// M(q), nv x nv row-major, symmetric
template <typename S> RBD_HD void crba(const ModelView<S>& m, Workspace<S>& w, const S* q, S* M) {
  crba_forward_pass(m, w, q);
  crba_backward_pass(m, w, M);
}

}  // namespace rbd
