// Kinematics identities and finite differences: frame Jacobians against
// differences of frame placements, dJ/dt against differences of J along qd,
// the dual-number and closed-form pose Hessians, Λ·(J M⁻¹ Jᵀ) = I, and the
// name checks. Pinocchio equivalence is in tests/python/test_kinematics.py.
#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <vector>

#include <Eigen/Dense>

#include "rbdkit/batch/kinematics_api.hpp"

using namespace rbd;

namespace {

using Vec = std::vector<double>;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

Model robot(const char* name, bool floating) {
  return Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/" + name + ".urdf", floating);
}
Model test_model(const char* name, bool floating) {
  return Model::from_urdf_file(std::string(RBDKIT_TEST_URDF_DIR) + "/" + name + ".urdf", floating);
}

Vec random_tangent(const Model& m, std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> U(-scale, scale);
  Vec v(m.nv);
  for (double& x : v) x = U(rng);
  return v;
}

Vec plus(const Model& m, const Vec& q, const Vec& dq, double h = 1) {
  Vec d(m.nv), out(m.nq);
  for (int k = 0; k < m.nv; ++k) d[k] = h * dq[k];
  batch::integrate(m, 1, q.data(), d.data(), out.data());
  return out;
}

Vec random_q(const Model& m, std::mt19937& rng) { return plus(m, m.neutral(), random_tangent(m, rng, 2.0)); }

Vec unit(int n, int k) {
  Vec e(n, 0.0);
  e[k] = 1;
  return e;
}

double max_abs(const Vec& a) {
  double s = 0;
  for (double x : a) s = std::max(s, std::fabs(x));
  return s;
}
double max_diff(const Vec& a, const Vec& b) {
  double s = 0;
  for (size_t k = 0; k < a.size(); ++k) s = std::max(s, std::fabs(a[k] - b[k]));
  return s;
}

// X_world_frame as Eigen (R, p)
void placement(const Model& m, const Vec& q, int frame, Eigen::Matrix3d& R, Eigen::Vector3d& p) {
  Vec Rv(9), pv(3);
  batch::frame_placement(m, 1, q.data(), frame, Rv.data(), pv.data());
  R = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(Rv.data());
  p = Eigen::Map<const Eigen::Vector3d>(pv.data());
}

const double kH = 1e-6;
}  // namespace

// WORLD columns: ω from Ṙ Rᵀ, v_O = ṗ - ω × p, by central differences of the placement
TEST(Kinematics, WorldFrameJacobianMatchesPlacementDifferences) {
  for (bool floating : {false, true}) {
    const Model m = robot("iiwa", floating);
    std::mt19937 rng(1);
    const Vec q = random_q(m, rng);
    for (const char* name : {"iiwa_link_7", "iiwa_joint_4", "iiwa_link_0"}) {
      const int f = frame_from_name(m, name);
      Vec J(6 * m.nv);
      batch::frame_jacobian(m, 1, q.data(), f, kWorld, J.data());
      Eigen::Matrix3d R, Rp, Rm;
      Eigen::Vector3d p, pp, pm;
      placement(m, q, f, R, p);
      for (int j = 0; j < m.nv; ++j) {
        placement(m, plus(m, q, unit(m.nv, j), kH), f, Rp, pp);
        placement(m, plus(m, q, unit(m.nv, j), -kH), f, Rm, pm);
        const Eigen::Matrix3d W = (Rp - Rm) / (2 * kH) * R.transpose();
        const Eigen::Vector3d w(W(2, 1), W(0, 2), W(1, 0));
        const Eigen::Vector3d v = (pp - pm) / (2 * kH) - w.cross(p);
        for (int r = 0; r < 3; ++r) {
          EXPECT_NEAR(J[r * m.nv + j], v[r], 1e-7) << name << " column " << j;
          EXPECT_NEAR(J[(r + 3) * m.nv + j], w[r], 1e-7) << name << " column " << j;
        }
      }
    }
  }
}

// dJ/dt = (J(q ⊕ h qd) - J(q ⊕ -h qd)) / 2h in every reference frame
TEST(Kinematics, JacobianTimeVariationMatchesDifferences) {
  for (const Model& m : {test_model("spherical", true), test_model("mimic", false), robot("hyq", true)}) {
    std::mt19937 rng(2);
    const Vec q = random_q(m, rng), qd = random_tangent(m, rng, 2.0);
    const int f = static_cast<int>(m.frames.size()) - 1;
    for (int rf : {kLocal, kWorld, kLocalWorldAligned}) {
      Vec dJ(6 * m.nv), Jp(6 * m.nv), Jm(6 * m.nv), fd(6 * m.nv);
      batch::frame_jacobian_dot(m, 1, q.data(), qd.data(), f, rf, dJ.data());
      const Vec qp = plus(m, q, qd, kH), qm = plus(m, q, qd, -kH);
      batch::frame_jacobian(m, 1, qp.data(), f, rf, Jp.data());
      batch::frame_jacobian(m, 1, qm.data(), f, rf, Jm.data());
      for (size_t k = 0; k < fd.size(); ++k) fd[k] = (Jp[k] - Jm[k]) / (2 * kH);
      EXPECT_LT(max_diff(dJ, fd), 1e-6 * std::max(1.0, max_abs(fd))) << m.name << " rf " << rf;
    }
  }
}

// the dual-number Hessian and the closed form agree to rounding, with offsets and several end effectors
TEST(Kinematics, PoseHessiansAgree) {
  for (const Model& m : {test_model("mixed", true), test_model("mimic", true), test_model("helical", false)}) {
    std::mt19937 rng(3);
    const Vec q = random_q(m, rng);
    EndEffectors ee;
    ee.bodies = leaf_bodies(m);
    Vec offsets(3 * ee.bodies.size());
    for (double& o : offsets) o = std::uniform_real_distribution<double>(-0.3, 0.3)(rng);
    ee.offsets = offsets.data();
    const long n = 6 * m.nv * m.nv * ee.size();
    Vec H(n), Ha(n);
    batch::end_effector_pose_hessian(m, 1, q.data(), ee, H.data());
    batch::end_effector_pose_hessian_analytic(m, 1, q.data(), ee, Ha.data());
    EXPECT_LT(max_diff(H, Ha), 1e-12 * std::max(1.0, max_abs(H))) << m.name;
    EXPECT_GT(max_abs(H), 1e-3) << m.name;
  }
}

// Λ (J M⁻¹ Jᵀ) = I with J the LOCAL_WORLD_ALIGNED Jacobian of the tool point
TEST(Kinematics, OscInertiaInvertsJMinvJt) {
  const Model m = robot("atlas", true);
  Dynamics d(m);
  std::mt19937 rng(4);
  const Vec q = random_q(m, rng);
  EndEffectors ee;
  ee.bodies = leaf_bodies(m);
  Vec offsets(3 * ee.bodies.size(), 0.05);
  ee.offsets = offsets.data();
  Vec L(36 * ee.size());
  batch::osc_inertia(m, 1, q.data(), ee, L.data());
  const RowMat Mi = d.minv(Eigen::Map<const Eigen::VectorXd>(q.data(), m.nq));
  WorkspaceBuffer buf(m);
  forward_kinematics(m.view(), buf.get(), q.data(), static_cast<const double*>(nullptr));
  for (long e = 0; e < ee.size(); ++e) {
    // the tool point's Jacobian: a frame at the offset
    const Transform<double> X = {Mat3<double>::identity(), {0.05, 0.05, 0.05}};
    RowMat J(6, m.nv);
    frame_jacobian(m.view(), buf.get(), ee.bodies[e], X, kLocalWorldAligned, J.data());
    const Eigen::Matrix<double, 6, 6, Eigen::RowMajor> Le(L.data() + 36 * e);
    const Eigen::Matrix<double, 6, 6> A = J * Mi * J.transpose();
    EXPECT_LT((Le * A - Eigen::Matrix<double, 6, 6>::Identity()).cwiseAbs().maxCoeff(), 1e-8) << "ee " << e;
  }
}

// roll-pitch-yaw angles rebuild the rotation, at and near gimbal lock too
TEST(Kinematics, RollPitchYawRebuildsRotation) {
  const Vec3<double> ex = {1, 0, 0}, ey = {0, 1, 0}, ez = {0, 0, 1};
  const double half_pi = std::acos(0.0);
  for (double pitch : {0.3, -1.2, half_pi, -half_pi, half_pi - 1e-9, -half_pi + 1e-12})
    for (double roll : {0.0, 0.7, -2.9})
      for (double yaw : {0.0, 1.1, 3.0}) {
        const Mat3<double> R = axis_angle(ez, yaw) * axis_angle(ey, pitch) * axis_angle(ex, roll);
        const Vec3<double> rpy = rpy_from_matrix(R);
        const Mat3<double> R2 = axis_angle(ez, rpy.z) * axis_angle(ey, rpy.y) * axis_angle(ex, rpy.x);
        for (int k = 0; k < 9; ++k) EXPECT_NEAR(R2.m[k], R.m[k], 1e-12) << roll << " " << pitch << " " << yaw;
        EXPECT_NEAR(rpy.y, pitch, 1e-7);
        if (std::fabs(pitch) < 1.5) {
          EXPECT_NEAR(rpy.x, roll, 1e-12);
          EXPECT_NEAR(rpy.z, yaw, 1e-12);
        }
      }
}

TEST(Kinematics, SingularOperationalSpaceIsAnError) {
  const Model m = robot("hyq", false);  // 3-DoF legs
  EndEffectors ee;
  ee.bodies = leaf_bodies(m);
  const Vec q = m.neutral();
  Vec L(36 * ee.size());
  EXPECT_THROW(batch::osc_inertia(m, 1, q.data(), ee, L.data()), std::invalid_argument);
}

TEST(Kinematics, NamesAreChecked) {
  const Model m = robot("iiwa", false);
  EXPECT_EQ(reference_frame_from_name("LOCAL"), kLocal);
  EXPECT_EQ(reference_frame_from_name("WORLD"), kWorld);
  EXPECT_EQ(reference_frame_from_name("LOCAL_WORLD_ALIGNED"), kLocalWorldAligned);
  auto message = [](auto fn) {
    try {
      fn();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_NE(message([] { reference_frame_from_name("world"); }).find("reference_frame: expected one of"),
            std::string::npos);
  EXPECT_NE(message([&] { frame_from_name(m, "nope"); }).find("frame_name: unknown frame 'nope'"), std::string::npos);
  EXPECT_NE(message([&] { end_effector_bodies(m, {"iiwa_joint_7", "nope"}); })
                .find("ee_joint_names: unknown joint 'nope'"),
            std::string::npos);
  EXPECT_NE(message([&] { end_effector_bodies(m, {"iiwa_base_joint"}); }).find("is fixed"), std::string::npos);
  EXPECT_EQ(end_effector_bodies(m, {"iiwa_joint_7", "iiwa_joint_2"}), (std::vector<int>{6, 1}));
  EXPECT_EQ(leaf_bodies(m), std::vector<int>{6});
  EXPECT_EQ(leaf_bodies(robot("hyq", true)).size(), 4u);
  // offsets are checked for finite values, naming the argument
  EndEffectors ee;
  ee.bodies = {6};
  const Vec bad = {0.0, std::nan(""), 0.0};
  ee.offsets = bad.data();
  Vec q = m.neutral(), pose(6);
  EXPECT_NE(message([&] { batch::end_effector_pose(m, 1, q.data(), ee, pose.data()); }).find("ee_offsets"),
            std::string::npos);
}
