// rbdkit/model/configuration.hpp — Lie-group operations on a whole configuration:
// integrate (q ⊕ v), difference (q1 ⊖ q0) and their tangent Jacobians.
// Free-flyer joints live on SE(3) (Pinocchio's convention: the twist is in the
// local frame), spherical joints on SO(3), every other joint on R; each
// joint's operation is its type's (joint_types.hpp).
//
//   integrate(q, v)             q (nq), v (nv)      -> q_next (nq)
//   difference(q0, q1)          q0, q1 (nq)         -> v (nv), integrate(q0, v) = q1
//   dintegrate(q, v, arg)       arg 0: ∂/∂q, 1: ∂/∂v -> J (nv x nv, row-major)
//   ddifference(q0, q1, arg)    arg 0: ∂/∂q0, 1: ∂/∂q1 -> J (nv x nv)
// integrate and dintegrate read only the model's structure: their values may
// be of another scalar V than the model's (dual numbers: d2Integrate).
#pragma once

#include "rbdkit/model/joint_types.hpp"

namespace rbd {

template <typename S, typename V> RBD_HD void integrate(const ModelView<S>& m, const V* q, const V* v, V* out) {
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    visit_joint(b.type, [&](auto J) { J.integrate(q + b.q_idx, v + b.v_idx, out + b.q_idx); });
  }
}

template <typename S> RBD_HD void difference(const ModelView<S>& m, const S* q0, const S* q1, S* out) {
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    visit_joint(b.type, [&](auto J) { J.difference(q0 + b.q_idx, q1 + b.q_idx, out + b.v_idx); });
  }
}

// arg 0: ∂integrate/∂q (tangent), arg 1: ∂integrate/∂v. J (nv x nv) block diagonal
template <typename S, typename V>
RBD_HD void dintegrate(const ModelView<S>& m, const V* q, const V* v, int arg, V* J) {
  (void)q;  // the Jacobians of a left-invariant retraction do not depend on q
  const int nv = m.nv;
  for (int k = 0; k < nv * nv; ++k) J[k] = V(0);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    const int o = b.v_idx;
    visit_joint(b.type, [&](auto JT) { JT.dintegrate(v + o, arg, J + o * nv + o, nv); });
  }
}

// arg 0: ∂difference/∂q0, arg 1: ∂difference/∂q1. J (nv x nv) block diagonal
template <typename S> RBD_HD void ddifference(const ModelView<S>& m, const S* q0, const S* q1, int arg, S* J) {
  const int nv = m.nv;
  for (int k = 0; k < nv * nv; ++k) J[k] = S(0);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    const int o = b.v_idx;
    visit_joint(b.type, [&](auto JT) { JT.ddifference(q0 + b.q_idx, q1 + b.q_idx, arg, J + o * nv + o, nv); });
  }
}

// the neutral configuration: zero coordinates, identity quaternions
template <typename S> RBD_HD void neutral(const ModelView<S>& m, S* q) {
  for (int k = 0; k < m.nq; ++k) q[k] = S(0);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    visit_joint(b.type, [&](auto J) { J.neutral(q + b.q_idx); });
  }
}

}  // namespace rbd
