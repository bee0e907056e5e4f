// rbdkit/batch/centroidal_api.hpp — host entry points of the energy and centroidal
// family: energies, the Coriolis matrix, the centre of mass and its Jacobian,
// the centroidal momentum matrix, its derivatives and time variation, and the
// centroidal dynamics derivatives (batched, checked; see dynamics.hpp for the
// conventions). Host only. The per-sample maths is in algorithms/energy.hpp
// and algorithms/centroidal.hpp.
//
// Every batched function takes B samples stacked on the leading axis:
// q (B x nq), qd / qdd (B x nv); outputs are row-major with the shapes given.
// Centroidal quantities are forces [linear; angular] about the centre of mass
// in world-aligned axes (Pinocchio's data.Ag, data.hg). Configuration
// derivatives are tangent-space: column k is along q ← integrate(q, δ e_k).
//
// Inputs are checked first (finite values, unit quaternions): a bad one
// throws std::invalid_argument naming the argument. A robot without mass
// (total mass 0) has no centre of mass: the centroidal functions throw
// std::runtime_error.
#pragma once

#include "rbdkit/batch/dynamics.hpp"

namespace rbd {
namespace batch {

// ---- energy (one scalar per sample, out (B))
// T = ½ qdᵀ M qd
void kinetic_energy(const Model& m, long B, const double* q, const double* qd, double* out,
                    Workspace<double>* ws = nullptr);
// V = -Σ m_i g·c_i with g = (0, 0, gravity)
void potential_energy(const Model& m, long B, const double* q, double gravity, double* out,
                      Workspace<double>* ws = nullptr);
// T + V
void mechanical_energy(const Model& m, long B, const double* q, const double* qd, double gravity, double* out,
                       Workspace<double>* ws = nullptr);
// C (B x nv x nv), Pinocchio's computeCoriolisMatrix: C qd + g = nonlinear effects, Ṁ - 2C skew
void coriolis_matrix(const Model& m, long B, const double* q, const double* qd, double* C,
                     Workspace<double>* ws = nullptr);

// ---- centre of mass
// c (B x 3), world frame
void center_of_mass(const Model& m, long B, const double* q, double* com, Workspace<double>* ws = nullptr);
// J_com (B x 3 x nv) = ∂c/∂δ
void jacobian_com(const Model& m, long B, const double* q, double* J, Workspace<double>* ws = nullptr);

// ---- centroidal momentum
// A (B x 6 x nv), h = A qd (B x 6)
void ccrba(const Model& m, long B, const double* q, const double* qd, double* A, double* h,
           Workspace<double>* ws = nullptr);
// h (B x 6), one O(n) forward pass
void centroidal_momentum(const Model& m, long B, const double* q, const double* qd, double* h,
                         Workspace<double>* ws = nullptr);
// dA (B x 6 x nv x nv), dA[b][r][j][k] = ∂A[r][j]/∂δ_k, analytic
void dccrba(const Model& m, long B, const double* q, double* dA, Workspace<double>* ws = nullptr);
// the same by central differences through integrate with step eps > 0: a
// cross-check of dccrba, not for production use
void dccrba_fd(const Model& m, long B, const double* q, double eps, double* dA);
// Ȧ (B x 6 x nv) = Σ_k dA[:, :, k] qd_k, in O(n) (Pinocchio's computeCentroidalMapTimeVariation)
void cmm_time_variation(const Model& m, long B, const double* q, const double* qd, double* Adot,
                        Workspace<double>* ws = nullptr);
// Σ_k dccrba_fd(q, eps)[:, :, k] qd_k: the finite-difference cross-check of cmm_time_variation
void cmm_time_variation_fd(const Model& m, long B, const double* q, const double* qd, double eps, double* Adot);
// ḣ (B x 6) = A qdd + Ȧ qd (gravity not included; Pinocchio's computeCentroidalMomentumTimeVariation)
void centroidal_momentum_time_variation(const Model& m, long B, const double* q, const double* qd,
                                        const double* qdd, double* hdot, Workspace<double>* ws = nullptr);
// (B x 6 x nv each): ∂h/∂δ at fixed qd, ∂ḣ/∂δ, ∂ḣ/∂qd, ∂ḣ/∂qdd = A
// (Pinocchio's computeCentroidalDynamicsDerivatives)
void centroidal_dynamics_derivatives(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                                     double* dh_dq, double* dhdot_dq, double* dhdot_dv, double* dhdot_da,
                                     Workspace<double>* ws = nullptr);

}  // namespace batch
}  // namespace rbd
