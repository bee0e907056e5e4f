// rbdkit/algorithms/kinematics.hpp — forward kinematics, frame placements,
// frame Jacobians and their time variation, end-effector poses and their
// first and second derivatives. The Jacobian is the stack of the world-frame
// motion subspaces of the support chain.
//
// Frame naming: X_world_body is the placement of a body in the world
// (x_world = R x_body + p); s = X_world_k · S_k[:, a] is the world-frame
// column of DoF a of body k (the spatial velocity, at the world origin in
// world axes, that a unit rate of that coordinate gives every body below k).
//
// Jacobians (6 x nv, row-major, rows [linear; angular]) of a frame F fixed on
// body b, at X_world_F = (R, p), in Pinocchio's three reference frames:
//   kWorld               column s for every DoF of b and its ancestors
//   kLocal               X_world_F⁻¹ · s         (F's velocity in F's axes)
//   kLocalWorldAligned   (s.lin + s.ang × p, s.ang)  (F's origin, world axes)
// Mimic bodies share their target's column (v_idx), so columns accumulate.
//
// End-effector pose (6): the world position of the point at `offset` (body
// frame) on body b, then the roll-pitch-yaw angles of X_world_b.R with
// R = Rz(yaw) Ry(pitch) Rx(roll), pitch in [-π/2, π/2]. Derivatives are
// with respect to tangent perturbations q ⊕ δ (nv columns).
#pragma once

#include "rbdkit/model/workspace.hpp"

namespace rbd {

enum ReferenceFrame : int {
  kLocal = 0,               // the frame's own axes, at its origin
  kWorld = 1,               // world axes, at the world origin
  kLocalWorldAligned = 2,   // world axes, at the frame's origin
};

// ---------------------------------------------------------------- placements

// forward kinematics: w.X (X_parent_body), w.Xw (X_world_body) for every body,
// and, when qd is not null, w.v (body velocity in the body frame).
//   q (nq), qd (nv or null)
template <typename S> RBD_HD void forward_kinematics(const ModelView<S>& m, Workspace<S>& w, const S* q, const S* qd) {
  place_joints(m, w.X_parent, q);  // X_λi
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    // X_0i = X_0λ X_λi
    w.X_world[i] = b.parent >= 0 ? w.X_world[b.parent] * w.X_parent[i] : w.X_parent[i];
    // v_i = X_λi⁻¹ v_λ + S qd
    if (!qd) continue;
    const Motion<S> vJ = joint_motion(b, qd + b.v_idx);
    w.v[i] = b.parent >= 0 ? w.X_parent[i].act_inv(w.v[b.parent]) + vJ : vJ;
  }
}

// X_world_frame of a frame at X_body_frame on `body` (-1: the world), after forward_kinematics
template <typename S>
RBD_HD Transform<S> frame_placement(const Workspace<S>& w, int body, const Transform<S>& X_body_frame) {
  return body >= 0 ? w.X_world[body] * X_body_frame : X_body_frame;
}

// world-frame velocity of a body (at the world origin, world axes), after
// forward_kinematics with qd; zero for the world (-1)
template <typename S> RBD_HD Motion<S> world_velocity(const Workspace<S>& w, int body) {
  return body >= 0 ? w.X_world[body].act(w.v[body]) : Motion<S>::zero();
}

// the world-frame column of DoF a of body k: X_world_k · S_k[:, a]
template <typename S> RBD_HD Motion<S> world_subspace_col(const ModelView<S>& m, const Workspace<S>& w, int k, int a) {
  return joint_subspace_col_in(m.body[k], w.X_world[k], a);
}

// a world-frame motion s re-expressed in reference frame rf for the frame at X_world_F
template <typename S> RBD_HD Motion<S> express_motion(const Motion<S>& s, const Transform<S>& X_world_F, int rf) {
  if (rf == kWorld) return s;
  if (rf == kLocal) return X_world_F.act_inv(s);
  return {s.lin + cross(s.ang, X_world_F.p), s.ang};
}

// add a 6D column to column c of a 6 x nv row-major matrix
template <typename S> RBD_HD void add_column(const Motion<S>& s, int c, int nv, S* J) {
  J[0 * nv + c] += s.lin.x; J[1 * nv + c] += s.lin.y; J[2 * nv + c] += s.lin.z;
  J[3 * nv + c] += s.ang.x; J[4 * nv + c] += s.ang.y; J[5 * nv + c] += s.ang.z;
}

// ----------------------------------------------------------------- Jacobians

// J (6 x nv, row-major) of the frame at X_body_frame on `body` (-1: zero) in
// reference frame rf, after forward_kinematics
template <typename S>
RBD_HD void frame_jacobian(const ModelView<S>& m, const Workspace<S>& w, int body, const Transform<S>& X_body_frame,
                           int rf, S* J) {
  const int nv = m.nv;
  for (int k = 0; k < 6 * nv; ++k) J[k] = S(0);
  const Transform<S> X_world_F = frame_placement(w, body, X_body_frame);
  // support chain: each ancestor-or-self k contributes its world columns
  for (int k = body; k >= 0; k = m.body[k].parent) {
    const BodyDesc<S>& b = m.body[k];
    for (int a = 0; a < b.nv; ++a)
      add_column(express_motion(world_subspace_col(m, w, k, a), X_world_F, rf), b.v_idx + a, nv, J);
  }
}

// dJ/dt (6 x nv, row-major) of the frame Jacobian in reference frame rf,
// along the velocity qd given to forward_kinematics. With v_k, v_b the world
// velocities of body k and of the frame's body, world column d/dt s = v_k × s:
//   kWorld               v_k × s
//   kLocal               X_world_F⁻¹ ((v_k - v_b) × s)     (d/dt of X⁻¹ s)
//   kLocalWorldAligned   (ṡ.lin + ṡ.ang × p + s.ang × ṗ, ṡ.ang),  ṗ = v_b.lin + v_b.ang × p
template <typename S>
RBD_HD void frame_jacobian_dot(const ModelView<S>& m, const Workspace<S>& w, int body,
                               const Transform<S>& X_body_frame, int rf, S* dJ) {
  const int nv = m.nv;
  for (int k = 0; k < 6 * nv; ++k) dJ[k] = S(0);
  const Transform<S> X_world_F = frame_placement(w, body, X_body_frame);
  const Motion<S> vb = world_velocity(w, body);
  const Vec3<S> pdot = vb.lin + cross(vb.ang, X_world_F.p);
  for (int k = body; k >= 0; k = m.body[k].parent) {
    const BodyDesc<S>& b = m.body[k];
    const Motion<S> vk = world_velocity(w, k);
    for (int a = 0; a < b.nv; ++a) {
      const Motion<S> s = world_subspace_col(m, w, k, a);
      Motion<S> ds;
      if (rf == kWorld) {
        ds = cross(vk, s);
      } else if (rf == kLocal) {
        ds = X_world_F.act_inv(cross(vk - vb, s));
      } else {
        ds = express_motion(cross(vk, s), X_world_F, rf);
        ds.lin += cross(s.ang, pdot);
      }
      add_column(ds, b.v_idx + a, nv, dJ);
    }
  }
}

// ------------------------------------------------------------ roll-pitch-yaw

// (roll, pitch, yaw) of R = Rz(yaw) Ry(pitch) Rx(roll), pitch in [-π/2, π/2],
// roll and yaw in (-π, π]. Roll is read from Rz(yaw)ᵀ R = Ry(pitch) Rx(roll),
// whose middle row (0, cos roll, -sin roll) does not depend on pitch, so the
// angles rebuild R even at pitch = ±π/2, where only roll ∓ yaw is defined
// (yaw is then whatever atan2 makes of the rounding, often 0).
template <typename S> RBD_HD Vec3<S> rpy_from_matrix(const Mat3<S>& R) {
  const S pitch = satan2(-R(2, 0), ssqrt(R(0, 0) * R(0, 0) + R(1, 0) * R(1, 0)));
  const S yaw = satan2(R(1, 0), R(0, 0));
  const S cy = scos(yaw), sy = ssin(yaw);
  const S roll = satan2(sy * R(0, 2) - cy * R(1, 2), cy * R(1, 1) - sy * R(0, 1));
  return {roll, pitch, yaw};
}

// E(rpy): world angular velocity ω = E · d(rpy)/dt; columns Rz Ry e_x, Rz e_y, e_z
template <typename S> RBD_HD Mat3<S> rpy_rate_matrix(const Vec3<S>& rpy) {
  const S cp = scos(rpy.y), sp = ssin(rpy.y), cy = scos(rpy.z), sy = ssin(rpy.z);
  return {{cy * cp, -sy, S(0), sy * cp, cy, S(0), -sp, S(0), S(1)}};
}

// E(rpy)⁻¹: d(rpy)/dt = E⁻¹ ω; singular at pitch = ±π/2
template <typename S> RBD_HD Mat3<S> rpy_rate_matrix_inverse(const Vec3<S>& rpy) {
  const S cp = scos(rpy.y), sp = ssin(rpy.y), cy = scos(rpy.z), sy = ssin(rpy.z);
  const S tp = sp / cp;
  return {{cy / cp, sy / cp, S(0), -sy, cy, S(0), cy * tp, sy * tp, S(1)}};
}

// dE for the rpy rate u: ∂E/∂pitch · u.pitch + ∂E/∂yaw · u.yaw (E does not depend on roll)
template <typename S> RBD_HD Mat3<S> rpy_rate_matrix_derivative(const Vec3<S>& rpy, const Vec3<S>& u) {
  const S cp = scos(rpy.y), sp = ssin(rpy.y), cy = scos(rpy.z), sy = ssin(rpy.z);
  const S dp = u.y, dy = u.z;
  return {{-cy * sp * dp - sy * cp * dy, -cy * dy, S(0),
           -sy * sp * dp + cy * cp * dy, -sy * dy, S(0),
           -cp * dp, S(0), S(0)}};
}

// ------------------------------------------------------------- end effectors

// pose (6) = [position of the point `offset` (body frame) of `body` in the world; roll, pitch, yaw]
template <typename S> RBD_HD void end_effector_pose(const Workspace<S>& w, int body, const Vec3<S>& offset, S* pose) {
  const Transform<S>& X = w.X_world[body];
  const Vec3<S> p = X.act_point(offset), rpy = rpy_from_matrix(X.R);
  pose[0] = p.x; pose[1] = p.y; pose[2] = p.z;
  pose[3] = rpy.x; pose[4] = rpy.y; pose[5] = rpy.z;
}

// G (6 x nv, row-major): ∂pose/∂δ. For every world column s of the support chain
//   position rows  s.lin + s.ang × p        (the point's velocity)
//   rpy rows       E(rpy)⁻¹ s.ang
template <typename S>
RBD_HD void end_effector_pose_gradient(const ModelView<S>& m, const Workspace<S>& w, int body, const Vec3<S>& offset,
                                       S* G) {
  const int nv = m.nv;
  for (int k = 0; k < 6 * nv; ++k) G[k] = S(0);
  const Vec3<S> p = w.X_world[body].act_point(offset);
  const Mat3<S> Einv = rpy_rate_matrix_inverse(rpy_from_matrix(w.X_world[body].R));
  for (int k = body; k >= 0; k = m.body[k].parent) {
    const BodyDesc<S>& b = m.body[k];
    for (int a = 0; a < b.nv; ++a) {
      const Motion<S> s = world_subspace_col(m, w, k, a);
      add_column(Motion<S>{s.lin + cross(s.ang, p), Einv * s.ang}, b.v_idx + a, nv, G);
    }
  }
}

// H (6 x nv x nv, row-major): H[r][j][k] = ∂G[r][k]/∂δ_j, in closed form. For
// support-chain columns s_j (of body bj) and s_k (of body bk), with
// [bj ⪯ bk] = 1 when bj is bk or one of its ancestors (then ∂s_k/∂δ_j = s_j × s_k):
//   position  [bj ⪯ bk] ((s_j × s_k).lin + (s_j × s_k).ang × p) + s_k.ang × ṗ_j
//             with ṗ_j = s_j.lin + s_j.ang × p (the tool point moves with s_j)
//   rpy       E⁻¹ ([bj ⪯ bk] s_j.ang × s_k.ang - dE(u_j) u_k),  u = E⁻¹ s.ang
// Within a free-flyer or spherical joint every pair counts in both orders, so
// H is not symmetric in (j, k) there (the tangent columns do not commute).
template <typename S>
RBD_HD void end_effector_pose_hessian_analytic(const ModelView<S>& m, const Workspace<S>& w, int body,
                                               const Vec3<S>& offset, S* H) {
  const int nv = m.nv;
  for (int k = 0; k < 6 * nv * nv; ++k) H[k] = S(0);
  const Vec3<S> p = w.X_world[body].act_point(offset);
  const Vec3<S> rpy = rpy_from_matrix(w.X_world[body].R);
  const Mat3<S> Einv = rpy_rate_matrix_inverse(rpy);
  // k: the differentiated column; j: the perturbation, over the support chain
  for (int bk = body; bk >= 0; bk = m.body[bk].parent) {
    const BodyDesc<S>& Bk = m.body[bk];
    for (int a = 0; a < Bk.nv; ++a) {
      const Motion<S> sk = world_subspace_col(m, w, bk, a);
      const Vec3<S> uk = Einv * sk.ang;
      const int ck = Bk.v_idx + a;
      for (int bj = body; bj >= 0; bj = m.body[bj].parent) {
        const BodyDesc<S>& Bj = m.body[bj];
        const bool moves_k = bj <= bk;  // on one chain: ancestor-or-self
        for (int c = 0; c < Bj.nv; ++c) {
          const Motion<S> sj = world_subspace_col(m, w, bj, c);
          const Vec3<S> pdot = sj.lin + cross(sj.ang, p);
          Vec3<S> dpos = cross(sk.ang, pdot);
          Vec3<S> dw = Vec3<S>::zero();
          if (moves_k) {
            const Motion<S> dsk = cross(sj, sk);
            dpos += dsk.lin + cross(dsk.ang, p);
            dw = dsk.ang;
          }
          const Vec3<S> drpy = Einv * (dw - rpy_rate_matrix_derivative(rpy, Einv * sj.ang) * uk);
          const int cj = Bj.v_idx + c;
          const Vec3<S> col[2] = {dpos, drpy};
          for (int r = 0; r < 6; ++r) H[(r * nv + cj) * nv + ck] += col[r / 3][r % 3];
        }
      }
    }
  }
}

}  // namespace rbd
