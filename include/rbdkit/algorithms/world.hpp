// rbdkit/algorithms/world.hpp — the world-coordinate kinematics that the
// world-frame algorithms (M⁻¹, derivatives, energy, regressors, centroidal,
// CRBA on the general path) share, one body at a time so each algorithm adds
// its own per-body work in the same sweep. Bodies in order (parents first).
#pragma once

#include "rbdkit/model/team.hpp"
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

// the parent's world-frame velocity and acceleration (the root's: 0 and -g; with_acc false: a
// parent's acceleration is not read, 0)
template <typename S>
RBD_HD void parent_motion(const ModelView<S>& m, const Workspace<S>& w, int i, S gravity, bool with_acc,
                          Motion<S>& vp, Motion<S>& ap) {
  const int p = m.body[i].parent;
  vp = Motion<S>::zero(), ap = Motion<S>::zero();
  if (p >= 0) {
    vp = w.v[p];
    if (with_acc) ap = w.a[p];
  } else {
    ap.lin.z = -gravity;
  }
}

// joint i's own motion in the world frame: vJ = s qd and (when with_acc and qdd is not null) aJ = s qdd
template <typename S>
RBD_HD void world_joint_motion(const ModelView<S>& m, const Workspace<S>& w, int i, const S* qd, const S* qdd,
                               bool with_acc, Motion<S>& vJ, Motion<S>& aJ) {
  const BodyDesc<S>& b = m.body[i];
  const Motion<S>* s = w.S_world + 6 * i;
  vJ = Motion<S>::zero(), aJ = Motion<S>::zero();
  for (int k = 0; k < b.nv; ++k) {
    vJ += qd[b.v_idx + k] * s[k];
    if (with_acc && qdd) aJ += qdd[b.v_idx + k] * s[k];
  }
}

// the column sensitivities of body i (rnea_derivatives): dVdq = v_λ × s, dAdq = a_λ × s + v_λ × dVdq,
// dAdv = v_i × s + dVdq.  reads w.S_world, w.v of body i; writes w.dVdq, w.dAdq, w.dAdv
template <typename S>
RBD_HD void motion_sensitivities(const ModelView<S>& m, Workspace<S>& w, int i, const Motion<S>& vp,
                                 const Motion<S>& ap) {
  const Motion<S>* s = w.S_world + 6 * i;
  for (int k = 0; k < m.body[i].nv; ++k) {
    const Motion<S> dv = cross(vp, s[k]);
    w.dVdq[6 * i + k] = dv;
    w.dAdq[6 * i + k] = cross(ap, s[k]) + cross(vp, dv);
    w.dAdv[6 * i + k] = cross(w.v[i], s[k]) + dv;
  }
}

// world-frame velocity v_i = v_λ + s qd and, when with_acc, acceleration
// a_i = a_λ + s qdd + v_i × s qd (a_0 = -g; qdd null: zero); sens: the column
// sensitivities (motion_sensitivities).  reads w.S_world of body i; writes w.v [, w.a, w.dVdq, w.dAdq, w.dAdv]
template <typename S>
RBD_HD void world_motion(const ModelView<S>& m, Workspace<S>& w, int i, const S* qd, const S* qdd, S gravity,
                         bool with_acc, bool sens) {
  Motion<S> vp, ap, vJ, aJ;
  parent_motion(m, w, i, gravity, with_acc, vp, ap);
  world_joint_motion(m, w, i, qd, qdd, with_acc, vJ, aJ);
  w.v[i] = vp + vJ;
  if (with_acc) w.a[i] = ap + aJ + cross(w.v[i], vJ);
  if (sens) motion_sensitivities(m, w, i, vp, ap);
}

// world_placement of every body on a team (model/team.hpp): the joint transforms X_λi side by side,
// the chain X_0i = X_0λ X_λi on one thread, then each body's subspace columns (with_subspace) and
// then_each(i) side by side. The same values as world_placement body by body
template <typename S, typename Team, typename F>
RBD_HD void world_placements_team(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q,
                                  bool with_subspace, F&& then_each) {
  t.each(m.nb, [&](long i) { w.X_parent[i] = body_transform(m.body[i], q); });
  t.one([&] {
    RBD_UNROLL
    for (int i = 0; i < m.nb; ++i) {
      const int p = m.body[i].parent;
      w.X_world[i] = p >= 0 ? w.X_world[p] * w.X_parent[i] : w.X_parent[i];
    }
  });
  t.each(m.nb, [&](long i) {
    const BodyDesc<S>& b = m.body[i];
    if (with_subspace)
      for (int k = 0; k < b.nv; ++k) w.S_world[6 * i + k] = joint_subspace_col_in(b, w.X_world[i], k);
    then_each(static_cast<int>(i));
  });
}

}  // namespace rbd
