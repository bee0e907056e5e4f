// rbdkit/algorithms/centroidal.hpp — centre of mass and its Jacobian, the
// centroidal momentum matrix A(q) (CCRBA, Orin, Goswami & Lee, "Centroidal
// dynamics of a humanoid robot", Auton. Robots 2013), its configuration
// derivative ∂A/∂q, its time variation Ȧ, the momentum rate ḣ and the
// derivatives of the centroidal dynamics (Pinocchio's
// computeCentroidalDynamicsDerivatives), all in world coordinates.
//
// Centroidal quantities are forces [linear; angular] about the centre of mass
// c, in world-aligned axes: h = A qd = (Σ m_i ċ_i, angular momentum about c).
// Every pass first builds world-origin forces F0 (the momentum of subtrees,
// composite inertia Ic times world columns s) and then moves them to c:
//     F = (F0.lin, F0.ang + F0.lin × c)
// Along a tangent step on DoF k the subtree of k moves rigidly with twist s_k,
// and c moves by ∂c/∂δ_k = A.lin[:, k] / M (M the total mass), which adds a
// term (·).lin × A.lin[:, k] / M to the angular rows of every derivative.
//
// Fixed-base models: the world-fixed root link is not part of the robot
// (the bodies are the moving ones, as in Pinocchio). A robot without mass
// has no centre of mass: the functions then return false (the test is on
// model data, the same in every lane of a SIMD pack: all_lanes).
//
// Layouts (row-major): A, Ȧ, J_com and the derivative matrices (rows x nv),
// dA (6 x nv x nv) with dA[r][j][k] = ∂A[r][j]/∂δ_k (δ_k: the tangent step
// q ← integrate(q, δ e_k)); mimic bodies add into their target's column.
#pragma once

#include "rbdkit/algorithms/crba.hpp"
#include "rbdkit/algorithms/energy.hpp"
#include "rbdkit/algorithms/rnea.hpp"
#include "rbdkit/algorithms/rnea_derivatives.hpp"
#include "rbdkit/model/configuration.hpp"

namespace rbd {

// ------------------------------------------------------------------ helpers

// add a force to column c of a 6 x n row-major matrix
template <typename S> RBD_HD void add_force_column(const Force<S>& f, int c, int n, S* A) {
  A[0 * n + c] += f.lin.x; A[1 * n + c] += f.lin.y; A[2 * n + c] += f.lin.z;
  A[3 * n + c] += f.ang.x; A[4 * n + c] += f.ang.y; A[5 * n + c] += f.ang.z;
}

// column c of a 6 x n row-major matrix as a force
template <typename S> RBD_HD Force<S> force_column(const S* A, int c, int n) {
  return {{A[0 * n + c], A[1 * n + c], A[2 * n + c]}, {A[3 * n + c], A[4 * n + c], A[5 * n + c]}};
}

// world-origin forces (6 x n, row-major) moved to the point c: ang += lin × c
template <typename S> RBD_HD void shift_forces(int n, const Vec3<S>& c, S* F) {
  for (int k = 0; k < n; ++k) {
    const Vec3<S> lin = {F[0 * n + k], F[1 * n + k], F[2 * n + k]};
    const Vec3<S> t = cross(lin, c);
    F[3 * n + k] += t.x; F[4 * n + k] += t.y; F[5 * n + k] += t.z;
  }
}

// a force at the world origin moved to the point c
template <typename S> RBD_HD Force<S> shift_force(const Force<S>& f, const Vec3<S>& c) {
  return {f.lin, f.ang + cross(f.lin, c)};
}

// composite inertias: Ic_λ += Ic_i from the leaves up (w.Ic holds world body
// inertias); returns the inertia of the whole robot (world frame)
template <typename S> RBD_HD Inertia<S> composite_inertia_pass(const ModelView<S>& m, Workspace<S>& w) {
  Inertia<S> total = Inertia<S>::zero();
  for (int i = m.nb - 1; i >= 0; --i) {
    const int p = m.body[i].parent;
    if (p >= 0) w.Ic[p] += w.Ic[i];
    else total += w.Ic[i];
  }
  return total;
}

// world-origin centroidal map A0 = [Ic_i s] per column (6 x nv), after the
// composite pass
template <typename S> RBD_HD void centroidal_map_pass(const ModelView<S>& m, const Workspace<S>& w, S* A0) {
  const int nv = m.nv;
  for (int k = 0; k < 6 * nv; ++k) A0[k] = S(0);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    for (int a = 0; a < b.nv; ++a) add_force_column(w.Ic[i] * w.S_world[6 * i + a], b.v_idx + a, nv, A0);
  }
}

// ------------------------------------------------------------ centre of mass

// c (3) = Σ m_i c_i / M in the world.   writes w.X_parent, w.X_world; false if M <= 0
template <typename S> RBD_HD bool center_of_mass(const ModelView<S>& m, Workspace<S>& w, const S* q, S* com) {
  forward_kinematics(m, w, q, static_cast<const S*>(nullptr));
  S M = S(0);
  Vec3<S> mc = Vec3<S>::zero();
  for (int i = 0; i < m.nb; ++i) {
    const Inertia<S>& I = m.body[i].I;
    // world first moment R h + m p
    mc += w.X_world[i].R * I.h + I.m * w.X_world[i].p;
    M += I.m;
  }
  if (!all_lanes(lane_gt(M, 0))) return false;
  com[0] = mc.x / M; com[1] = mc.y / M; com[2] = mc.z / M;
  return true;
}

// J_com (3 x nv, row-major) = ∂c/∂δ: column (Ic_i s).lin / M, the velocity
// of the subtree's centre of mass weighted by its share of the mass.
// com (3) too when not null.   writes w.X_parent, w.X_world, w.S_world, w.Ic (composites); false if M <= 0
template <typename S>
RBD_HD bool jacobian_com(const ModelView<S>& m, Workspace<S>& w, const S* q, S* J, S* com = nullptr) {
  const int nv = m.nv;
  crba_forward_pass(m, w, q);
  const Inertia<S> total = composite_inertia_pass(m, w);
  if (!all_lanes(lane_gt(total.m, 0))) return false;
  const S inv_m = S(1) / total.m;
  for (int k = 0; k < 3 * nv; ++k) J[k] = S(0);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    for (int a = 0; a < b.nv; ++a) {
      const Vec3<S> col = inv_m * (w.Ic[i] * w.S_world[6 * i + a]).lin;
      for (int r = 0; r < 3; ++r) J[r * nv + b.v_idx + a] += col[r];
    }
  }
  if (com) {
    const Vec3<S> c = inv_m * total.h;
    com[0] = c.x; com[1] = c.y; com[2] = c.z;
  }
  return true;
}

// ------------------------------------------------------------------- CCRBA

// A(q) (6 x nv) and, when qd is not null, h = A qd (6). com (3) when not null.
//   passes: crba_forward_pass (X, Xw, Sw, world body inertias), composite
//   inertias, A0 = Ic s, then the move to c.   false if M <= 0
template <typename S>
RBD_HD bool ccrba(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, S* A, S* h, S* com = nullptr) {
  const int nv = m.nv;
  crba_forward_pass(m, w, q);
  const Inertia<S> total = composite_inertia_pass(m, w);
  if (!all_lanes(lane_gt(total.m, 0))) return false;
  const Vec3<S> c = (S(1) / total.m) * total.h;
  centroidal_map_pass(m, w, A);
  shift_forces(nv, c, A);
  if (qd && h)
    for (int r = 0; r < 6; ++r) {
      S acc = S(0);
      for (int k = 0; k < nv; ++k) acc += A[r * nv + k] * qd[k];
      h[r] = acc;
    }
  if (com) com[0] = c.x, com[1] = c.y, com[2] = c.z;
  return true;
}

// h (6) = Σ X_0i* I_i v_i moved to c, in one forward pass (no A).
//   writes w.X_parent, w.X_world, w.v (body frame); false if M <= 0
template <typename S>
RBD_HD bool centroidal_momentum(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, S* h) {
  forward_kinematics(m, w, q, qd);
  Inertia<S> total = Inertia<S>::zero();
  Force<S> h0 = Force<S>::zero();
  for (int i = 0; i < m.nb; ++i) {
    const Inertia<S>& I = m.body[i].I;
    h0 += w.X_world[i].act(I * w.v[i]);
    total.m += I.m;
    total.h += w.X_world[i].R * I.h + I.m * w.X_world[i].p;
  }
  if (!all_lanes(lane_gt(total.m, 0))) return false;
  store(shift_force(h0, (S(1) / total.m) * total.h), h);
  return true;
}

// ----------------------------------------------------------------- ∂A/∂q

// A (6 x nv) and dA (6 x nv x nv), dA[r][j][k] = ∂A[r][j]/∂δ_k. For the
// column j (DoF of body bj) and the step k (DoF of body bk), world origin:
//   bk = bj or an ancestor:   ∂(Ic_bj s_j) = s_k ×* (Ic_bj s_j)           (all of it moves)
//   bk strictly below bj:     ∂(Ic_bj s_j) = s_k ×* (Ic_bk s_j) - Ic_bk (s_k × s_j)
//                                                          (only subtree(bk) moves)
//   otherwise                 0
// then the move to c: ∂A.ang = ∂A0.ang + ∂A0.lin × c + A0.lin[j] × A0.lin[k] / M.
// writes w.X_parent, w.X_world, w.S_world, w.Ic (composites); false if M <= 0
template <typename S> RBD_HD bool dccrba(const ModelView<S>& m, Workspace<S>& w, const S* q, S* A, S* dA) {
  const int nv = m.nv, nn = nv * nv;
  crba_forward_pass(m, w, q);
  const Inertia<S> total = composite_inertia_pass(m, w);
  if (!all_lanes(lane_gt(total.m, 0))) return false;
  const S inv_m = S(1) / total.m;
  const Vec3<S> c = inv_m * total.h;
  centroidal_map_pass(m, w, A);
  for (int k = 0; k < 6 * nn; ++k) dA[k] = S(0);
  for (int j = 0; j < m.nb; ++j) {
    const BodyDesc<S>& bj = m.body[j];
    for (int a = 0; a < bj.nv; ++a) {
      const Motion<S>& sj = w.S_world[6 * j + a];
      const Force<S> F = w.Ic[j] * sj;
      // steps on j itself and its ancestors move the whole composite
      for (int k = j; k >= 0; k = m.body[k].parent) {
        const BodyDesc<S>& bk = m.body[k];
        for (int b = 0; b < bk.nv; ++b)
          add_force_column(cross(w.S_world[6 * k + b], F), (bj.v_idx + a) * nv + bk.v_idx + b, nn, dA);
      }
      // a step on j moves only subtree(j) inside the composites of its strict
      // ancestors e: column of e's DoF b gets s_j ×* (Ic_j s_e) - Ic_j (s_j × s_e)
      for (int e = bj.parent; e >= 0; e = m.body[e].parent) {
        const BodyDesc<S>& be = m.body[e];
        for (int b = 0; b < be.nv; ++b) {
          const Motion<S>& se = w.S_world[6 * e + b];
          const Force<S> d = cross(sj, w.Ic[j] * se) - w.Ic[j] * cross(sj, se);
          add_force_column(d, (be.v_idx + b) * nv + bj.v_idx + a, nn, dA);
        }
      }
    }
  }
  // move to c: first the derivatives (they need the world-origin A0.lin), then A
  for (int j = 0; j < nv; ++j)
    for (int k = 0; k < nv; ++k) {
      const int col = j * nv + k;
      const Vec3<S> dlin = {dA[0 * nn + col], dA[1 * nn + col], dA[2 * nn + col]};
      const Vec3<S> aj = {A[0 * nv + j], A[1 * nv + j], A[2 * nv + j]};
      const Vec3<S> ak = {A[0 * nv + k], A[1 * nv + k], A[2 * nv + k]};
      const Vec3<S> t = cross(dlin, c) + inv_m * cross(aj, ak);
      dA[3 * nn + col] += t.x; dA[4 * nn + col] += t.y; dA[5 * nn + col] += t.z;
    }
  shift_forces(nv, c, A);
  return true;
}

// --------------------------------------------------------------- Ȧ and ḣ

// Ȧ (6 x nv) = Σ_k dA[:, :, k] qd_k (Pinocchio's computeCentroidalMapTimeVariation),
// with A (6 x nv) and h = A qd (6, when not null), in O(n):
//   Ȧ0 = Bc s + Ic (v × s) per column (Bc = Σ_subtree v_i ×* I_i - I_i v_i×, v the column's body velocity)
//   Ȧ.ang = Ȧ0.ang + Ȧ0.lin × c + A0.lin × ċ,   ċ = h.lin / M
// writes w.X_parent, w.X_world, w.S_world, w.v (world), w.Ic, w.h, w.B (composites); false if M <= 0
template <typename S>
RBD_HD bool cmm_time_variation(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, S* A, S* Adot,
                               S* h = nullptr) {
  const int nv = m.nv;
  momentum_forward_pass(m, w, q, qd);
  // composites, and the world-origin momentum h0 of the whole robot
  Inertia<S> total = Inertia<S>::zero();
  Force<S> h0 = Force<S>::zero();
  for (int i = m.nb - 1; i >= 0; --i) {
    const int p = m.body[i].parent;
    if (p >= 0) {
      w.Ic[p] += w.Ic[i];
      w.h[p] += w.h[i];
      w.B[p] += w.B[i];
    } else {
      total += w.Ic[i];
      h0 += w.h[i];
    }
  }
  if (!all_lanes(lane_gt(total.m, 0))) return false;
  const S inv_m = S(1) / total.m;
  const Vec3<S> c = inv_m * total.h, cdot = inv_m * h0.lin;
  // world-origin columns
  for (int k = 0; k < 6 * nv; ++k) A[k] = S(0), Adot[k] = S(0);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    for (int a = 0; a < b.nv; ++a) {
      const Motion<S>& s = w.S_world[6 * i + a];
      add_force_column(w.Ic[i] * s, b.v_idx + a, nv, A);
      add_force_column(w.B[i] * s + w.Ic[i] * cross(w.v[i], s), b.v_idx + a, nv, Adot);
    }
  }
  // move to c (Ȧ first: it needs A0.lin, which the move leaves unchanged anyway)
  for (int k = 0; k < nv; ++k) {
    const Force<S> a0 = force_column(A, k, nv), d0 = force_column(Adot, k, nv);
    const Vec3<S> t = cross(d0.lin, c) + cross(a0.lin, cdot);
    Adot[3 * nv + k] += t.x; Adot[4 * nv + k] += t.y; Adot[5 * nv + k] += t.z;
  }
  shift_forces(nv, c, A);
  if (h) store(shift_force(h0, c), h);
  return true;
}

// ḣ (6) = A qdd + Ȧ qd, the rate of the centroidal momentum (gravity not
// included: ḣ is the net external wrench minus the weight), and h (6) when
// not null, in one forward pass (Pinocchio's computeCentroidalMomentumTimeVariation):
//   body frame: v, a (no gravity), f = I a + v ×* I v (rnea_forward_pass), then
//   h0 = Σ X_0i* I v,  ḣ0 = Σ X_0i* f, moved to c.
// writes w.X_parent, w.X_world, w.v, w.a, w.f (body frame); false if M <= 0
template <typename S>
RBD_HD bool centroidal_momentum_time_variation(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd,
                                               const S* qdd, S* hdot, S* h = nullptr) {
  rnea_forward_pass(m, w, q, qd, qdd, static_cast<const S*>(nullptr), S(0));
  Inertia<S> total = Inertia<S>::zero();
  Force<S> h0 = Force<S>::zero(), f0 = Force<S>::zero();
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    w.X_world[i] = b.parent >= 0 ? w.X_world[b.parent] * w.X_parent[i] : w.X_parent[i];
    h0 += w.X_world[i].act(b.I * w.v[i]);
    f0 += w.X_world[i].act(w.f[i]);
    total.m += b.I.m;
    total.h += w.X_world[i].R * b.I.h + b.I.m * w.X_world[i].p;
  }
  if (!all_lanes(lane_gt(total.m, 0))) return false;
  const Vec3<S> c = (S(1) / total.m) * total.h;
  store(shift_force(f0, c), hdot);
  if (h) store(shift_force(h0, c), h);
  return true;
}

// ------------------------------------------------- centroidal dynamics derivatives

// backward pass after rnea_derivatives_forward_pass at gravity 0 (world
// frame: columns s, dV/dq, dA/dq, dA/dqd; per body Ic, h, f, B), subtree sums
// as in rnea_derivatives. At body i, composites complete, per DoF column k
// (world origin; the derivatives of the subtree's momentum and force):
//   ∂h0/∂δ_k    = s ×* hc + Ic dVdq
//   ∂ḣ0/∂δ_k    = s ×* fc + Ic dAdq + Bc dVdq + dVdq ×* hc
//   ∂ḣ0/∂qd_k   = Ic dAdv + Bc s + s ×* hc
//   ∂ḣ0/∂qdd_k  = Ic s                          (= A0)
// writes the four 6 x nv matrices (world origin); returns the whole robot's
// inertia, and its momentum h0 and rate f0 (world origin)
template <typename S>
RBD_HD void centroidal_derivatives_backward_pass(const ModelView<S>& m, Workspace<S>& w, S* dh_dq, S* dhdot_dq,
                                                 S* dhdot_dv, S* dhdot_da, Inertia<S>& total, Force<S>& h0,
                                                 Force<S>& f0) {
  const int nv = m.nv;
  for (int k = 0; k < 6 * nv; ++k) dh_dq[k] = S(0), dhdot_dq[k] = S(0), dhdot_dv[k] = S(0), dhdot_da[k] = S(0);
  total = Inertia<S>::zero();
  h0 = Force<S>::zero();
  f0 = Force<S>::zero();
  for (int i = m.nb - 1; i >= 0; --i) {
    const BodyDesc<S>& b = m.body[i];
    const Inertia<S>& Ic = w.Ic[i];
    for (int a = 0; a < b.nv; ++a) {
      const int k = 6 * i + a, col = b.v_idx + a;
      const Motion<S>& s = w.S_world[k];
      const Motion<S>& dv = w.dVdq[k];
      add_force_column(cross(s, w.h[i]) + Ic * dv, col, nv, dh_dq);
      add_force_column(cross(s, w.f[i]) + Ic * w.dAdq[k] + w.B[i] * dv + cross(dv, w.h[i]), col, nv, dhdot_dq);
      add_force_column(Ic * w.dAdv[k] + w.B[i] * s + cross(s, w.h[i]), col, nv, dhdot_dv);
      add_force_column(Ic * s, col, nv, dhdot_da);
    }
    // subtree sums handed to the parent (or to the whole robot)
    const int p = b.parent;
    if (p >= 0) {
      w.Ic[p] += w.Ic[i];
      w.h[p] += w.h[i];
      w.f[p] += w.f[i];
      w.B[p] += w.B[i];
    } else {
      total += w.Ic[i];
      h0 += w.h[i];
      f0 += w.f[i];
    }
  }
}

// the derivatives of the centroidal momentum h(q, qd) and of its rate
// ḣ(q, qd, qdd) (Pinocchio's computeCentroidalDynamicsDerivatives), each
// 6 x nv, row-major: dh_dq = ∂h/∂δ (at fixed qd), dhdot_dq = ∂ḣ/∂δ,
// dhdot_dv = ∂ḣ/∂qd, dhdot_da = ∂ḣ/∂qdd = A. h, hdot (6) when not null.
// O(n). false if M <= 0
template <typename S>
RBD_HD bool centroidal_dynamics_derivatives(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd,
                                            const S* qdd, S* dh_dq, S* dhdot_dq, S* dhdot_dv, S* dhdot_da,
                                            S* h = nullptr, S* hdot = nullptr) {
  const int nv = m.nv;
  rnea_derivatives_forward_pass(m, w, q, qd, qdd, static_cast<const S*>(nullptr), S(0), false, true);
  Inertia<S> total;
  Force<S> h0, f0;
  centroidal_derivatives_backward_pass(m, w, dh_dq, dhdot_dq, dhdot_dv, dhdot_da, total, h0, f0);
  if (!all_lanes(lane_gt(total.m, 0))) return false;
  const S inv_m = S(1) / total.m;
  const Vec3<S> c = inv_m * total.h;
  // move to c; c moves by A0.lin[k] / M along δ_k
  const Force<S> hg = shift_force(h0, c), fg = shift_force(f0, c);
  for (int k = 0; k < nv; ++k) {
    const Vec3<S> dc = inv_m * force_column(dhdot_da, k, nv).lin;
    const Vec3<S> th = cross(hg.lin, dc), tf = cross(fg.lin, dc);
    dh_dq[3 * nv + k] += th.x; dh_dq[4 * nv + k] += th.y; dh_dq[5 * nv + k] += th.z;
    dhdot_dq[3 * nv + k] += tf.x; dhdot_dq[4 * nv + k] += tf.y; dhdot_dq[5 * nv + k] += tf.z;
  }
  shift_forces(nv, c, dh_dq);
  shift_forces(nv, c, dhdot_dq);
  shift_forces(nv, c, dhdot_dv);
  shift_forces(nv, c, dhdot_da);
  if (h) store(hg, h);
  if (hdot) store(fg, hdot);
  return true;
}

// ------------------------------------------------ finite-difference cross-checks
// Central differences of A along the tangent steps q ⊕ ±eps·e_k: the checks of
// dccrba and cmm_time_variation, not for production (in float32 a step of
// 1e-5 leaves about two of the seven digits).

// scratch values of dccrba_fd: delta (nv), q± (2 nq), A± (12 nv)
RBD_HD constexpr long dccrba_fd_scratch(int nq, int nv) { return 13L * nv + 2L * nq; }

// dA (6 x nv x nv) as dccrba's, from 2 nv calls of ccrba; false if M <= 0
template <typename S>
RBD_HD bool dccrba_fd(const ModelView<S>& m, Workspace<S>& w, const S* q, S eps, S* dA, S* scratch) {
  const int nq = m.nq, nv = m.nv;
  S* delta = scratch;
  S* qp = delta + nv;
  S* qm = qp + nq;
  S* Ap = qm + nq;
  S* Am = Ap + 6 * nv;
  for (int k = 0; k < nv; ++k) delta[k] = S(0);
  const S* none = nullptr;
  for (int k = 0; k < nv; ++k) {
    // A(q ⊕ ±eps e_k), the central difference into dA[:, :, k]
    delta[k] = eps;
    integrate(m, q, delta, qp);
    delta[k] = -eps;
    integrate(m, q, delta, qm);
    delta[k] = S(0);
    if (!ccrba(m, w, qp, none, Ap, static_cast<S*>(nullptr)) || !ccrba(m, w, qm, none, Am, static_cast<S*>(nullptr)))
      return false;
    for (int r = 0; r < 6; ++r)
      for (int j = 0; j < nv; ++j) dA[(r * nv + j) * nv + k] = (Ap[r * nv + j] - Am[r * nv + j]) / (S(2) * eps);
  }
  return true;
}

// Ȧ (6 x nv) = Σ_k dccrba_fd(q, eps)[:, :, k] qd_k; scratch: 6 nv² + dccrba_fd_scratch values
template <typename S>
RBD_HD bool cmm_time_variation_fd(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd, S eps, S* Adot,
                                  S* scratch) {
  const int nv = m.nv;
  S* dA = scratch;
  if (!dccrba_fd(m, w, q, eps, dA, scratch + 6 * nv * nv)) return false;
  for (int rj = 0; rj < 6 * nv; ++rj) {
    S acc = S(0);
    for (int k = 0; k < nv; ++k) acc += dA[rj * nv + k] * qd[k];
    Adot[rj] = acc;
  }
  return true;
}

}  // namespace rbd
