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

// scalar functions, overloaded per Scalar type (the dual number type in
// dual.hpp adds its own overloads) so templates never call std:: directly.
RBD_HD double ssin(double x) { return ::sin(x); }
RBD_HD double scos(double x) { return ::cos(x); }
RBD_HD double ssqrt(double x) { return ::sqrt(x); }
RBD_HD double satan2(double y, double x) { return ::atan2(y, x); }
RBD_HD double sabs(double x) { return ::fabs(x); }
RBD_HD double slog(double x) { return ::log(x); }
RBD_HD float ssin(float x) { return ::sinf(x); }
RBD_HD float scos(float x) { return ::cosf(x); }
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
