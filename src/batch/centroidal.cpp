// Host API of the energy and centroidal family: input checks and the batched
// loops over the per-sample passes of algorithms/energy.hpp and
// algorithms/centroidal.hpp.
#include "rbdkit/batch/centroidal_api.hpp"

#include <sstream>
#include <stdexcept>
#include <vector>

#include "rbdkit/algorithms/centroidal.hpp"
#include "rbdkit/algorithms/energy.hpp"

namespace rbd {
namespace batch {

namespace {

void check_state(const Model& m, long B, const double* q, const double* qd, const double* qdd) {
  check_configurations(m, B, q, "q");
  if (qd) check_finite(qd, B * m.nv, "qd");
  if (qdd) check_finite(qdd, B * m.nv, "qdd");
}

void check_eps(double eps) {
  check_finite(&eps, 1, "eps");
  if (!(eps > 0)) {
    std::ostringstream os;
    os << "eps: expected a positive finite-difference step, got " << eps;
    throw std::invalid_argument(os.str());
  }
}

[[noreturn]] void no_mass(const char* what, long s) {
  std::ostringstream os;
  os << what << ": the robot has no mass (total mass 0 at sample " << s
     << "), so its centre of mass is undefined";
  throw std::runtime_error(os.str());
}

}  // namespace

// ------------------------------------------------------------------ energy

void kinetic_energy(const Model& m, long B, const double* q, const double* qd, double* out, Workspace<double>* ws) {
  check_state(m, B, q, qd, nullptr);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) out[s] = rbd::kinetic_energy(mv, buf.get(), q + s * m.nq, qd + s * m.nv);
}

void potential_energy(const Model& m, long B, const double* q, double gravity, double* out, Workspace<double>* ws) {
  check_state(m, B, q, nullptr, nullptr);
  check_finite(&gravity, 1, "gravity");
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) out[s] = rbd::potential_energy(mv, buf.get(), q + s * m.nq, gravity);
}

void mechanical_energy(const Model& m, long B, const double* q, const double* qd, double gravity, double* out,
                       Workspace<double>* ws) {
  check_state(m, B, q, qd, nullptr);
  check_finite(&gravity, 1, "gravity");
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    out[s] = rbd::kinetic_energy(mv, buf.get(), q + s * m.nq, qd + s * m.nv) +
             rbd::potential_energy(mv, buf.get(), q + s * m.nq, gravity);
}

void coriolis_matrix(const Model& m, long B, const double* q, const double* qd, double* C, Workspace<double>* ws) {
  check_state(m, B, q, qd, nullptr);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    rbd::coriolis_matrix(mv, buf.get(), q + s * m.nq, qd + s * m.nv, C + s * m.nv * m.nv);
}

// ---------------------------------------------------------- centre of mass

void center_of_mass(const Model& m, long B, const double* q, double* com, Workspace<double>* ws) {
  check_state(m, B, q, nullptr, nullptr);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    if (!rbd::center_of_mass(mv, buf.get(), q + s * m.nq, com + 3 * s)) no_mass("com", s);
}

void jacobian_com(const Model& m, long B, const double* q, double* J, Workspace<double>* ws) {
  check_state(m, B, q, nullptr, nullptr);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    if (!rbd::jacobian_com(mv, buf.get(), q + s * m.nq, J + s * 3 * m.nv)) no_mass("jacobian_com", s);
}

// ------------------------------------------------------ centroidal momentum

void ccrba(const Model& m, long B, const double* q, const double* qd, double* A, double* h, Workspace<double>* ws) {
  check_state(m, B, q, qd, nullptr);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    if (!rbd::ccrba(mv, buf.get(), q + s * m.nq, qd + s * m.nv, A + s * 6 * m.nv, h + s * 6)) no_mass("ccrba", s);
}

void centroidal_momentum(const Model& m, long B, const double* q, const double* qd, double* h,
                         Workspace<double>* ws) {
  check_state(m, B, q, qd, nullptr);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    if (!rbd::centroidal_momentum(mv, buf.get(), q + s * m.nq, qd + s * m.nv, h + s * 6))
      no_mass("centroidal_momentum", s);
}

void dccrba(const Model& m, long B, const double* q, double* dA, Workspace<double>* ws) {
  check_state(m, B, q, nullptr, nullptr);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  const long nv = m.nv;
  std::vector<double> A(6 * nv);
  for (long s = 0; s < B; ++s)
    if (!rbd::dccrba(mv, buf.get(), q + s * m.nq, A.data(), dA + s * 6 * nv * nv)) no_mass("dccrba", s);
}

void dccrba_fd(const Model& m, long B, const double* q, double eps, double* dA) {
  check_state(m, B, q, nullptr, nullptr);
  check_eps(eps);
  WorkspaceBuffer buf(m);
  const ModelView<double> mv = m.view();
  const int nq = m.nq, nv = m.nv;
  std::vector<double> delta(nv, 0.0), qp(nq), qm(nq), Ap(6 * nv), Am(6 * nv);
  for (long s = 0; s < B; ++s) {
    const double* qs = q + s * nq;
    double* out = dA + s * 6 * nv * nv;
    for (int k = 0; k < nv; ++k) {
      // A(q ⊕ ±eps e_k), central difference into dA[:, :, k]
      delta.assign(nv, 0.0);
      delta[k] = eps;
      rbd::integrate(mv, qs, delta.data(), qp.data());
      delta[k] = -eps;
      rbd::integrate(mv, qs, delta.data(), qm.data());
      if (!rbd::ccrba(mv, buf.get(), qp.data(), static_cast<const double*>(nullptr), Ap.data(),
                      static_cast<double*>(nullptr)) ||
          !rbd::ccrba(mv, buf.get(), qm.data(), static_cast<const double*>(nullptr), Am.data(),
                      static_cast<double*>(nullptr)))
        no_mass("dccrba_fd", s);
      for (int r = 0; r < 6; ++r)
        for (int j = 0; j < nv; ++j) out[(r * nv + j) * nv + k] = (Ap[r * nv + j] - Am[r * nv + j]) / (2 * eps);
    }
  }
}

void cmm_time_variation(const Model& m, long B, const double* q, const double* qd, double* Adot,
                        Workspace<double>* ws) {
  check_state(m, B, q, qd, nullptr);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  std::vector<double> A(6 * m.nv);
  for (long s = 0; s < B; ++s)
    if (!rbd::cmm_time_variation(mv, buf.get(), q + s * m.nq, qd + s * m.nv, A.data(), Adot + s * 6 * m.nv))
      no_mass("cmm_time_variation", s);
}

void cmm_time_variation_fd(const Model& m, long B, const double* q, const double* qd, double eps, double* Adot) {
  check_state(m, B, q, qd, nullptr);
  check_eps(eps);
  const long nv = m.nv;
  std::vector<double> dA(6 * nv * nv);
  for (long s = 0; s < B; ++s) {
    dccrba_fd(m, 1, q + s * m.nq, eps, dA.data());
    // Ȧ[r][j] = Σ_k dA[r][j][k] qd_k
    for (long rj = 0; rj < 6 * nv; ++rj) {
      double acc = 0;
      for (long k = 0; k < nv; ++k) acc += dA[rj * nv + k] * qd[s * nv + k];
      Adot[s * 6 * nv + rj] = acc;
    }
  }
}

void centroidal_momentum_time_variation(const Model& m, long B, const double* q, const double* qd,
                                        const double* qdd, double* hdot, Workspace<double>* ws) {
  check_state(m, B, q, qd, qdd);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    if (!rbd::centroidal_momentum_time_variation(mv, buf.get(), q + s * m.nq, qd + s * m.nv, qdd + s * m.nv,
                                                 hdot + s * 6))
      no_mass("centroidal_momentum_time_variation", s);
}

void centroidal_dynamics_derivatives(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                                     double* dh_dq, double* dhdot_dq, double* dhdot_dv, double* dhdot_da,
                                     Workspace<double>* ws) {
  check_state(m, B, q, qd, qdd);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  const long blk = 6 * m.nv;
  for (long s = 0; s < B; ++s)
    if (!rbd::centroidal_dynamics_derivatives(mv, buf.get(), q + s * m.nq, qd + s * m.nv, qdd + s * m.nv,
                                              dh_dq + s * blk, dhdot_dq + s * blk, dhdot_dv + s * blk,
                                              dhdot_da + s * blk))
      no_mass("centroidal_dynamics_derivatives", s);
}

}  // namespace batch
}  // namespace rbd
