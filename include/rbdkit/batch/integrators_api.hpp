// rbdkit/batch/integrators_api.hpp — host entry points of the time integrators
// (batched, checked; conventions in dynamics.hpp). Host only.
#pragma once

#include <string>

#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/batch/mujoco_api.hpp"
#include "rbdkit/plant/integrators.hpp"

namespace rbd {

// "euler", "semi_implicit_euler", "midpoint", "rk4", "trapezoidal",
// "constant_acceleration" -> IntegratorType; anything else throws
// std::invalid_argument listing the valid names
int integrator_from_name(const std::string& name);

namespace batch {
// x⁺ = [q⁺; v⁺] (B x (nq + nv)); fext (B x nb x 6) may be null. convention
// (OutputConvention): the layout, frames and ⊕ of q, v, u and x⁺
void integrator(const Model& m, long B, const double* q, const double* v, const double* u, const double* fext,
                double dt, double gravity, int type, double* x_next, int convention = kPinocchioConvention);
// x⁺ and [A | B] = ∂x⁺/∂(x, u) (B x 2nv x 3nv), in the convention's tangent space
void integrator_gradient(const Model& m, long B, const double* q, const double* v, const double* u,
                         const double* fext, double dt, double gravity, int type, double* x_next, double* AB,
                         int convention = kPinocchioConvention);
// x⁺ (B x (nq + nv)), AB (B x 2nv x 3nv) and the step Hessian H (B x 2nv x 3nv x 3nv),
// H[i, j, k] = ∂²ψ_i/∂z_j∂z_k as defined in plant/integrator_hessian.hpp, in the
// convention's coordinates and tangent (as integrator_gradient); no external forces
// (src/batch/integrator_hessian.cpp)
void plant_step_hessian(const Model& m, long B, const double* q, const double* v, const double* u, double dt,
                        double gravity, int type, double* x_next, double* AB, double* H,
                        int convention = kPinocchioConvention);
}  // namespace batch
}  // namespace rbd
