// rbdkit/model/input_bounds.hpp — the bounds on inputs that every surface
// checks (ops::check_call on the host, the CUDA kernels' inputs_ok on device
// arrays). Beyond kMaxInput the algorithms' products overflow (a velocity
// enters squared, times inertias up to 1e15 and lengths up to 1e12,
// ModelBuilder's limits); beyond kMaxAngle an angle has no precision left in
// sin and cos (its float64 spacing exceeds 1e-4 rad). Results that still come
// out non-finite throw std::runtime_error (check_result).
#pragma once

#include <math.h>

#include "rbdkit/model/joint_types.hpp"

namespace rbd {

constexpr double kMaxInput = 1e100;    // |q| (positions), |qd|, |qdd|, |tau|, |u|, |f_ext|, |gravity|, ...
constexpr double kMaxAngle = 1e12;     // |q| of revolute and helical joints (rad)
constexpr double kMaxTimeStep = 1e6;   // dt (s) of the integrators and the solver
// the same bounds for float32 computations (float32's range and spacing)
constexpr double kMaxInputF32 = 1e15;
constexpr double kMaxAngleF32 = 1e4;

// x[0, n) finite, of magnitude at most `bound` (false for a NaN)
template <typename T> RBD_HD bool within_bound(const T* x, long n, double bound) {
  bool ok = true;
  for (long k = 0; k < n; ++k) ok &= fabs(static_cast<double>(x[k])) <= bound;
  return ok;
}

// a configuration q (nq values) of the bodies b[0, nb): values within `input`, the angles of revolute
// and helical joints within `angle`, unit quaternions (|‖quat‖ - 1| <= 1e-6, in double, rounded
// alike on host and device: no fused multiply-add)
template <typename S, typename T>
RBD_HD bool configuration_within_bounds(const BodyDesc<S>* b, int nb, int nq, const T* q, double input, double angle) {
  bool ok = within_bound(q, nq, input);
  for (int i = 0; i < nb; ++i) {
    if (b[i].mimic) continue;
    if (b[i].type == kRevolute || b[i].type == kHelical) ok &= fabs(static_cast<double>(q[b[i].q_idx])) <= angle;
    const int r = quat_offset(b[i]);  // a free or ball joint's quaternion
    if (r >= 0) {
      const T* h = q + r;
      double n2 = 0;
      for (int k = 0; k < 4; ++k) {
        const double x = h[k];
#if defined(__CUDA_ARCH__)
        n2 = __dadd_rn(n2, __dmul_rn(x, x));
#else
        n2 += x * x;
#endif
      }
      ok &= fabs(sqrt(n2) - 1.0) <= 1e-6;
    }
  }
  return ok;
}

}  // namespace rbd
