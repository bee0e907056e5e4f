// rbdkit/spatial/dual.hpp — forward-mode dual numbers a + b·ε (ε² = 0). Running a
// Scalar-templated routine on Dual<S> gives its exact directional derivative;
// d2integrate uses it to differentiate the closed-form Jacobians of
// integrate. Not a finite difference: the result is exact to rounding.
#pragma once

#include <type_traits>

#include "rbdkit/spatial/config.hpp"

namespace rbd {

template <typename S> struct Dual {
  S v, d;  // value, derivative
  RBD_HD Dual() : v(0), d(0) {}
  RBD_HD Dual(S value) : v(value), d(0) {}
  RBD_HD Dual(S value, S deriv) : v(value), d(deriv) {}
  // from a plain number (int, or the base scalar of a nested dual) without rounding through int
  template <typename T, typename = typename std::enable_if<std::is_arithmetic<T>::value>::type>
  RBD_HD explicit Dual(T value) : v(S(value)), d(0) {}
  RBD_HD Dual& operator+=(const Dual& o) { v += o.v; d += o.d; return *this; }
  RBD_HD Dual& operator-=(const Dual& o) { v -= o.v; d -= o.d; return *this; }
  RBD_HD Dual& operator*=(const Dual& o) { d = d * o.v + v * o.d; v *= o.v; return *this; }
};

template <typename S> RBD_HD Dual<S> operator+(const Dual<S>& a, const Dual<S>& b) { return {a.v + b.v, a.d + b.d}; }
template <typename S> RBD_HD Dual<S> operator-(const Dual<S>& a, const Dual<S>& b) { return {a.v - b.v, a.d - b.d}; }
template <typename S> RBD_HD Dual<S> operator-(const Dual<S>& a) { return {-a.v, -a.d}; }
template <typename S> RBD_HD Dual<S> operator*(const Dual<S>& a, const Dual<S>& b) { return {a.v * b.v, a.d * b.v + a.v * b.d}; }
template <typename S> RBD_HD Dual<S> operator/(const Dual<S>& a, const Dual<S>& b) {
  return {a.v / b.v, (a.d * b.v - a.v * b.d) / (b.v * b.v)};
}

// the real part, through nested duals (Dual<Dual<S>> -> S)
template <typename S> struct DualBase { using type = S; };
template <typename S> struct DualBase<Dual<S>> { using type = typename DualBase<S>::type; };
template <typename S> RBD_HD typename DualBase<S>::type value_of(const Dual<S>& a) { return value_of(a.v); }
template <typename S> RBD_HD Dual<S> ssin(const Dual<S>& a) { return {ssin(a.v), a.d * scos(a.v)}; }
template <typename S> RBD_HD Dual<S> scos(const Dual<S>& a) { return {scos(a.v), -a.d * ssin(a.v)}; }
template <typename S> RBD_HD void ssincos(const Dual<S>& a, Dual<S>& s, Dual<S>& c) {
  const S d = a.d;  // (a may be s or c)
  S sv, cv;
  ssincos(a.v, sv, cv);
  s = {sv, d * cv};
  c = {cv, -d * sv};
}
template <typename S> RBD_HD Dual<S> ssqrt(const Dual<S>& a) {
  const S r = ssqrt(a.v);
  return {r, a.d / (S(2) * r)};
}
template <typename S> RBD_HD Dual<S> satan2(const Dual<S>& y, const Dual<S>& x) {
  return {satan2(y.v, x.v), (x.v * y.d - y.v * x.d) / (x.v * x.v + y.v * y.v)};
}
// branches on the real part (config.hpp): a bool for a scalar base, a lane
// mask for a SIMD pack (simd.hpp), whose duals select lane by lane
template <typename S, typename B> RBD_HD auto lane_lt(const Dual<S>& a, B b) { return lane_lt(a.v, b); }
template <typename S, typename B> RBD_HD auto lane_gt(const Dual<S>& a, B b) { return lane_gt(a.v, b); }
template <typename T, int W> struct PackMask;
template <typename T, int W, typename S>
RBD_HD Dual<S> select(const PackMask<T, W>& c, const Dual<S>& a, const Dual<S>& b) {
  return {select(c, a.v, b.v), select(c, a.d, b.d)};
}
template <typename S> RBD_HD Dual<S> sabs(const Dual<S>& a) { return select(lane_lt(a, 0), -a, a); }

template <typename S> struct Eps<Dual<S>> {
  static constexpr std::remove_cv_t<decltype(Eps<S>::small)> small = Eps<S>::small;
  static constexpr std::remove_cv_t<decltype(Eps<S>::machine)> machine = Eps<S>::machine;
};

}  // namespace rbd
