// rbdkit/codegen/unrolled.hpp — CRBA unrolled body by body over a generated
// robot's constant bodies (codegen/robot_model.hpp's kBodies), for host code in
// double: a per-robot instance's crba kernel (codegen/instance.hpp) and a
// generated header's crba (codegen/generate.hpp) off the device.
//
// The generic passes loop over the bodies at run time, so a body's placement
// and inertia reach the code as loads from the table. Here each body is a
// template argument: its description is a constant expression, so its joint
// type, parent, subtree and sizes fold, and the placement skips the exact
// zeros of X_tree's rotation (a signed permutation in most URDFs) by
// `if constexpr` rather than multiplying by them. The passes are crba.hpp's
// (crba_body_backward_pass's per-body step, the same helpers in the same
// order): M is crba's to the sign of a zero.
//
// Measured (-O3 -march=native, the iiwa, HyQ, Atlas and the floating HyQ and
// Atlas, against the instance's generic crba in one harness): 0.69, 0.60,
// 0.85, 0.78, 0.89 of its time (docs/performance.md, sixteenth round).
#pragma once

#include <type_traits>
#include <utility>

#include "rbdkit/algorithms/crba.hpp"
#include "rbdkit/codegen/robot_model.hpp"

// host code only (the table is a host constant): always inlined, so the bodies' constants reach one function
// (undefined again at the end of this header)
#define RBD_HOST_INLINE inline __attribute__((always_inline))

namespace rbd {
namespace instance {

// the passes of robot R (the generated struct: nb, nv, has_mimic, constexpr bodies<double>)
template <class R> struct Unrolled {
  static constexpr int nb = R::nb, nv = R::nv;
  template <int I> static constexpr const BodyDesc<double>& body() { return kBodies<R, double>.body[I]; }

  // body I's joint a revolute about a frame axis (RevoluteJoint::placement's turn), owning its angle
  template <int I> static constexpr bool turns() {
    return body<I>().type == kRevolute && body<I>().axis_k != 0 && !body<I>().mimic;
  }

  // row r of X_λi's rotation R_tree · rot(e_K, t) (turn_columns<K>) from c = cos t and sg = ±sin t (the
  // axis's sign), with the products by R_tree's exact zeros left out
  template <int I, int r> RBD_HOST_INLINE static void turn_row(double c, double sg, Mat3<double>& Rx) {
    constexpr const BodyDesc<double>& b = body<I>();
    constexpr int K = b.axis_k - 1, i = (K + 1) % 3, j = (K + 2) % 3;
    constexpr double ri = b.X_tree.R.m[3 * r + i], rj = b.X_tree.R.m[3 * r + j];
    Rx.m[3 * r + K] = b.X_tree.R.m[3 * r + K];
    if constexpr (ri == 0 && rj == 0) {
      Rx.m[3 * r + i] = 0, Rx.m[3 * r + j] = 0;
    } else if constexpr (ri == 0) {
      Rx.m[3 * r + i] = sg * rj, Rx.m[3 * r + j] = c * rj;
    } else if constexpr (rj == 0) {
      Rx.m[3 * r + i] = c * ri, Rx.m[3 * r + j] = -(sg * ri);
    } else {
      Rx.m[3 * r + i] = c * ri + sg * rj, Rx.m[3 * r + j] = c * rj - sg * ri;
    }
  }

  // X_λi of body I from its joint's sine and cosine (sn, cs: turns<I>) or body_transform
  template <int I> RBD_HOST_INLINE static void place(const double* q, const double* sn, const double* cs, Transform<double>* X) {
    constexpr const BodyDesc<double>& b = body<I>();
    if constexpr (turns<I>()) {
      constexpr double axis = b.axis_k == 1 ? b.axis.x : (b.axis_k == 2 ? b.axis.y : b.axis.z);
      const double sg = axis > 0 ? sn[I] : -sn[I];
      turn_row<I, 0>(cs[I], sg, X[I].R), turn_row<I, 1>(cs[I], sg, X[I].R), turn_row<I, 2>(cs[I], sg, X[I].R);
      X[I].p = b.X_tree.p;
    } else {
      X[I] = body_transform(b, q);
    }
  }

  // the angle whose sine and cosine body I's placement takes (0: none)
  template <int I> RBD_HOST_INLINE static double angle(const double* q) {
    if constexpr (turns<I>()) return q[body<I>().q_idx];
    return 0.0;
  }

  // X_λi of every body (place_joints' values): the sines and cosines RBD_HOST_LANES at a time
  // (sincos_lanes, each lane ssincos's bit for bit), then each body's placement
  template <int... I> RBD_HOST_INLINE static void place_all(std::integer_sequence<int, I...>, const double* q, Transform<double>* X) {
#if defined(RBD_HOST_LANES)
    typedef double V __attribute__((vector_size(RBD_HOST_VECTOR_BYTES)));
    constexpr int L = RBD_HOST_LANES, packs = (nb + L - 1) / L;
    const double t[L * packs] = {angle<I>(q)...};
    double sn[L * packs], cs[L * packs];
    for (int k = 0; k < packs; ++k) {
      V tv, sv, cv;
      __builtin_memcpy(&tv, t + L * k, sizeof tv);
      sincos_lanes(tv, sv, cv);
      __builtin_memcpy(sn + L * k, &sv, sizeof sv);
      __builtin_memcpy(cs + L * k, &cv, sizeof cv);
    }
#else
    double sn[nb], cs[nb];
    ((turns<I>() ? ssincos(angle<I>(q), sn[I], cs[I]) : void(sn[I] = cs[I] = 0)), ...);
#endif
    (place<I>(q, sn, cs, X), ...);
  }

  // body I's step of crba_body_backward_pass: its columns F = Ic_I s, its rows of M, then its composite
  // and the subtree's columns moved to the parent's frame
  template <int E, int I>
  RBD_HOST_INLINE static void crba_step(const ModelView<double>& m, const Transform<double>* X, Inertia<double>* Ic,
                                      double* F, double* M) {
    constexpr const BodyDesc<double>& b = body<I>();
    constexpr int vi = b.v_idx, c_end = vi + b.nv_subtree;
    double sign;
    const int fc = joint_frame_column(b, sign);
    if (fc >= 0) store(sign * Ic[I].column(fc), F + 6 * vi);
    else if (b.type == kFree) for (int k = 0; k < 6; ++k) store(Ic[I].column(k), F + 6 * (vi + k));
    else for (int k = 0; k < b.nv; ++k) store(Ic[I] * joint_subspace_col(b, k), F + 6 * (vi + k));
    crba_store_rows<E>(m, I, fc, sign, F, M);
    if constexpr (b.parent >= 0) {
      Ic[b.parent] += transform_inertia(X[I], Ic[I]);
      crba_act_columns(X[I], F + 6 * vi, c_end - vi);
    }
  }
  template <int E, int... I>
  RBD_HOST_INLINE static void crba_steps(std::integer_sequence<int, I...>, const ModelView<double>& m,
                                       const Transform<double>* X, Inertia<double>* Ic, double* F, double* M) {
    (crba_step<E, nb - 1 - I>(m, X, Ic, F, M), ...);  // leaves first
  }

  // M(q) (nv x nv row-major; E: crba's MassEntries). The placements, composites and columns on the stack
  template <int E> __attribute__((flatten)) static void crba_body(const double* q, double* M) {
    static_assert(!R::has_mimic, "Unrolled::crba: a model without mimic joints, bodies depth-first");
    const ModelView<double> m = RobotModel<R>::view(ModelView<double>{});
    Transform<double> X[nb];
    Inertia<double> Ic[nb];
    double F[6 * nv];
    place_all(std::make_integer_sequence<int, nb>{}, q, X);
    for (int i = 0; i < nb; ++i) Ic[i] = m.body[i].I;
    if (E != kMassLowerPattern)
      for (int k = 0; k < nv * nv; ++k) M[k] = 0.0;
    crba_steps<E>(std::make_integer_sequence<int, nb>{}, m, X, Ic, F, M);
  }
};

// M(q) of robot R, nv x nv row-major, both triangles (crba's, body by body)
template <class R> inline void unrolled_crba(const double* q, double* M) { Unrolled<R>::template crba_body<kMassFull>(q, M); }

}  // namespace instance
}  // namespace rbd

#undef RBD_HOST_INLINE
