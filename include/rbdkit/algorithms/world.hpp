// rbdkit/algorithms/world.hpp — the kinematics in one inertial reference frame
// (the world's, or a free root's: below) that M⁻¹, the derivatives, energy,
// regressors, centroidal and CRBA on the general path share, one body at a
// time so each algorithm adds its own per-body work in the same sweep. Bodies
// in order (parents first).
#pragma once

#include "rbdkit/model/team.hpp"
#include "rbdkit/model/workspace.hpp"

namespace rbd {

// The reference frame. The world's, or (leave_world false) for a tree with a free root, that root's
// own frame at q: an inertial frame like the world's (every algorithm on these placements holds in
// either), in which the root's S is the identity and the base's position never enters, so no lever arm
// is longer than the robot (in the world's, 100 m from the origin, M⁻¹ keeps 4 digits fewer). Gravity
// there is R_0rᵀ g (parent_motion). M⁻¹, forward dynamics through it and the first derivatives
// (rnea_derivatives, aba_derivatives) take the root's; the passes whose outputs or later steps are
// world quantities (the ∇ID per-pass helpers, second order, centroidal, energy, regressors) the world's
// (minv's split passes take the root's: their rows of M⁻¹ do not depend on the frame).
template <typename S> RBD_HD bool in_root_frame(const BodyDesc<S>& b, bool leave_world) {
  return !leave_world && b.type == kFree && b.parent < 0;
}

// X_0i = X_0λ X_λi of body i from its w.X_parent and its parent's w.X_world, relative to the
// reference frame: the identity for a root in_root_frame, X_λi for its children and other roots
template <typename S> RBD_HD void reference_placement(const ModelView<S>& m, Workspace<S>& w, int i, bool leave_world) {
  const BodyDesc<S>& b = m.body[i];
  if (in_root_frame(b, leave_world)) w.X_world[i] = Transform<S>::identity();
  else if (b.parent >= 0 && !in_root_frame(m.body[b.parent], leave_world))
    w.X_world[i] = w.X_world[b.parent] * w.X_parent[i];
  else w.X_world[i] = w.X_parent[i];
}

// X_0i (reference_placement) of body i from its w.X_parent (place_joints'); with_subspace: also its
// motion subspace columns in the reference frame, s = X_0i S.  writes w.X_world [, w.S_world]
template <typename S>
RBD_HD void placed_world(const ModelView<S>& m, Workspace<S>& w, int i, bool with_subspace = true,
                         bool leave_world = true) {
  const BodyDesc<S>& b = m.body[i];
  reference_placement(m, w, i, leave_world);
  if (with_subspace)
    for (int k = 0; k < b.nv; ++k) w.S_world[6 * i + k] = joint_subspace_col_in(b, w.X_world[i], k);
}

// body i's inertia in the reference frame (a root in_root_frame's is its own, not transformed)
template <typename S>
RBD_HD Inertia<S> reference_inertia(const ModelView<S>& m, const Workspace<S>& w, int i, bool leave_world) {
  const BodyDesc<S>& b = m.body[i];
  return in_root_frame(b, leave_world) ? b.I : transform_inertia(w.X_world[i], b.I);
}

// X_0i, the subspace columns and the body inertias of every body in the reference frame from the
// w.X_parent that a pass left (rnea's, crba's), without placing the joints again: what
// placed_world and reference_inertia write body by body.  writes w.X_world, w.S_world, w.Ic
template <typename S> RBD_HD void reference_placements(const ModelView<S>& m, Workspace<S>& w, bool leave_world) {
  RBD_UNROLL
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    reference_placement(m, w, i, leave_world);
    for (int k = 0; k < b.nv; ++k) w.S_world[6 * i + k] = joint_subspace_col_in(b, w.X_world[i], k);
    w.Ic[i] = reference_inertia(m, w, i, leave_world);
  }
}

// the parent's velocity and acceleration in the reference frame (a root's: 0 and -g, g = (0, 0,
// gravity) in the world, R_0rᵀ g in a root's frame with R_0r its w.X_parent; with_acc false: a
// parent's acceleration is not read, 0)
template <typename S>
RBD_HD void parent_motion(const ModelView<S>& m, const Workspace<S>& w, int i, S gravity, bool with_acc,
                          Motion<S>& vp, Motion<S>& ap, bool leave_world = true) {
  const int p = m.body[i].parent;
  vp = Motion<S>::zero(), ap = Motion<S>::zero();
  if (p >= 0) {
    vp = w.v[p];
    if (with_acc) ap = w.a[p];
  } else if (in_root_frame(m.body[i], leave_world)) {
    const Mat3<S>& R = w.X_parent[i].R;
    ap.lin = {-gravity * R(2, 0), -gravity * R(2, 1), -gravity * R(2, 2)};
  } else {
    ap.lin.z = -gravity;
  }
}

// joint i's own motion in the reference frame: vJ = s qd and (when with_acc and qdd is not null) aJ = s qdd
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

// velocity v_i = v_λ + s qd and, when with_acc, acceleration a_i = a_λ + s qdd + v_i × s qd (a_0 = -g;
// qdd null: zero) in the reference frame (leave_world: as placed_world's); sens: the column
// sensitivities (motion_sensitivities).  reads w.S_world of body i; writes w.v [, w.a, w.dVdq, w.dAdq, w.dAdv]
template <typename S>
RBD_HD void world_motion(const ModelView<S>& m, Workspace<S>& w, int i, const S* qd, const S* qdd, S gravity,
                         bool with_acc, bool sens, bool leave_world = true) {
  Motion<S> vp, ap, vJ, aJ;
  parent_motion(m, w, i, gravity, with_acc, vp, ap, leave_world);
  world_joint_motion(m, w, i, qd, qdd, with_acc, vJ, aJ);
  w.v[i] = vp + vJ;
  if (with_acc) w.a[i] = ap + aJ + cross(w.v[i], vJ);
  if (sens) motion_sensitivities(m, w, i, vp, ap);
}

// place_joints and placed_world of every body on a team (model/team.hpp): the joint transforms X_λi
// side by side, the chain X_0i = X_0λ X_λi on one thread, then each body's subspace columns
// (with_subspace) and then_each(i) side by side. The same values as place_joints and placed_world body
// by body (leave_world as its)
template <typename S, typename Team, typename F>
RBD_HD void world_placements_team(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q,
                                  bool with_subspace, F&& then_each, bool leave_world = true) {
  t.each(m.nb, [&](long i) { w.X_parent[i] = body_transform(m.body[i], q); });
  t.one([&] {
    RBD_UNROLL
    for (int i = 0; i < m.nb; ++i) reference_placement(m, w, i, leave_world);
  });
  t.each(m.nb, [&](long i) {
    const BodyDesc<S>& b = m.body[i];
    if (with_subspace)
      for (int k = 0; k < b.nv; ++k) w.S_world[6 * i + k] = joint_subspace_col_in(b, w.X_world[i], k);
    then_each(static_cast<int>(i));
  });
}

}  // namespace rbd
