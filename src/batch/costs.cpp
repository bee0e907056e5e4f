// Host entry points of the plant layer's costs and barriers.
#include "rbdkit/batch/costs_api.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace rbd {
namespace batch {

namespace {
void check_weights(const double* W, long n, const char* name) {
  check_finite(W, n, name);
  for (long k = 0; k < n; ++k)
    if (W[k] < 0) {
      std::ostringstream os;
      os << name << ": expected non-negative weights, got " << W[k] << " at flat index " << k;
      throw std::invalid_argument(os.str());
    }
}
}  // namespace

void quadratic_cost(long B, int n, const double* x, const double* x_des, const double* W, double* value,
                    double* grad, double* H, const char* x_name, const char* des_name, const char* w_name) {
  check_finite(x, B * n, x_name);
  check_finite(x_des, B * n, des_name);
  check_weights(W, B * n, w_name);
  for (long s = 0; s < B; ++s)
    value[s] = rbd::quadratic_cost(n, x + s * n, x_des + s * n, W + s * n, grad + s * n, H + s * n * n);
}

void quadratic_state_cost_tangent(const Model& m, long B, const double* x, const double* x_des, const double* Q,
                                  double* value, double* grad, double* H, int convention) {
  const int nx = m.nq + m.nv, n2 = 2 * m.nv;
  check_convention(convention);
  for (long s = 0; s < B; ++s) {
    check_configuration_in(m, x + s * nx, "x", B > 1 ? s : -1, convention);
    check_configuration_in(m, x_des + s * nx, "x_des", B > 1 ? s : -1, convention);
  }
  check_finite(x, B * nx, "x");
  check_finite(x_des, B * nx, "x_des");
  check_weights(Q, B * n2, "Q");
  const ModelView<double> mv = m.view();
  std::vector<double> scratch(m.nv * m.nv + m.nv);
  for (long s = 0; s < B; ++s)
    value[s] = rbd::quadratic_state_cost_tangent(mv, x + s * nx, x_des + s * nx, Q + s * n2, grad + s * n2,
                                                 H + s * n2 * n2, scratch.data(), convention);
}

void ee_pos_cost(const Model& m, long B, const double* q, const double* p_des, const double* W, int body,
                 const double* offset, double* value, double* grad, double* H, int convention) {
  check_convention(convention);
  check_configurations_in(m, B, q, "q", convention);
  check_finite(p_des, B * 3, "p_des");
  check_weights(W, B * 3, "W");
  if (offset) check_finite(offset, 3, "ee_offset");
  if (body < 0 || body >= m.nb()) throw std::invalid_argument("body: expected a body index below nb");
  const int nx = m.nq + m.nv;
  WorkspaceBuffer buf(m, kLinearWorkspace);
  const ModelView<double> mv = m.view();
  std::vector<double> scratch(ee_pos_cost_scratch(m.nq, m.nv));
  for (long s = 0; s < B; ++s)
    rbd::ee_pos_cost(mv, buf.get(), q + s * m.nq, p_des + s * 3, W + s * 3, body, offset, convention, value + s,
                     grad + s * nx, H + s * nx * nx, scratch.data());
}

void com_cost(const Model& m, long B, const double* q, const double* p_des, const double* W, double* value,
              double* grad, double* H, int convention) {
  check_convention(convention);
  check_configurations_in(m, B, q, "q", convention);
  check_finite(p_des, B * 3, "p_des");
  check_weights(W, B * 3, "W");
  const int nx = m.nq + m.nv;
  WorkspaceBuffer buf(m, kLinearWorkspace);
  const ModelView<double> mv = m.view();
  std::vector<double> scratch(com_cost_scratch(m.nq, m.nv));
  for (long s = 0; s < B; ++s)
    if (!rbd::com_cost(mv, buf.get(), q + s * m.nq, p_des + s * 3, W + s * 3, convention, value + s, grad + s * nx,
                       H + s * nx * nx, scratch.data()))
      throw std::runtime_error("com_cost: the robot has no mass (total mass 0), so its centre of mass is undefined");
}

void momentum_cost(const Model& m, long B, const double* q, const double* qd, const double* h_des, const double* W,
                   double* value, double* grad, double* H, int convention) {
  check_convention(convention);
  check_configurations_in(m, B, q, "q", convention);
  check_finite(qd, B * m.nv, "qd");
  check_finite(h_des, B * 6, "h_des");
  check_weights(W, B * 6, "W");
  const int n2 = 2 * m.nv;
  WorkspaceBuffer buf(m, kLinearWorkspace);
  const ModelView<double> mv = m.view();
  std::vector<double> scratch(momentum_cost_scratch(m.nq, m.nv));
  for (long s = 0; s < B; ++s)
    if (!rbd::momentum_cost(mv, buf.get(), q + s * m.nq, qd + s * m.nv, h_des + s * 6, W + s * 6, convention,
                            value + s, grad + s * n2, H + s * n2 * n2, scratch.data()))
      throw std::runtime_error("momentum_cost: the robot has no mass (total mass 0), so its centre of mass is "
                               "undefined");
}

void log_barrier(long B, int n, const double* x, const double* lower, const double* upper, double mu,
                 double* value, double* grad, double* Hdiag, const char* x_name) {
  check_finite(x, B * n, x_name);
  for (long k = 0; k < B * n; ++k) {
    if (std::isnan(lower[k]) || std::isnan(upper[k]) || lower[k] == INFINITY || upper[k] == -INFINITY ||
        lower[k] >= upper[k]) {
      std::ostringstream os;
      os << "lower, upper: expected lower < upper (infinite bounds allowed: -inf below, +inf above), got "
         << lower[k] << " and " << upper[k] << " at flat index " << k;
      throw std::invalid_argument(os.str());
    }
  }
  if (!std::isfinite(mu) || mu <= 0) {
    std::ostringstream os;
    os << "mu: expected a positive barrier weight, got " << mu;
    throw std::invalid_argument(os.str());
  }
  for (long s = 0; s < B; ++s)
    value[s] = rbd::log_barrier(n, x + s * n, lower + s * n, upper + s * n, mu, grad + s * n, Hdiag + s * n);
}

}  // namespace batch
}  // namespace rbd
