// rbdkit/batch/derivatives_api.hpp — host entry points for the first-order
// dynamics derivatives and the per-pass helpers (batched, checked; see
// dynamics.hpp for the conventions). Host only.
//
// Per-DoF column arrays of the gradient passes are per body, (nb x 6 x 6):
// [b][r][a] is row r of the 6D column of DoF a of body b's joint (a < the
// joint's nv, zero beyond), world frame, [linear; angular].
#pragma once

#include "rbdkit/batch/dynamics.hpp"

namespace rbd {
namespace batch {

// [∂tau/∂q | ∂tau/∂qd] (B x nv x 2nv) of tau = ID(q, qd, qdd, f_ext); qdd, fext may be null
void inverse_dynamics_gradient(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                               const double* fext, double gravity, double* out, Workspace<double>* ws = nullptr);
// ∂qdd/∂q, ∂qdd/∂qd (B x nv x nv each) of qdd = FD(q, qd, tau, f_ext); qdd (B x nv) when not null
void forward_dynamics_gradient(const Model& m, long B, const double* q, const double* qd, const double* tau,
                               const double* fext, double gravity, double* dqdd_dq, double* dqdd_dqd, double* qdd,
                               Workspace<double>* ws = nullptr);
// ∂tau/∂f_ext = -J_bᵀ and ∂qdd/∂f_ext = M⁻¹ J_bᵀ per body (B x nb x nv x 6 each)
void fext_gradient(const Model& m, long B, const double* q, double* dtau_dfext, double* dqdd_dfext);

// ---- per-pass helpers (to check an accelerator port pass by pass)
// RNEA forward pass: per body (B x nb x 6, body frame) velocity v, acceleration
// a (the fictitious gravity acceleration included) and net body force f
void inverse_dynamics_fpass(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                            const double* fext, double gravity, double* v, double* a, double* f);
// RNEA backward pass from net body forces f_in (B x nb x 6): tau (B x nv) and
// the joint forces f_out (B x nb x 6)
void inverse_dynamics_bpass(const Model& m, long B, const double* q, const double* f_in, double* tau, double* f_out);
// M⁻¹ backward pass: the upper rows over subtree columns (B x nv x nv); models without mimic joints
void minv_bpass(const Model& m, long B, const double* q, double* minv_b);
// M⁻¹ forward pass from minv_b: the upper triangle of M⁻¹ (B x nv x nv)
void minv_fpass(const Model& m, long B, const double* q, const double* minv_b, double* minv_out);
// gradient forward pass: wrt 0 (q): dV/dq, dA/dq; wrt 1 (qd): S, dA/dqd (B x nb x 6 x 6 each)
void inverse_dynamics_gradient_fpass(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                                     double gravity, int wrt, double* out1, double* out2);
// gradient backward pass from the forward pass's columns: ∂tau/∂q (wrt 0, from dV/dq,
// dA/dq) or ∂tau/∂qd (wrt 1, from S, dA/dqd), (B x nv x nv)
void inverse_dynamics_gradient_bpass(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                                     double gravity, int wrt, const double* in1, const double* in2, double* dtau);
}  // namespace batch
}  // namespace rbd
