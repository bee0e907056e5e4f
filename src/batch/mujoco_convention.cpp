// Host entry points of the MuJoCo output convention.
#include "rbdkit/batch/mujoco_api.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace rbd {

int convention_from_name(const std::string& name) {
  if (name == "pinocchio") return kPinocchioConvention;
  if (name == "mujoco") return kMujocoConvention;
  throw std::invalid_argument("output_convention: unknown convention '" + name +
                              "'; expected one of pinocchio, mujoco");
}

void check_convention(int code) {
  if (code != kPinocchioConvention && code != kMujocoConvention) {
    std::ostringstream os;
    os << "output_convention: expected 0 (pinocchio) or 1 (mujoco), got " << code;
    throw std::invalid_argument(os.str());
  }
}

void check_configuration_in(const Model& m, const double* q, const char* arg, long sample, int convention) {
  check_convention(convention);
  if (convention == kPinocchioConvention) return check_configuration(m, q, arg, sample);
  std::ostringstream label;
  label << arg;
  if (sample >= 0) label << "[" << sample << "]";
  check_finite(q, m.nq, label.str().c_str());
  check_joint_angles(m, q, label.str().c_str());
  for (size_t i = 0; i < m.bodies.size(); ++i) {
    const int o = quat_offset(m.bodies[i]);
    if (o < 0) continue;
    const double n = std::sqrt(q[o] * q[o] + q[o + 1] * q[o + 1] + q[o + 2] * q[o + 2] + q[o + 3] * q[o + 3]);
    if (std::fabs(n - 1.0) > 1e-6) {
      std::ostringstream os;
      os << label.str() << ": the quaternion of joint '" << m.joints[i].name << "' (q[" << o << ":" << o + 4
         << "], w x y z, MuJoCo layout) must have unit norm, got norm " << n;
      throw std::invalid_argument(os.str());
    }
  }
}

void check_configurations_in(const Model& m, long B, const double* q, const char* arg, int convention) {
  for (long s = 0; s < B; ++s) check_configuration_in(m, q + s * m.nq, arg, B > 1 ? s : -1, convention);
}

namespace batch {

void state_to_mujoco(const Model& m, long B, const double* x, double* out) {
  const int nq = m.nq, nx = m.nq + m.nv;
  for (long s = 0; s < B; ++s) check_configuration_in(m, x + s * nx, "x", B > 1 ? s : -1, kPinocchioConvention);
  check_finite(x, B * nx, "x");
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) {
    const double* xs = x + s * nx;
    double* o = out + s * nx;
    configuration_to_mujoco(mv, xs, o);
    rotate_to_mujoco(mv, o, xs + nq, o + nq);
  }
}

void state_from_mujoco(const Model& m, long B, const double* x, double* out) {
  const int nq = m.nq, nx = m.nq + m.nv;
  for (long s = 0; s < B; ++s) check_configuration_in(m, x + s * nx, "x", B > 1 ? s : -1, kMujocoConvention);
  check_finite(x, B * nx, "x");
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) {
    const double* xs = x + s * nx;
    double* o = out + s * nx;
    rotate_from_mujoco(mv, xs, xs + nq, o + nq);
    configuration_from_mujoco(mv, xs, o);
  }
}

void force_to_mujoco(const Model& m, long B, const double* q_mj, const double* u, double* out) {
  check_configurations_in(m, B, q_mj, "qpos", kMujocoConvention);
  check_finite(u, B * m.nv, "u");
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) rotate_to_mujoco(mv, q_mj + s * m.nq, u + s * m.nv, out + s * m.nv);
}

void force_from_mujoco(const Model& m, long B, const double* q_mj, const double* u, double* out) {
  check_configurations_in(m, B, q_mj, "qpos", kMujocoConvention);
  check_finite(u, B * m.nv, "u");
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) rotate_from_mujoco(mv, q_mj + s * m.nq, u + s * m.nv, out + s * m.nv);
}

void mujoco_integrate(const Model& m, long B, const double* q, const double* v, double* out) {
  check_configurations_in(m, B, q, "qpos", kMujocoConvention);
  check_finite(v, B * m.nv, "v");
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) mj_integrate(mv, q + s * m.nq, v + s * m.nv, out + s * m.nq);
}

void mujoco_difference(const Model& m, long B, const double* q0, const double* q1, double* out) {
  check_configurations_in(m, B, q0, "qpos0", kMujocoConvention);
  check_configurations_in(m, B, q1, "qpos1", kMujocoConvention);
  const ModelView<double> mv = m.view();
  for (long s = 0; s < B; ++s) mj_difference(mv, q0 + s * m.nq, q1 + s * m.nq, out + s * m.nv);
}

}  // namespace batch
}  // namespace rbd
