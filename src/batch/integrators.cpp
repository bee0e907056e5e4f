// Host entry points of the time integrators.
#include "rbdkit/batch/integrators_api.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace rbd {

int integrator_from_name(const std::string& name) {
  static const char* names[] = {"euler", "semi_implicit_euler", "midpoint", "rk4", "trapezoidal",
                                "constant_acceleration"};
  for (int k = 0; k < 6; ++k)
    if (name == names[k]) return k;
  std::string hint;
  if (name == "rk3") hint = " (rk3 was removed)";
  if (name == "si_euler") hint = " (si_euler was removed; use semi_implicit_euler)";
  throw std::invalid_argument("integrator_type: unknown integrator '" + name + "'" + hint +
                              "; expected one of euler, semi_implicit_euler, midpoint, rk4, trapezoidal, "
                              "constant_acceleration");
}

namespace batch {
namespace {
void check_step(const Model& m, long B, const double* q, const double* v, const double* u, const double* fext,
                double dt, double gravity, int type, int convention) {
  check_convention(convention);
  check_configurations_in(m, B, q, "q", convention);
  check_finite(v, B * m.nv, "qd");
  check_finite(u, B * m.nv, "u");
  if (fext) check_finite(fext, B * m.nb() * 6, "f_ext");
  check_finite(&gravity, 1, "gravity");
  check_time_step(dt);
  if (type < kEuler || type > kConstantAcceleration) throw std::invalid_argument("integrator_type: out of range");
}
// a failed step: a joint that moves no mass, or (none at q) a later stage
// whose state overflowed, which makes its mass matrix non-finite
[[noreturn]] void step_failed(const Model& m, const char* what, const double* q, long s) {
  if (singular_joint(m, q) >= 0) throw_not_positive_definite(m, what, q, s);
  std::ostringstream os;
  os << what << ": a stage of the step overflowed (non-finite state or mass matrix)";
  if (s >= 0) os << " at sample " << s;
  os << "; reduce dt or the magnitudes of qd and u";
  throw std::runtime_error(os.str());
}
}  // namespace

void integrator(const Model& m, long B, const double* q, const double* v, const double* u, const double* fext,
                double dt, double gravity, int type, double* x_next, int convention) {
  check_step(m, B, q, v, u, fext, dt, gravity, type, convention);
  WorkspaceBuffer buf(m, aba_layout(m));  // every explicit step runs on aba
  const ModelView<double> mv = m.view();
  const int nq = m.nq, nv = m.nv;
  std::vector<double> scratch(integrator_scratch_values(nq, nv));
  for (long s = 0; s < B; ++s) {
    double* x = x_next + s * (nq + nv);
    if (!integrator_step(mv, buf.get(), type, q + s * nq, v + s * nv, u + s * nv,
                         fext ? fext + s * m.nb() * 6 : nullptr, dt, gravity, x, x + nq, scratch.data(),
                         convention))
      step_failed(m, "integrator", q + s * nq, B > 1 ? s : -1);
  }
  check_result(x_next, B * (nq + nv), "integrator", "x_next");
}

void integrator_gradient(const Model& m, long B, const double* q, const double* v, const double* u,
                         const double* fext, double dt, double gravity, int type, double* x_next, double* AB,
                         int convention) {
  check_step(m, B, q, v, u, fext, dt, gravity, type, convention);
  WorkspaceBuffer buf(m);
  const ModelView<double> mv = m.view();
  const int nq = m.nq, nv = m.nv;
  std::vector<double> scratch(integrator_gradient_scratch_values(nq, nv));
  for (long s = 0; s < B; ++s) {
    double* x = x_next + s * (nq + nv);
    if (!rbd::integrator_gradient(mv, buf.get(), type, q + s * nq, v + s * nv, u + s * nv,
                                  fext ? fext + s * m.nb() * 6 : nullptr, dt, gravity, x, x + nq,
                                  AB + s * 6L * nv * nv, scratch.data(), convention))
      step_failed(m, "integrator_gradient", q + s * nq, B > 1 ? s : -1);
  }
  check_result(x_next, B * (nq + nv), "integrator_gradient", "x_next");
  check_result(AB, B * 6L * nv * nv, "integrator_gradient", "AB");
}

}  // namespace batch
}  // namespace rbd
