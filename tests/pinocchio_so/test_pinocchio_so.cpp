// tests/pinocchio_so/test_pinocchio_so.cpp — rbdkit's second-order inverse-
// dynamics derivatives (both IDSVA-SO recursions) against Pinocchio's
// ComputeRNEASecondOrderDerivatives (C++ only in Pinocchio 4), 1e-9 relative.
//
// The Pinocchio model is built from the rbdkit model body by body (the same
// joint placements, axes and inertias: RevoluteUnaligned, PrismaticUnaligned,
// HelicalUnaligned, Spherical, FreeFlyer), so every joint type of the test
// models is covered without Pinocchio's URDF reader; the models' URDF
// reading is checked against Pinocchio's own reader in tests/python. Mimic
// joints are independent joints in the Pinocchio model (v_pin = G v), and
// its tensors are contracted with G on every index.
//
// Conventions matched: d2tau_dqdq(i, j, k) and rbdkit's d2tau_dq2[i, j, k] are
// both ∂/∂q_k(∂tau_i/∂q_j) in the tangent space (k the outer derivative, also
// inside free-flyer and spherical joints); d2tau_dvdv, d2tau_dqdv
// (∂²tau_i/∂q_j∂v_k) and d2tau_dadq (∂M_ij/∂q_k) index like rbdkit's
// d2tau_dqd2, d2tau_dqdqd and dM_dq. Floating bases included.
//
//   test_pinocchio_so <robots dir> <test urdf dir>    exit 0: all agree
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <pinocchio/algorithm/rnea-second-order-derivatives.hpp>
#include <pinocchio/multibody.hpp>

#include "rbdkit/algorithms/idsva_so.hpp"
#include "rbdkit/batch/dynamics.hpp"

namespace {

constexpr double kTolerance = 1e-9;

// a Pinocchio model of the rbdkit model; G: the column of each Pinocchio
// velocity coordinate in rbdkit's and its factor (the mimic multiplier)
struct PinModel {
  pinocchio::Model model;
  std::vector<int> col;        // (pin nv) rbdkit column
  std::vector<double> factor;  // (pin nv)
};

PinModel to_pinocchio(const rbd::Model& m) {
  PinModel out;
  for (int i = 0; i < m.nb(); ++i) {
    const rbd::BodyDesc<double>& b = m.bodies[i];
    const Eigen::Vector3d axis(b.axis.x, b.axis.y, b.axis.z);
    Eigen::Matrix3d R;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R(r, c) = b.X_tree.R(r, c);
    const pinocchio::SE3 placement(R, Eigen::Vector3d(b.X_tree.p.x, b.X_tree.p.y, b.X_tree.p.z));
    const pinocchio::JointIndex parent = b.parent < 0 ? 0 : static_cast<pinocchio::JointIndex>(b.parent + 1);
    const std::string name = m.joints[i].name;
    pinocchio::JointIndex id = 0;
    switch (b.type) {
      case rbd::kRevolute: id = out.model.addJoint(parent, pinocchio::JointModelRevoluteUnaligned(axis), placement, name); break;
      case rbd::kPrismatic: id = out.model.addJoint(parent, pinocchio::JointModelPrismaticUnaligned(axis), placement, name); break;
      case rbd::kHelical: id = out.model.addJoint(parent, pinocchio::JointModelHelicalUnaligned(axis, b.pitch), placement, name); break;
      case rbd::kSpherical: id = out.model.addJoint(parent, pinocchio::JointModelSpherical(), placement, name); break;
      default: id = out.model.addJoint(parent, pinocchio::JointModelFreeFlyer(), placement, name); break;
    }
    // rbdkit: mass, first moment m·c, inertia about the body origin; Pinocchio: about the centre of mass
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    if (b.I.m > 0) c = Eigen::Vector3d(b.I.h.x, b.I.h.y, b.I.h.z) / b.I.m;
    Eigen::Matrix3d Io;
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) Io(r, k) = b.I.I(r, k);
    const Eigen::Matrix3d Ic = Io - b.I.m * (c.squaredNorm() * Eigen::Matrix3d::Identity() - c * c.transpose());
    out.model.appendBodyToJoint(id, pinocchio::Inertia(b.I.m, c, Ic), pinocchio::SE3::Identity());
    const int nvj = out.model.joints[id].nv();
    for (int a = 0; a < nvj; ++a) {
      out.col.push_back(b.v_idx + a);
      out.factor.push_back(b.mimic ? b.mult : 1.0);
    }
  }
  return out;
}

// rbdkit q -> Pinocchio q (mimic joints: mult·q + offset)
Eigen::VectorXd pin_q(const rbd::Model& m, const PinModel& pm, const std::vector<double>& q) {
  Eigen::VectorXd out(pm.model.nq);
  for (int i = 0; i < m.nb(); ++i) {
    const rbd::BodyDesc<double>& b = m.bodies[i];
    const auto& jm = pm.model.joints[i + 1];
    for (int a = 0; a < jm.nq(); ++a) out[jm.idx_q() + a] = b.mimic ? b.mult * q[b.q_idx] + b.offset : q[b.q_idx + a];
  }
  return out;
}

Eigen::VectorXd pin_v(const PinModel& pm, const std::vector<double>& v) {
  Eigen::VectorXd out(pm.model.nv);
  for (int k = 0; k < pm.model.nv; ++k) out[k] = pm.factor[k] * v[pm.col[k]];
  return out;
}

// Gᵀ-contraction of a Pinocchio tensor on every index, into rbdkit's [i][j][k] array
std::vector<double> reduce(const PinModel& pm, int nv, const pinocchio::Data::Tensor3x& T) {
  std::vector<double> out(static_cast<size_t>(nv) * nv * nv, 0.0);
  const int n = pm.model.nv;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        out[(static_cast<size_t>(pm.col[i]) * nv + pm.col[j]) * nv + pm.col[k]] +=
            pm.factor[i] * pm.factor[j] * pm.factor[k] * T(i, j, k);
      }
  return out;
}

// max |a - b| / max(1, max |b|)
double rel_err(const std::vector<double>& a, const std::vector<double>& b) {
  double e = 0, s = 1;
  for (size_t i = 0; i < a.size(); ++i) s = std::max(s, std::fabs(b[i]));
  for (size_t i = 0; i < a.size(); ++i) e = std::max(e, std::fabs(a[i] - b[i]));
  return e / s;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s <robots dir> <test urdf dir>\n", argv[0]);
    return 2;
  }
  std::vector<std::string> paths;
  for (const char* r : {"iiwa", "hyq", "atlas"}) paths.push_back(std::string(argv[1]) + "/" + r + ".urdf");
  for (const char* r : {"spherical", "helical", "planar", "mixed", "mimic"})
    paths.push_back(std::string(argv[2]) + "/" + r + ".urdf");

  const char* names[4] = {"d2tau_dq2", "d2tau_dqd2", "d2tau_dqdqd", "dM_dq"};
  int failures = 0;
  std::printf("rbdkit IDSVA-SO vs pinocchio::ComputeRNEASecondOrderDerivatives, max relative error (tolerance %.0e)\n",
              kTolerance);
  for (const std::string& path : paths)
    for (bool floating : {false, true}) {
      const rbd::Model m = rbd::Model::from_urdf_file(path, floating);
      const PinModel pm = to_pinocchio(m);
      pinocchio::Data pdata(pm.model);
      rbd::WorkspaceBuffer buf(m);
      const rbd::ModelView<double> mv = m.view();
      const int nv = m.nv;
      const size_t n3 = static_cast<size_t>(nv) * nv * nv;
      std::mt19937 rng(7);
      std::uniform_real_distribution<double> U(-1, 1);
      double worst[2][4] = {{0, 0, 0, 0}, {0, 0, 0, 0}};
      for (int sample = 0; sample < 3; ++sample) {
        // a random state; the last one fast
        std::vector<double> q0 = m.neutral(), d(nv), q(m.nq), qd(nv), qdd(nv);
        for (auto& x : d) x = 3 * U(rng);
        rbd::integrate(mv, q0.data(), d.data(), q.data());
        const double vs = sample == 2 ? 10.0 : 2.0;
        for (int k = 0; k < nv; ++k) qd[k] = vs * U(rng), qdd[k] = 3 * U(rng);

        // Pinocchio, reduced to rbdkit's coordinates
        pinocchio::ComputeRNEASecondOrderDerivatives(pm.model, pdata, pin_q(m, pm, q), pin_v(pm, qd), pin_v(pm, qdd));
        const std::vector<double> ref[4] = {reduce(pm, nv, pdata.d2tau_dqdq), reduce(pm, nv, pdata.d2tau_dvdv),
                                            reduce(pm, nv, pdata.d2tau_dqdv), reduce(pm, nv, pdata.d2tau_dadq)};
        for (int variant = 0; variant < 2; ++variant) {
          std::vector<double> T[4];
          for (auto& t : T) t.resize(n3);
          if (variant == 0)
            rbd::idsva_so_body_frame(mv, buf.get(), q.data(), qd.data(), qdd.data(), -9.81, T[0].data(), T[1].data(),
                                     T[2].data(), T[3].data());
          else
            rbd::idsva_so_world_frame(mv, buf.get(), q.data(), qd.data(), qdd.data(), -9.81, T[0].data(),
                                      T[1].data(), T[2].data(), T[3].data());
          for (int t = 0; t < 4; ++t) worst[variant][t] = std::max(worst[variant][t], rel_err(T[t], ref[t]));
        }
      }
      std::string label = path.substr(path.find_last_of('/') + 1);
      label = label.substr(0, label.find('.')) + (floating ? " floating" : " fixed");
      std::printf("  %-20s", label.c_str());
      bool ok = true;
      for (int variant = 0; variant < 2; ++variant) {
        std::printf("%s", variant == 0 ? " body:" : "  world:");
        for (int t = 0; t < 4; ++t) {
          std::printf(" %.1e", worst[variant][t]);
          if (!(worst[variant][t] <= kTolerance)) {
            ok = false;
            std::printf("(%s!)", names[t]);
          }
        }
      }
      std::printf("  %s\n", ok ? "ok" : "FAIL");
      failures += ok ? 0 : 1;
    }
  std::printf("%s\n", failures ? "test_pinocchio_so: FAILED" : "test_pinocchio_so: all agree");
  return failures ? 1 : 0;
}
