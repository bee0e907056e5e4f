// Host entry point of the step Hessian (plant/integrator_hessian.hpp):
// input checks and the batched loop.
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "rbdkit/batch/integrators_api.hpp"
#include "rbdkit/batch/mujoco_api.hpp"
#include "rbdkit/plant/integrator_hessian.hpp"

namespace rbd {
namespace batch {

void plant_step_hessian(const Model& m, long B, const double* q, const double* v, const double* u, double dt,
                        double gravity, int type, double* x_next, double* AB, double* H, int convention) {
  check_convention(convention);
  check_configurations_in(m, B, q, "q", convention);
  check_finite(v, B * m.nv, "qd");
  check_finite(u, B * m.nv, "u");
  check_finite(&gravity, 1, "gravity");
  check_time_step(dt);
  if (type < kEuler || type > kConstantAcceleration) throw std::invalid_argument("integrator_type: out of range");
  WorkspaceBuffer buf(m);
  const ModelView<double> mv = m.view();
  const int nq = m.nq, nv = m.nv;
  const long n_ab = 6L * nv * nv, n_h = 18L * nv * nv * nv;
  std::vector<double> scratch(integrator_hessian_scratch_values(nq, nv));
  for (long s = 0; s < B; ++s) {
    double* x = x_next + s * (nq + nv);
    if (!integrator_hessian(mv, buf.get(), type, q + s * nq, v + s * nv, u + s * nv, dt, gravity, x, x + nq,
                            AB + s * n_ab, H + s * n_h, scratch.data(), convention))
      throw_not_positive_definite(m, "plant_step_hessian", q + s * nq, B > 1 ? s : -1);
  }
}

}  // namespace batch
}  // namespace rbd
