// rbdkit/algorithms/world.hpp — the world-coordinate kinematics that the
// world-frame algorithms (CRBA, M⁻¹, derivatives, energy, regressors) share,
// one body at a time so each algorithm adds its own per-body work in the
// same sweep. Bodies in order (parents first).
#pragma once

#include "rbdkit/model/workspace.hpp"

namespace rbd {

// X_λi and X_0i = X_0λ X_λi of body i; with_subspace: also its motion
// subspace columns in the world frame, s = X_0i S.  writes w.X_parent, w.X_world [, w.S_world]
template <typename S>
RBD_HD void world_placement(const ModelView<S>& m, Workspace<S>& w, const S* q, int i, bool with_subspace = true) {
  const BodyDesc<S>& b = m.body[i];
  w.X_parent[i] = body_transform(b, q);
  w.X_world[i] = b.parent >= 0 ? w.X_world[b.parent] * w.X_parent[i] : w.X_parent[i];
  if (with_subspace)
    for (int k = 0; k < b.nv; ++k) w.S_world[6 * i + k] = joint_subspace_col_in(b, w.X_world[i], k);
}

// world-frame velocity v_i = v_λ + s qd and, when with_acc, acceleration
// a_i = a_λ + s qdd + v_i × s qd (a_0 = -g; qdd null: zero); sens: the column
// sensitivities of rnea_derivatives, dVdq = v_λ × s, dAdq = a_λ × s + v_λ × dVdq,
// dAdv = v_i × s + dVdq.  reads w.S_world of body i; writes w.v [, w.a, w.dVdq, w.dAdq, w.dAdv]
template <typename S>
RBD_HD void world_motion(const ModelView<S>& m, Workspace<S>& w, int i, const S* qd, const S* qdd, S gravity,
                         bool with_acc, bool sens) {
  const BodyDesc<S>& b = m.body[i];
  const Motion<S>* s = w.S_world + 6 * i;
  Motion<S> vp = Motion<S>::zero(), ap = Motion<S>::zero();
  if (b.parent >= 0) {
    vp = w.v[b.parent];
    if (with_acc) ap = w.a[b.parent];
  } else {
    ap.lin.z = -gravity;
  }
  Motion<S> vJ = Motion<S>::zero(), aJ = Motion<S>::zero();
  for (int k = 0; k < b.nv; ++k) {
    vJ += qd[b.v_idx + k] * s[k];
    if (with_acc && qdd) aJ += qdd[b.v_idx + k] * s[k];
  }
  w.v[i] = vp + vJ;
  if (with_acc) w.a[i] = ap + aJ + cross(w.v[i], vJ);
  if (!sens) return;
  for (int k = 0; k < b.nv; ++k) {
    const Motion<S> dv = cross(vp, s[k]);
    w.dVdq[6 * i + k] = dv;
    w.dAdq[6 * i + k] = cross(ap, s[k]) + cross(vp, dv);
    w.dAdv[6 * i + k] = cross(w.v[i], s[k]) + dv;
  }
}

}  // namespace rbd
