// The operation registry (include/rbdkit/ops/): every registered operation,
// on every test model, through rbd::Handle's serial loop (against the
// checked batch:: entry points where one exists), the engine in float64
// (equal to the serial loop, bit-identical whatever the thread count) and
// float32 (within the family's bound), with broadcast inputs and f_ext.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "rbdkit/batch/centroidal_api.hpp"
#include "rbdkit/batch/costs_api.hpp"
#include "rbdkit/batch/derivatives_api.hpp"
#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/batch/integrators_api.hpp"
#include "rbdkit/batch/kinematics_api.hpp"
#include "rbdkit/batch/mujoco_api.hpp"
#include "rbdkit/batch/regressor_api.hpp"
#include "rbdkit/batch/second_order_api.hpp"
#include "rbdkit/handle/handle.hpp"
#include "rbdkit/ops/registry.hpp"
#include "rbdkit/ops/table.hpp"
#include "rbdkit/parsers/builder.hpp"
#include "registry_helpers.hpp"
#include "test_models.hpp"

using rbd::Model;
using rbd_test::max_rel_err;
using rbd_test::ModelCase;
using namespace rbd_test;
namespace ops = rbd::ops;

namespace {

class RegistryModels : public ::testing::TestWithParam<ModelCase> {};

}  // namespace

TEST(Registry, TableFollowsTheList) {
  ASSERT_EQ(static_cast<int>(ops::op_table().size()), ops::AllOps::size);
  for (const ops::OpEntry& e : ops::op_table()) {
    EXPECT_EQ(ops::find_op(e.spec->name), e.id);
    EXPECT_NE(rbd::algorithm_of(e.spec->name), "") << e.spec->name << " is in no handle algorithm";
    EXPECT_EQ(rbd::algorithm_of(e.spec->name), e.spec->algorithm) << e.spec->name;
    EXPECT_LE(e.spec->n_args, ops::kMaxArgs);
    EXPECT_NE(e.spec->returns, 0u);
  }
  EXPECT_EQ(ops::find_op("no_such_operation"), -1);
}

// the serial loop against the checked batch:: entry points (tested against Pinocchio)
TEST_P(RegistryModels, SerialLoopEqualsTheBatchEntryPoints) {
  const ModelCase& mc = GetParam();
  const Model m = Model::from_urdf_file(mc.path, mc.floating);
  rbd::Handle h(m);
  const long B = 3;
  for (const char* name :
       {"inverse_dynamics", "crba", "minv", "aba", "forward_dynamics", "inverse_dynamics_gradient", "integrate",
        "integrator", "kinetic_energy", "potential_energy", "mechanical_energy", "coriolis_matrix", "com",
        "jacobian_com", "ccrba", "centroidal_momentum", "dccrba", "cmm_time_variation",
        "centroidal_momentum_time_variation", "centroidal_dynamics_derivatives", "inverse_dynamics_regressor",
        "kinetic_energy_regressor", "potential_energy_regressor", "f_ext_gradient", "idsva_so_body_frame",
        "idsva_so_world_frame", "idsva_so", "fdsva_so", "state_to_mujoco", "state_from_mujoco", "force_to_mujoco",
        "force_from_mujoco", "mujoco_integrate", "mujoco_difference", "inverse_dynamics_fpass",
        "inverse_dynamics_bpass", "minv_bpass", "minv_fpass", "inverse_dynamics_gradient_fpass_dq",
        "inverse_dynamics_gradient_fpass_dqd", "inverse_dynamics_gradient_bpass_dq",
        "inverse_dynamics_gradient_bpass_dqd", "dccrba_fd", "cmm_time_variation_fd",
        "inverse_dynamics_regressor_gradient", "forward_dynamics_parameter_gradient", "quadratic_state_cost_tangent",
        "com_cost", "momentum_cost", "forward_kinematics", "frame_placement", "frame_jacobian", "frame_jacobian_dot",
        "ee_pos_cost", "end_effector_pose", "end_effector_pose_gradient", "end_effector_pose_hessian_analytic",
        "osc_inertia", "plant_step_hessian", "d2Integrate", "end_effector_pose_hessian"}) {
    SCOPED_TRACE(name);
    const int id = ops::find_op(name);
    const ops::OpSpec& op = *ops::op_table()[id].spec;
    if (op.model == ops::kNoMimic && m.has_mimic()) continue;  // RequirementsAreChecked
    const Inputs in = make_inputs(m, op, B, 3, true);
    if (op.failure == ops::kOscSingular && !six_dof_reach(m, in.ee)) continue;  // EngineEqualsSerialLoop
    const std::vector<double> got = run<double>(h, id, in, op.returns);  // what RBD returns
    const long w = static_cast<long>(got.size()) / B, nv = m.nv;
    std::vector<double> ref(B * w), tau(B * nv), v(B * m.nb() * 6), a(B * m.nb() * 6), f(B * m.nb() * 6);
    auto in_of = [&](int k) { return in.arrays[k].empty() ? nullptr : in.arrays[k].data(); };
    const std::string n = name;
    // outputs written one array after the other (B samples each) into ref's per-sample layout
    auto interleave = [&](std::initializer_list<std::vector<double>*> parts) {
      long o = 0;
      for (std::vector<double>* p : parts) {
        const long blk = static_cast<long>(p->size()) / B;
        for (long s = 0; s < B; ++s) std::copy_n(p->data() + s * blk, blk, ref.data() + s * w + o);
        o += blk;
      }
    };
    if (n == "inverse_dynamics") {
      rbd::batch::inverse_dynamics(m, B, in_of(0), in_of(1), in_of(2), in_of(4), -9.81, tau.data(), v.data(), a.data(),
                                   f.data());
      for (long s = 0; s < B; ++s) {
        double* r = ref.data() + s * w;
        std::copy_n(tau.data() + s * nv, nv, r);
        std::copy_n(v.data() + s * m.nb() * 6, m.nb() * 6, r + nv);
        std::copy_n(a.data() + s * m.nb() * 6, m.nb() * 6, r + nv + m.nb() * 6);
        std::copy_n(f.data() + s * m.nb() * 6, m.nb() * 6, r + nv + 12 * m.nb());
      }
    } else if (n == "crba") {
      rbd::batch::crba(m, B, in_of(0), ref.data());
    } else if (n == "minv") {
      rbd::batch::minv(m, B, in_of(0), true, ref.data());
    } else if (n == "aba") {
      rbd::batch::aba(m, B, in_of(0), in_of(1), in_of(2), in_of(3), -9.81, ref.data());
    } else if (n == "forward_dynamics") {
      rbd::batch::forward_dynamics(m, B, in_of(0), in_of(1), in_of(2), in_of(3), -9.81, ref.data());
    } else if (n == "inverse_dynamics_gradient") {
      rbd::batch::inverse_dynamics_gradient(m, B, in_of(0), in_of(1), in_of(2), in_of(4), -9.81, ref.data());
    } else if (n == "integrate") {
      rbd::batch::integrate(m, B, in_of(0), in_of(1), ref.data());
    } else if (n == "integrator") {
      rbd::batch::integrator(m, B, in_of(0), in_of(1), in_of(2), in_of(5), 0.01, -9.81, rbd::kEuler, ref.data());
    } else if (n == "kinetic_energy") {
      rbd::batch::kinetic_energy(m, B, in_of(0), in_of(1), ref.data());
    } else if (n == "potential_energy") {
      rbd::batch::potential_energy(m, B, in_of(0), -9.81, ref.data());
    } else if (n == "mechanical_energy") {
      rbd::batch::mechanical_energy(m, B, in_of(0), in_of(1), -9.81, ref.data());
    } else if (n == "coriolis_matrix") {
      rbd::batch::coriolis_matrix(m, B, in_of(0), in_of(1), ref.data());
    } else if (n == "com") {
      rbd::batch::center_of_mass(m, B, in_of(0), ref.data());
    } else if (n == "jacobian_com") {
      rbd::batch::jacobian_com(m, B, in_of(0), ref.data());
    } else if (n == "ccrba") {  // per sample A (6 x nv) then h (6)
      std::vector<double> A(B * 6 * nv), h(B * 6);
      rbd::batch::ccrba(m, B, in_of(0), in_of(1), A.data(), h.data());
      for (long s = 0; s < B; ++s) {
        std::copy_n(A.data() + s * 6 * nv, 6 * nv, ref.data() + s * w);
        std::copy_n(h.data() + s * 6, 6, ref.data() + s * w + 6 * nv);
      }
    } else if (n == "centroidal_momentum") {
      rbd::batch::centroidal_momentum(m, B, in_of(0), in_of(1), ref.data());
    } else if (n == "dccrba") {
      rbd::batch::dccrba(m, B, in_of(0), ref.data());
    } else if (n == "dccrba_fd") {
      rbd::batch::dccrba_fd(m, B, in_of(0), 1e-5, ref.data());
    } else if (n == "cmm_time_variation_fd") {
      rbd::batch::cmm_time_variation_fd(m, B, in_of(0), in_of(1), 1e-5, ref.data());
    } else if (n == "inverse_dynamics_fpass") {
      rbd::batch::inverse_dynamics_fpass(m, B, in_of(0), in_of(1), in_of(2), in_of(4), -9.81, v.data(), a.data(),
                                         f.data());
      interleave({&v, &a, &f});
    } else if (n == "inverse_dynamics_bpass") {
      rbd::batch::inverse_dynamics_bpass(m, B, in_of(0), in_of(1), tau.data(), f.data());
      interleave({&tau, &f});
    } else if (n == "minv_bpass") {
      rbd::batch::minv_bpass(m, B, in_of(0), ref.data());
    } else if (n == "minv_fpass") {
      rbd::batch::minv_fpass(m, B, in_of(0), in_of(1), ref.data());
    } else if (n.rfind("inverse_dynamics_gradient_fpass", 0) == 0) {
      std::vector<double> c1(B * m.nb() * 36), c2(B * m.nb() * 36);
      rbd::batch::inverse_dynamics_gradient_fpass(m, B, in_of(0), in_of(1), in_of(2), -9.81, n.back() == 'q' ? 0 : 1,
                                                  c1.data(), c2.data());
      interleave({&c1, &c2});
    } else if (n.rfind("inverse_dynamics_gradient_bpass", 0) == 0) {
      rbd::batch::inverse_dynamics_gradient_bpass(m, B, in_of(0), in_of(1), in_of(2), -9.81, n.back() == 'q' ? 0 : 1,
                                                  in_of(3), in_of(4), ref.data());
    } else if (n == "inverse_dynamics_regressor_gradient") {
      rbd::batch::inverse_dynamics_regressor_gradient(m, B, in_of(0), in_of(1), in_of(2), -9.81, ref.data());
    } else if (n == "forward_dynamics_parameter_gradient") {
      rbd::batch::forward_dynamics_parameter_gradient(m, B, in_of(0), in_of(1), in_of(2), -9.81, ref.data());
    } else if (n == "quadratic_state_cost_tangent" || n == "com_cost" || n == "momentum_cost") {
      const long nx = static_cast<long>(std::sqrt(double(w - 1)));  // w = 1 + n + n²
      std::vector<double> val(B), g(B * nx), H(B * nx * nx);
      if (n == "com_cost")
        rbd::batch::com_cost(m, B, in_of(0), in_of(1), in_of(2), val.data(), g.data(), H.data());
      else if (n == "momentum_cost")
        rbd::batch::momentum_cost(m, B, in_of(0), in_of(1), in_of(2), in_of(3), val.data(), g.data(), H.data());
      else
        rbd::batch::quadratic_state_cost_tangent(m, B, in_of(0), in_of(1), in_of(2), val.data(), g.data(), H.data());
      interleave({&val, &g, &H});
    } else if (n == "forward_kinematics") {
      std::vector<double> R(B * m.nb() * 9), p(B * m.nb() * 3);
      rbd::batch::forward_kinematics(m, B, in_of(0), R.data(), p.data());
      interleave({&R, &p});
    } else if (n == "frame_placement") {
      std::vector<double> R(B * 9), p(B * 3);
      rbd::batch::frame_placement(m, B, in_of(0), in.call.choice[1], R.data(), p.data());
      interleave({&R, &p});
    } else if (n == "frame_jacobian") {
      rbd::batch::frame_jacobian(m, B, in_of(0), in.call.choice[1], in.call.choice[2], ref.data());
    } else if (n == "frame_jacobian_dot") {
      rbd::batch::frame_jacobian_dot(m, B, in_of(0), in_of(1), in.call.choice[2], in.call.choice[3], ref.data());
    } else if (n == "d2Integrate") {  // arg1, arg2 = 'v', 'v' (the defaults)
      rbd::batch::d2integrate(m, B, in_of(0), in_of(1), 1, 1, ref.data());
    } else if (n.rfind("end_effector_pose", 0) == 0) {  // the leaf bodies, each sample's tool points
      rbd::EndEffectors ee;
      ee.bodies = in.ee;
      ee.offsets = in_of(n.rfind("end_effector_pose_hessian", 0) == 0 ? 1 : 2);
      if (n == "end_effector_pose") rbd::batch::end_effector_pose(m, B, in_of(0), ee, ref.data());
      else if (n == "end_effector_pose_gradient") rbd::batch::end_effector_pose_gradient(m, B, in_of(0), ee, ref.data());
      else if (n == "end_effector_pose_hessian") rbd::batch::end_effector_pose_hessian(m, B, in_of(0), ee, ref.data());
      else rbd::batch::end_effector_pose_hessian_analytic(m, B, in_of(0), ee, ref.data());
    } else if (n == "plant_step_hessian") {  // x split into q and qd; euler, Pinocchio's convention
      const long nx = m.nq + nv;
      std::vector<double> q(B * m.nq), qd(B * nv), xn(B * nx), AB(B * 6 * nv * nv);
      for (long s = 0; s < B; ++s) {
        std::copy_n(in_of(0) + s * nx, m.nq, q.data() + s * m.nq);
        std::copy_n(in_of(0) + s * nx + m.nq, nv, qd.data() + s * nv);
      }
      rbd::batch::plant_step_hessian(m, B, q.data(), qd.data(), in_of(1), in.call.real[2], -9.81, rbd::kEuler,
                                     xn.data(), AB.data(), ref.data());
    } else if (n == "osc_inertia") {
      rbd::EndEffectors ee;
      ee.bodies = in.ee;
      ee.offsets = in_of(2);
      rbd::batch::osc_inertia(m, B, in_of(0), ee, ref.data());
    } else if (n == "ee_pos_cost") {  // the default end effector, each sample's own tool point
      const long nx = m.nq + nv;
      std::vector<double> val(B), g(B * nx), H(B * nx * nx);
      for (long s = 0; s < B; ++s)
        rbd::batch::ee_pos_cost(m, 1, in_of(0) + s * m.nq, in_of(1) + 3 * s, in_of(2) + 3 * s,
                                rbd::leaf_bodies(m).front(), in_of(4) + 3 * s, val.data() + s, g.data() + s * nx,
                                H.data() + s * nx * nx);
      interleave({&val, &g, &H});
    } else if (n == "cmm_time_variation") {
      rbd::batch::cmm_time_variation(m, B, in_of(0), in_of(1), ref.data());
    } else if (n == "centroidal_momentum_time_variation") {
      rbd::batch::centroidal_momentum_time_variation(m, B, in_of(0), in_of(1), in_of(2), ref.data());
    } else if (n == "centroidal_dynamics_derivatives") {  // per sample the four (6 x nv) blocks
      std::vector<double> d(4 * B * 6 * nv);
      const long blk = 6 * nv;
      rbd::batch::centroidal_dynamics_derivatives(m, B, in_of(0), in_of(1), in_of(2), d.data(), d.data() + B * blk,
                                                  d.data() + 2 * B * blk, d.data() + 3 * B * blk);
      for (long s = 0; s < B; ++s)
        for (int o = 0; o < 4; ++o) std::copy_n(d.data() + (o * B + s) * blk, blk, ref.data() + s * w + o * blk);
    } else if (n == "inverse_dynamics_regressor") {
      rbd::batch::inverse_dynamics_regressor(m, B, in_of(0), in_of(1), in_of(2), -9.81, ref.data());
    } else if (n == "kinetic_energy_regressor") {
      rbd::batch::kinetic_energy_regressor(m, B, in_of(0), in_of(1), ref.data());
    } else if (n == "f_ext_gradient") {  // per sample the two (nb x nv x 6) blocks
      const long blk = m.nb() * nv * 6;
      std::vector<double> d(2 * B * blk);
      rbd::batch::fext_gradient(m, B, in_of(0), d.data(), d.data() + B * blk);
      for (long s = 0; s < B; ++s)
        for (int o = 0; o < 2; ++o) std::copy_n(d.data() + (o * B + s) * blk, blk, ref.data() + s * w + o * blk);
    } else if (n.rfind("idsva_so", 0) == 0 || n == "fdsva_so") {  // per sample the four (nv x nv x nv) blocks
      const long blk = nv * nv * nv;
      std::vector<double> d(4 * B * blk);
      double* o[4] = {d.data(), d.data() + B * blk, d.data() + 2 * B * blk, d.data() + 3 * B * blk};
      if (n == "fdsva_so")
        rbd::batch::fdsva_so(m, B, in_of(0), in_of(1), in_of(2), -9.81, o[0], o[1], o[2], o[3]);
      else
        rbd::batch::idsva_so(m, B, in_of(0), in_of(1), in_of(2), -9.81,
                             n == "idsva_so" ? rbd::kSoAuto : n == "idsva_so_body_frame" ? rbd::kSoBodyFrame
                                                                                         : rbd::kSoWorldFrame,
                             o[0], o[1], o[2], o[3]);
      for (long s = 0; s < B; ++s)
        for (int k = 0; k < 4; ++k) std::copy_n(o[k] + s * blk, blk, ref.data() + s * w + k * blk);
    } else if (n == "state_to_mujoco") {
      rbd::batch::state_to_mujoco(m, B, in_of(0), ref.data());
    } else if (n == "state_from_mujoco") {
      rbd::batch::state_from_mujoco(m, B, in_of(0), ref.data());
    } else if (n == "force_to_mujoco") {
      rbd::batch::force_to_mujoco(m, B, in_of(0), in_of(1), ref.data());
    } else if (n == "force_from_mujoco") {
      rbd::batch::force_from_mujoco(m, B, in_of(0), in_of(1), ref.data());
    } else if (n == "mujoco_integrate") {
      rbd::batch::mujoco_integrate(m, B, in_of(0), in_of(1), ref.data());
    } else if (n == "mujoco_difference") {
      rbd::batch::mujoco_difference(m, B, in_of(0), in_of(1), ref.data());
    } else {
      ASSERT_EQ(n, "potential_energy_regressor");
      rbd::batch::potential_energy_regressor(m, B, in_of(0), -9.81, ref.data());
    }
    EXPECT_LE(max_rel_err(got, ref), 1e-14);
  }
}

// every registered operation on the engine: float64 equal to the serial loop
// (bit-identical whatever the thread count), float32 within its family's
// bound; f_ext taken; an unbatched input broadcast
TEST_P(RegistryModels, EngineEqualsSerialLoop) {
  const ModelCase& mc = GetParam();
  const Model m = Model::from_urdf_file(mc.path, mc.floating);
  rbd::Handle serial(m), e1(m, {}, 1), e2(m, {}, 2), f32(m, {}, 2, "float32");
  const long B = 11;
  for (const ops::OpEntry& e : ops::op_table()) {
    const ops::OpSpec& op = *e.spec;
    SCOPED_TRACE(op.name);
    if (op.model == ops::kNoMimic && m.has_mimic()) continue;  // RequirementsAreChecked
    const Inputs in = make_inputs(m, op, B, 5, true);
    if (op.failure == ops::kOscSingular && !six_dof_reach(m, in.ee)) {  // Λ is undefined there
      EXPECT_THROW(run<double>(e2, e.id, in), std::invalid_argument);
      continue;
    }
    const long w = sample_width(m, op, in.call.n_ee);
    const std::vector<double> ref = run<double>(serial, e.id, in);
    const std::vector<double> r1 = run<double>(e1, e.id, in), r2 = run<double>(e2, e.id, in);
    ASSERT_EQ(r1.size(), r2.size());
    EXPECT_EQ(std::memcmp(r1.data(), r2.data(), r1.size() * sizeof(double)), 0) << "1 and 2 threads differ";
    // the engine's sin and cos are within an ulp of libm's; M⁻¹ amplifies that by cond(M)
    const double tol = float32_bound(op) > 1e-4 ? 1e-8 : 1e-11;
    for (long s = 0; s < B; ++s) EXPECT_LE(max_rel_err(sample_of(r1, w, s), sample_of(ref, w, s)), tol) << "sample " << s;
    const std::vector<double> r32 = run<float>(f32, e.id, in);
    for (long s = 0; s < B; ++s)
      EXPECT_LE(max_rel_err(sample_of(r32, w, s), sample_of(ref, w, s)), float32_bound(op)) << "float32 sample " << s;
    // the first array unbatched: every sample sees sample 0's values
    Inputs bc = in;
    bc.call.batched[0] = false;
    const std::vector<double> rb = run<double>(e2, e.id, bc), rs = run<double>(serial, e.id, bc);
    for (long s = 0; s < B; ++s) {
      Inputs one = in;
      one.call.B = 1;
      one.B = 1;
      for (int k = 1; k < op.n_args; ++k) one.first[k] = s;
      const std::vector<double> r = run<double>(serial, e.id, one);
      EXPECT_LE(max_rel_err(sample_of(rs, w, s), r), 0.0) << "serial broadcast, sample " << s;
      EXPECT_LE(max_rel_err(sample_of(rb, w, s), r), tol) << "engine broadcast, sample " << s;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Models, RegistryModels, ::testing::ValuesIn(rbd_test::all_cases()), rbd_test::case_name);

TEST(Registry, ChecksNameTheArgumentAndSample) {
  const Model m = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", true);
  auto message = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const std::exception& e) {
      return e.what();
    }
    return "";
  };
  for (const char* dtype : {"float64", "float32"}) {
    rbd::Handle h(m, {}, 0, dtype);
    const int id = ops::find_op("aba");
    Inputs in = make_inputs(m, *ops::op_table()[id].spec, 2, 1, false);
    auto run_any = [&](const Inputs& x) {
      if (std::string(dtype) == "float64") run<double>(h, id, x);
      else run<float>(h, id, x);
    };
    Inputs bad = in;
    bad.arrays[0][m.nq + 3] = 2.0;  // sample 1's free-flyer quaternion
    bad.call.in[0] = bad.arrays[0].data();
    EXPECT_NE(message([&] { run_any(bad); }).find("q[1]: the quaternion of joint 'root_joint'"), std::string::npos);
    bad = in;
    bad.arrays[1][m.nv + 2] = std::nan("");
    bad.call.in[1] = bad.arrays[1].data();
    EXPECT_EQ(message([&] { run_any(bad); }).rfind("qd[1]: expected finite values, got nan at flat index 2", 0), 0u);
    bad = in;
    bad.arrays[2][1] = 1e20;  // beyond float32's bound, within float64's
    bad.call.in[2] = bad.arrays[2].data();
    const std::string msg = message([&] { run_any(bad); });
    if (std::string(dtype) == "float32") EXPECT_EQ(msg.rfind("tau[0]: expected values of magnitude at most 1e+15", 0), 0u) << msg;
    else EXPECT_EQ(msg, "");
    bad = in;
    bad.call.real[4] = std::nan("");
    EXPECT_EQ(message([&] { run_any(bad); }).rfind("gravity: expected a finite number", 0), 0u);
    // a configuration in MuJoCo's layout: its quaternion is checked there (w x y z)
    const int mj = ops::find_op("mujoco_integrate");
    Inputs qpos = make_inputs(m, *ops::op_table()[mj].spec, 2, 1, false);
    qpos.arrays[0][m.nq + 3] *= 1.5;  // sample 1's free-flyer quaternion
    qpos.call.in[0] = qpos.arrays[0].data();
    const std::string mj_msg = message([&] {
      if (std::string(dtype) == "float64") run<double>(h, mj, qpos);
      else run<float>(h, mj, qpos);
    });
    EXPECT_NE(mj_msg.find("qpos[1]: the quaternion of joint 'root_joint'"), std::string::npos) << mj_msg;
    EXPECT_NE(mj_msg.find("w x y z, MuJoCo layout"), std::string::npos) << mj_msg;
  }
  // an operation the handle was not built with names the algorithm to add
  rbd::Handle only_crba(m, {"crba"});
  EXPECT_FALSE(only_crba.has("aba"));
  EXPECT_TRUE(only_crba.has("crba"));
  const int id = ops::find_op("aba");
  const Inputs in = make_inputs(m, *ops::op_table()[id].spec, 1, 1, false);
  EXPECT_EQ(message([&] { run<double>(only_crba, id, in); }).rfind("aba: this handle was not built with it", 0), 0u);
}

// a robot of total mass 0 has no centre of mass: every centroidal operation
// fails with that message (kNoMass) on the serial loop and on the engine
// (float64 and float32), not with the massless joint's singular mass matrix
TEST(Registry, MasslessRobotHasNoCentreOfMass) {
  const Model m = Model::from_urdf_string(
      "<?xml version=\"1.0\"?><robot name=\"ghost\"><link name=\"a\"/><link name=\"b\"/>"
      "<joint name=\"j\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/><axis xyz=\"0 0 1\"/></joint>"
      "</robot>");
  rbd::Handle serial(m), e64(m, {}, 2), e32(m, {}, 2, "float32");
  int checked = 0;
  for (const ops::OpEntry& e : ops::op_table()) {
    const ops::OpSpec& op = *e.spec;
    if (op.failure != ops::kNoMass) continue;
    SCOPED_TRACE(op.name);
    const Inputs in = make_inputs(m, op, 3, 2, false);
    const std::string want = std::string(op.name) + ": the robot has no mass (total mass 0 at sample 0)";
    for (rbd::Handle* h : {&serial, &e64, &e32}) {
      std::string msg;
      try {
        if (h == &e32) run<float>(*h, e.id, in);
        else run<double>(*h, e.id, in);
      } catch (const std::runtime_error& err) {
        msg = err.what();
      }
      EXPECT_EQ(msg.rfind(want, 0), 0u) << msg;
    }
    ++checked;
  }
  // com, jacobian_com, ccrba, centroidal_momentum, dccrba, cmm_time_variation, ḣ, its derivatives, the two
  // finite-difference checks, com_cost, momentum_cost
  EXPECT_EQ(checked, 12);
}

// what an operation needs of the model, and its finite-difference steps, are
// checked with messages naming them, on the serial loop and the engine
TEST(Registry, RequirementsAreChecked) {
  const Model mimic = Model::from_urdf_file(std::string(RBDKIT_TEST_URDF_DIR) + "/mimic.urdf", false);
  const Model hyq = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", true);
  auto message = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  int checked = 0;
  for (const ops::OpEntry& e : ops::op_table()) {
    const ops::OpSpec& op = *e.spec;
    if (op.model != ops::kNoMimic) continue;
    for (int threads : {0, 2}) {
      rbd::Handle h(mimic, {}, threads);
      const Inputs in = make_inputs(mimic, op, 3, 1, false);
      EXPECT_EQ(message([&] { run<double>(h, e.id, in); }),
                std::string(op.name) + ": this operation applies to models without mimic joints; this model has "
                                       "mimic joints");
    }
    ++checked;
  }
  EXPECT_EQ(checked, 2);  // minv_bpass, minv_fpass
  for (const char* name : {"dccrba_fd", "cmm_time_variation_fd"}) {
    const int id = ops::find_op(name);
    const ops::OpSpec& op = *ops::op_table()[id].spec;
    int k = 0;
    while (op.args[k].kind != ops::kPositive) ++k;
    for (const char* dtype : {"float64", "float32"}) {
      rbd::Handle h(hyq, {}, 2, dtype);
      Inputs in = make_inputs(hyq, op, 2, 1, false);
      for (double eps : {0.0, -1e-3, std::nan("")}) {
        in.call.real[k] = eps;
        const std::string msg = message([&] {
          if (std::string(dtype) == "float64") run<double>(h, id, in);
          else run<float>(h, id, in);
        });
        const char* want = std::isnan(eps) ? "eps: expected a finite number, got nan"
                                           : "eps: expected a positive finite-difference step, got";
        EXPECT_EQ(msg.rfind(want, 0), 0u) << msg;
      }
      // a step that float32 rounds to 0
      in.call.real[k] = 1e-50;
      const std::string msg = message([&] {
        if (std::string(dtype) == "float64") run<double>(h, id, in);
        else run<float>(h, id, in);
      });
      if (std::string(dtype) == "float32")
        EXPECT_EQ(msg.rfind("eps: expected a positive finite-difference step of at least 1.4013e-45 (the handle's "
                            "dtype rounds it to 0), got 1e-50", 0), 0u) << msg;
      else
        EXPECT_EQ(msg, "") << msg;
    }
  }
}

// the outputs every surface asks for (the kernels write them unconditionally)
// are required: a C++ caller passing null gets an error naming the output,
// not a crash; and a frame index on a model without frames says so
TEST(Registry, NullOutputsAndMissingFramesAreRefused) {
  const Model iiwa = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false);
  int checked = 0;
  for (const char* dtype : {"float64", "float32"}) {
    rbd::Handle h(iiwa, {}, 2, dtype);
    for (const ops::OpEntry& e : ops::op_table()) {
      const ops::OpSpec& op = *e.spec;
      const unsigned needed = ops::required_outputs(op);
      if (needed == 0) continue;  // inverse_dynamics_gradient: dtau or its halves
      int first = 0;
      while (!(needed >> first & 1u)) ++first;
      const Inputs in = make_inputs(iiwa, op, 2, 1, false);
      std::string msg;
      try {
        if (std::string(dtype) == "float64") run<double>(h, e.id, in, ~needed);
        else run<float>(h, e.id, in, ~needed);
      } catch (const std::invalid_argument& err) {
        msg = err.what();
      }
      EXPECT_EQ(msg, std::string(op.name) + ": output " + op.out[first].name + ": expected an array, got nothing (null)");
      ++checked;
    }
  }
  EXPECT_EQ(checked, 2 * (static_cast<int>(ops::op_table().size()) - 1));
  rbd::ModelBuilder b("no_frames");
  rbd::JointSpec j;
  j.name = "j", j.type = "revolute";
  b.add_body(-1, j, "link", rbd::rigid_inertia(1.0, {0, 0, 0.1}, rbd::Mat3<double>::identity()));
  const Model bare = b.build();
  ASSERT_TRUE(bare.frames.empty());
  rbd::Handle hb(bare);
  const int fp = ops::find_op("frame_placement");
  const Inputs in = make_inputs(bare, *ops::op_table()[fp].spec, 1, 1, false);
  std::string msg;
  try {
    run<double>(hb, fp, in);
  } catch (const std::invalid_argument& err) {
    msg = err.what();
  }
  EXPECT_EQ(msg, "frame_name: the model has no frames");
}

// a log barrier outside its bounds: +inf and NaN derivatives in that sample's
// coordinate, on the serial loop and the engine alike, and no overflow error
TEST(Registry, BarriersAreInfiniteOutside) {
  const Model m = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false);
  rbd::Handle serial(m), engine(m, {}, 2);
  const int id = ops::find_op("joint_velocity_barrier");
  Inputs in = make_inputs(m, *ops::op_table()[id].spec, 5, 4, false);
  in.arrays[0][3 * m.nv + 1] = in.arrays[2][3 * m.nv + 1];  // sample 3: qd on its upper bound (finite: 1 % 3 != 2)
  const long w = 1 + 2 * m.nv;
  for (rbd::Handle* h : {&serial, &engine}) {
    const std::vector<double> r = run<double>(*h, id, in);
    for (long s = 0; s < 5; ++s) {
      const std::vector<double> x = sample_of(r, w, s);
      if (s != 3) {
        for (double v : x) EXPECT_TRUE(std::isfinite(v)) << "sample " << s;
        continue;
      }
      EXPECT_EQ(x[0], INFINITY);
      for (int k = 0; k < m.nv; ++k) {
        EXPECT_EQ(std::isnan(x[1 + k]), k == 1) << k;
        EXPECT_EQ(std::isnan(x[1 + m.nv + k]), k == 1) << k;
      }
    }
  }
  // bounds out of order name both arguments and the entry
  Inputs bad = make_inputs(m, *ops::op_table()[id].spec, 2, 4, false);
  bad.arrays[1][m.nv + 4] = 5;  // sample 1: lower above upper
  std::string msg;
  try {
    run<double>(engine, id, bad);
  } catch (const std::invalid_argument& e) {
    msg = e.what();
  }
  EXPECT_EQ(msg.rfind("lower, upper: expected lower < upper", 0), 0u) << msg;
  EXPECT_NE(msg.find("at sample 1, flat index 4"), std::string::npos) << msg;
}

// names: a frame's index and an end effector's body are checked, and a frame
// on the world (no body) keeps its placement on a model without joints
TEST(Registry, NamesAreResolved) {
  const Model hyq = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", true);
  rbd::Handle h(hyq, {}, 2);
  const int fp = ops::find_op("frame_placement");
  Inputs in = make_inputs(hyq, *ops::op_table()[fp].spec, 3, 1, false);
  for (int bad : {-1, static_cast<int>(hyq.frames.size())}) {
    in.call.choice[1] = bad;
    std::string msg;
    try {
      run<double>(h, fp, in);
    } catch (const std::invalid_argument& e) {
      msg = e.what();
    }
    EXPECT_EQ(msg.rfind("frame_name: expected a frame index in 0..", 0), 0u) << msg;
  }
  // the same frame through the engine and one sample at a time: its body's placement times X_body_frame
  in.call.choice[1] = hyq.frame_index("lf_lowerleg");
  const std::vector<double> r = run<double>(h, fp, in);
  std::vector<double> R(9), p(3);
  for (long s = 0; s < 3; ++s) {
    rbd::batch::frame_placement(hyq, 1, in.arrays[0].data() + s * hyq.nq, hyq.frame_index("lf_lowerleg"), R.data(),
                                p.data());
    R.insert(R.end(), p.begin(), p.end());
    EXPECT_LE(max_rel_err(sample_of(r, 12, s), R), 1e-14);
    R.resize(9);
  }
  // a model without joints: a frame on the world is where the model put it
  const Model rigid = Model::from_urdf_string(
      "<?xml version=\"1.0\"?><robot name=\"rock\"><link name=\"a\"/><link name=\"b\"/>"
      "<joint name=\"j\" type=\"fixed\"><parent link=\"a\"/><child link=\"b\"/><origin xyz=\"0 0 2\"/></joint>"
      "</robot>");
  ASSERT_EQ(rigid.nb(), 0);
  rbd::Handle hr(rigid);
  Inputs ri = make_inputs(rigid, *ops::op_table()[fp].spec, 2, 1, false);
  ri.arrays[0].assign(1, 0.0);  // q has no values: a non-null pointer
  ri.call.in[0] = ri.arrays[0].data();
  ri.call.choice[1] = rigid.frame_index("b");
  const std::vector<double> rr = run<double>(hr, fp, ri);
  EXPECT_EQ(rr[11], 2.0);  // p.z of sample 0
  EXPECT_EQ(rr[0], 1.0);   // R = I
  // ee_pos_cost's end effector: -1 (the first leaf body) or a body index
  const int ee = ops::find_op("ee_pos_cost");
  Inputs ei = make_inputs(hyq, *ops::op_table()[ee].spec, 2, 1, false);
  ei.call.choice[3] = hyq.nb();
  std::string msg;
  try {
    run<double>(h, ee, ei);
  } catch (const std::invalid_argument& e) {
    msg = e.what();
  }
  EXPECT_EQ(msg.rfind("ee_joint_name: expected a body index in 0..", 0), 0u) << msg;
}

// a kernel failing in one lane of a pack: the engine names that sample (the
// pack's lanes again one at a time), with the operation's own message
TEST(Registry, EngineNamesTheFailingSample) {
  const Model iiwa = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false);
  rbd::Handle serial(iiwa), engine(iiwa, {}, 2);
  const int id = ops::find_op("osc_inertia");
  Inputs in = make_inputs(iiwa, *ops::op_table()[id].spec, 6, 2, false);
  for (int k = 0; k < iiwa.nq; ++k) in.arrays[0][3 * iiwa.nq + k] = 0;  // sample 3: stretched out, singular
  for (rbd::Handle* h : {&serial, &engine}) {
    std::string msg;
    try {
      run<double>(*h, id, in);
    } catch (const std::invalid_argument& e) {
      msg = e.what();
    }
    EXPECT_EQ(msg.rfind("osc_inertia: J M⁻¹ Jᵀ of an end effector is singular at sample 3: the configuration is "
                        "singular", 0),
              0u)
        << msg;
  }
  // a leg of 3 DoF: the end effector and its DoF are named
  const Model hyq = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", false);
  rbd::Handle h(hyq, {}, 2);
  const Inputs legs = make_inputs(hyq, *ops::op_table()[id].spec, 4, 2, false);
  std::string msg;
  try {
    run<double>(h, id, legs);
  } catch (const std::invalid_argument& e) {
    msg = e.what();
  }
  EXPECT_NE(msg.find("of end effector 0 (joint '"), std::string::npos) << msg;
  EXPECT_NE(msg.find("only 3 DoF reach it (6 are needed)"), std::string::npos) << msg;
}
