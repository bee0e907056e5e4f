// rbdkit/batch/simd.hpp — Pack<T, W>: W samples of scalar T side by side in one
// vector register, a Scalar type for the per-sample algorithms (the CPU
// batch engine instantiates them on it; engine.hpp). Host only (GCC/Clang
// vector extensions).
//
//   arithmetic     + - * / and compound forms, lane by lane; a plain
//                  number converts to a pack with every lane equal to it
//   functions      ssqrt, satan2, sabs, slog: lane by lane, exactly the
//                  scalar results; ssin, scos (ssincos): vectorised,
//                  within an ulp or two of libm
//   branches       lane_lt / lane_gt give a lane mask; any_lane, all_lanes
//                  and select (config.hpp) turn scalar branches into
//                  lane-correct ones. value_of is deliberately not defined:
//                  a branch on one value does not compile for a pack.
//
// The vector type is aligned to its element only, so packs live anywhere
// (workspaces carved at 16 bytes, the stack); loads are unaligned moves.
#pragma once

#include <math.h>

#include <type_traits>

#include "rbdkit/spatial/config.hpp"

namespace rbd {

template <typename T, int W> struct Pack {
  typedef T vec __attribute__((vector_size(sizeof(T) * W), aligned(sizeof(T))));
  typedef decltype(vec{} < vec{}) mask;
  static constexpr int width = W;
  vec v;

  Pack() = default;
  // broadcast of a plain number
  template <typename U, typename = typename std::enable_if<std::is_arithmetic<U>::value>::type>
  Pack(U x) : v(vec{} + static_cast<T>(x)) {}
  static Pack from(vec x) {
    Pack p;
    p.v = x;
    return p;
  }
  T operator[](int l) const { return v[l]; }
  void set(int l, T x) { v[l] = x; }

  Pack& operator+=(const Pack& o) { v += o.v; return *this; }
  Pack& operator-=(const Pack& o) { v -= o.v; return *this; }
  Pack& operator*=(const Pack& o) { v *= o.v; return *this; }
  Pack& operator/=(const Pack& o) { v /= o.v; return *this; }
};

template <typename T, int W> inline Pack<T, W> operator+(const Pack<T, W>& a, const Pack<T, W>& b) { return Pack<T, W>::from(a.v + b.v); }
template <typename T, int W> inline Pack<T, W> operator-(const Pack<T, W>& a, const Pack<T, W>& b) { return Pack<T, W>::from(a.v - b.v); }
template <typename T, int W> inline Pack<T, W> operator*(const Pack<T, W>& a, const Pack<T, W>& b) { return Pack<T, W>::from(a.v * b.v); }
template <typename T, int W> inline Pack<T, W> operator/(const Pack<T, W>& a, const Pack<T, W>& b) { return Pack<T, W>::from(a.v / b.v); }
template <typename T, int W> inline Pack<T, W> operator-(const Pack<T, W>& a) { return Pack<T, W>::from(-a.v); }

// ---- lane-wise functions (scalar libm per lane: the scalar path's values)
#define RBD_PACK_UNARY(name)                                  \
  template <typename T, int W> inline Pack<T, W> name(const Pack<T, W>& a) { \
    Pack<T, W> r;                                             \
    for (int l = 0; l < W; ++l) r.v[l] = name(a.v[l]);        \
    return r;                                                 \
  }
RBD_PACK_UNARY(sabs)
RBD_PACK_UNARY(slog)
#undef RBD_PACK_UNARY

// IEEE square root, correctly rounded like the scalar one (vectorises)
template <typename T, int W> inline Pack<T, W> ssqrt(const Pack<T, W>& a) {
  Pack<T, W> r;
  for (int l = 0; l < W; ++l) r.v[l] = __builtin_sqrt(a.v[l]);
  return r;
}
template <int W> inline Pack<float, W> ssqrt(const Pack<float, W>& a) {
  Pack<float, W> r;
  for (int l = 0; l < W; ++l) r.v[l] = __builtin_sqrtf(a.v[l]);
  return r;
}
// ---- sin and cos, vectorised: the scalar ssincos's shift, reduction and series (spatial/config.hpp)
// on every lane, so a lane's result is the scalar one; the quadrant's sign and swap as lane masks.
// The helpers work on the vector type in its natural alignment (NaturalVec: what their V is deduced
// as), in locals: a pack's own vector is only element-aligned, since packs live anywhere
template <int W> struct NaturalVec {
  typedef double type __attribute__((vector_size(sizeof(double) * W)));
};
template <int W> inline void sincos_pack(const typename Pack<double, W>::vec& x_in, typename Pack<double, W>::vec& s_out,
                                         typename Pack<double, W>::vec& c_out) {
  typedef typename NaturalVec<W>::type V;
  const V x = x_in;
  V s, c;
  sincos_lanes(x, s, c);
  s_out = s, c_out = c;
}
template <typename T, int W> inline void ssincos(const Pack<T, W>& x, Pack<T, W>& s, Pack<T, W>& c);
template <int W> inline void ssincos(const Pack<double, W>& x, Pack<double, W>& s, Pack<double, W>& c) {
  sincos_pack<W>(x.v, s.v, c.v);
}
template <int W> inline void ssincos(const Pack<float, W>& x, Pack<float, W>& s, Pack<float, W>& c) {
  typedef typename Pack<double, W>::vec V;
  V sd, cd;
  sincos_pack<W>(__builtin_convertvector(x.v, V), sd, cd);
  s.v = __builtin_convertvector(sd, typename Pack<float, W>::vec);
  c.v = __builtin_convertvector(cd, typename Pack<float, W>::vec);
}
template <typename T, int W> inline Pack<T, W> ssin(const Pack<T, W>& x) {
  Pack<T, W> s, c;
  ssincos(x, s, c);
  return s;
}
template <typename T, int W> inline Pack<T, W> scos(const Pack<T, W>& x) {
  Pack<T, W> s, c;
  ssincos(x, s, c);
  return c;
}

template <typename T, int W> inline Pack<T, W> satan2(const Pack<T, W>& y, const Pack<T, W>& x) {
  Pack<T, W> r;
  for (int l = 0; l < W; ++l) r.v[l] = satan2(y.v[l], x.v[l]);
  return r;
}

// ---- lane masks and choices (a class in rbd, so that argument-dependent
// lookup finds these from templates defined before this header)
template <typename T, int W> struct PackMask {
  typename Pack<T, W>::mask m;
};
template <typename T, int W, typename B> inline PackMask<T, W> lane_lt(const Pack<T, W>& a, B b) {
  return {a.v < static_cast<T>(b)};
}
template <typename T, int W, typename B> inline PackMask<T, W> lane_gt(const Pack<T, W>& a, B b) {
  return {a.v > static_cast<T>(b)};
}
template <typename T, int W> inline bool any_lane(const PackMask<T, W>& c) {
  bool r = false;
  for (int l = 0; l < W; ++l) r |= c.m[l] != 0;
  return r;
}
template <typename T, int W> inline bool all_lanes(const PackMask<T, W>& c) {
  bool r = true;
  for (int l = 0; l < W; ++l) r &= c.m[l] != 0;
  return r;
}
template <typename T, int W> inline Pack<T, W> select(const PackMask<T, W>& c, const Pack<T, W>& a, const Pack<T, W>& b) {
  return Pack<T, W>::from(c.m ? a.v : b.v);
}

template <typename T, int W> struct Eps<Pack<T, W>> {
  static constexpr T small = Eps<T>::small;
  static constexpr T machine = Eps<T>::machine;
};

}  // namespace rbd
