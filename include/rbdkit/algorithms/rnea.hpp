// rbdkit/algorithms/rnea.hpp — inverse dynamics by the recursive Newton–Euler
// algorithm (Featherstone, RBDA §5.3, table 5.1), in body coordinates.
//
//   tau = M(q)·qdd + C(q, qd)·qd + g(q) - Σ Jᵀ f_ext
//
// gravity is the world-z component of the gravity acceleration (default
// -9.81); it enters as a fictitious base acceleration a_0 = -g.
#pragma once

#include "rbdkit/model/team.hpp"
#include "rbdkit/model/workspace.hpp"

namespace rbd {

// body i's velocity and acceleration, v_i = X⁻¹ v_λ + S qd, a_i = X⁻¹ a_λ + S qdd + v_i × S qd (a_0 = -g),
// from w.X_parent of i and its parent's.  writes w.v, w.a of body i
template <typename S>
RBD_HD void rnea_body_motion(const ModelView<S>& m, Workspace<S>& w, int i, const S* qd, const S* qdd, S gravity) {
  const BodyDesc<S>& b = m.body[i];
  const Motion<S> vJ = joint_motion(b, qd + b.v_idx);
  Motion<S> vp = Motion<S>::zero(), ap = Motion<S>::zero();
  if (b.parent >= 0) {
    vp = w.v[b.parent];
    ap = w.a[b.parent];
  } else {
    ap.lin.z = -gravity;
  }
  w.v[i] = w.X_parent[i].act_inv(vp) + vJ;
  w.a[i] = w.X_parent[i].act_inv(ap) + cross(w.v[i], vJ);
  if (qdd) w.a[i] += joint_motion(b, qdd + b.v_idx);
}

// body i's net force f_i = I a_i + v_i ×* I v_i - f_ext.  writes w.f of body i
template <typename S> RBD_HD void rnea_body_force(const ModelView<S>& m, Workspace<S>& w, int i, const S* fext) {
  const BodyDesc<S>& b = m.body[i];
  w.f[i] = b.I * w.a[i] + cross(w.v[i], b.I * w.v[i]);
  if (fext) w.f[i] -= load_force(fext + 6 * i);
}

// forward pass: body transforms, velocities, accelerations, net body forces
//   q (nq), qd (nv), qdd (nv or null: zero), fext (nb x 6 body frame or null)
//   writes w.X_parent, w.v, w.a (gravity included), w.f
template <typename S>
RBD_HD void rnea_forward_pass(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd,
                              const S* qdd, const S* fext, S gravity) {
  place_joints(m, w.X_parent, q);
  RBD_UNROLL
  for (int i = 0; i < m.nb; ++i) {
    rnea_body_motion(m, w, i, qd, qdd, gravity);
    rnea_body_force(m, w, i, fext);
  }
}

// backward pass: tau_i = Sᵀ f_i, f_λ += X f_i    writes tau (nv), w.f
template <typename S> RBD_HD void rnea_backward_pass(const ModelView<S>& m, Workspace<S>& w, S* tau) {
  for (int k = 0; k < m.nv; ++k) tau[k] = S(0);
  RBD_UNROLL
  for (int i = m.nb - 1; i >= 0; --i) {
    const BodyDesc<S>& b = m.body[i];
    S t[6];
    joint_project(b, w.f[i], t);
    for (int k = 0; k < b.nv; ++k) tau[b.v_idx + k] += t[k];
    if (b.parent >= 0) w.f[b.parent] += w.X_parent[i].act(w.f[i]);
  }
}

// tau = ID(q, qd, qdd, f_ext). qdd and fext may be null (zero).
template <typename S> RBD_FLATTEN
RBD_HD void rnea(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* qdd,
                 const S* fext, S gravity, S* tau) {
  rnea_forward_pass(m, w, q, qd, qdd, fext, gravity);
  rnea_backward_pass(m, w, tau);
}

// r (nv) = tau - c(q, qd, f_ext), the bias c = ID(q, qd, 0, f_ext) by rnea (which leaves w.X_parent
// at q): the right-hand side of M qdd = tau - c that forward dynamics through M or M⁻¹ solves. r may
// not alias tau
template <typename S>
RBD_HD void bias_residual(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* tau,
                          const S* fext, S gravity, S* r) {
  rnea(m, w, q, qd, static_cast<const S*>(nullptr), fext, gravity, r);
  for (int k = 0; k < m.nv; ++k) r[k] = tau[k] - r[k];
}

// rnea on a team of threads (model/team.hpp): the joint transforms side by side, the velocity and
// acceleration chain on one thread, the net forces side by side, the backward pass on one thread. The
// same values as rnea. An InlineTeam runs rnea
template <typename S, typename Team>
RBD_HD void rnea_team(const Team& t, const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, const S* qdd,
                      const S* fext, S gravity, S* tau) {
  if constexpr (!Team::cooperative) {
    rnea(m, w, q, qd, qdd, fext, gravity, tau);
  } else {
    t.each(m.nb, [&](long i) { w.X_parent[i] = body_transform(m.body[i], q); });
    t.one([&] {
      RBD_UNROLL
      for (int i = 0; i < m.nb; ++i) rnea_body_motion(m, w, i, qd, qdd, gravity);
    });
    t.each(m.nb, [&](long i) { rnea_body_force(m, w, static_cast<int>(i), fext); });
    t.one([&] { rnea_backward_pass(m, w, tau); });
  }
}

// body accelerations without the fictitious gravity term (writes a_out, nb)
// from w.a and w.X_parent after a forward pass
template <typename S>
RBD_HD void remove_gravity(const ModelView<S>& m, const Workspace<S>& w, S gravity, Motion<S>* a_out) {
  // g_i: the base acceleration -g expressed in body i; accumulated rotations only
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    Vec3<S> gp = {S(0), S(0), -gravity};
    if (b.parent >= 0) gp = a_out[b.parent].lin;  // temporarily holds g of the parent (see below)
    a_out[i].lin = mul_t(w.X_parent[i].R, gp);
  }
  for (int i = 0; i < m.nb; ++i) {
    a_out[i] = {w.a[i].lin - a_out[i].lin, w.a[i].ang};
  }
}

}  // namespace rbd
