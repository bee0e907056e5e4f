// rbdkit/codegen/unrolled.hpp — CRBA unrolled body by body over a generated
// robot's constant bodies (codegen/robot_model.hpp's kBodies), for host code in
// double: a per-robot instance's crba and minv kernels (codegen/instance.hpp)
// and a generated header's crba and minv (codegen/generate.hpp) off the device.
//
// The generic passes loop over the bodies at run time, so a body's placement
// and inertia reach the code as loads from the table. Here each body is a
// template argument: its description is a constant expression, so its joint
// type, parent, subtree and sizes fold, and the placement skips the exact
// zeros of X_tree's rotation (a signed permutation in most URDFs) by
// `if constexpr` rather than multiplying by them. The pass is crba.hpp's
// crba_body_backward_pass (its per-body helpers: the joint's columns, the rows
// of M, the inertia transform), with the columns F laid out as six rows over
// the DoFs, so that a subtree's columns move to the parent's frame a vector of
// columns at a time, without the products by the placement's exact zeros (of
// R and of X_tree's offset). M is crba's to rounding. M⁻¹ is minv's, with this
// CRBA in its factorised form.
//
// Measured (-O3 -march=native, one harness, against the generic crba on the same
// constant table): 0.58 (iiwa), 0.45 (HyQ), 0.63 (Atlas), 0.71 (floating HyQ),
// 0.66 (floating Atlas) of its time (docs/performance.md, seventeenth round).
#pragma once

#include <type_traits>
#include <utility>

#include "rbdkit/algorithms/crba.hpp"
#include "rbdkit/algorithms/minv.hpp"
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

  // ---- the columns F = Ic s of crba_body_backward_pass, here as six rows over the DoFs: component k
  // of column c at F[k * kF + c], so that a subtree's columns move to the parent's frame a vector of
  // kLanes columns at a time (the generic pass moves one column per 3-vector). A subtree's last
  // vector may read up to kLanes - 1 entries past nv, which the padding holds; it writes only its own
#if defined(RBD_HOST_LANES)
  static constexpr int kLanes = RBD_HOST_LANES;
  typedef double Lanes __attribute__((vector_size(RBD_HOST_VECTOR_BYTES)));
#else
  static constexpr int kLanes = 1;
  typedef double Lanes;
#endif
  static constexpr int kF = (nv + 2 * kLanes - 2) / kLanes * kLanes;

  // whether entry (r, k) of body I's X_λi(q).R is an exact zero for every q (turn_row's zeros)
  template <int I> static constexpr bool rotation_zero(int r, int k) {
    if (!turns<I>()) return false;
    const BodyDesc<double>& b = body<I>();
    const int K = b.axis_k - 1, i = (K + 1) % 3, j = (K + 2) % 3;
    if (k == K) return b.X_tree.R.m[3 * r + K] == 0;
    return b.X_tree.R.m[3 * r + i] == 0 && b.X_tree.R.m[3 * r + j] == 0;
  }
  // whether component k of body I's X_λi(q).p is an exact zero for every q (place: X_tree's)
  template <int I> static constexpr bool offset_zero(int k) {
    return turns<I>() && (k == 0 ? body<I>().X_tree.p.x : (k == 1 ? body<I>().X_tree.p.y : body<I>().X_tree.p.z)) == 0;
  }

  // y_r = Σ_k R_rk x_k over row r's entries that can be nonzero, in k's order (Transform::act's sums
  // without the exact zeros' terms); T: double, or Lanes (a column per lane)
  template <int I, int r, class T>
  RBD_HOST_INLINE static T rotate_row(const Transform<double>& X, const T& x0, const T& x1, const T& x2) {
    constexpr bool z0 = rotation_zero<I>(r, 0), z1 = rotation_zero<I>(r, 1), z2 = rotation_zero<I>(r, 2);
    const double* Rr = X.R.m + 3 * r;
    T y = x0 * 0.0;  // (a rotation's row has a nonzero entry: overwritten below)
    if constexpr (!z0) y = Rr[0] * x0;
    if constexpr (!z1) y = z0 ? Rr[1] * x1 : y + Rr[1] * x1;
    if constexpr (!z2) y = z0 && z1 ? Rr[2] * x2 : y + Rr[2] * x2;
    return y;
  }
  // a_r + (p_s l_t - p_t l_s) for (r, s, t) a cyclic order: a_r + (p × l)_r, p's exact zeros left out
  template <int I, int r, class T>
  RBD_HOST_INLINE static T add_offset_cross(const Transform<double>& X, const T& a, const T& ls, const T& lt) {
    constexpr int s = (r + 1) % 3, t = (r + 2) % 3;
    constexpr bool zs = offset_zero<I>(s), zt = offset_zero<I>(t);
    const double ps = s == 0 ? X.p.x : (s == 1 ? X.p.y : X.p.z), pt = t == 0 ? X.p.x : (t == 1 ? X.p.y : X.p.z);
    if constexpr (zs && zt) return a;
    else if constexpr (zs) return a - pt * ls;
    else if constexpr (zt) return a + ps * lt;
    else return a + (ps * lt - pt * ls);
  }
  // F's columns [c, c + lanes of T) <- X* F: f_lin' = R f_lin, f_ang' = R f_ang + p × f_lin'
  template <int I, class T> RBD_HOST_INLINE static void act_lanes(const Transform<double>& X, double* F, int c) {
    T f[6];
    for (int k = 0; k < 6; ++k) __builtin_memcpy(&f[k], F + k * kF + c, sizeof(T));
    const T l[3] = {rotate_row<I, 0>(X, f[0], f[1], f[2]), rotate_row<I, 1>(X, f[0], f[1], f[2]),
                    rotate_row<I, 2>(X, f[0], f[1], f[2])};
    const T a[3] = {add_offset_cross<I, 0>(X, rotate_row<I, 0>(X, f[3], f[4], f[5]), l[1], l[2]),
                    add_offset_cross<I, 1>(X, rotate_row<I, 1>(X, f[3], f[4], f[5]), l[2], l[0]),
                    add_offset_cross<I, 2>(X, rotate_row<I, 2>(X, f[3], f[4], f[5]), l[0], l[1])};
    for (int k = 0; k < 3; ++k) __builtin_memcpy(F + k * kF + c, &l[k], sizeof(T));
    for (int k = 0; k < 3; ++k) __builtin_memcpy(F + (3 + k) * kF + c, &a[k], sizeof(T));
  }
  // body I's subtree's columns moved to its parent's frame: kLanes at a time from v_I, the rest one by one
  template <int I, int c = body<I>().v_idx> RBD_HOST_INLINE static void act_subtree(const Transform<double>& X, double* F) {
    constexpr int end = body<I>().v_idx + body<I>().nv_subtree;
    if constexpr (c + kLanes <= end) {
      act_lanes<I, Lanes>(X, F, c);
      act_subtree<I, c + kLanes>(X, F);
    } else if constexpr (c < end) {
      act_lanes<I, double>(X, F, c);
      act_subtree<I, c + 1>(X, F);
    }
  }

  // body I's step of crba_body_backward_pass: its columns F = Ic_I s, its rows of M, then its composite
  // and the subtree's columns moved to the parent's frame
  template <int E, int I>
  RBD_HOST_INLINE static void crba_step(const ModelView<double>& m, const Transform<double>* X, Inertia<double>* Ic,
                                      double* F, double* M) {
    constexpr const BodyDesc<double>& b = body<I>();
    double sign;
    const int fc = joint_frame_column(b, sign);
    crba_joint_columns(b, fc, sign, Ic[I], [F](int c, const Force<double>& f) {
      F[c] = f.lin.x, F[kF + c] = f.lin.y, F[2 * kF + c] = f.lin.z;
      F[3 * kF + c] = f.ang.x, F[4 * kF + c] = f.ang.y, F[5 * kF + c] = f.ang.z;
    });
    crba_store_rows_of<E>(m, I, fc, sign, [F](int c, int k) { return F[k * kF + c]; }, M);
    if constexpr (b.parent >= 0) {
      Ic[b.parent] += transform_inertia(X[I], Ic[I]);
      act_subtree<I>(X[I], F);
    }
  }
  template <int E, int... I>
  RBD_HOST_INLINE static void crba_steps(std::integer_sequence<int, I...>, const ModelView<double>& m,
                                       const Transform<double>* X, Inertia<double>* Ic, double* F, double* M) {
    (crba_step<E, nb - 1 - I>(m, X, Ic, F, M), ...);  // leaves first
  }

  // M(q) (nv x nv row-major; E: crba's MassEntries), and the composites into Ic (nb; the workspace's,
  // which mass_factor reads, or the stack's). The placements and columns on the stack
  template <int E> RBD_HOST_INLINE static void crba_pass(const double* q, double* M, Inertia<double>* Ic) {
    static_assert(!R::has_mimic, "Unrolled::crba: a model without mimic joints, bodies depth-first");
    const ModelView<double> m = RobotModel<R>::view(ModelView<double>{});
    Transform<double> X[nb];
    double F[6 * kF];
    for (int k = 0; k < 6; ++k)  // the padding, which the last vectors read (finite lanes, no slow operands)
      for (int c = nv; c < kF; ++c) F[k * kF + c] = 0.0;
    place_all(std::make_integer_sequence<int, nb>{}, q, X);
    for (int i = 0; i < nb; ++i) Ic[i] = m.body[i].I;
    if (E != kMassLowerPattern)
      for (int k = 0; k < nv * nv; ++k) M[k] = 0.0;
    crba_steps<E>(std::make_integer_sequence<int, nb>{}, m, X, Ic, F, M);
  }
  template <int E> __attribute__((flatten)) static void crba_body(const double* q, double* M) {
    Inertia<double> Ic[nb];
    crba_pass<E>(q, M, Ic);
  }

  // ---- the DoF tree (crba.hpp's dof_tree) as constants, walked as DofWalk walks its arrays with each DoF
  // an integral constant: the factorisation's and M⁻¹'s loops over runs then have constant bounds
  struct Tree {
    int lambda[nv > 0 ? nv : 1], run[nv > 0 ? nv : 1];  // (a robot with no DoF: one unused entry)
  };
  static constexpr Tree tree() {
    Tree t{};
    dof_tree(ModelView<double>{nb, R::nq, nv, R::has_mimic, kBodies<R, double>.body}, t.lambda, t.run);
    return t;
  }
  static constexpr Tree kTree = tree();
  template <int k> using Dof = std::integral_constant<int, k>;
  struct ConstantWalk {
    template <int k> static constexpr Dof<kTree.lambda[k]> parent(Dof<k>) { return {}; }
    template <int e, class F> RBD_HOST_INLINE static void runs(Dof<e>, F&& f) {
      if constexpr (e >= 0) {
        f(kTree.run[e], e);
        runs(Dof<kTree.lambda[kTree.run[e]]>{}, f);
      }
    }
    template <int i, int i0, class F> RBD_HOST_INLINE static void down(F&& f) {
      if constexpr (i >= i0) {
        f(Dof<i>{});
        down<i - 1, i0>(f);
      }
    }
    template <int e, class F> RBD_HOST_INLINE static void dofs(Dof<e>, F&& f) {
      if constexpr (e >= 0) {
        down<e, kTree.run[e]>(f);
        dofs(Dof<kTree.lambda[kTree.run[e]]>{}, f);
      }
    }
    template <int i, int i1, class F> RBD_HOST_INLINE static void up(F&& f) {
      if constexpr (i <= i1) {
        f(Dof<i>{});
        up<i + 1, i1>(f);
      }
    }
    template <int e, class F> RBD_HOST_INLINE static void dofs_from_root(Dof<e>, F&& f) {
      if constexpr (e >= 0) {
        dofs_from_root(Dof<kTree.lambda[kTree.run[e]]>{}, f);
        up<kTree.run[e], e>(f);
      }
    }
    template <class F, int... k> RBD_HOST_INLINE static bool down_all(F&& f, std::integer_sequence<int, k...>) {
      return (f(Dof<nv - 1 - k>{}) && ...);
    }
    template <class F> RBD_HOST_INLINE static bool each_down(F&& f) { return down_all(f, std::make_integer_sequence<int, nv>{}); }
    template <class F, int... k> RBD_HOST_INLINE static void up_all(F&& f, std::integer_sequence<int, k...>) {
      (f(Dof<k>{}), ...);
    }
    template <class F> RBD_HOST_INLINE static void each_up(F&& f) { up_all(f, std::make_integer_sequence<int, nv>{}); }
  };

  // M⁻¹(q) (minv's: nv x nv row-major, dense or the upper triangle) by minv_factored, its crba body by
  // body and its factorisation over the constant DoF tree, on every robot (crba_pass: no mimic joints);
  // where the factorisation's pivot check refuses, by the passes, whose verdict stands. w: the full
  // workspace. false if M is not PD
  __attribute__((flatten)) static bool minv(Workspace<double>& w, const double* q, bool dense, double* Minv) {
    if (factor_inverse(w, q, dense, Minv)) return true;
    return minv_fallback(w, q, dense, Minv);
  }
  // M⁻¹ by the factorisation alone: false where its pivot check refuses
  RBD_HOST_INLINE static bool factor_inverse(Workspace<double>& w, const double* q, bool dense, double* Minv) {
    const ModelView<double> m = RobotModel<R>::view(ModelView<double>{});
    crba_pass<kMassLowerPattern>(q, w.dense2, w.Ic);
    return minv_of_factor_with(m, w, ConstantWalk{}, dense, Minv);
  }
  // forward_dynamics's and aba_derivatives's M⁻¹ (minv.hpp's FactoredMinv) as minv's above, on every
  // robot: false where the pivot check refuses, and they run the passes. Out of line: inlined into
  // aba_derivatives's flattened body (or the generic FactoredMinv there), ∇FD took 15-18 % (floating
  // HyQ) and 6-7 % (floating Atlas) longer (docs/performance.md, twentieth round)
  struct Factored {
    bool operator()(const ModelView<double>&, Workspace<double>& w, const double* q, double* Minv) const {
      return factor_dense(w, q, Minv);
    }
  };
  __attribute__((noinline, flatten)) static bool factor_dense(Workspace<double>& w, const double* q, double* Minv) {
    return factor_inverse(w, q, true, Minv);
  }
  // the passes, out of minv's body: flattened into it they made fixed Atlas's M⁻¹ a quarter slower
  __attribute__((noinline, cold)) static bool minv_fallback(Workspace<double>& w, const double* q, bool dense,
                                                            double* Minv) {
    return minv_passes(RobotModel<R>::view(ModelView<double>{}), w, q, dense, Minv);
  }
};

// M(q) of robot R, nv x nv row-major, both triangles (crba's, body by body)
template <class R> inline void unrolled_crba(const double* q, double* M) { Unrolled<R>::template crba_body<kMassFull>(q, M); }
// M⁻¹(q) of robot R as minv's (dense: both triangles, else the upper one), its crba body by body; w: the
// full workspace. false if M is not PD
template <class R> inline bool unrolled_minv(Workspace<double>& w, const double* q, bool dense, double* Minv) {
  return Unrolled<R>::minv(w, q, dense, Minv);
}

}  // namespace instance
}  // namespace rbd

#undef RBD_HOST_INLINE
