// Host entry points of the dynamics derivatives and per-pass helpers.
#include <memory>
#include <sstream>
#include <stdexcept>

#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/batch/derivatives_api.hpp"

namespace rbd {
namespace batch {

namespace {
void check_inputs(const Model& m, long B, const double* q, const double* qd, const double* qdd, const double* tau,
                  const double* fext, double gravity, const char* tau_name = "tau") {
  check_configurations(m, B, q, "q");
  if (qd) check_finite(qd, B * m.nv, "qd");
  if (qdd) check_finite(qdd, B * m.nv, "qdd");
  if (tau) check_finite(tau, B * m.nv, tau_name);
  if (fext) check_finite(fext, B * m.nb() * 6, "f_ext");
  check_finite(&gravity, 1, "gravity");
}

void require_no_mimic(const Model& m, const char* what) {
  if (m.has_mimic())
    throw std::invalid_argument(std::string(what) +
                                ": the direct inverse's passes apply to models without mimic joints; "
                                "this model has mimic joints (use minv)");
  if (m.general_path())
    throw std::invalid_argument(std::string(what) +
                                ": the direct inverse's passes need each subtree's coordinates contiguous (bodies "
                                "added depth-first); this model's are not (use minv)");
}

// per-body DoF columns <-> (nb x 6 x 6) arrays
void store_cols(const Model& m, const Motion<double>* cols, double* out) {
  for (int b = 0; b < m.nb(); ++b)
    for (int a = 0; a < 6; ++a) {
      double x[6] = {0, 0, 0, 0, 0, 0};
      if (a < m.bodies[b].nv) store(cols[6 * b + a], x);
      for (int r = 0; r < 6; ++r) out[(b * 6 + r) * 6 + a] = x[r];
    }
}
void load_cols(const Model& m, const double* in, Motion<double>* cols) {
  for (int b = 0; b < m.nb(); ++b)
    for (int a = 0; a < m.bodies[b].nv; ++a) {
      double x[6];
      for (int r = 0; r < 6; ++r) x[r] = in[(b * 6 + r) * 6 + a];
      cols[6 * b + a] = load_motion(x);
    }
}
}  // namespace

void inverse_dynamics_gradient(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                               const double* fext, double gravity, double* out, Workspace<double>* ws) {
  check_inputs(m, B, q, qd, qdd, nullptr, fext, gravity);
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  const int nv = m.nv;
  std::vector<double> dq(nv * nv), dv(nv * nv);
  for (long s = 0; s < B; ++s) {
    rnea_derivatives(mv, buf.get(), q + s * m.nq, qd + s * nv, qdd ? qdd + s * nv : nullptr,
                     fext ? fext + s * m.nb() * 6 : nullptr, gravity, dq.data(), dv.data());
    double* o = out + s * nv * 2 * nv;
    for (int r = 0; r < nv; ++r)
      for (int c = 0; c < nv; ++c) {
        o[r * 2 * nv + c] = dq[r * nv + c];
        o[r * 2 * nv + nv + c] = dv[r * nv + c];
      }
  }
}

void forward_dynamics_gradient(const Model& m, long B, const double* q, const double* qd, const double* tau,
                               const double* fext, double gravity, double* dqdd_dq, double* dqdd_dqd, double* qdd,
                               Workspace<double>* ws) {
  check_inputs(m, B, q, qd, nullptr, tau, fext, gravity, "u");
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  const int nv = m.nv;
  std::vector<double> acc(nv);
  for (long s = 0; s < B; ++s) {
    double* a = qdd ? qdd + s * nv : acc.data();
    if (!aba_derivatives(mv, buf.get(), q + s * m.nq, qd + s * nv, tau + s * nv, fext ? fext + s * m.nb() * 6 : nullptr,
                         gravity, a, dqdd_dq + s * nv * nv, dqdd_dqd + s * nv * nv))
      throw_not_positive_definite(m, "forward_dynamics_gradient", q + s * m.nq, B > 1 ? s : -1);
  }
}

void fext_gradient(const Model& m, long B, const double* q, double* dtau_dfext, double* dqdd_dfext) {
  check_inputs(m, B, q, nullptr, nullptr, nullptr, nullptr, 0.0);
  WorkspaceBuffer buf(m);
  const ModelView<double> mv = m.view();
  const long blk = static_cast<long>(m.nb()) * m.nv * 6;
  for (long s = 0; s < B; ++s)
    if (!fext_derivatives(mv, buf.get(), q + s * m.nq, dtau_dfext + s * blk, dqdd_dfext + s * blk))
      throw_not_positive_definite(m, "f_ext_gradient", q + s * m.nq, B > 1 ? s : -1);
}

void inverse_dynamics_fpass(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                            const double* fext, double gravity, double* v, double* a, double* f) {
  check_inputs(m, B, q, qd, qdd, nullptr, fext, gravity);
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nb = m.nb();
  for (long s = 0; s < B; ++s) {
    rnea_forward_pass(mv, w, q + s * m.nq, qd + s * m.nv, qdd ? qdd + s * m.nv : nullptr,
                      fext ? fext + s * nb * 6 : nullptr, gravity);
    for (int i = 0; i < nb; ++i) {
      store(w.v[i], v + (s * nb + i) * 6);
      store(w.a[i], a + (s * nb + i) * 6);
      store(w.f[i], f + (s * nb + i) * 6);
    }
  }
}

void inverse_dynamics_bpass(const Model& m, long B, const double* q, const double* f_in, double* tau, double* f_out) {
  check_inputs(m, B, q, nullptr, nullptr, nullptr, nullptr, 0.0);
  check_finite(f_in, B * m.nb() * 6, "f");
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nb = m.nb();
  for (long s = 0; s < B; ++s) {
    for (int i = 0; i < nb; ++i) {
      w.X_parent[i] = body_transform(m.bodies[i], q + s * m.nq);
      w.f[i] = load_force(f_in + (s * nb + i) * 6);
    }
    rnea_backward_pass(mv, w, tau + s * m.nv);
    for (int i = 0; i < nb; ++i) store(w.f[i], f_out + (s * nb + i) * 6);
  }
}

void minv_bpass(const Model& m, long B, const double* q, double* minv_b) {
  require_no_mimic(m, "minv_bpass");
  check_inputs(m, B, q, nullptr, nullptr, nullptr, nullptr, 0.0);
  WorkspaceBuffer buf(m);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    if (!minv_backward_pass(mv, buf.get(), q + s * m.nq, minv_b + s * m.nv * m.nv))
      throw_not_positive_definite(m, "minv_bpass", q + s * m.nq, B > 1 ? s : -1);
}

void minv_fpass(const Model& m, long B, const double* q, const double* minv_b, double* minv_out) {
  require_no_mimic(m, "minv_fpass");
  check_inputs(m, B, q, nullptr, nullptr, nullptr, nullptr, 0.0);
  check_finite(minv_b, B * m.nv * m.nv, "minv_b");
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nv = m.nv;
  for (long s = 0; s < B; ++s) {
    // the backward pass's articulated quantities (U, D⁻¹, S), then the forward pass on the given rows
    if (!minv_backward_pass(mv, w, q + s * m.nq, w.dense))
      throw_not_positive_definite(m, "minv_fpass", q + s * m.nq, B > 1 ? s : -1);
    double* out = minv_out + s * nv * nv;
    for (int k = 0; k < nv * nv; ++k) out[k] = minv_b[s * nv * nv + k];
    minv_forward_pass(mv, w, out);
    for (int r = 1; r < nv; ++r)
      for (int c = 0; c < r; ++c) out[r * nv + c] = 0.0;
  }
}

void inverse_dynamics_gradient_fpass(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                                     double gravity, int wrt, double* out1, double* out2) {
  check_inputs(m, B, q, qd, qdd, nullptr, nullptr, gravity);
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const long blk = static_cast<long>(m.nb()) * 36;
  for (long s = 0; s < B; ++s) {
    rnea_derivatives_forward_pass(mv, w, q + s * m.nq, qd + s * m.nv, qdd ? qdd + s * m.nv : nullptr,
                                  static_cast<const double*>(nullptr), gravity, false, true);  // (world quantities out)
    store_cols(m, wrt == 0 ? w.dVdq : w.S_world, out1 + s * blk);
    store_cols(m, wrt == 0 ? w.dAdq : w.dAdv, out2 + s * blk);
  }
}

void inverse_dynamics_gradient_bpass(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                                     double gravity, int wrt, const double* in1, const double* in2, double* dtau) {
  check_inputs(m, B, q, qd, qdd, nullptr, nullptr, gravity);
  const long blk = static_cast<long>(m.nb()) * 36;
  check_finite(in1, B * blk, wrt == 0 ? "dV_dq" : "S");
  check_finite(in2, B * blk, wrt == 0 ? "dA_dq" : "dA_dqd");
  WorkspaceBuffer buf(m);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nv = m.nv;
  std::vector<double> other(nv * nv);
  for (long s = 0; s < B; ++s) {
    // composites from the state, DoF columns from the caller
    rnea_derivatives_forward_pass(mv, w, q + s * m.nq, qd + s * nv, qdd ? qdd + s * nv : nullptr,
                                  static_cast<const double*>(nullptr), gravity, false, true);  // (world: as the registry's)
    load_cols(m, in1 + s * blk, wrt == 0 ? w.dVdq : w.S_world);
    load_cols(m, in2 + s * blk, wrt == 0 ? w.dAdq : w.dAdv);
    double* o = dtau + s * nv * nv;
    if (wrt == 0) rnea_derivatives_backward_pass(mv, w, o, other.data(), static_cast<double*>(nullptr));
    else rnea_derivatives_backward_pass(mv, w, other.data(), o, static_cast<double*>(nullptr));
  }
}

}  // namespace batch
}  // namespace rbd
