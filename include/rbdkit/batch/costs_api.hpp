// rbdkit/batch/costs_api.hpp — host entry points of the plant layer's costs and
// barriers (batched, checked). Layouts in plant/costs.hpp. Host only.
#pragma once

#include "rbdkit/batch/centroidal_api.hpp"
#include "rbdkit/batch/kinematics_api.hpp"
#include "rbdkit/batch/mujoco_api.hpp"
#include "rbdkit/plant/costs.hpp"

namespace rbd {
namespace batch {
// ½ Σ W (x - x_des)² over width n: value (B), grad (B x n), H (B x n x n); names label errors
void quadratic_cost(long B, int n, const double* x, const double* x_des, const double* W, double* value,
                    double* grad, double* H, const char* x_name, const char* des_name, const char* w_name);
// Below, convention (OutputConvention) gives the layout and frames of x, q, qd
// and the tangent of the derivatives (MuJoCo: qpos/qvel and mj_integratePos).
// the log-map state cost: x, x_des (B x NX), Q (B x 2nv) -> value (B), grad (B x 2nv), H (B x 2nv x 2nv)
void quadratic_state_cost_tangent(const Model& m, long B, const double* x, const double* x_des, const double* Q,
                                  double* value, double* grad, double* H, int convention = kPinocchioConvention);
// end-effector position tracking of end effector `body` with tool point
// `offset` (3, body frame): q (B x nq), p_des, W (B x 3) -> value (B), grad (B x NX), H (B x NX x NX)
void ee_pos_cost(const Model& m, long B, const double* q, const double* p_des, const double* W, int body,
                 const double* offset, double* value, double* grad, double* H,
                 int convention = kPinocchioConvention);
// centre-of-mass tracking: q (B x nq), p_des, W (B x 3) -> value (B), grad (B x NX), H (B x NX x NX)
void com_cost(const Model& m, long B, const double* q, const double* p_des, const double* W, double* value,
              double* grad, double* H, int convention = kPinocchioConvention);
// centroidal momentum tracking, r = A(q) qd - h_des (6), J = [(∂A/∂q) qd | A] (6 x 2nv):
// q (B x nq), qd (B x nv), h_des, W (B x 6) -> value (B), grad Jᵀ W r (B x 2nv),
// Gauss–Newton H = Jᵀ W J (B x 2nv x 2nv). MuJoCo convention: r = A(q) Cᵀ qd - h_des and J
// includes the configuration dependence of Cᵀ (the velocity-frame conversion)
void momentum_cost(const Model& m, long B, const double* q, const double* qd, const double* h_des, const double* W,
                   double* value, double* grad, double* H, int convention = kPinocchioConvention);
// log barrier over width n: value (B), grad (B x n), Hdiag (B x n)
void log_barrier(long B, int n, const double* x, const double* lower, const double* upper, double mu,
                 double* value, double* grad, double* Hdiag, const char* x_name);
}  // namespace batch
}  // namespace rbd
