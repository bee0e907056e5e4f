// rbdkit/batch/regressor_api.hpp — host entry points of the inertial-parameter
// regressors (batched, checked; see dynamics.hpp for the conventions and
// algorithms/regressor.hpp for the maths). Host only.
//
// π (10 nb) stacks per body, in body order (Model::body_names), Pinocchio's
// dynamic parameters [m, m·c_x, m·c_y, m·c_z, I_xx, I_xy, I_yy, I_xz, I_yz,
// I_zz], I about the body-frame origin in body axes (Model::inertial_parameters).
#pragma once

#include "rbdkit/batch/dynamics.hpp"

namespace rbd {
namespace batch {

// Y (B x nv x 10nb): tau = Y·π = ID(q, qd, qdd) (without external forces); qdd may be null (zero)
void inverse_dynamics_regressor(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                                double gravity, double* Y, Workspace<double>* ws = nullptr);
// dY (B x 2nv x nv x 10nb): dY[c]·π = ∂tau/∂x_c, x = [q (tangent); qd]; qdd may be null
void inverse_dynamics_regressor_gradient(const Model& m, long B, const double* q, const double* qd,
                                         const double* qdd, double gravity, double* dY,
                                         Workspace<double>* ws = nullptr);
// ∂qdd/∂π (B x nv x 10nb) = -M⁻¹·Y at qdd = FD(q, qd, u); qdd (B x nv) too when not null
void forward_dynamics_parameter_gradient(const Model& m, long B, const double* q, const double* qd, const double* u,
                                         double gravity, double* dqdd_dpi, double* qdd = nullptr,
                                         Workspace<double>* ws = nullptr);
// y (B x 10nb): kinetic energy T = y·π
void kinetic_energy_regressor(const Model& m, long B, const double* q, const double* qd, double* y,
                              Workspace<double>* ws = nullptr);
// y (B x 10nb): potential energy V = y·π = -Σ m_b g·c_b (world origin at zero, Pinocchio's)
void potential_energy_regressor(const Model& m, long B, const double* q, double gravity, double* y,
                                Workspace<double>* ws = nullptr);

}  // namespace batch
}  // namespace rbd
