// Model: lookups by name, the neutral configuration and the derived
// per-body sizes the algorithms read.
#include "rbdkit/parsers/model.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "rbdkit/algorithms/regressor.hpp"
#include "rbdkit/model/configuration.hpp"

namespace rbd {

bool Model::has_mimic() const {
  for (const auto& b : bodies)
    if (b.mimic) return true;
  return false;
}

bool Model::general_path() const { return has_mimic() || !subtrees_contiguous(bodies.data(), nb()); }

void Model::finalize() {
  // 1-DoF axes along a frame axis: the kinematics then turn two columns instead of multiplying 3x3s
  for (auto& b : bodies) {
    const double a[3] = {b.axis.x, b.axis.y, b.axis.z};
    b.axis_k = 0;
    for (int k = 0; k < 3; ++k)
      if (std::abs(a[k]) == 1.0 && a[(k + 1) % 3] == 0.0 && a[(k + 2) % 3] == 0.0) b.axis_k = k + 1;
  }
  // velocity coordinates in each subtree (children come after parents)
  for (auto& b : bodies) b.nv_subtree = b.mimic ? 0 : b.nv;
  for (int i = nb() - 1; i >= 0; --i)
    if (bodies[i].parent >= 0) bodies[bodies[i].parent].nv_subtree += bodies[i].nv_subtree;
}

std::vector<std::string> Model::joint_names() const {
  std::vector<std::string> out;
  for (const auto& j : joints)
    if (j.mimic_of.empty()) out.push_back(j.name);
  return out;
}

std::vector<std::string> Model::frame_names() const {
  std::vector<std::string> out;
  for (const auto& f : frames) out.push_back(f.name);
  return out;
}

namespace {
// a short list of known names sharing a prefix with the unknown one
std::string suggestions(const std::string& name, const std::vector<std::string>& known) {
  std::vector<std::string> close;
  for (const auto& k : known) {
    size_t p = 0;
    while (p < k.size() && p < name.size() && k[p] == name[p]) ++p;
    if (p >= 3 || k.find(name) != std::string::npos) close.push_back(k);
  }
  std::string s;
  const auto& list = close.empty() ? known : close;
  for (size_t i = 0; i < list.size() && i < 8; ++i) s += (i ? ", '" : "'") + list[i] + "'";
  if (list.size() > 8) s += ", ...";
  return s;
}
}  // namespace

int Model::frame_index(const std::string& frame) const {
  for (size_t i = 0; i < frames.size(); ++i)
    if (frames[i].name == frame) return static_cast<int>(i);
  throw std::invalid_argument("unknown frame '" + frame + "' in robot '" + name + "'; known frames include " +
                              suggestions(frame, frame_names()));
}

int Model::joint_index(const std::string& joint) const {
  std::vector<std::string> names;
  for (size_t i = 0; i < joints.size(); ++i) {
    if (joints[i].name == joint) return static_cast<int>(i);
    names.push_back(joints[i].name);
  }
  throw std::invalid_argument("unknown joint '" + joint + "' in robot '" + name + "'; known joints include " +
                              suggestions(joint, names));
}

std::vector<double> Model::neutral() const {
  std::vector<double> q(nq);
  rbd::neutral(view(), q.data());
  return q;
}

std::vector<double> Model::inertial_parameters() const {
  std::vector<double> pi(10 * bodies.size());
  for (size_t b = 0; b < bodies.size(); ++b) inertia_to_parameters(bodies[b].I, pi.data() + 10 * b);
  return pi;
}

namespace {
const char* kParameterNames[10] = {"m", "m*c_x", "m*c_y", "m*c_z", "I_xx", "I_xy", "I_yy", "I_xz", "I_yz", "I_zz"};

// throws std::invalid_argument unless pi_b is a physically consistent rigid
// body: m >= 0, h = 0 when m = 0, and the rotational inertia about the centre
// of mass I_c = I - (|h|² 1 - h hᵀ)/m positive semi-definite with principal
// moments obeying the triangle inequalities (the pseudo-inertia is PSD)
void check_consistent(const Model& model, int b, const double* pi) {
  auto fail = [&](const std::string& why) {
    std::ostringstream os;
    os << "pi: link '" << model.body_names[b] << "' (body " << b << ", pi[" << 10 * b << ":" << 10 * b + 10
       << "]): " << why;
    throw std::invalid_argument(os.str());
  };
  const double m = pi[0];
  const Eigen::Vector3d h(pi[1], pi[2], pi[3]);
  Eigen::Matrix3d I;
  I << pi[4], pi[5], pi[7], pi[5], pi[6], pi[8], pi[7], pi[8], pi[9];
  if (m < 0) {
    std::ostringstream os;
    os << "negative mass m = " << m << " (mass must be >= 0)";
    fail(os.str());
  }
  if (m == 0 && h.squaredNorm() > 0) {
    std::ostringstream os;
    os << "zero mass with a non-zero first moment m*c = (" << h(0) << ", " << h(1) << ", " << h(2)
       << ") (a massless body has m*c = 0)";
    fail(os.str());
  }
  Eigen::Matrix3d Ic = I;
  if (m > 0) Ic -= (h.squaredNorm() * Eigen::Matrix3d::Identity() - h * h.transpose()) / m;
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(Ic, Eigen::EigenvaluesOnly).eigenvalues();
  const double tol = 1e-10 * std::fabs(I.trace());  // rounding of I - m [c]ᵀ[c]
  std::ostringstream moments;
  moments << "principal moments " << ev(0) << ", " << ev(1) << ", " << ev(2);
  if (ev(0) < -tol)
    fail("the rotational inertia about the centre of mass is not positive semi-definite (" + moments.str() + ")");
  // ascending: the largest moment is the only one that can exceed the sum of the other two
  if (ev(2) > ev(0) + ev(1) + tol)
    fail("the rotational inertia about the centre of mass violates the triangle inequality (" + moments.str() +
         ": the largest exceeds the sum of the other two)");
}
}  // namespace

Model Model::with_inertial_parameters(const std::vector<double>& pi) const {
  const size_t n = 10 * bodies.size();
  if (pi.size() != n) {
    std::ostringstream os;
    os << "pi: expected 10*nb = " << n << " inertial parameters (10 per body, nb = " << bodies.size() << "), got "
       << pi.size();
    throw std::invalid_argument(os.str());
  }
  for (size_t k = 0; k < n; ++k)
    if (!std::isfinite(pi[k])) {
      std::ostringstream os;
      os << "pi: expected finite values, got " << pi[k] << " at index " << k << " (" << kParameterNames[k % 10]
         << " of link '" << body_names[k / 10] << "')";
      throw std::invalid_argument(os.str());
    }
  Model out = *this;
  for (int b = 0; b < nb(); ++b) {
    const double* p = pi.data() + 10 * b;
    double old[10];
    inertia_to_parameters(bodies[b].I, old);
    if (std::equal(p, p + 10, old)) continue;  // unchanged: kept as read
    check_consistent(*this, b, p);
    out.bodies[b].I = inertia_from_parameters(p);
  }
  return out;
}

}  // namespace rbd
