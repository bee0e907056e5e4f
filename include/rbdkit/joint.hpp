// rbdkit/joint.hpp — the closed set of joint types and their kinematics
// (Featherstone's jcalc): joint transform X_J(q), motion subspace S and the
// projections S·qd and Sᵀ·f. Dispatched once per body with a switch.
//
// Every joint's velocity is expressed in its child (body) frame, so S is
// constant in body coordinates and the joint bias c_J = Ṡ·qd is zero for all
// types below.
#pragma once

#include "spatial.hpp"

namespace rbd {

enum JointType : int {
  kRevolute = 0,   // rotation about a unit axis; nq = nv = 1
  kPrismatic = 1,  // translation along a unit axis; nq = nv = 1
  kHelical = 2,    // screw: rotation q about the axis and translation pitch·q along it
  kSpherical = 3,  // quaternion (x, y, z, w); nq = 4, nv = 3 (local angular velocity)
  kFree = 4,       // [p (3), quaternion (4)]; nq = 7, nv = 6 ([v_lin; w] local)
};

// One moving body and the joint that connects it to its parent. Bodies are
// stored in topological order (parent index < own index).
template <typename S> struct BodyDesc {
  int parent;         // parent body, -1 for the world
  int type;           // JointType
  int q_idx, v_idx;   // first configuration / velocity coordinate (a mimic: its target's)
  int nq, nv;         // coordinates of the joint (a mimic: 1, 1, shared with the target)
  int nv_subtree;     // velocity coordinates in this body's subtree, itself included (mimics excluded)
  int mimic;          // 1: q_joint = mult·q[q_idx] + offset and the joint owns no coordinate
  S mult, offset;     // mimic multiplier and offset (1, 0 otherwise)
  S pitch;            // helical pitch, metres per radian
  Vec3<S> axis;       // unit joint axis in the joint frame (1-DoF joints)
  Transform<S> X_tree;  // X_parent_joint: joint frame placed in the parent body frame
  Inertia<S> I;       // spatial inertia in the body frame (merged fixed links included)
};

// device-copyable view of a model: sizes and a pointer to nb bodies
template <typename S> struct ModelView {
  int nb, nq, nv;
  int has_mimic;            // 1 if any body is a mimic (forward dynamics then uses the dense path)
  const BodyDesc<S>* body;  // (nb)
};

// coordinate of a 1-DoF joint, mimic folded in
template <typename S> RBD_HD S joint_angle(const BodyDesc<S>& b, const S* q) {
  return b.mimic ? b.mult * q[b.q_idx] + b.offset : q[b.q_idx];
}

// X_J(q): the child frame placed in the joint frame
template <typename S> RBD_HD Transform<S> joint_transform(const BodyDesc<S>& b, const S* q) {
  switch (b.type) {
    case kRevolute: return {axis_angle(b.axis, joint_angle(b, q)), Vec3<S>::zero()};
    case kPrismatic: return {Mat3<S>::identity(), joint_angle(b, q) * b.axis};
    case kHelical: {
      const S t = joint_angle(b, q);
      return {axis_angle(b.axis, t), (b.pitch * t) * b.axis};
    }
    case kSpherical: return {quat_to_matrix(q + b.q_idx), Vec3<S>::zero()};
    default: {  // kFree
      const S* qj = q + b.q_idx;
      return {quat_to_matrix(qj + 3), {qj[0], qj[1], qj[2]}};
    }
  }
}

// X_parent_body = X_tree · X_J(q)
template <typename S> RBD_HD Transform<S> body_transform(const BodyDesc<S>& b, const S* q) {
  const Transform<S> XJ = joint_transform(b, q);
  if (b.type == kRevolute) return {b.X_tree.R * XJ.R, b.X_tree.p};
  return b.X_tree * XJ;
}

// column k of the motion subspace S (mimic multiplier included)
template <typename S> RBD_HD Motion<S> joint_subspace_col(const BodyDesc<S>& b, int k) {
  switch (b.type) {
    case kRevolute: return {Vec3<S>::zero(), b.mult * b.axis};
    case kPrismatic: return {b.mult * b.axis, Vec3<S>::zero()};
    case kHelical: return {(b.mult * b.pitch) * b.axis, b.mult * b.axis};
    case kSpherical: {
      Motion<S> m = Motion<S>::zero();
      m.ang[k] = S(1);
      return m;
    }
    default: {  // kFree
      Motion<S> m = Motion<S>::zero();
      if (k < 3) m.lin[k] = S(1);
      else m.ang[k - 3] = S(1);
      return m;
    }
  }
}

// S·x for the joint's nv coordinates x
template <typename S> RBD_HD Motion<S> joint_motion(const BodyDesc<S>& b, const S* x) {
  switch (b.type) {
    case kSpherical: return {Vec3<S>::zero(), {x[0], x[1], x[2]}};
    case kFree: return {{x[0], x[1], x[2]}, {x[3], x[4], x[5]}};
    default: return x[0] * joint_subspace_col(b, 0);
  }
}

// Sᵀ·f, written to out[0..nv)
template <typename S> RBD_HD void joint_project(const BodyDesc<S>& b, const Force<S>& f, S* out) {
  switch (b.type) {
    case kSpherical: out[0] = f.ang.x; out[1] = f.ang.y; out[2] = f.ang.z; return;
    case kFree:
      out[0] = f.lin.x; out[1] = f.lin.y; out[2] = f.lin.z;
      out[3] = f.ang.x; out[4] = f.ang.y; out[5] = f.ang.z;
      return;
    default: out[0] = dot(joint_subspace_col(b, 0), f); return;
  }
}

}  // namespace rbd
