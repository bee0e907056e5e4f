// rbdkit/model/joint.hpp — the closed set of joint types, the description of one
// body and its joint (BodyDesc) and the device-copyable model view. Each
// type's kinematics (Featherstone's jcalc: X_J(q), S, S·qd, Sᵀ·f) and
// configuration operations are in joint_types.hpp, dispatched once per body.
//
// Every joint's velocity is expressed in its child (body) frame, so S is
// constant in body coordinates and the joint bias c_J = Ṡ·qd is zero for all
// types below.
#pragma once

#include "rbdkit/spatial/spatial.hpp"

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
  int axis_k;         // k + 1 when axis = ±e_k, a frame axis (kinematics without products by its zeros); 0 otherwise.
                      // Derived from axis by Model::finalize: set it again after changing axis
  Transform<S> X_tree;  // X_parent_joint: joint frame placed in the parent body frame
  Inertia<S> I;       // spatial inertia in the body frame (merged fixed links included)
};

// a body description in scalar T (a dual number, float): the constants converted, the structure kept
template <typename T, typename S> RBD_HD void body_as(const BodyDesc<S>& b, BodyDesc<T>& o) {
  o.parent = b.parent, o.type = b.type, o.q_idx = b.q_idx, o.v_idx = b.v_idx, o.nq = b.nq, o.nv = b.nv;
  o.nv_subtree = b.nv_subtree, o.mimic = b.mimic, o.axis_k = b.axis_k;
  o.mult = T(b.mult), o.offset = T(b.offset), o.pitch = T(b.pitch);
  o.axis = {T(b.axis.x), T(b.axis.y), T(b.axis.z)};
  for (int k = 0; k < 9; ++k) o.X_tree.R.m[k] = T(b.X_tree.R.m[k]), o.I.I.m[k] = T(b.I.I.m[k]);
  o.X_tree.p = {T(b.X_tree.p.x), T(b.X_tree.p.y), T(b.X_tree.p.z)};
  o.I.m = T(b.I.m);
  o.I.h = {T(b.I.h.x), T(b.I.h.y), T(b.I.h.z)};
}

// device-copyable view of a model: sizes and a pointer to nb bodies
template <typename S> struct ModelView {
  int nb, nq, nv;
  int has_mimic;            // 1 if any body is a mimic, or the bodies are not in depth-first order
                            // (Model::general_path): the algorithms then take their general paths
                            // (world-frame CRBA, M⁻¹ and forward dynamics through M's Cholesky factor)
  const BodyDesc<S>* body;  // (nb)
};

// whether each body's subtree owns the velocity coordinates [v_idx, v_idx + nv_subtree), one
// contiguous range: bodies in depth-first order, as URDF and MJCF models are, and a ModelBuilder's
// when its bodies were added so. The body-frame CRBA and the direct M⁻¹ rely on it. It holds when
// each body's range lies in its parent's: a range then holds its subtree's coordinates, and as many.
// Models without mimic joints (a mimic body owns no coordinate)
template <typename S> RBD_HD bool subtrees_contiguous(const BodyDesc<S>* body, int nb) {
  for (int i = 0; i < nb; ++i) {
    const int p = body[i].parent;
    if (p < 0) continue;
    const BodyDesc<S>& b = body[i];
    const BodyDesc<S>& a = body[p];
    if (b.v_idx < a.v_idx || b.v_idx + b.nv_subtree > a.v_idx + a.nv_subtree) return false;
  }
  return true;
}

// coordinate of a 1-DoF joint, mimic folded in
template <typename S> RBD_HD S joint_angle(const BodyDesc<S>& b, const S* q) {
  return b.mimic ? b.mult * q[b.q_idx] + b.offset : q[b.q_idx];
}

}  // namespace rbd
