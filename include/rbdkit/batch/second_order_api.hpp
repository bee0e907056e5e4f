// rbdkit/batch/second_order_api.hpp — host entry points of the second-order
// dynamics derivatives (batched, checked; conventions in dynamics.hpp and
// algorithms/idsva_so.hpp). Host only.
//
// Every tensor is (B x nv x nv x nv), row-major, [s][i][j][k]:
//   d2tau_dq2[i, j, k]  = ∂/∂q_k (∂tau_i/∂q_j)    (tangent steps through integrate)
//   d2tau_dqd2[i, j, k] = ∂²tau_i/∂qd_j∂qd_k,  d2tau_dqdqd[i, j, k] = ∂²tau_i/∂q_j∂qd_k
//   dM_dq[i, j, k]      = ∂M_ij/∂q_k
// and the same for qdd = FD(q, qd, u), with d2qdd_dqdu[i, j, k] = ∂²qdd_i/∂q_j∂u_k.
#pragma once

#include "rbdkit/batch/dynamics.hpp"

namespace rbd {

// which recursion idsva_so runs
enum SecondOrderFrame : int {
  kSoBodyFrame = 0,   // body-frame propagation, composites carried to the parent
  kSoWorldFrame = 1,  // world-frame propagation, composites added in place
  kSoAuto = 2,        // body frame for a fixed base, world frame for a floating base
};

namespace batch {
// second-order inverse dynamics at (q, qd, qdd): q (B x nq), qd, qdd (B x nv)
void idsva_so(const Model& m, long B, const double* q, const double* qd, const double* qdd, double gravity,
              int frame, double* d2tau_dq2, double* d2tau_dqd2, double* d2tau_dqdqd, double* dM_dq,
              Workspace<double>* ws = nullptr);
// second-order forward dynamics at (q, qd, u), qdd = FD(q, qd, u): q (B x nq), qd, u (B x nv)
void fdsva_so(const Model& m, long B, const double* q, const double* qd, const double* u, double gravity,
              double* d2qdd_dq2, double* d2qdd_dqd2, double* d2qdd_dqdqd, double* d2qdd_dqdu,
              Workspace<double>* ws = nullptr);
}  // namespace batch
}  // namespace rbd
