// rbdkit/configuration.hpp — Lie-group operations on a whole configuration:
// integrate (q ⊕ v), difference (q1 ⊖ q0) and their tangent Jacobians.
// Free-flyer joints live on SE(3) (Pinocchio's convention: the twist is in the
// local frame), spherical joints on SO(3), every other joint on R.
//
//   integrate(q, v)             q (nq), v (nv)      -> q_next (nq)
//   difference(q0, q1)          q0, q1 (nq)         -> v (nv), integrate(q0, v) = q1
//   dintegrate(q, v, arg)       arg 0: ∂/∂q, 1: ∂/∂v -> J (nv x nv, row-major)
//   ddifference(q0, q1, arg)    arg 0: ∂/∂q0, 1: ∂/∂q1 -> J (nv x nv)
#pragma once

#include "joint.hpp"
#include "lie.hpp"

namespace rbd {

// unit quaternion in the hemisphere of `ref`
template <typename S> RBD_HD Quat<S> normalize_near(Quat<S> a, const Quat<S>& ref) {
  const S d = a.x * ref.x + a.y * ref.y + a.z * ref.z + a.w * ref.w;
  const S s = select(lane_lt(d, 0), S(-1), S(1)) / ssqrt(a.x * a.x + a.y * a.y + a.z * a.z + a.w * a.w);
  return {s * a.x, s * a.y, s * a.z, s * a.w};
}

template <typename S> RBD_HD void integrate(const ModelView<S>& m, const S* q, const S* v, S* out) {
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    const S* qj = q + b.q_idx;
    const S* vj = v + b.v_idx;
    S* oj = out + b.q_idx;
    if (b.type == kFree) {
      // M1 = M0 exp6(v)
      const Quat<S> r0 = load_quat(qj + 3);
      const Motion<S> x = load_motion(vj);
      const Transform<S> E = exp6(x);
      const Vec3<S> p = Vec3<S>{qj[0], qj[1], qj[2]} + to_matrix(r0) * E.p;
      oj[0] = p.x; oj[1] = p.y; oj[2] = p.z;
      store_quat(normalize_near(r0 * quat_exp(x.ang), r0), oj + 3);
    } else if (b.type == kSpherical) {
      const Quat<S> r0 = load_quat(qj);
      store_quat(normalize_near(r0 * quat_exp(Vec3<S>{vj[0], vj[1], vj[2]}), r0), oj);
    } else {
      oj[0] = qj[0] + vj[0];
    }
  }
}

template <typename S> RBD_HD void difference(const ModelView<S>& m, const S* q0, const S* q1, S* out) {
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    const S* a = q0 + b.q_idx;
    const S* c = q1 + b.q_idx;
    S* o = out + b.v_idx;
    if (b.type == kFree) {
      // log6(M0⁻¹ M1)
      const Quat<S> r0 = load_quat(a + 3);
      const Vec3<S> dp = Vec3<S>{c[0] - a[0], c[1] - a[1], c[2] - a[2]};
      store(log6(conj(r0) * load_quat(c + 3), mul_t(to_matrix(r0), dp)), o);
    } else if (b.type == kSpherical) {
      const Vec3<S> w = quat_log(conj(load_quat(a)) * load_quat(c));
      o[0] = w.x; o[1] = w.y; o[2] = w.z;
    } else {
      o[0] = c[0] - a[0];
    }
  }
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

// arg 0: ∂integrate/∂q (tangent), arg 1: ∂integrate/∂v. J (nv x nv) block diagonal
template <typename S> RBD_HD void dintegrate(const ModelView<S>& m, const S* q, const S* v, int arg, S* J) {
  (void)q;  // the Jacobians of a left-invariant retraction do not depend on q
  const int nv = m.nv;
  for (int k = 0; k < nv * nv; ++k) J[k] = S(0);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    const S* vj = v + b.v_idx;
    const int o = b.v_idx;
    if (b.type == kFree) {
      const Motion<S> x = load_motion(vj);
      if (arg == 0) {
        put_mat6(motion_matrix(exp6(x).inverse()), S(1), J, nv, o);  // Ad(exp(v)⁻¹)
      } else {
        S B[36];
        jexp6(x, B);
        put_block6(B, J, nv, o);
      }
    } else if (b.type == kSpherical) {
      const Vec3<S> w = {vj[0], vj[1], vj[2]};
      put_block3(arg == 0 ? transpose(to_matrix(quat_exp(w))) : jexp3(w), J, nv, o, o);
    } else {
      J[o * nv + o] = S(1);
    }
  }
}

// arg 0: ∂difference/∂q0, arg 1: ∂difference/∂q1. J (nv x nv) block diagonal
template <typename S> RBD_HD void ddifference(const ModelView<S>& m, const S* q0, const S* q1, int arg, S* J) {
  const int nv = m.nv;
  for (int k = 0; k < nv * nv; ++k) J[k] = S(0);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    const S* a = q0 + b.q_idx;
    const S* c = q1 + b.q_idx;
    const int o = b.v_idx;
    if (b.type == kFree) {
      // M = M0⁻¹ M1, d = log6(M): ∂/∂q1 = Jlog6(d), ∂/∂q0 = -Jlog6(d) Ad(M⁻¹)
      const Quat<S> r0 = load_quat(a + 3);
      const Quat<S> r = conj(r0) * load_quat(c + 3);
      const Vec3<S> p = mul_t(to_matrix(r0), Vec3<S>{c[0] - a[0], c[1] - a[1], c[2] - a[2]});
      S L[36];
      jlog6(log6(r, p), L);
      if (arg == 1) {
        put_block6(L, J, nv, o);
      } else {
        const Transform<S> Minv = Transform<S>{to_matrix(r), p}.inverse();
        const Mat6<S> A = motion_matrix(Minv);
        for (int rr = 0; rr < 6; ++rr)
          for (int cc = 0; cc < 6; ++cc) {
            S acc = S(0);
            for (int k = 0; k < 6; ++k) acc += L[rr * 6 + k] * A(k, cc);
            J[(o + rr) * nv + o + cc] = -acc;
          }
      }
    } else if (b.type == kSpherical) {
      const Quat<S> r = conj(load_quat(a)) * load_quat(c);
      const Mat3<S> Jl = jlog3(quat_log(r));
      put_block3(arg == 1 ? Jl : S(-1) * (Jl * transpose(to_matrix(r))), J, nv, o, o);
    } else {
      J[o * nv + o] = arg == 1 ? S(1) : S(-1);
    }
  }
}

// the neutral configuration: zero coordinates, identity quaternions
template <typename S> RBD_HD void neutral(const ModelView<S>& m, S* q) {
  for (int k = 0; k < m.nq; ++k) q[k] = S(0);
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (b.mimic) continue;
    if (b.type == kFree) q[b.q_idx + 6] = S(1);
    if (b.type == kSpherical) q[b.q_idx + 3] = S(1);
  }
}

}  // namespace rbd
