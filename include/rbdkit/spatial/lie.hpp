// rbdkit/spatial/lie.hpp — SO(3) and SE(3) exponential, logarithm and their
// Jacobians; the primitives of the configuration-space operations.
//
// Quaternions are stored (x, y, z, w). Twists are [v_lin; w]. The Jacobians
// are right (body-frame) Jacobians: exp(x + δ) = exp(x)·exp(Jr(x) δ + O(δ²)).
#pragma once

#include "rbdkit/spatial/spatial.hpp"

namespace rbd {

template <typename S> struct Quat {
  S x, y, z, w;
};

template <typename S> RBD_HD Quat<S> load_quat(const S* q) { return {q[0], q[1], q[2], q[3]}; }
template <typename S> RBD_HD void store_quat(const Quat<S>& a, S* q) { q[0] = a.x; q[1] = a.y; q[2] = a.z; q[3] = a.w; }

template <typename S> RBD_HD Quat<S> operator*(const Quat<S>& a, const Quat<S>& b) {
  return {a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y, a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
          a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w, a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z};
}
template <typename S> RBD_HD Quat<S> conj(const Quat<S>& a) { return {-a.x, -a.y, -a.z, a.w}; }
template <typename S> RBD_HD Mat3<S> to_matrix(const Quat<S>& a) {
  const S q[4] = {a.x, a.y, a.z, a.w};
  return quat_to_matrix(q);
}

// ---- scalar coefficient functions of t2 = θ². Below θ = 1 their closed
// forms lose digits to cancellation, so a Taylor series in t2 (exact
// rational coefficients, truncated past 1e-17 at θ = 1) replaces them; the
// series is also what makes dual-number derivatives exact at θ = 0.

// Σ c_k t2^k by Horner
template <typename S, int N> RBD_HD S series(const S& t2, const double (&c)[N]) {
  S acc = S(c[N - 1]);
  for (int k = N - 2; k >= 0; --k) acc = S(c[k]) + t2 * acc;
  return acc;
}

// (1 - cos θ)/θ²
template <typename S> RBD_HD S coef_a(const S& t2) {
  const auto small = lane_lt(t2, 1);
  const double c[] = {0.5, -0.041666666666666664, 0.001388888888888889, -2.48015873015873e-05, 2.755731922398589e-07, -2.08767569878681e-09, 1.1470745597729725e-11, -4.779477332387385e-14, 1.5619206968586225e-16, -4.110317623312165e-19, 8.896791392450574e-22};
  S r = S(0);
  if (any_lane(small)) r = series(t2, c);
  if (!all_lanes(small)) {
    const S t = ssqrt(t2);
    r = select(small, r, (S(1) - scos(t)) / t2);
  }
  return r;
}

// (θ - sin θ)/θ³
template <typename S> RBD_HD S coef_b(const S& t2) {
  const auto small = lane_lt(t2, 1);
  const double c[] = {0.16666666666666666, -0.008333333333333333, 0.0001984126984126984, -2.7557319223985893e-06, 2.505210838544172e-08, -1.6059043836821613e-10, 7.647163731819816e-13, -2.8114572543455206e-15, 8.22063524662433e-18, -1.9572941063391263e-20, 3.868170170630684e-23};
  S r = S(0);
  if (any_lane(small)) r = series(t2, c);
  if (!all_lanes(small)) {
    const S t = ssqrt(t2);
    r = select(small, r, (t - ssin(t)) / (t2 * t));
  }
  return r;
}

// (1 - (θ/2) cot(θ/2)) / θ²
template <typename S> RBD_HD S coef_c(const S& t2) {
  const auto small = lane_lt(t2, 1);
  const double c[] = {0.08333333333333333, 0.001388888888888889, 3.306878306878307e-05, 8.267195767195768e-07, 2.08767569878681e-08, 5.284190138687493e-10, 1.3382536530684679e-11, 3.3896802963225827e-13, 8.586062056277845e-15, 2.174868698558062e-16, 5.5090028283602295e-18, 1.3954464685812522e-19};
  S r = S(0);
  if (any_lane(small)) r = series(t2, c);
  if (!all_lanes(small)) {
    const S t = ssqrt(t2);
    S st, ct;
    ssincos(t, st, ct);
    r = select(small, r, (S(1) - S(0.5) * t * st / (S(1) - ct)) / t2);
  }
  return r;
}

// (θ² + 2 cos θ - 2) / (2 θ⁴)
template <typename S> RBD_HD S coef_d(const S& t2) {
  const auto small = lane_lt(t2, 1);
  const double c[] = {0.041666666666666664, -0.001388888888888889, 2.48015873015873e-05, -2.755731922398589e-07, 2.08767569878681e-09, -1.1470745597729725e-11, 4.779477332387385e-14, -1.5619206968586225e-16, 4.110317623312165e-19, -8.896791392450574e-22, 1.6117375710961184e-24};
  S r = S(0);
  if (any_lane(small)) r = series(t2, c);
  if (!all_lanes(small)) {
    const S t = ssqrt(t2);
    r = select(small, r, (t2 + S(2) * scos(t) - S(2)) / (S(2) * t2 * t2));
  }
  return r;
}

// (2θ - 3 sin θ + θ cos θ) / (2 θ⁵)
template <typename S> RBD_HD S coef_e(const S& t2) {
  const auto small = lane_lt(t2, 1);
  const double c[] = {0.008333333333333333, -0.0003968253968253968, 8.267195767195768e-06, -1.0020843354176688e-07, 8.029521918410807e-10, -4.58829823909189e-12, 1.9680200780418645e-14, -6.576508197299464e-17, 1.7615646957052136e-19, -3.868170170630684e-22, 7.091645312822921e-25};
  S r = S(0);
  if (any_lane(small)) r = series(t2, c);
  if (!all_lanes(small)) {
    const S t = ssqrt(t2);
    S st, ct;
    ssincos(t, st, ct);
    r = select(small, r, (S(2) * t - S(3) * st + t * ct) / (S(2) * t2 * t2 * t));
  }
  return r;
}

// ---- SO(3)

// exp(w) as a unit quaternion
template <typename S> RBD_HD Quat<S> quat_exp(const Vec3<S>& w) {
  const S t2 = dot(w, w);
  S c = S(0), sinc = S(0);  // cos(θ/2), sin(θ/2)/θ
  const auto small = lane_lt(t2, Eps<S>::small * Eps<S>::small);
  if (any_lane(small)) {
    c = S(1) - t2 / S(8) + t2 * t2 / S(384);
    sinc = S(0.5) - t2 / S(48) + t2 * t2 / S(3840);
  }
  if (!all_lanes(small)) {
    const S t = ssqrt(t2);
    S sh, ch;  // sin(θ/2), cos(θ/2)
    ssincos(S(0.5) * t, sh, ch);
    c = select(small, c, ch);
    sinc = select(small, sinc, sh / t);
  }
  return {sinc * w.x, sinc * w.y, sinc * w.z, c};
}

// log of a unit quaternion, the rotation vector with |w| <= π
template <typename S> RBD_HD Vec3<S> quat_log(Quat<S> a) {
  const auto neg = lane_lt(a.w, 0);
  if (any_lane(neg)) a = {select(neg, -a.x, a.x), select(neg, -a.y, a.y), select(neg, -a.z, a.z), select(neg, -a.w, a.w)};
  const S n2 = a.x * a.x + a.y * a.y + a.z * a.z;
  S k = S(0);  // θ / sin(θ/2), θ = 2 atan2(|v|, w)
  const auto small = lane_lt(n2, Eps<S>::small * Eps<S>::small);
  if (any_lane(small)) {
    // 2 atan(n/w)/n ≈ (2/w)(1 - n²/(3w²) + n⁴/(5w⁴))
    const S r = n2 / (a.w * a.w);
    k = S(2) / a.w * (S(1) - r / S(3) + r * r / S(5));
  }
  if (!all_lanes(small)) {
    const S n = ssqrt(n2);
    k = select(small, k, S(2) * satan2(n, a.w) / n);
  }
  return {k * a.x, k * a.y, k * a.z};
}

// Jr(w) = I - a [w] + b [w]²  (right Jacobian of exp)
template <typename S> RBD_HD Mat3<S> jexp3(const Vec3<S>& w) {
  const S t2 = dot(w, w);
  const Mat3<S> W = skew(w);
  return Mat3<S>::identity() - coef_a(t2) * W + coef_b(t2) * (W * W);
}
// Jr(w)⁻¹ = I + ½ [w] + c [w]²
template <typename S> RBD_HD Mat3<S> jlog3(const Vec3<S>& w) {
  const S t2 = dot(w, w);
  const Mat3<S> W = skew(w);
  return Mat3<S>::identity() + S(0.5) * W + coef_c(t2) * (W * W);
}

// ---- SE(3): twist [nu; w]

// exp of a twist: rotation exp(w), translation V(w) nu with V = Jr(-w)
template <typename S> RBD_HD Transform<S> exp6(const Motion<S>& x) {
  const S t2 = dot(x.ang, x.ang);
  const Mat3<S> W = skew(x.ang);
  const Mat3<S> V = Mat3<S>::identity() + coef_a(t2) * W + coef_b(t2) * (W * W);
  return {to_matrix(quat_exp(x.ang)), V * x.lin};
}

// log of a placement given as (quaternion, translation)
template <typename S> RBD_HD Motion<S> log6(const Quat<S>& r, const Vec3<S>& p) {
  const Vec3<S> w = quat_log(r);
  const S t2 = dot(w, w);
  const Mat3<S> W = skew(w);
  const Mat3<S> Vinv = Mat3<S>::identity() - S(0.5) * W + coef_c(t2) * (W * W);
  return {Vinv * p, w};
}

// Q block of the SE(3) right Jacobian (Barfoot's Q evaluated at -x)
template <typename S> RBD_HD Mat3<S> se3_q_block(const Motion<S>& x) {
  const S t2 = dot(x.ang, x.ang);
  const Mat3<S> W = skew(x.ang), P = skew(x.lin);
  const Mat3<S> WP = W * P, PW = P * W, WPW = WP * W, WW = W * W;
  const S b = coef_b(t2), d = coef_d(t2), e = coef_e(t2);
  Mat3<S> Q = S(-0.5) * P + b * (WP + PW - WPW);
  Q = Q - d * (WW * P + PW * W - S(3) * WPW);
  Q = Q + e * (WPW * W + WW * P * W);
  return Q;
}

// 6x6 right Jacobian of exp6 (row-major, [lin; ang] blocks): [[Jr, Q], [0, Jr]]
template <typename S> RBD_HD void jexp6(const Motion<S>& x, S* J) {
  const Mat3<S> Jr = jexp3(x.ang), Q = se3_q_block(x);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      J[r * 6 + c] = Jr(r, c);
      J[r * 6 + c + 3] = Q(r, c);
      J[(r + 3) * 6 + c] = S(0);
      J[(r + 3) * 6 + c + 3] = Jr(r, c);
    }
}
// its inverse, [[Jr⁻¹, -Jr⁻¹ Q Jr⁻¹], [0, Jr⁻¹]]
template <typename S> RBD_HD void jlog6(const Motion<S>& x, S* J) {
  const Mat3<S> Ji = jlog3(x.ang), Q = se3_q_block(x);
  const Mat3<S> B = S(-1) * (Ji * Q * Ji);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      J[r * 6 + c] = Ji(r, c);
      J[r * 6 + c + 3] = B(r, c);
      J[(r + 3) * 6 + c] = S(0);
      J[(r + 3) * 6 + c + 3] = Ji(r, c);
    }
}

}  // namespace rbd
