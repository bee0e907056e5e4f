// Host API: input checks, batched loops over the per-sample algorithms, and
// the Eigen front end.
#include "rbdkit/batch/dynamics.hpp"

#include <cmath>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "rbdkit/spatial/dual.hpp"

namespace rbd {

namespace {

std::string sample_label(const char* arg, long sample) {
  std::ostringstream os;
  os << arg;
  if (sample >= 0) os << "[" << sample << "]";
  return os.str();
}

}  // namespace

void check_finite(const double* x, long n, const char* arg) {
  for (long k = 0; k < n; ++k)
    if (!std::isfinite(x[k])) {
      std::ostringstream os;
      os << arg << ": expected finite values, got " << x[k] << " at flat index " << k;
      throw std::invalid_argument(os.str());
    } else if (std::fabs(x[k]) > kMaxInput) {
      std::ostringstream os;
      os << arg << ": expected values of magnitude at most " << kMaxInput << " (larger ones overflow), got " << x[k]
         << " at flat index " << k;
      throw std::invalid_argument(os.str());
    }
}

void check_time_step(double dt, const char* arg) {
  if (!(dt > 0 && dt <= kMaxTimeStep)) {
    std::ostringstream os;
    os << arg << ": expected a positive finite time step of at most " << kMaxTimeStep << " s, got " << dt;
    throw std::invalid_argument(os.str());
  }
}

void check_result(const double* x, long n, const char* what, const char* out) {
  for (long k = 0; k < n; ++k)
    if (!std::isfinite(x[k])) {
      std::ostringstream os;
      os << what << ": the result " << out << " is not finite (" << x[k] << " at flat index " << k
         << "): the computation overflowed; reduce the inputs' magnitudes (or dt)";
      throw std::runtime_error(os.str());
    }
}

void check_joint_angles(const Model& m, const double* q, const char* label) {
  for (size_t i = 0; i < m.bodies.size(); ++i) {
    const BodyDesc<double>& b = m.bodies[i];
    if (!b.mimic && (b.type == kRevolute || b.type == kHelical) && std::fabs(q[b.q_idx]) > kMaxAngle) {
      std::ostringstream os;
      os << label << ": the angle of joint '" << m.joints[i].name << "' (q[" << b.q_idx << "]) must have magnitude "
         << "at most " << kMaxAngle << " rad (beyond it sin and cos have no precision left), got " << q[b.q_idx];
      throw std::invalid_argument(os.str());
    }
  }
}

void check_configuration(const Model& m, const double* q, const char* arg, long sample) {
  const std::string label = sample_label(arg, sample);
  check_finite(q, m.nq, label.c_str());
  check_joint_angles(m, q, label.c_str());
  for (size_t i = 0; i < m.bodies.size(); ++i) {
    const BodyDesc<double>& b = m.bodies[i];
    const int o = quat_offset(b);  // free and ball joints
    if (o < 0) continue;
    const double n = std::sqrt(q[o] * q[o] + q[o + 1] * q[o + 1] + q[o + 2] * q[o + 2] + q[o + 3] * q[o + 3]);
    if (std::fabs(n - 1.0) > 1e-6) {
      std::ostringstream os;
      os << label << ": the quaternion of joint '" << m.joints[i].name << "' (q[" << o << ":" << o + 4
         << "], x y z w) must have unit norm, got norm " << n;
      throw std::invalid_argument(os.str());
    }
  }
}

void check_configurations(const Model& m, long B, const double* q, const char* arg) {
  for (long s = 0; s < B; ++s) check_configuration(m, q + s * m.nq, arg, B > 1 ? s : -1);
}

int singular_joint(const Model& m, const double* q) {
  if (m.has_mimic()) return -1;  // the tree test does not apply: mimic models use the dense path
  WorkspaceBuffer buf(m, kLinearWorkspace);  // the error path only (aba_singular_body: X, IA, U, Dinv)
  return aba_singular_body(m.view(), buf.get(), q);
}

void throw_not_positive_definite(const Model& m, const char* what, const double* q, long sample) {
  const int i = singular_joint(m, q);
  std::ostringstream os;
  os << what << ": ";
  if (i >= 0) {
    os << "joint '" << m.joints[i].name << "' moves no mass";
    if (sample >= 0) os << " at sample " << sample;
    os << ": the mass matrix is singular (not positive definite); give the bodies it moves a mass and "
          "inertia, or make the joint fixed";
  } else {
    os << "the mass matrix is not positive definite";
    if (sample >= 0) os << " at sample " << sample;
  }
  throw std::runtime_error(os.str());
}

namespace batch {

namespace {

// checks shared by the dynamics entry points
void check_state(const Model& m, long B, const double* q, const double* qd, const char* qd_name) {
  check_configurations(m, B, q, "q");
  if (qd) check_finite(qd, B * m.nv, qd_name);
}
}  // namespace

void inverse_dynamics(const Model& m, long B, const double* q, const double* qd, const double* qdd,
                      const double* fext, double gravity, double* tau, double* v, double* a, double* f,
                      Workspace<double>* ws) {
  check_state(m, B, q, qd, "qd");
  if (qdd) check_finite(qdd, B * m.nv, "qdd");
  if (fext) check_finite(fext, B * m.nb() * 6, "f_ext");
  check_finite(&gravity, 1, "gravity");
  ScopedWorkspace buf(m, ws, kLinearWorkspace);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nb = m.nb();
  for (long s = 0; s < B; ++s) {
    rnea(mv, w, q + s * m.nq, qd + s * m.nv, qdd ? qdd + s * m.nv : nullptr, fext ? fext + s * nb * 6 : nullptr,
         gravity, tau + s * m.nv);
    if (v)
      for (int i = 0; i < nb; ++i) store(w.v[i], v + (s * nb + i) * 6);
    if (f)
      for (int i = 0; i < nb; ++i) store(w.f[i], f + (s * nb + i) * 6);
    if (a) {
      remove_gravity(mv, w, gravity, w.c);  // w.c is free after RNEA
      for (int i = 0; i < nb; ++i) store(w.c[i], a + (s * nb + i) * 6);
    }
  }
  check_result(tau, B * m.nv, "inverse_dynamics", "tau");
}

void crba(const Model& m, long B, const double* q, double* M, Workspace<double>* ws) {
  check_state(m, B, q, nullptr, "");
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) rbd::crba(mv, buf.get(), q + s * m.nq, M + s * m.nv * m.nv);
  check_result(M, B * m.nv * m.nv, "crba", "M");
}

void minv(const Model& m, long B, const double* q, bool dense, double* Minv, Workspace<double>* ws) {
  check_state(m, B, q, nullptr, "");
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    if (!rbd::minv(mv, buf.get(), q + s * m.nq, dense, Minv + s * m.nv * m.nv))
      throw_not_positive_definite(m, "minv", q + s * m.nq, B > 1 ? s : -1);
  check_result(Minv, B * m.nv * m.nv, "minv", "Minv");
}

void aba(const Model& m, long B, const double* q, const double* qd, const double* tau, const double* fext,
         double gravity, double* qdd, Workspace<double>* ws) {
  check_state(m, B, q, qd, "qd");
  check_finite(tau, B * m.nv, "tau");
  if (fext) check_finite(fext, B * m.nb() * 6, "f_ext");
  check_finite(&gravity, 1, "gravity");
  ScopedWorkspace buf(m, ws, aba_layout(m));
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    if (!rbd::aba(mv, buf.get(), q + s * m.nq, qd + s * m.nv, tau + s * m.nv, fext ? fext + s * m.nb() * 6 : nullptr,
                  gravity, qdd + s * m.nv))
      throw_not_positive_definite(m, "aba", q + s * m.nq, B > 1 ? s : -1);
  check_result(qdd, B * m.nv, "aba", "qdd");
}

void forward_dynamics(const Model& m, long B, const double* q, const double* qd, const double* tau,
                      const double* fext, double gravity, double* qdd, Workspace<double>* ws) {
  check_state(m, B, q, qd, "qd");
  check_finite(tau, B * m.nv, "u");
  if (fext) check_finite(fext, B * m.nb() * 6, "f_ext");
  check_finite(&gravity, 1, "gravity");
  ScopedWorkspace buf(m, ws);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s)
    if (!rbd::forward_dynamics(mv, buf.get(), q + s * m.nq, qd + s * m.nv, tau + s * m.nv,
                               fext ? fext + s * m.nb() * 6 : nullptr, gravity, qdd + s * m.nv))
      throw_not_positive_definite(m, "forward_dynamics", q + s * m.nq, B > 1 ? s : -1);
  check_result(qdd, B * m.nv, "forward_dynamics", "qdd");
}

void integrate(const Model& m, long B, const double* q, const double* v, double* out) {
  check_state(m, B, q, v, "v");
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) rbd::integrate(mv, q + s * m.nq, v + s * m.nv, out + s * m.nq);
}

void difference(const Model& m, long B, const double* q0, const double* q1, double* out) {
  for (long s = 0; s < B; ++s) {
    check_configuration(m, q0 + s * m.nq, "q0", B > 1 ? s : -1);
    check_configuration(m, q1 + s * m.nq, "q1", B > 1 ? s : -1);
  }
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) rbd::difference(mv, q0 + s * m.nq, q1 + s * m.nq, out + s * m.nv);
}

void dintegrate(const Model& m, long B, const double* q, const double* v, int arg, double* J) {
  check_state(m, B, q, v, "v");
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) rbd::dintegrate(mv, q + s * m.nq, v + s * m.nv, arg, J + s * m.nv * m.nv);
}

void ddifference(const Model& m, long B, const double* q0, const double* q1, int arg, double* J) {
  for (long s = 0; s < B; ++s) {
    check_configuration(m, q0 + s * m.nq, "q0", B > 1 ? s : -1);
    check_configuration(m, q1 + s * m.nq, "q1", B > 1 ? s : -1);
  }
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) rbd::ddifference(mv, q0 + s * m.nq, q1 + s * m.nq, arg, J + s * m.nv * m.nv);
}

void d2integrate(const Model& m, long B, const double* q, const double* v, int arg1, int arg2, double* H) {
  check_state(m, B, q, v, "v");
  using D = Dual<double>;
  const int nq = m.nq, nv = m.nv;
  // the model in dual numbers (constants: zero derivative parts)
  const std::vector<BodyDesc<D>> bodies = m.bodies_as<D>();
  const ModelView<D> mv = {m.nb(), nq, nv, m.general_path() ? 1 : 0, bodies.data()};
  std::vector<D> qd(nq), vd(nv), delta(nv), qp(nq), J(nv * nv);
  for (long s = 0; s < B; ++s) {
    const double* qs = q + s * nq;
    const double* vs = v + s * nv;
    double* Hs = H + s * nv * nv * nv;
    for (int k = 0; k < nv; ++k) {
      // seed direction k of arg2
      for (int i = 0; i < nq; ++i) qd[i] = D(qs[i]);
      for (int i = 0; i < nv; ++i) vd[i] = D(vs[i], arg2 == 1 && i == k ? 1.0 : 0.0);
      if (arg2 == 0) {
        for (int i = 0; i < nv; ++i) delta[i] = D(0.0, i == k ? 1.0 : 0.0);
        rbd::integrate(mv, qd.data(), delta.data(), qp.data());
      } else {
        qp = qd;
      }
      rbd::dintegrate(mv, qp.data(), vd.data(), arg1, J.data());
      for (int i = 0; i < nv; ++i)
        for (int j = 0; j < nv; ++j) Hs[(i * nv + j) * nv + k] = J[i * nv + j].d;
    }
  }
}

}  // namespace batch

// ------------------------------------------------------------------ Dynamics

namespace {
void expect_size(const Eigen::VectorXd& x, long n, const char* arg, const char* what) {
  if (x.size() != n) {
    std::ostringstream os;
    os << arg << ": expected a vector of size " << what << "=" << n << ", got size " << x.size();
    throw std::invalid_argument(os.str());
  }
}
// f_ext as (nb x 6) row-major storage, or null when empty
const double* fext_ptr(const Model& m, const Eigen::MatrixXd& fext, std::vector<double>& tmp) {
  if (fext.size() == 0) return nullptr;
  if (fext.rows() != m.nb() || fext.cols() != 6) {
    std::ostringstream os;
    os << "f_ext: expected shape (nb=" << m.nb() << ", 6), got (" << fext.rows() << ", " << fext.cols() << ")";
    throw std::invalid_argument(os.str());
  }
  tmp.resize(fext.size());
  for (int i = 0; i < m.nb(); ++i)
    for (int k = 0; k < 6; ++k) tmp[i * 6 + k] = fext(i, k);
  return tmp.data();
}
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
}  // namespace

Dynamics::Dynamics(Model model) : model_(std::move(model)) {}

Eigen::VectorXd Dynamics::inverse_dynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                           const Eigen::VectorXd& qdd, double gravity, const Eigen::MatrixXd& fext) {
  expect_size(q, model_.nq, "q", "nq");
  expect_size(qd, model_.nv, "qd", "nv");
  if (qdd.size()) expect_size(qdd, model_.nv, "qdd", "nv");
  std::vector<double> tmp;
  Eigen::VectorXd tau(model_.nv);
  batch::inverse_dynamics(model_, 1, q.data(), qd.data(), qdd.size() ? qdd.data() : nullptr,
                          fext_ptr(model_, fext, tmp), gravity, tau.data(), nullptr, nullptr, nullptr,
                          &ws_.get(model_, kLinearWorkspace));
  return tau;
}

Eigen::MatrixXd Dynamics::crba(const Eigen::VectorXd& q) {
  expect_size(q, model_.nq, "q", "nq");
  RowMat M(model_.nv, model_.nv);
  batch::crba(model_, 1, q.data(), M.data(), &ws_.get(model_, kFullWorkspace));
  return M;
}

Eigen::MatrixXd Dynamics::minv(const Eigen::VectorXd& q, bool dense) {
  expect_size(q, model_.nq, "q", "nq");
  RowMat Mi(model_.nv, model_.nv);
  batch::minv(model_, 1, q.data(), dense, Mi.data(), &ws_.get(model_, kFullWorkspace));
  return Mi;
}

Eigen::VectorXd Dynamics::aba(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, const Eigen::VectorXd& tau,
                              double gravity, const Eigen::MatrixXd& fext) {
  expect_size(q, model_.nq, "q", "nq");
  expect_size(qd, model_.nv, "qd", "nv");
  expect_size(tau, model_.nv, "tau", "nv");
  std::vector<double> tmp;
  Eigen::VectorXd qdd(model_.nv);
  batch::aba(model_, 1, q.data(), qd.data(), tau.data(), fext_ptr(model_, fext, tmp), gravity, qdd.data(),
             &ws_.get(model_, aba_layout(model_)));
  return qdd;
}

Eigen::VectorXd Dynamics::forward_dynamics(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                           const Eigen::VectorXd& tau, double gravity, const Eigen::MatrixXd& fext) {
  expect_size(q, model_.nq, "q", "nq");
  expect_size(qd, model_.nv, "qd", "nv");
  expect_size(tau, model_.nv, "u", "nv");
  std::vector<double> tmp;
  Eigen::VectorXd qdd(model_.nv);
  batch::forward_dynamics(model_, 1, q.data(), qd.data(), tau.data(), fext_ptr(model_, fext, tmp), gravity,
                          qdd.data(), &ws_.get(model_, kFullWorkspace));
  return qdd;
}

Eigen::VectorXd Dynamics::nonlinear_effects(const Eigen::VectorXd& q, const Eigen::VectorXd& qd, double gravity) {
  return inverse_dynamics(q, qd, Eigen::VectorXd(), gravity);
}

Eigen::VectorXd Dynamics::generalized_gravity(const Eigen::VectorXd& q, double gravity) {
  return inverse_dynamics(q, Eigen::VectorXd::Zero(model_.nv), Eigen::VectorXd(), gravity);
}

Eigen::VectorXd Dynamics::integrate(const Eigen::VectorXd& q, const Eigen::VectorXd& v) {
  expect_size(q, model_.nq, "q", "nq");
  expect_size(v, model_.nv, "v", "nv");
  Eigen::VectorXd out(model_.nq);
  batch::integrate(model_, 1, q.data(), v.data(), out.data());
  return out;
}

Eigen::VectorXd Dynamics::difference(const Eigen::VectorXd& q0, const Eigen::VectorXd& q1) {
  expect_size(q0, model_.nq, "q0", "nq");
  expect_size(q1, model_.nq, "q1", "nq");
  Eigen::VectorXd out(model_.nv);
  batch::difference(model_, 1, q0.data(), q1.data(), out.data());
  return out;
}

}  // namespace rbd
