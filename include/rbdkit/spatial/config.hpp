// rbdkit/spatial/config.hpp — the host/device macro and the scalar maths the per-sample
// code uses. Everything under include/rbdkit/ except the host API headers
// (model.hpp, urdf.hpp, dynamics.hpp) must compile with nvcc in device code:
// no std containers, no exceptions, no virtual calls, no allocation.
#pragma once

#include <math.h>

#if defined(__CUDACC__)
#define RBD_HD __host__ __device__ inline
#else
#define RBD_HD inline
#endif
// RBD_HD, and inlined whatever the compiler's size heuristics say: for a short helper that a hot
// per-body loop calls and that several algorithms of one translation unit share (one copy out of
// line would make each call pass its result through memory)
#if defined(__CUDACC__)
#define RBD_HD_INLINE __host__ __device__ __forceinline__
#elif defined(__GNUC__) || defined(__clang__)
#define RBD_HD_INLINE inline __attribute__((always_inline))
#else
#define RBD_HD_INLINE inline
#endif
// an algorithm's entry point on the host: every call inside it inlined, its passes and their per-body
// helpers one function (the compilers' size heuristics leave passes and joint visits out of line,
// and in a large translation unit stop inlining early: a quarter of RNEA's time on the iiwa). nvcc
// inlines device code by its own rules. RBDKIT_NO_FLATTEN (the sanitizer build) compiles everything
// as written, faster
#if !defined(__CUDACC__) && !defined(RBDKIT_NO_FLATTEN) && (defined(__GNUC__) || defined(__clang__))
#define RBD_FLATTEN __attribute__((flatten))
#else
#define RBD_FLATTEN
#endif
// a large host function kept out of line whatever its callers' size: inlined into the step Hessian's
// driver, the jets' composition (integrator_hessian.hpp) ran the same instructions 25-45 % slower on
// floating HyQ and Atlas. Device code: nvcc's own rules
#if !defined(__CUDACC__) && (defined(__GNUC__) || defined(__clang__))
#define RBD_NOINLINE __attribute__((noinline))
#else
#define RBD_NOINLINE
#endif
// the vectors the host column loops (minv.hpp, dense.hpp) take first, in bytes: 16 (SSE2, x86-64's
// baseline, what the library is built for), 32 under AVX (a per-robot instance compiled with
// -march=native); then 16 bytes, then single entries, every column with the same operations in the
// same order. Not 64 under AVX-512: the columns are a few dozen at most, and on the machine measured
// (AMD Zen 4, whose 512-bit operations are two 256-bit halves) 64 was no faster, slower on the small robots
#if defined(__AVX__)
#define RBD_HOST_VECTOR_BYTES 32
#else
#define RBD_HOST_VECTOR_BYTES 16
#endif
// the single-sample code's own vectors on the host (GCC/clang vector extensions; the batch engine's
// packs, batch/simd.hpp, run across samples instead): RBD_HOST_LANES doubles of RBD_HOST_VECTOR_BYTES
// (the joints' sin and cos, joint_types.hpp's place_joints); on x86-64, 2-lane vectors for the inertia
// transform (spatial.hpp's transform_inertia_pairs) and, without AVX, for CRBA's column transforms two
// columns at a time (crba.hpp's crba_act_column_pairs); under AVX (RBD_HOST_AVX: a per-robot instance
// compiled with -march=native) 4-lane 3-vectors for those column transforms (crba_act_columns_avx).
// Each lane has the scalar form's operations in its order. Not in CUDA sources, whose host pass keeps
// the scalar forms
#if !defined(__CUDACC__) && (defined(__GNUC__) || defined(__clang__))
#define RBD_HOST_LANES (RBD_HOST_VECTOR_BYTES / 8)
#if defined(__AVX__)
#define RBD_HOST_AVX 1
#endif
#endif
// a lambda always inlined where it is called (written after its parameter list), in host code from g++
// and clang: the inner walks of M's factorisation and of M⁻¹'s rows over a constant DoF tree
// (codegen/unrolled.hpp), which a large instance otherwise leaves as calls per ancestor DoF. (Each DoF's
// own step stays the compiler's choice: on floating Atlas inlining those too made the code slower)
#if !defined(__CUDACC__) && (defined(__GNUC__) || defined(__clang__))
#define RBD_LAMBDA_INLINE __attribute__((always_inline))
#else
#define RBD_LAMBDA_INLINE
#endif
// a body or coordinate loop that nvcc unrolls whole where its trip count is a compile-time constant
// (a per-robot instance's model: a robot's sizes and bodies as constants, cuda/instance.cuh), which
// turns the bodies' joint types, parents and constants into immediates and keeps a chain's values in
// registers; a loop over a view's run-time sizes is left as it is. The host compilers ignore it
#if defined(__CUDACC__)
#define RBD_UNROLL _Pragma("unroll")
#else
#define RBD_UNROLL
#endif
// a pointer through which nothing else in its scope reads or writes (lets
// the compiler vectorise a loop over it); g++, clang and nvcc spell it alike
#define RBD_RESTRICT __restrict__

namespace rbd {

// ---- sin and cos together, for a joint's rotation in every pass: x = k·π/2 + r (Cody–Waite, π/2 in
// three parts, k·part exact for |k| < 2²⁰), then Taylor series of sin and cos on |r| ≤ π/4 (9 terms:
// the remainder is below 1e-19) and the quadrant's sign and swap. Within two ulps of libm (the
// reduction's roundings), and inlined where libm's sin and cos are calls of ~100 instructions each;
// |x| > 1e5, inf and NaN go to libm, and so does everything under -ffast-math (which would fold the
// shift and the reduction). float is computed in double and rounded. The SIMD packs (batch/simd.hpp)
// share sincos_shift, sincos_reduce and sincos_quarter lane for lane, so a pack's lanes equal the
// scalar results. Device code: CUDA's sincos.
// V: double, or a GCC/clang vector of doubles in its natural alignment (a pack's own vector is only
// element-aligned: simd.hpp copies it into a local first)
// fl(x·2/π) + 1.5·2⁵²: its low mantissa bits are k, fl(x·2/π) rounded to an integer (ties to even),
// exactly, for |x| ≤ 1e5; k = shifted - kSincosShift, and k mod 4 is the low two bits of its representation
constexpr double kSincosShift = 6755399441055744.0;
// (the helpers write through references: no vector passes by value, whose ABI depends on the target)
template <typename V> RBD_HD_INLINE void sincos_shift(const V& x, V& shifted) {
  shifted = x * 0.6366197723675814 + kSincosShift;
}
// r = x - k·π/2 for k = shifted - kSincosShift
template <typename V> RBD_HD_INLINE void sincos_reduce(const V& x, const V& shifted, V& r) {
  const V k = shifted - kSincosShift;
  r = ((x - k * 1.5707963267341256) - k * 6.077100506303966e-11) - k * 2.0222662487959506e-21;
}
// sr = sin r, cr = cos r for |r| ≤ π/4: sin r = r + r·z·(-1/3! + z/5! - ...), cos r = 1 - z/2 +
// z²·(1/4! - z/6! + ...) (z = r²), the series' tails by Estrin's scheme (z, z², z⁴: 3 levels where
// Horner's chain has 8); the leading terms added last, cos's 1 - z/2 with its rounding error carried
// (w + ((1 - w) - z/2)), for results within about half an ulp of sin r and cos r; sin(±0) = ±0
template <typename V> RBD_HD_INLINE void sincos_quarter(const V& r, V& sr, V& cr) {
  const double sc[8] = {-1.0 / 121645100408832000.0, 1.0 / 355687428096000.0, -1.0 / 1307674368000.0,
                        1.0 / 6227020800.0, -1.0 / 39916800.0, 1.0 / 362880.0, -1.0 / 5040.0, 1.0 / 120.0};
  const double cc[8] = {1.0 / 6402373705728000.0, -1.0 / 20922789888000.0, 1.0 / 87178291200.0,
                        -1.0 / 479001600.0, 1.0 / 3628800.0, -1.0 / 40320.0, 1.0 / 720.0, -1.0 / 24.0};
  const V z = r * r, z2 = z * z, z4 = z2 * z2;
  const V ps = ((sc[7] + sc[6] * z) + (sc[5] + sc[4] * z) * z2) + ((sc[3] + sc[2] * z) + (sc[1] + sc[0] * z) * z2) * z4;
  const V pc = ((cc[7] + cc[6] * z) + (cc[5] + cc[4] * z) * z2) + ((cc[3] + cc[2] * z) + (cc[1] + cc[0] * z) * z2) * z4;
  sr = r + r * (z * (ps * z - 1.0 / 6.0));
  sr = r == 0.0 ? r : sr;  // the sum above is +0 for r = -0
  const V hz = 0.5 * z, w = 1.0 - hz;
  cr = w + (((1.0 - w) - hz) + z * (z * -pc));
}
// s, c from sin r, cos r and the quadrant q = k mod 4 (an int, or a vector of them on the packs):
// sin and cos swap in odd quadrants, sin is negated in quadrants 2 and 3, cos in 1 and 2
template <typename Q, typename V>
RBD_HD_INLINE void sincos_quadrant(const Q& q, const V& sr, const V& cr, V& s, V& c) {
  const V s1 = (q & 1) != 0 ? cr : sr, c1 = (q & 1) != 0 ? sr : cr;
  s = (q & 2) != 0 ? -s1 : s1;
  c = ((q + 1) & 2) != 0 ? -c1 : c1;
}
#if defined(RBD_HOST_LANES)
// sin and cos of every lane of x, a GCC/clang vector of doubles in its natural alignment: ssincos's
// shift, reduction and series lane for lane (so each lane is the scalar result bit for bit), the
// quadrant's sign and swap as lane masks, and libm for the lanes beyond |x| ≤ 1e5 (inf, NaN) and
// for every lane under -ffast-math. Host only: the SIMD packs (batch/simd.hpp) and place_joints
template <typename V> inline void sincos_lanes(const V& x, V& s, V& c) {
  constexpr int n = sizeof(V) / sizeof(double);
#if defined(__FAST_MATH__)
  for (int l = 0; l < n; ++l) s[l] = ::sin(x[l]), c[l] = ::cos(x[l]);
#else
  typedef decltype(x < x) M;
  V shifted, r, sr, cr;
  sincos_shift(x, shifted);
  sincos_reduce(x, shifted, r);
  sincos_quarter(r, sr, cr);
  M q;
  __builtin_memcpy(&q, &shifted, sizeof q);
  q = q & 3;
  sincos_quadrant(q, sr, cr, s, c);
  const M big = (x > 1e5) | (x < -1e5) | (x != x);
  bool any = false;
  for (int l = 0; l < n; ++l) any |= big[l] != 0;
  if (any)
    for (int l = 0; l < n; ++l)
      if (big[l]) s[l] = ::sin(x[l]), c[l] = ::cos(x[l]);
#endif
}
#endif
RBD_HD_INLINE void ssincos(double x, double& s, double& c) {
#if defined(__CUDA_ARCH__)
  ::sincos(x, &s, &c);
#elif defined(__FAST_MATH__)
  s = ::sin(x), c = ::cos(x);
#else
  if (!(::fabs(x) <= 1e5)) {
    s = ::sin(x), c = ::cos(x);
    return;
  }
  double shifted, r, sr, cr;
  sincos_shift(x, shifted);
  sincos_reduce(x, shifted, r);
  sincos_quarter(r, sr, cr);
  long long bits;
  __builtin_memcpy(&bits, &shifted, sizeof bits);
  sincos_quadrant(static_cast<int>(bits & 3), sr, cr, s, c);
#endif
}
RBD_HD_INLINE void ssincos(float x, float& s, float& c) {
#if defined(__CUDA_ARCH__)
  ::sincosf(x, &s, &c);
#else
  double sd, cd;
  ssincos(static_cast<double>(x), sd, cd);
  s = static_cast<float>(sd), c = static_cast<float>(cd);
#endif
}

// scalar functions, overloaded per Scalar type (the dual number type in
// dual.hpp adds its own overloads) so templates never call std:: directly.
// sin and cos are ssincos's halves, on the host and the device alike
template <typename S> RBD_HD_INLINE S sincos_sin(S x) {
  S s, c;
  ssincos(x, s, c);
  return s;
}
template <typename S> RBD_HD_INLINE S sincos_cos(S x) {
  S s, c;
  ssincos(x, s, c);
  return c;
}
RBD_HD_INLINE double ssin(double x) { return sincos_sin(x); }
RBD_HD_INLINE double scos(double x) { return sincos_cos(x); }
RBD_HD_INLINE float ssin(float x) { return sincos_sin(x); }
RBD_HD_INLINE float scos(float x) { return sincos_cos(x); }
RBD_HD double ssqrt(double x) { return ::sqrt(x); }
RBD_HD double satan2(double y, double x) { return ::atan2(y, x); }
RBD_HD double sabs(double x) { return ::fabs(x); }
RBD_HD double slog(double x) { return ::log(x); }
RBD_HD float ssqrt(float x) { return ::sqrtf(x); }
RBD_HD float satan2(float y, float x) { return ::atan2f(y, x); }
RBD_HD float sabs(float x) { return ::fabsf(x); }
RBD_HD float slog(float x) { return ::logf(x); }

// value of a scalar for branching (the real part of a dual number)
RBD_HD double value_of(double x) { return x; }
RBD_HD float value_of(float x) { return x; }

// lane-correct branching: a condition on a scalar is a bool here; on a SIMD
// pack (simd.hpp) it is a lane mask, with the same four helpers. A branch
// written as `if (any_lane(c)) ...; if (!all_lanes(c)) ...; select(c, a, b)`
// takes one side for a scalar and both, blended per lane, for a pack.
template <typename S, typename B> RBD_HD bool lane_lt(const S& a, B b) { return value_of(a) < b; }
template <typename S, typename B> RBD_HD bool lane_gt(const S& a, B b) { return value_of(a) > b; }
RBD_HD bool any_lane(bool c) { return c; }
RBD_HD bool all_lanes(bool c) { return c; }
template <typename S> RBD_HD S select(bool c, const S& a, const S& b) { return c ? a : b; }

// small: the small-angle threshold below which series expansions replace the
// closed forms; machine: the unit roundoff's scale (DBL_EPSILON / FLT_EPSILON)
template <typename S> struct Eps;
template <> struct Eps<double> {
  static constexpr double small = 1e-4;
  static constexpr double machine = 2.220446049250313e-16;
};
template <> struct Eps<float> {
  static constexpr float small = 1e-2f;
  static constexpr float machine = 1.1920929e-7f;
};

}  // namespace rbd
