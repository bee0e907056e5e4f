// rbdkit/model/joint_types.hpp — each joint type in one place: its sizes, its
// kinematics (Featherstone's jcalc: X_J(q) and the motion subspace S) and the
// operations of its configuration manifold in both conventions; and the one
// dispatch on the type, visit_joint, that the per-body functions below and the
// whole-configuration loops (configuration.hpp, mujoco_convention.hpp) go through.
//
// A joint type is a struct of static functions. The kinematics take the body
// and the whole q (a mimic reads its target's coordinate); the manifold
// operations take the joint's own coordinates, qj (nq) and vj (nv), and write
// a Jacobian's diagonal block (nv x nv) at Jj, row stride ld:
//   nq, nv, rot                  sizes; rot: the offset of the rotation, its
//                                quaternion in qj and its angular velocity in vj
//                                (-1: none)
//   transform(b, q)              X_J(q): the child frame placed in the joint frame
//   subspace_col(b, k)           column k of S (mimic multiplier included)
//   motion(b, x), project(b, f, out)       S·x (x: nv), Sᵀ·f (out: nv)
//   integrate(qj, vj, out)       q ⊕ v      (Pinocchio's: out nq)
//   difference(q0j, q1j, out)    q1 ⊖ q0    (out nv)
//   dintegrate(vj, arg, Jj, ld)  arg 0: ∂(q ⊕ v)/∂q, 1: ∂/∂v
//   ddifference(q0j, q1j, arg, Jj, ld)     arg 0: ∂(q1 ⊖ q0)/∂q0, 1: ∂/∂q1
//   mj_integrate, mj_difference, mj_dintegrate, mj_ddifference: the same in
//                                MuJoCo's convention (mujoco_convention.hpp)
//   neutral(qj)                  zero coordinates, identity quaternion
//   bracket(x, y, out), mj_bracket(x, y, out)   the Lie bracket of two tangent
//                                vectors (zero on R; so(3); se(3), or R³ × so(3))
// and, with defaults in JointDefaults that a type replaces where its structure
// saves work:
//   placement(b, q)              X_tree · X_J(q) (revolute: two turned columns,
//                                prismatic: a translation)
//   subspace_col_in(b, X, k)     X · (column k of S) without S's zero products
//   project_in(b, X, sx, F, out) (X S)ᵀ F from the columns sx = X S (free: X⁻¹ F)
//   frame_column(b, sign)        c when S = sign·e_c (a 1-DoF joint about a frame
//                                axis), else -1
// Manifolds: a 1-DoF joint R in both conventions; spherical SO(3), quaternion
// (x, y, z, w) in ours, (w, x, y, z) in MuJoCo's; free SE(3) with the twist in
// the local frame in ours (Pinocchio's), R³ × SO(3) in MuJoCo's (the position
// additive, the rotation in the body frame).
#pragma once

#include <type_traits>

#include "rbdkit/model/joint.hpp"
#include "rbdkit/spatial/lie.hpp"

namespace rbd {

// ---- helpers

// unit quaternion in the hemisphere of `ref`
template <typename S> RBD_HD Quat<S> normalize_near(Quat<S> a, const Quat<S>& ref) {
  const S d = a.x * ref.x + a.y * ref.y + a.z * ref.z + a.w * ref.w;
  const S s = select(lane_lt(d, 0), S(-1), S(1)) / ssqrt(a.x * a.x + a.y * a.y + a.z * a.z + a.w * a.w);
  return {s * a.x, s * a.y, s * a.z, s * a.w};
}

// quaternion (w, x, y, z) stored at q (MuJoCo's order)
template <typename S> RBD_HD Quat<S> load_quat_wxyz(const S* q) { return {q[1], q[2], q[3], q[0]}; }
template <typename S> RBD_HD void store_quat_wxyz(const Quat<S>& a, S* q) {
  q[0] = a.w; q[1] = a.x; q[2] = a.y; q[3] = a.z;
}

// write a 3x3 / 6x6 block at (r0, r0) of an nv x nv row-major matrix
template <typename S> RBD_HD void put_block3(const Mat3<S>& B, S* J, int nv, int r0, int c0) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) J[(r0 + r) * nv + c0 + c] = B(r, c);
}
template <typename S> RBD_HD void put_block6(const S* B, S* J, int nv, int r0) {
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) J[(r0 + r) * nv + r0 + c] = B[r * 6 + c];
}
template <typename S> RBD_HD void put_mat6(const Mat6<S>& B, S sign, S* J, int nv, int r0) {
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) J[(r0 + r) * nv + r0 + c] = sign * B(r, c);
}

// R · rot(e_K, t) for c = cos t, s = sin t: columns i, j = K+1, K+2 (mod 3)
// of R turned in their plane, column K kept (K a constant: registers on a GPU)
template <int K, typename S> RBD_HD Mat3<S> turn_columns(const Mat3<S>& R, const S& c, const S& s) {
  constexpr int i = (K + 1) % 3, j = (K + 2) % 3;
  Mat3<S> o = R;
  for (int r = 0; r < 3; ++r) {
    o(r, i) = c * R(r, i) + s * R(r, j);
    o(r, j) = c * R(r, j) - s * R(r, i);
  }
  return o;
}

// R · rot(axis, t) for a 1-DoF body whose axis is ±e_k (b.axis_k = k + 1), from c = cos t, s = sin t
template <typename S>
RBD_HD Mat3<S> turn_about_frame_axis(const BodyDesc<S>& b, const Mat3<S>& R, const S& c, const S& s) {
  switch (b.axis_k) {
    case 1: return turn_columns<0>(R, c, b.axis.x * s);
    case 2: return turn_columns<1>(R, c, b.axis.y * s);
    default: return turn_columns<2>(R, c, b.axis.z * s);
  }
}
template <typename S> RBD_HD Mat3<S> rotate_about_frame_axis(const BodyDesc<S>& b, const Mat3<S>& R, const S& t) {
  S s, c;
  ssincos(t, s, c);
  return turn_about_frame_axis(b, R, c, s);
}

// R · axis for a 1-DoF body: a column of R when the axis is a frame axis
template <typename S> RBD_HD Vec3<S> rotate_axis(const BodyDesc<S>& b, const Mat3<S>& R) {
  switch (b.axis_k) {
    case 1: return b.axis.x * Vec3<S>{R(0, 0), R(1, 0), R(2, 0)};
    case 2: return b.axis.y * Vec3<S>{R(0, 1), R(1, 1), R(2, 1)};
    case 3: return b.axis.z * Vec3<S>{R(0, 2), R(1, 2), R(2, 2)};
    default: return R * b.axis;
  }
}

// ---- what a joint type does unless it says otherwise (JT: the joint type)

template <typename JT> struct JointDefaults {
  // X_parent_body = X_tree · X_J(q)
  template <typename S> RBD_HD static Transform<S> placement(const BodyDesc<S>& b, const S* q) {
    return b.X_tree * JT::transform(b, q);
  }
  // X · (column k of S), for X mapping the body frame to another (X_0i: the world)
  template <typename S> RBD_HD static Motion<S> subspace_col_in(const BodyDesc<S>& b, const Transform<S>& X, int k) {
    return X.act(JT::subspace_col(b, k));
  }
  // (X S)ᵀ F for a force F in X's frame, given the columns X S (sx: nv of them)
  template <typename S>
  RBD_HD static void project_in(const BodyDesc<S>&, const Transform<S>&, const Motion<S>* sx, const Force<S>& F,
                                S* out) {
    for (int l = 0; l < JT::nv; ++l) out[l] = dot(sx[l], F);
  }
  // the column c of a 6x6 that S picks when S is ±e_c (sign: the ± and the
  // mimic multiplier), else -1
  template <typename S> RBD_HD static int frame_column(const BodyDesc<S>&, S&) { return -1; }
  // the Lie bracket [x, y] of two tangent vectors of the joint (nv each): zero
  // on an abelian manifold
  template <typename S> RBD_HD static void bracket(const S*, const S*, S* out) {
    for (int l = 0; l < JT::nv; ++l) out[l] = S(0);
  }
  // the same in MuJoCo's convention
  template <typename S> RBD_HD static void mj_bracket(const S* x, const S* y, S* out) { JT::bracket(x, y, out); }
};

// ---- 1-DoF joints: the manifold R in both conventions (JT: the joint type)

template <typename JT> struct OneDofJoint : JointDefaults<JT> {
  static constexpr int nq = 1, nv = 1, rot = -1;
  template <typename S> RBD_HD static Motion<S> motion(const BodyDesc<S>& b, const S* x) {
    return x[0] * JT::subspace_col(b, 0);
  }
  template <typename S> RBD_HD static void project(const BodyDesc<S>& b, const Force<S>& f, S* out) {
    out[0] = dot(JT::subspace_col(b, 0), f);
  }
  template <typename S> RBD_HD static void integrate(const S* qj, const S* vj, S* out) { out[0] = qj[0] + vj[0]; }
  template <typename S> RBD_HD static void difference(const S* a, const S* c, S* out) { out[0] = c[0] - a[0]; }
  template <typename S> RBD_HD static void dintegrate(const S*, int, S* Jj, int) { Jj[0] = S(1); }
  template <typename S> RBD_HD static void ddifference(const S*, const S*, int arg, S* Jj, int) {
    Jj[0] = arg == 1 ? S(1) : S(-1);
  }
  template <typename S> RBD_HD static void mj_integrate(const S* qj, const S* vj, S* out) { integrate(qj, vj, out); }
  template <typename S> RBD_HD static void mj_difference(const S* a, const S* c, S* out) { difference(a, c, out); }
  template <typename S> RBD_HD static void mj_dintegrate(const S* vj, int arg, S* Jj, int ld) {
    dintegrate(vj, arg, Jj, ld);
  }
  template <typename S> RBD_HD static void mj_ddifference(const S* a, const S* c, int arg, S* Jj, int ld) {
    ddifference(a, c, arg, Jj, ld);
  }
  template <typename S> RBD_HD static void neutral(S* qj) { qj[0] = S(0); }
};

// rotation about a unit axis
struct RevoluteJoint : OneDofJoint<RevoluteJoint> {
  template <typename S> RBD_HD static Transform<S> transform(const BodyDesc<S>& b, const S* q) {
    return {axis_angle(b.axis, joint_angle(b, q)), Vec3<S>::zero()};
  }
  template <typename S> RBD_HD static Motion<S> subspace_col(const BodyDesc<S>& b, int) {
    return {Vec3<S>::zero(), b.mult * b.axis};
  }
  // X_J is a pure rotation: two turned columns of X_tree about a frame axis
  template <typename S> RBD_HD static Transform<S> placement(const BodyDesc<S>& b, const S* q) {
    if (b.axis_k) return {rotate_about_frame_axis(b, b.X_tree.R, joint_angle(b, q)), b.X_tree.p};
    return {b.X_tree.R * axis_angle(b.axis, joint_angle(b, q)), b.X_tree.p};
  }
  template <typename S> RBD_HD static Motion<S> subspace_col_in(const BodyDesc<S>& b, const Transform<S>& X, int) {
    const Vec3<S> w = b.mult * rotate_axis(b, X.R);
    return {cross(X.p, w), w};
  }
  template <typename S> RBD_HD static int frame_column(const BodyDesc<S>& b, S& sign) {
    if (!b.axis_k) return -1;
    sign = b.mult * b.axis[b.axis_k - 1];
    return 3 + b.axis_k - 1;
  }
};

// translation along a unit axis
struct PrismaticJoint : OneDofJoint<PrismaticJoint> {
  template <typename S> RBD_HD static Transform<S> transform(const BodyDesc<S>& b, const S* q) {
    return {Mat3<S>::identity(), joint_angle(b, q) * b.axis};
  }
  template <typename S> RBD_HD static Motion<S> subspace_col(const BodyDesc<S>& b, int) {
    return {b.mult * b.axis, Vec3<S>::zero()};
  }
  // X_J is a pure translation
  template <typename S> RBD_HD static Transform<S> placement(const BodyDesc<S>& b, const S* q) {
    return {b.X_tree.R, b.X_tree.p + joint_angle(b, q) * rotate_axis(b, b.X_tree.R)};
  }
  template <typename S> RBD_HD static Motion<S> subspace_col_in(const BodyDesc<S>& b, const Transform<S>& X, int) {
    return {b.mult * rotate_axis(b, X.R), Vec3<S>::zero()};
  }
  template <typename S> RBD_HD static int frame_column(const BodyDesc<S>& b, S& sign) {
    if (!b.axis_k) return -1;
    sign = b.mult * b.axis[b.axis_k - 1];
    return b.axis_k - 1;
  }
};

// screw: rotation q about the axis and translation pitch·q along it
struct HelicalJoint : OneDofJoint<HelicalJoint> {
  template <typename S> RBD_HD static Transform<S> transform(const BodyDesc<S>& b, const S* q) {
    const S t = joint_angle(b, q);
    return {axis_angle(b.axis, t), (b.pitch * t) * b.axis};
  }
  template <typename S> RBD_HD static Motion<S> subspace_col(const BodyDesc<S>& b, int) {
    return {(b.mult * b.pitch) * b.axis, b.mult * b.axis};
  }
};

// ---- spherical: SO(3), the local angular velocity

struct SphericalJoint : JointDefaults<SphericalJoint> {
  static constexpr int nq = 4, nv = 3, rot = 0;
  // X S: column k of X's rotation, and p × it
  template <typename S> RBD_HD static Motion<S> subspace_col_in(const BodyDesc<S>&, const Transform<S>& X, int k) {
    const Vec3<S> w = {X.R(0, k), X.R(1, k), X.R(2, k)};
    return {cross(X.p, w), w};
  }
  // so(3): [x, y] = x × y, in both conventions
  template <typename S> RBD_HD static void bracket(const S* x, const S* y, S* out) {
    store3(cross(load3(x), load3(y)), out);
  }
  template <typename S> RBD_HD static Transform<S> transform(const BodyDesc<S>& b, const S* q) {
    return {quat_to_matrix(q + b.q_idx), Vec3<S>::zero()};
  }
  template <typename S> RBD_HD static Motion<S> subspace_col(const BodyDesc<S>&, int k) {
    Motion<S> m = Motion<S>::zero();
    m.ang[k] = S(1);
    return m;
  }
  template <typename S> RBD_HD static Motion<S> motion(const BodyDesc<S>&, const S* x) {
    return {Vec3<S>::zero(), {x[0], x[1], x[2]}};
  }
  template <typename S> RBD_HD static void project(const BodyDesc<S>&, const Force<S>& f, S* out) {
    out[0] = f.ang.x; out[1] = f.ang.y; out[2] = f.ang.z;
  }
  // r ⊗ exp(v), kept in the hemisphere of r
  template <typename S> RBD_HD static void integrate(const S* qj, const S* vj, S* out) {
    const Quat<S> r0 = load_quat(qj);
    store_quat(normalize_near(r0 * quat_exp(Vec3<S>{vj[0], vj[1], vj[2]}), r0), out);
  }
  template <typename S> RBD_HD static void difference(const S* a, const S* c, S* o) {
    const Vec3<S> w = quat_log(conj(load_quat(a)) * load_quat(c));
    o[0] = w.x; o[1] = w.y; o[2] = w.z;
  }
  // (the Jacobians of a left-invariant retraction do not depend on q)
  template <typename S> RBD_HD static void dintegrate(const S* vj, int arg, S* Jj, int ld) {
    const Vec3<S> w = {vj[0], vj[1], vj[2]};
    put_block3(arg == 0 ? transpose(to_matrix(quat_exp(w))) : jexp3(w), Jj, ld, 0, 0);
  }
  template <typename S> RBD_HD static void ddifference(const S* a, const S* c, int arg, S* Jj, int ld) {
    const Quat<S> r = conj(load_quat(a)) * load_quat(c);
    const Mat3<S> Jl = jlog3(quat_log(r));
    put_block3(arg == 1 ? Jl : S(-1) * (Jl * transpose(to_matrix(r))), Jj, ld, 0, 0);
  }
  // MuJoCo's ball: (w, x, y, z), normalized product, no hemisphere flip (as mju_quatIntegrate)
  template <typename S> RBD_HD static void mj_integrate(const S* qj, const S* vj, S* out) {
    const Quat<S> a = load_quat_wxyz(qj) * quat_exp(Vec3<S>{vj[0], vj[1], vj[2]});
    const S n = S(1) / ssqrt(a.x * a.x + a.y * a.y + a.z * a.z + a.w * a.w);
    store_quat_wxyz(Quat<S>{n * a.x, n * a.y, n * a.z, n * a.w}, out);
  }
  template <typename S> RBD_HD static void mj_difference(const S* a, const S* c, S* o) {
    const Vec3<S> w = quat_log(conj(load_quat_wxyz(a)) * load_quat_wxyz(c));
    o[0] = w.x; o[1] = w.y; o[2] = w.z;
  }
  template <typename S> RBD_HD static void mj_dintegrate(const S* vj, int arg, S* Jj, int ld) {
    dintegrate(vj, arg, Jj, ld);
  }
  template <typename S> RBD_HD static void mj_ddifference(const S* a, const S* c, int arg, S* Jj, int ld) {
    const Quat<S> d = conj(load_quat_wxyz(a)) * load_quat_wxyz(c);
    const Mat3<S> Jl = jlog3(quat_log(d));
    put_block3(arg == 1 ? Jl : S(-1) * (Jl * transpose(to_matrix(d))), Jj, ld, 0, 0);
  }
  template <typename S> RBD_HD static void neutral(S* qj) {
    qj[0] = S(0), qj[1] = S(0), qj[2] = S(0), qj[3] = S(1);
  }
};

// ---- free: [p (3), quaternion (4)], the twist [v_lin; w] in the local frame

struct FreeJoint : JointDefaults<FreeJoint> {
  static constexpr int nq = 7, nv = 6, rot = 3;
  // X S: the columns of X's rotation (linear), and p × them (angular)
  template <typename S> RBD_HD static Motion<S> subspace_col_in(const BodyDesc<S>&, const Transform<S>& X, int k) {
    const int c = k < 3 ? k : k - 3;
    const Vec3<S> e = {X.R(0, c), X.R(1, c), X.R(2, c)};
    if (k < 3) return {e, Vec3<S>::zero()};
    return {cross(X.p, e), e};
  }
  // (X S)ᵀ F = Sᵀ (X⁻¹ F) = F in the joint's own frame: one force transform
  // instead of six dot products
  template <typename S>
  RBD_HD static void project_in(const BodyDesc<S>&, const Transform<S>& X, const Motion<S>*, const Force<S>& F,
                                S* out) {
    store(X.act_inv(F), out);
  }
  // se(3) ([v; ω]): the motion cross product; MuJoCo's R³ × so(3) ([p; θ]):
  // the position additive
  template <typename S> RBD_HD static void bracket(const S* x, const S* y, S* out) {
    const Motion<S> c = cross(Motion<S>{load3(x), load3(x + 3)}, Motion<S>{load3(y), load3(y + 3)});
    store3(c.lin, out), store3(c.ang, out + 3);
  }
  template <typename S> RBD_HD static void mj_bracket(const S* x, const S* y, S* out) {
    store3(Vec3<S>::zero(), out);
    store3(cross(load3(x + 3), load3(y + 3)), out + 3);
  }
  template <typename S> RBD_HD static Transform<S> transform(const BodyDesc<S>& b, const S* q) {
    const S* qj = q + b.q_idx;
    return {quat_to_matrix(qj + 3), {qj[0], qj[1], qj[2]}};
  }
  template <typename S> RBD_HD static Motion<S> subspace_col(const BodyDesc<S>&, int k) {
    Motion<S> m = Motion<S>::zero();
    if (k < 3) m.lin[k] = S(1);
    else m.ang[k - 3] = S(1);
    return m;
  }
  template <typename S> RBD_HD static Motion<S> motion(const BodyDesc<S>&, const S* x) {
    return {{x[0], x[1], x[2]}, {x[3], x[4], x[5]}};
  }
  template <typename S> RBD_HD static void project(const BodyDesc<S>&, const Force<S>& f, S* out) {
    out[0] = f.lin.x; out[1] = f.lin.y; out[2] = f.lin.z;
    out[3] = f.ang.x; out[4] = f.ang.y; out[5] = f.ang.z;
  }
  // M1 = M0 exp6(v)
  template <typename S> RBD_HD static void integrate(const S* qj, const S* vj, S* oj) {
    const Quat<S> r0 = load_quat(qj + 3);
    const Motion<S> x = load_motion(vj);
    const Transform<S> E = exp6(x);
    const Vec3<S> p = Vec3<S>{qj[0], qj[1], qj[2]} + to_matrix(r0) * E.p;
    oj[0] = p.x; oj[1] = p.y; oj[2] = p.z;
    store_quat(normalize_near(r0 * quat_exp(x.ang), r0), oj + 3);
  }
  // log6(M0⁻¹ M1)
  template <typename S> RBD_HD static void difference(const S* a, const S* c, S* o) {
    const Quat<S> r0 = load_quat(a + 3);
    const Vec3<S> dp = Vec3<S>{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    store(log6(conj(r0) * load_quat(c + 3), mul_t(to_matrix(r0), dp)), o);
  }
  template <typename S> RBD_HD static void dintegrate(const S* vj, int arg, S* Jj, int ld) {
    const Motion<S> x = load_motion(vj);
    if (arg == 0) {
      put_mat6(motion_matrix(exp6(x).inverse()), S(1), Jj, ld, 0);  // Ad(exp(v)⁻¹)
    } else {
      S B[36];
      jexp6(x, B);
      put_block6(B, Jj, ld, 0);
    }
  }
  // M = M0⁻¹ M1, d = log6(M): ∂/∂q1 = Jlog6(d), ∂/∂q0 = -Jlog6(d) Ad(M⁻¹)
  template <typename S> RBD_HD static void ddifference(const S* a, const S* c, int arg, S* Jj, int ld) {
    const Quat<S> r0 = load_quat(a + 3);
    const Quat<S> r = conj(r0) * load_quat(c + 3);
    const Vec3<S> p = mul_t(to_matrix(r0), Vec3<S>{c[0] - a[0], c[1] - a[1], c[2] - a[2]});
    S L[36];
    jlog6(log6(r, p), L);
    if (arg == 1) {
      put_block6(L, Jj, ld, 0);
    } else {
      const Transform<S> Minv = Transform<S>{to_matrix(r), p}.inverse();
      const Mat6<S> A = motion_matrix(Minv);
      for (int rr = 0; rr < 6; ++rr)
        for (int cc = 0; cc < 6; ++cc) {
          S acc = S(0);
          for (int k = 0; k < 6; ++k) acc += L[rr * 6 + k] * A(k, cc);
          Jj[rr * ld + cc] = -acc;
        }
    }
  }
  // MuJoCo's free joint: the position additive (world), the quaternion as a ball's
  template <typename S> RBD_HD static void mj_integrate(const S* qj, const S* vj, S* oj) {
    for (int k = 0; k < 3; ++k) oj[k] = qj[k] + vj[k];
    SphericalJoint::mj_integrate(qj + 3, vj + 3, oj + 3);
  }
  template <typename S> RBD_HD static void mj_difference(const S* a, const S* c, S* o) {
    for (int k = 0; k < 3; ++k) o[k] = c[k] - a[k];
    SphericalJoint::mj_difference(a + 3, c + 3, o + 3);
  }
  template <typename S> RBD_HD static void mj_dintegrate(const S* vj, int arg, S* Jj, int ld) {
    for (int k = 0; k < 3; ++k) Jj[k * ld + k] = S(1);  // additive position
    SphericalJoint::mj_dintegrate(vj + 3, arg, Jj + 3 * ld + 3, ld);
  }
  template <typename S> RBD_HD static void mj_ddifference(const S* a, const S* c, int arg, S* Jj, int ld) {
    const S sign = arg == 1 ? S(1) : S(-1);
    for (int k = 0; k < 3; ++k) Jj[k * ld + k] = sign;
    SphericalJoint::mj_ddifference(a + 3, c + 3, arg, Jj + 3 * ld + 3, ld);
  }
  template <typename S> RBD_HD static void neutral(S* qj) {
    for (int k = 0; k < 6; ++k) qj[k] = S(0);
    qj[6] = S(1);
  }
};

// ---- the dispatch

// f(JT{}) for the joint type JT of `type` (JointType); every branch returns the same type
// (a chain of compares, the revolute first, that the branch predictor learns
// per body: no jump table)
template <typename F> RBD_HD decltype(auto) visit_joint(int type, F&& f) {
  if (type == kRevolute) return f(RevoluteJoint{});
  if (type == kPrismatic) return f(PrismaticJoint{});
  if (type == kHelical) return f(HelicalJoint{});
  if (type == kSpherical) return f(SphericalJoint{});
  return f(FreeJoint{});  // kFree
}

// sizes of a joint type
RBD_HD int joint_nq(int type) {
  return visit_joint(type, [](auto J) { return decltype(J)::nq; });
}
RBD_HD int joint_nv(int type) {
  return visit_joint(type, [](auto J) { return decltype(J)::nv; });
}
// the offset of its rotation in qj and vj (-1: none)
RBD_HD int joint_rot(int type) {
  return visit_joint(type, [](auto J) { return decltype(J)::rot; });
}

// first quaternion coordinate of a free or ball joint in q, -1 for other joints and mimics
template <typename S> RBD_HD int quat_offset(const BodyDesc<S>& b) {
  if (b.mimic) return -1;
  const int r = joint_rot(b.type);
  return r < 0 ? -1 : b.q_idx + r;
}

// ---- per body (joint.hpp's kinematics)

// X_J(q): the child frame placed in the joint frame
template <typename S> RBD_HD Transform<S> joint_transform(const BodyDesc<S>& b, const S* q) {
  return visit_joint(b.type, [&](auto J) { return J.transform(b, q); });
}

// X_parent_body = X_tree · X_J(q)
template <typename S> RBD_HD Transform<S> body_transform(const BodyDesc<S>& b, const S* q) {
  return visit_joint(b.type, [&](auto J) { return J.placement(b, q); });
}

// X_λi = body_transform of every body into X (nb). On the host, in double and float, the sines and
// cosines of the revolute joints about a frame axis (RevoluteJoint::placement's turn) come
// RBD_HOST_LANES joints at a time (sincos_lanes: each lane ssincos's result bit for bit, so X is
// body_transform's). Every placement pass starts here
template <typename S> RBD_HD void place_joints(const ModelView<S>& m, Transform<S>* X, const S* q) {
#if defined(RBD_HOST_LANES) && !defined(__CUDA_ARCH__)
  if constexpr (std::is_floating_point<S>::value) {
    typedef double V __attribute__((vector_size(RBD_HOST_VECTOR_BYTES)));
    constexpr int L = RBD_HOST_LANES;
    const auto turns = [](const BodyDesc<S>& b) { return b.type == kRevolute && b.axis_k != 0; };
    for (int i0 = 0; i0 < m.nb; i0 += L) {
      const int n = m.nb - i0 < L ? m.nb - i0 : L;
      V t = {}, s, c;
      for (int l = 0; l < n; ++l)
        if (turns(m.body[i0 + l])) t[l] = static_cast<double>(joint_angle(m.body[i0 + l], q));
      sincos_lanes(t, s, c);
      for (int l = 0; l < n; ++l) {
        const BodyDesc<S>& b = m.body[i0 + l];
        if (turns(b)) X[i0 + l] = {turn_about_frame_axis(b, b.X_tree.R, S(c[l]), S(s[l])), b.X_tree.p};
        else X[i0 + l] = body_transform(b, q);
      }
    }
    return;
  }
#endif
  RBD_UNROLL
  for (int i = 0; i < m.nb; ++i) X[i] = body_transform(m.body[i], q);
}

// X · (column k of S): a subspace column in the frame X maps the body frame
// to (the world for X_0i)
template <typename S> RBD_HD Motion<S> joint_subspace_col_in(const BodyDesc<S>& b, const Transform<S>& X, int k) {
  return visit_joint(b.type, [&](auto J) { return J.subspace_col_in(b, X, k); });
}

// (X S)ᵀ F (out: nv), given the columns sx = X S
template <typename S>
RBD_HD void joint_project_in(const BodyDesc<S>& b, const Transform<S>& X, const Motion<S>* sx, const Force<S>& F,
                             S* out) {
  visit_joint(b.type, [&](auto J) { J.project_in(b, X, sx, F, out); });
}

// the column of a 6x6 that S picks (S = sign·e_c), or -1
template <typename S> RBD_HD int joint_frame_column(const BodyDesc<S>& b, S& sign) {
  return visit_joint(b.type, [&](auto J) { return J.frame_column(b, sign); });
}

// column k of the motion subspace S (mimic multiplier included)
template <typename S> RBD_HD Motion<S> joint_subspace_col(const BodyDesc<S>& b, int k) {
  return visit_joint(b.type, [&](auto J) { return J.subspace_col(b, k); });
}

// S·x for the joint's nv coordinates x
template <typename S> RBD_HD Motion<S> joint_motion(const BodyDesc<S>& b, const S* x) {
  return visit_joint(b.type, [&](auto J) { return J.motion(b, x); });
}

// Sᵀ·f, written to out[0..nv)
template <typename S> RBD_HD void joint_project(const BodyDesc<S>& b, const Force<S>& f, S* out) {
  visit_joint(b.type, [&](auto J) { J.project(b, f, out); });
}

}  // namespace rbd
