// rbdkit/config.hpp — the host/device macro and the scalar maths the per-sample
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

// small-angle threshold below which series expansions replace the closed forms
template <typename S> struct Eps;
template <> struct Eps<double> { static constexpr double small = 1e-4; };
template <> struct Eps<float> { static constexpr float small = 1e-2f; };

}  // namespace rbd
