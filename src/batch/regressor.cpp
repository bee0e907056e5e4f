// Host entry points of the inertial-parameter regressors.
#include <sstream>
#include <stdexcept>
#include <vector>

#include "rbdkit/algorithms/regressor.hpp"
#include "rbdkit/batch/regressor_api.hpp"

namespace rbd {
namespace batch {

namespace {
void check_inputs(const Model& m, long B, const double* q, const double* qd, const double* qdd, const double* u,
                  double gravity) {
  check_configurations(m, B, q, "q");
  if (qd) check_finite(qd, B * m.nv, "qd");
  if (qdd) check_finite(qdd, B * m.nv, "qdd");
  if (u) check_finite(u, B * m.nv, "u");
  check_finite(&gravity, 1, "gravity");
}
}  // namespace

void inverse_dynamics_regressor(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                                double gravity, double* Y, Workspace<double>* ws) {
  check_inputs(m, B, q, qd, qdd, nullptr, gravity);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  const long blk = static_cast<long>(m.nv) * 10 * m.nb();
  for (long s = 0; s < B; ++s)
    rbd::inverse_dynamics_regressor(mv, buf.get(), q + s * m.nq, qd + s * m.nv, qdd ? qdd + s * m.nv : nullptr,
                                    gravity, Y + s * blk);
}

void inverse_dynamics_regressor_gradient(const Model& m, long B, const double* q, const double* qd,
                                         const double* qdd, double gravity, double* dY, Workspace<double>* ws) {
  check_inputs(m, B, q, qd, qdd, nullptr, gravity);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  const long blk = 2l * m.nv * m.nv * 10 * m.nb();
  for (long s = 0; s < B; ++s)
    rbd::inverse_dynamics_regressor_gradient(mv, buf.get(), q + s * m.nq, qd + s * m.nv,
                                             qdd ? qdd + s * m.nv : nullptr, gravity, dY + s * blk);
}

void forward_dynamics_parameter_gradient(const Model& m, long B, const double* q, const double* qd, const double* u,
                                         double gravity, double* dqdd_dpi, double* qdd, Workspace<double>* ws) {
  check_inputs(m, B, q, qd, nullptr, u, gravity);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  const long blk = static_cast<long>(m.nv) * 10 * m.nb();
  std::vector<double> acc(m.nv);
  for (long s = 0; s < B; ++s) {
    double* a = qdd ? qdd + s * m.nv : acc.data();
    if (!rbd::forward_dynamics_parameter_gradient(mv, buf.get(), q + s * m.nq, qd + s * m.nv, u + s * m.nv, gravity,
                                                  a, dqdd_dpi + s * blk))
      throw_not_positive_definite(m, "forward_dynamics_parameter_gradient", q + s * m.nq, B > 1 ? s : -1);
  }
}

void kinetic_energy_regressor(const Model& m, long B, const double* q, const double* qd, double* y,
                              Workspace<double>* ws) {
  check_inputs(m, B, q, qd, nullptr, nullptr, 0.0);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    rbd::kinetic_energy_regressor(mv, buf.get(), q + s * m.nq, qd + s * m.nv, y + s * 10 * m.nb());
}

void potential_energy_regressor(const Model& m, long B, const double* q, double gravity, double* y,
                                Workspace<double>* ws) {
  check_inputs(m, B, q, nullptr, nullptr, nullptr, gravity);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) rbd::potential_energy_regressor(mv, buf.get(), q + s * m.nq, gravity, y + s * 10 * m.nb());
}

}  // namespace batch
}  // namespace rbd
