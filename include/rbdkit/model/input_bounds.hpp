// rbdkit/model/input_bounds.hpp — the bounds on inputs that every surface
// checks (ops::check_call on the host, the CUDA kernels' inputs_ok on device
// arrays). Beyond kMaxInput the algorithms' products overflow (a velocity
// enters squared, times inertias up to 1e15 and lengths up to 1e12,
// ModelBuilder's limits); beyond kMaxAngle an angle has no precision left in
// sin and cos (its float64 spacing exceeds 1e-4 rad). Results that still come
// out non-finite throw std::runtime_error (check_result).
#pragma once

namespace rbd {

constexpr double kMaxInput = 1e100;    // |q| (positions), |qd|, |qdd|, |tau|, |u|, |f_ext|, |gravity|, ...
constexpr double kMaxAngle = 1e12;     // |q| of revolute and helical joints (rad)
constexpr double kMaxTimeStep = 1e6;   // dt (s) of the integrators and the solver
// the same bounds for float32 computations (float32's range and spacing)
constexpr double kMaxInputF32 = 1e15;
constexpr double kMaxAngleF32 = 1e4;

}  // namespace rbd
