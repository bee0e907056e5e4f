// The CUDA backend (include/rbdkit/cuda/cuda_engine.hpp) in interpret mode:
// the kernels' source (include/rbdkit/cuda/kernels.cuh) under the emulated launch, so
// that CI, which has no GPU, runs every registered operation on every test
// model against the CPU: float64 to 1e-12 relative of the serial loop (1e-11
// where M⁻¹ is applied: float64_bound),
// float32 within the engine's bounds per family; device arrays in place; a
// failed sample named; device arrays' values checked by the kernels, in the
// host's words; the work in shared and in global memory; the launch shapes;
// no device and no interpret mode: a clear error.
#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "device.hpp"
#include "registry_helpers.hpp"
#include "test_models.hpp"

using rbd::Model;
using rbd_test::max_rel_err;
using rbd_test::ModelCase;
using namespace rbd_test;

namespace {

// RBDKIT_TEST_CUDA_DEVICE=1 (scripts/gpu-check.sh): the same tests on the real device
bool on_device() {
  const char* v = std::getenv("RBDKIT_TEST_CUDA_DEVICE");
  return v && std::string(v) == "1";
}

// a Backend::CUDA handle in interpret mode (RBDKIT_CUDA_INTERPRET=1 while it is built), or on the device
std::unique_ptr<rbd::Handle> interpret_handle(const Model& m, const std::string& dtype) {
  if (!on_device()) setenv("RBDKIT_CUDA_INTERPRET", "1", 1);
  auto h = std::make_unique<rbd::Handle>(m, std::vector<std::string>{}, rbd::Backend::CUDA, dtype);
  unsetenv("RBDKIT_CUDA_INTERPRET");
  return h;
}

// the message of the exception that f() throws ("" when it throws none)
template <typename F> std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {  // (invalid_argument for values, runtime_error for a failed sample)
    return e.what();
  }
  return "";
}

// float64 against the serial loop. Interpret mode runs the kernels' own arithmetic: 1e-12, and 1e-11
// for the families that apply M⁻¹, where a team's ∇FD forms qdd as M⁻¹ (u - c) and the serial loop
// runs ABA (the two agree to cond(M)·ε: 2.2e-12 on floating Atlas). On the device FMAs and the
// device's sin and cos round differently: the engine's bounds (M⁻¹ amplifies rounding by cond(M)).
// The second-order families carry M⁻¹'s rounding twice (cond(M)²·ε, as float32_bound says): with M⁻¹
// by M's factorisation in the serial loop (forward_dynamics, where minv_factored_pays) and by its
// columns in a team, the step Hessian differed by up to 2.1e-11 on the floating planar model
// (cond(M) up to 2e4), so 1e-10 there
double float64_bound(const ops::OpSpec& op) {
  const bool minv_applied = float32_bound(op) > 1e-4;
  const std::string f = op.family;
  if (!on_device() && (f == "fdsva_so" || f == "integrator_hessian")) return 1e-10;
  if (!on_device()) return minv_applied ? 1e-11 : 1e-12;
  return minv_applied ? 1e-8 : 1e-11;
}

class CudaModels : public ::testing::TestWithParam<ModelCase> {};

}  // namespace

TEST_P(CudaModels, InterpretEqualsCpu) {
  const ModelCase& mc = GetParam();
  const Model m = Model::from_urdf_file(mc.path, mc.floating);
  rbd::Handle serial(m);
  const auto p64 = interpret_handle(m, "float64"), p32 = interpret_handle(m, "float32");
  rbd::Handle &cu64 = *p64, &cu32 = *p32;
  ASSERT_TRUE(cu64.cuda() && cu64.cuda()->interpret() != on_device());
  if (!on_device()) EXPECT_EQ(cu64.cuda()->device_name(), "interpret (CPU)");

  const long B = 7;
  for (const ops::OpEntry& e : ops::op_table()) {
    const ops::OpSpec& op = *e.spec;
    SCOPED_TRACE(op.name);
    if (op.model == ops::kNoMimic && m.has_mimic()) continue;
    const Inputs in = make_inputs(m, op, B, 9, true);
    if (op.failure == ops::kOscSingular && !six_dof_reach(m, in.ee)) {
      EXPECT_THROW(run<double>(cu64, e.id, in), std::invalid_argument);
      continue;
    }
    const long w = sample_width(m, op, in.call.n_ee);
    const double tol64 = float64_bound(op);
    const std::vector<double> ref = run<double>(serial, e.id, in);
    const std::vector<double> r64 = run<double>(cu64, e.id, in), r32 = run<float>(cu32, e.id, in);
    // device arrays, in place (interpret mode: host memory is the device's)
    const std::vector<double> dev = on_device() ? r64 : run<double>(cu64, e.id, in, ~0u, true);
    ASSERT_EQ(r64.size(), ref.size());
    for (long s = 0; s < B; ++s) {
      EXPECT_LE(max_rel_err(sample_of(r64, w, s), sample_of(ref, w, s)), tol64) << "float64 sample " << s;
      EXPECT_LE(max_rel_err(sample_of(dev, w, s), sample_of(ref, w, s)), tol64) << "device arrays, sample " << s;
      EXPECT_LE(max_rel_err(sample_of(r32, w, s), sample_of(ref, w, s)), float32_bound(op)) << "float32 sample " << s;
    }
    // the first array unbatched (stride 0): every sample sees sample 0's values
    Inputs bc = in;
    bc.call.batched[0] = false;
    const std::vector<double> rb = run<double>(cu64, e.id, bc), rs = run<double>(serial, e.id, bc);
    EXPECT_LE(max_rel_err(rb, rs), tol64) << "broadcast";
  }
}

INSTANTIATE_TEST_SUITE_P(Models, CudaModels, ::testing::ValuesIn(rbd_test::all_cases()), rbd_test::case_name);

// a batch larger than one launch's work buffer: several launches, the same results
TEST(Cuda, ChunkedLaunchesEqualOne) {
  const Model hyq = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", true);
  const auto hp = interpret_handle(hyq, "float64");
  rbd::Handle serial(hyq);
  for (const char* name : {"forward_dynamics_gradient", "integrator_gradient", "crba"}) {
    SCOPED_TRACE(name);
    const int id = ops::find_op(name);
    Inputs in = make_inputs(hyq, *ops::op_table()[id].spec, 10, 4, true);
    in.call.batched[1] = false;  // one unbatched input, broadcast over the chunks
    const std::vector<double> ref = run<double>(serial, id, in);
    hp->cuda()->set_work_memory("global");  // (chunks are of the global work buffer)
    hp->cuda()->set_max_work_bytes(300000);  // at most 300 kB of work buffer per launch: a few samples
    const std::vector<double> got = run<double>(*hp, id, in);
    EXPECT_LE(max_rel_err(got, ref), on_device() ? 1e-8 : 1e-12);
    // a bad value in a later chunk: the failure flag and the statuses span the chunks
    if (!on_device()) {
      Inputs bad = in;
      bad.arrays[0][8 * hyq.nq + 8] = NAN;
      const std::string msg = error_of([&] { run<double>(*hp, id, bad, ~0u, true); });
      EXPECT_NE(msg.find("q[8]"), std::string::npos) << msg;
    }
    hp->cuda()->set_max_work_bytes(0);
    hp->cuda()->set_work_memory("auto");
  }
}

// the samples whose kernel fails are named, with the CPU's reason
TEST(Cuda, FailedSamplesAreNamed) {
  const Model iiwa = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false);
  const auto hp = interpret_handle(iiwa, "float64");
  rbd::Handle& h = *hp;
  const int id = ops::find_op("osc_inertia");
  Inputs in = make_inputs(iiwa, *ops::op_table()[id].spec, 6, 2, false);
  for (int s : {3, 5})
    for (int k = 0; k < iiwa.nq; ++k) in.arrays[0][s * iiwa.nq + k] = 0;  // stretched out: singular
  const std::string msg = error_of([&] { run<double>(h, id, in); });
  EXPECT_EQ(msg.rfind("osc_inertia: J M⁻¹ Jᵀ of an end effector is singular at sample 3", 0), 0u) << msg;
  EXPECT_NE(msg.find("[backend='cuda': 2 of 6 samples, samples 3, 5]"), std::string::npos) << msg;
}

// a team kernel's failure (a joint that moves no mass: D = 0 in M⁻¹'s articulated inertias, read by M⁻¹,
// FD, ∇FD, the step, its gradient and its Hessian) names the joint and the samples as the CPU does, and as
// the sample kernel does
TEST(Cuda, TeamFailuresAreNamed) {
  const Model m = Model::from_urdf_string(R"(<robot name="r"><link name="base"/>
    <link name="a"><inertial><mass value="1"/><origin xyz="0 0 0.1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
    <link name="b"/>
    <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
      <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
    <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 0.2"/><axis xyz="1 0 0"/>
      <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>)");
  rbd::Handle serial(m);
  const auto hp = interpret_handle(m, "float64");
  for (const char* name :
       {"minv", "forward_dynamics", "forward_dynamics_gradient", "integrator", "plant_step", "integrator_gradient",
        "plant_step_gradient", "plant_step_hessian"}) {
    SCOPED_TRACE(name);
    const int id = ops::find_op(name);
    const Inputs in = make_inputs(m, *ops::op_table()[id].spec, 3, 4, false);
    const std::string cpu = error_of([&] { run<double>(serial, id, in); });
    EXPECT_NE(cpu.find("joint 'j2' moves no mass at sample 0"), std::string::npos) << cpu;
    for (const char* kernel : {"team", "sample"}) {
      hp->cuda()->set_kernel(kernel);
      ASSERT_EQ(hp->cuda()->kernel_for(id, 3), kernel);
      const std::string msg = error_of([&] { run<double>(*hp, id, in); });
      EXPECT_EQ(msg.rfind(cpu, 0), 0u) << kernel << ": " << msg;  // the CPU's message, then the samples
      EXPECT_NE(msg.find("[backend='cuda': 3 of 3 samples"), std::string::npos) << kernel << ": " << msg;
    }
    hp->cuda()->set_kernel("auto");
  }
}

// values are checked as on the CPU (one pass, the argument and the sample named)
TEST(Cuda, ChecksAreTheCpus) {
  const Model iiwa = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false);
  const auto hp = interpret_handle(iiwa, "float64");
  rbd::Handle& h = *hp;
  const int id = ops::find_op("crba");
  Inputs in = make_inputs(iiwa, *ops::op_table()[id].spec, 4, 1, false);
  in.arrays[0][2 * iiwa.nq + 1] = NAN;
  for (bool device : {false, true}) {
    if (device && on_device()) continue;  // host memory is not the device's
    const std::string msg = error_of([&] { run<double>(h, id, in, ~0u, device); });
    EXPECT_NE(msg.find("q[2]"), std::string::npos) << msg;
  }
}

// the work slices in shared memory and in global memory give the same results (a model whose slices
// fit a block's shared memory, and floating Atlas, whose full-layout slices do not)
TEST(Cuda, WorkMemoriesAgree) {
  for (const auto& [file, floating] : {std::pair<const char*, bool>{"iiwa.urdf", false}, {"atlas.urdf", true}}) {
    const Model m = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/" + file, floating);
    SCOPED_TRACE(file);
    rbd::Handle serial(m);
    const auto hp = interpret_handle(m, "float64");
    EXPECT_EQ(hp->cuda()->work_memory(), "auto");
    const long B = 9;  // (on the interpret device's 4 SMs: blocks of 3 samples in shared memory)
    for (const ops::OpEntry& e : ops::op_table()) {
      const ops::OpSpec& op = *e.spec;
      SCOPED_TRACE(op.name);
      if (op.failure == ops::kOscSingular) continue;  // (their failures: FailedSamplesAreNamed)
      const Inputs in = make_inputs(m, op, B, 5, true);
      const std::vector<double> ref = run<double>(serial, e.id, in);
      for (const char* where : {"global", "shared"}) {
        hp->cuda()->set_work_memory(where);
        try {
          EXPECT_LE(max_rel_err(run<double>(*hp, e.id, in), ref), on_device() ? 1e-8 : 1e-12) << where;
        } catch (const std::invalid_argument& x) {  // a slice larger than a block's shared memory
          EXPECT_STREQ(where, "shared");
          EXPECT_NE(std::string(x.what()).find("exceeds a block's shared memory"), std::string::npos) << x.what();
        }
      }
      hp->cuda()->set_work_memory("auto");
    }
  }
  const Model iiwa = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false);
  EXPECT_THROW(interpret_handle(iiwa, "float64")->cuda()->set_work_memory("texture"), std::invalid_argument);
}

// the team kernels (include/rbdkit/cuda/team_kernels.cuh: ID, M, M⁻¹ (dense and upper), FD, ∇ID, ∇FD, the
// step's value, its gradient with and without ∂x⁺/∂f_ext (integrator and plant layouts), the step's Hessian;
// a block of threads per sample) against
// the serial loop, as the sample-per-thread kernels are: every test model, both dtypes, the work in shared
// and in global memory, every output or some, f_ext, every integrator scheme in both conventions
// (MuJoCo's, asked for, on one thread of the team), the Hessian in both of its forms;
// mimic models keep the sample kernel; device arrays' values checked by the team. A test per model
// (ctest runs them side by side: under the sanitizers the sixteen took 122 s as one test)
class CudaTeamModels : public ::testing::TestWithParam<ModelCase> {};
TEST_P(CudaTeamModels, TeamKernelsEqualCpu) {
  const ModelCase& mc = GetParam();
  const Model m = Model::from_urdf_file(mc.path, mc.floating);
  SCOPED_TRACE(mc.path + (mc.floating ? " floating" : " fixed"));
  rbd::Handle serial(m);
  const auto p64 = interpret_handle(m, "float64"), p32 = interpret_handle(m, "float32");
  for (const char* name : {"inverse_dynamics", "crba", "minv", "forward_dynamics", "inverse_dynamics_gradient",
                           "forward_dynamics_gradient", "integrator", "plant_step", "integrator_gradient",
                           "integrator_f_ext_gradient", "plant_step_gradient", "plant_step_hessian"}) {
    SCOPED_TRACE(name);
    const int id = ops::find_op(name);
    const ops::OpSpec& op = *ops::op_table()[id].spec;
    const bool hessian = std::string(name) == "plant_step_hessian";
    const bool step = std::string(op.family) == "integrators" || hessian, minv = std::string(name) == "minv";
    const bool q_only = minv || std::string(name) == "crba";  // (M and M⁻¹ take q alone)
    const bool plant = std::string(op.args[0].name) == "x";   // (x = [q; qd], then u)
    const int o = plant ? 0 : 1;  // a step's arguments after x, or after q and qd
    const bool step_value = step && op.n_out == 1;  // (the step's value: FD's rule, 8 per SM)
    // auto: the team on a small batch (at most 8 per SM, 32 for a step's derivatives: 32 or 128
    // samples on the interpret device's 4 SMs), or when nv >= 16 (but for ID); a mimic model keeps
    // the sample kernel whatever is asked
    EXPECT_EQ(p64->cuda()->kernel(), "auto");
    EXPECT_EQ(p64->cuda()->kernel_for(id, 5), m.has_mimic() ? "sample" : "team");
    const bool wide = m.nv >= 16 && std::string(name) != "inverse_dynamics";  // (ID: O(nb), never wide)
    EXPECT_EQ(p64->cuda()->kernel_for(id, 1000000), m.has_mimic() || !wide ? "sample" : "team");
    if (!on_device()) {  // the per-SM bound, at the interpret device's 4 SMs
      const long bound = 4 * (step && !step_value ? 32 : 8);
      EXPECT_EQ(p64->cuda()->kernel_for(id, bound), m.has_mimic() ? "sample" : "team");
      EXPECT_EQ(p64->cuda()->kernel_for(id, bound + 1), m.has_mimic() || !wide ? "sample" : "team");
    }
    if (step) EXPECT_EQ(p64->cuda()->kernel_for(id, 5, 1), "sample");  // (MuJoCo's convention: no team form)
    p64->cuda()->set_kernel("team");
    EXPECT_EQ(p64->cuda()->kernel_for(id, 1000000), m.has_mimic() ? "sample" : "team");
    p64->cuda()->set_kernel("sample");
    EXPECT_EQ(p64->cuda()->kernel_for(id, 5), "sample");
    p64->cuda()->set_kernel("auto");
    Inputs in = make_inputs(m, op, hessian ? 3 : 5, 11, true);
    // ID: every output, tau and v; M⁻¹ and FD: their one output; ∇ID: every output, dtau alone, the
    // halves alone; ∇FD: every output, the two matrices alone; the steps: every output, the last alone;
    // M⁻¹ dense and upper; each step with every scheme (the 6 integrator types) and convention (0:
    // Pinocchio's, 1: MuJoCo's)
    const std::vector<unsigned> masks =
        op.n_out == 1 ? std::vector<unsigned>{1u}
        : step        ? std::vector<unsigned>{(1u << op.n_out) - 1, 1u << (op.n_out - 1)}
        : op.n_out == 3 ? std::vector<unsigned>{0b111, 0b001, 0b110} : std::vector<unsigned>{0b1111, 0b0011};
    for (int variant = 0; variant < (step ? 12 : minv ? 2 : 1); ++variant)
    for (unsigned mask : masks) {
      SCOPED_TRACE(mask);
      SCOPED_TRACE(variant);
      if (hessian) {  // the Hessian: integrator_type, output_convention, form (the reference one for H alone)
        in.call.choice[3] = variant % 6, in.call.choice[5] = variant / 6, in.call.choice[6] = mask == 1u << 2;
      } else if (step) {
        in.call.choice[3 + o] = variant % 6, in.call.choice[6 + o] = variant / 6;
      }
      if (minv) in.call.choice[1] = 1 - variant;  // output_dense: True, then False
      // MuJoCo's convention: the team asked for, which runs the step on one of its threads
      const char* kernel = step && variant >= 6 ? "team" : "auto";
      p64->cuda()->set_kernel(kernel), p32->cuda()->set_kernel(kernel);
      const std::vector<double> ref = run<double>(serial, id, in, mask);
      for (const char* where : {"shared", "global"}) {
        p64->cuda()->set_work_memory(where), p32->cuda()->set_work_memory(where);
        try {
          EXPECT_LE(max_rel_err(run<double>(*p64, id, in, mask), ref), on_device() ? 1e-8 : float64_bound(op)) << where;
          EXPECT_LE(max_rel_err(run<float>(*p32, id, in, mask), ref), float32_bound(op)) << where;
        } catch (const std::invalid_argument& x) {  // (floating Atlas: a slice larger than a block's)
          EXPECT_STREQ(where, "shared");
          EXPECT_NE(std::string(x.what()).find("exceeds a block's shared memory"), std::string::npos) << x.what();
        }
      }
      p64->cuda()->set_work_memory("auto"), p32->cuda()->set_work_memory("auto");
      p64->cuda()->set_kernel("auto"), p32->cuda()->set_kernel("auto");
    }
    if (on_device()) continue;
    // a device array's bad value: the team's check names it, as the host's does
    Inputs bad = in;
    bad.arrays[q_only ? 0 : 1][(hessian ? 2 : 3) * (q_only ? m.nq : m.nv)] = NAN;
    const std::string msg = error_of([&] { run<double>(*p64, id, bad, ~0u, true); });
    EXPECT_NE(msg.find(q_only ? "q[3]" : hessian ? "u[2]" : plant ? "u[3]" : "qd[3]"), std::string::npos) << msg;
  }
}
INSTANTIATE_TEST_SUITE_P(Models, CudaTeamModels, ::testing::ValuesIn(rbd_test::all_cases()), rbd_test::case_name);

TEST(Cuda, UnknownKernelIsRefused) {
  const Model iiwa = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false);
  EXPECT_THROW(interpret_handle(iiwa, "float64")->cuda()->set_kernel("warp"), std::invalid_argument);
}

// the costs' and barriers' team forms (plant/costs.hpp) against the serial loop: every test model, both
// dtypes and both output conventions, the work in shared and in global memory. auto takes the team on a
// small batch in either convention, and at every B from nv = 16 on but for the barriers (O(nv));
// a barrier outside its interval gives +inf and NaN where the CPU does; a robot without mass fails
// com_cost and momentum_cost by the team with the CPU's message
TEST(Cuda, TeamCostsEqualCpu) {
  const char* names[] = {"quadratic_state_cost",   "quadratic_input_cost",   "quadratic_state_cost_tangent",
                         "ee_pos_cost",            "com_cost",               "momentum_cost",
                         "joint_position_barrier", "joint_velocity_barrier", "joint_torque_barrier"};
  for (const ModelCase& mc : rbd_test::all_cases()) {
    const Model m = Model::from_urdf_file(mc.path, mc.floating);
    SCOPED_TRACE(mc.path + (mc.floating ? " floating" : " fixed"));
    rbd::Handle serial(m);
    const auto p64 = interpret_handle(m, "float64"), p32 = interpret_handle(m, "float32");
    for (const char* name : names) {
      SCOPED_TRACE(name);
      const int id = ops::find_op(name);
      const ops::OpSpec& op = *ops::op_table()[id].spec;
      const bool barrier = std::string(op.algorithm) == "barriers";
      int convention_arg = -1;
      for (int k = 0; k < op.n_args; ++k)
        if (op.args[k].kind == ops::kConvention) convention_arg = k;
      ASSERT_GE(convention_arg, 0);
      Inputs in = make_inputs(m, op, 5, 13, true);
      for (int convention : {0, 1}) {
        SCOPED_TRACE(convention);
        in.call.choice[convention_arg] = convention;
        EXPECT_EQ(p64->cuda()->kernel_for(id, 5, convention), m.has_mimic() ? "sample" : "team");
        const bool wide = m.nv >= 16 && !barrier;
        EXPECT_EQ(p64->cuda()->kernel_for(id, 1000000, convention), m.has_mimic() || !wide ? "sample" : "team");
        const std::vector<double> ref = run<double>(serial, id, in);
        for (const char* where : {"shared", "global"}) {
          p64->cuda()->set_work_memory(where), p32->cuda()->set_work_memory(where);
          try {
            EXPECT_LE(max_rel_err(run<double>(*p64, id, in), ref), float64_bound(op)) << where;
            EXPECT_LE(max_rel_err(run<float>(*p32, id, in), ref), float32_bound(op)) << where;
          } catch (const std::invalid_argument& x) {  // (floating Atlas: a slice larger than a block's)
            EXPECT_STREQ(where, "shared");
            EXPECT_NE(std::string(x.what()).find("exceeds a block's shared memory"), std::string::npos) << x.what();
          }
        }
        p64->cuda()->set_work_memory("auto"), p32->cuda()->set_work_memory("auto");
      }
      if (!barrier || m.has_mimic()) continue;
      // sample 3's second coordinate past its upper bound (every bound but each third one is finite):
      // that sample's value +inf, that coordinate's gradient and Hessian entries NaN, as on the CPU
      Inputs out = in;
      const long n = ops::arg_values(op.args[0], m, 0);
      out.arrays[0][3 * n + 1] = out.arrays[2][3 * n + 1] + 1;
      const std::vector<double> want = run<double>(serial, id, out), got = run<double>(*p64, id, out);
      ASSERT_EQ(got.size(), want.size());
      ASSERT_EQ(want.size(), static_cast<size_t>(5 * (2 * n + 1)));
      EXPECT_EQ(want[3 * (2 * n + 1)], INFINITY);
      for (size_t k = 0; k < want.size(); ++k)
        if (std::isnan(want[k])) EXPECT_TRUE(std::isnan(got[k])) << k << ": " << got[k];
        else if (std::isinf(want[k])) EXPECT_EQ(got[k], want[k]) << k;
        else EXPECT_NEAR(got[k], want[k], 1e-12 * (1 + std::fabs(want[k]))) << k;
    }
  }
  const Model ghost = Model::from_urdf_string(
      "<?xml version=\"1.0\"?><robot name=\"ghost\"><link name=\"a\"/><link name=\"b\"/>"
      "<joint name=\"j\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/><axis xyz=\"0 0 1\"/></joint>"
      "</robot>");
  rbd::Handle serial(ghost);
  const auto hp = interpret_handle(ghost, "float64");
  for (const char* name : {"com_cost", "momentum_cost"}) {
    SCOPED_TRACE(name);
    const int id = ops::find_op(name);
    const Inputs in = make_inputs(ghost, *ops::op_table()[id].spec, 3, 2, false);
    const std::string cpu = error_of([&] { run<double>(serial, id, in); });
    EXPECT_EQ(cpu.rfind(std::string(name) + ": the robot has no mass (total mass 0 at sample 0)", 0), 0u) << cpu;
    ASSERT_EQ(hp->cuda()->kernel_for(id, 3), "team");
    const std::string msg = error_of([&] { run<double>(*hp, id, in); });
    EXPECT_EQ(msg.rfind(cpu, 0), 0u) << msg;
    EXPECT_NE(msg.find("[backend='cuda': 3 of 3 samples"), std::string::npos) << msg;
  }
}

// a batch large enough that blocks hold several samples' work in shared memory on any device (on an
// H100, 600 samples are 5 per block, as many as fit in interpret mode; scripts/gpu-check.sh runs this under compute-sanitizer's racecheck)
TEST(Cuda, SharedBlocksOfManySamples) {
  const Model iiwa = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false);
  rbd::Handle serial(iiwa);
  const auto hp = interpret_handle(iiwa, "float64");
  hp->cuda()->set_work_memory("shared");  // (auto would choose global memory on the interpret device's 4 SMs)
  for (const char* name : {"inverse_dynamics", "forward_dynamics_gradient", "integrator_gradient"}) {
    SCOPED_TRACE(name);
    const int id = ops::find_op(name);
    const Inputs in = make_inputs(iiwa, *ops::op_table()[id].spec, 600, 8, true);
    EXPECT_LE(max_rel_err(run<double>(*hp, id, in), run<double>(serial, id, in)), on_device() ? 1e-8 : 1e-12);
  }
}

// the launch shapes on an H100 (132 SMs, 227 kB of shared memory per block)
TEST(Cuda, TeamLaunchShapes) {
  using rbd::cuda::team_launch_shape;
  const rbd::cuda::DeviceLimits h100{132, 227ul * 1024};
  // a block of kTeam threads per sample; a 40 kB slice: 5 fit an SM, shared memory up to three waves
  auto s = team_launch_shape(256, 40000, h100, rbd::cuda::kWorkAuto);
  EXPECT_EQ(s.team, 1);
  EXPECT_EQ(s.threads, rbd::cuda::kTeam);
  EXPECT_EQ(s.blocks, 256);
  EXPECT_EQ(s.shared_bytes, 40000ul);
  EXPECT_EQ(team_launch_shape(3 * 132 * 5, 40000, h100, rbd::cuda::kWorkAuto).shared_bytes, 40000ul);
  EXPECT_EQ(team_launch_shape(3 * 132 * 5 + 1, 40000, h100, rbd::cuda::kWorkAuto).shared_bytes, 0ul);
  // a slice larger than a block's shared memory: global; past kMaxBlocks samples the grid strides
  EXPECT_EQ(team_launch_shape(8, 250000, h100, rbd::cuda::kWorkAuto).shared_bytes, 0ul);
  EXPECT_EQ(team_launch_shape(100000, 40000, h100, rbd::cuda::kWorkGlobal).blocks, rbd::cuda::kMaxBlocks);
  EXPECT_EQ(team_launch_shape(100000, 40000, h100, rbd::cuda::kWorkShared).shared_bytes, 40000ul);
}

TEST(Cuda, LaunchShapes) {
  using rbd::cuda::launch_shape;
  const rbd::cuda::DeviceLimits h100{132, 227ul * 1024};
  // a 30 kB slice: 7 fit a block, 924 samples on the whole GPU at once. Up to three such waves, the work
  // in shared memory, the samples spread one or two per block over every SM, then as many as fit
  auto s = launch_shape(256, 30000, h100, rbd::cuda::kWorkAuto);
  EXPECT_EQ(s.threads, 2);
  EXPECT_EQ(s.blocks, 128);
  EXPECT_EQ(s.shared_bytes, 60000ul);
  s = launch_shape(900, 30000, h100, rbd::cuda::kWorkAuto);
  EXPECT_EQ(s.threads, 7);
  EXPECT_EQ(s.blocks, (900 + 6) / 7);
  EXPECT_EQ(s.shared_bytes, 210000ul);
  s = launch_shape(2700, 30000, h100, rbd::cuda::kWorkAuto);
  EXPECT_EQ(s.threads, 7);
  EXPECT_EQ(s.blocks, (2700 + 6) / 7);
  EXPECT_EQ(s.shared_bytes, 210000ul);
  s = launch_shape(1, 30000, h100, rbd::cuda::kWorkAuto);
  EXPECT_EQ(s.threads, 1);
  EXPECT_EQ(s.blocks, 1);
  // a 120 kB slice (floating Atlas's ∇FD in float32): one per block, 132 at once, three waves of them
  s = launch_shape(256, 120000, h100, rbd::cuda::kWorkAuto);
  EXPECT_EQ(s.threads, 1);
  EXPECT_EQ(s.blocks, 256);
  EXPECT_EQ(s.shared_bytes, 120000ul);
  EXPECT_EQ(launch_shape(396, 120000, h100, rbd::cuda::kWorkAuto).shared_bytes, 120000ul);
  EXPECT_EQ(launch_shape(397, 120000, h100, rbd::cuda::kWorkAuto).shared_bytes, 0ul);
  // more samples than three waves in shared memory: global memory, warps, spread, at most 128 threads
  s = launch_shape(16384, 30000, h100, rbd::cuda::kWorkAuto);
  EXPECT_EQ(s.shared_bytes, 0ul);
  EXPECT_EQ(s.threads, 128);
  EXPECT_EQ(s.blocks, 128);
  // ... unless shared memory is asked for: blocks of as many as fit
  s = launch_shape(16384, 30000, h100, rbd::cuda::kWorkShared);
  EXPECT_EQ(s.threads, 7);
  EXPECT_EQ(s.blocks, (16384 + 6) / 7);
  // slices that do not fit a block, or global memory asked for
  s = launch_shape(256, 250000, h100, rbd::cuda::kWorkAuto);
  EXPECT_EQ(s.threads, 32);
  EXPECT_EQ(s.blocks, 8);
  EXPECT_EQ(s.shared_bytes, 0ul);
  s = launch_shape(256, 30000, h100, rbd::cuda::kWorkGlobal);
  EXPECT_EQ(s.shared_bytes, 0ul);
  EXPECT_EQ(s.threads, 32);
  s = launch_shape(100000000, 250000, h100, rbd::cuda::kWorkAuto);  // the grid strides past kMaxBlocks
  EXPECT_EQ(s.blocks, rbd::cuda::kMaxBlocks);
  EXPECT_EQ(s.threads, 128);
}

// device arrays' values are checked by the kernels (no copy to the host on the way in), and a bad
// sample's error is the host's, word for word: every array of every operation, each kind of bad value
TEST(Cuda, DeviceChecksSayWhatHostChecksSay) {
  // (the test hands host vectors in as device arrays, which only interpret mode can read; on a GPU the
  // checks are the same source compiled by nvcc, not fed bad values by these tests)
  if (on_device()) GTEST_SKIP() << "host vectors as device arrays: interpret mode only";
  const Model m = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/hyq.urdf", true);
  const auto p64 = interpret_handle(m, "float64"), p32 = interpret_handle(m, "float32");
  int compared = 0;
  for (const ops::OpEntry& e : ops::op_table()) {
    const ops::OpSpec& op = *e.spec;
    SCOPED_TRACE(op.name);
    const Inputs good = make_inputs(m, op, 4, 3, true);
    for (int k = 0; k < op.n_args; ++k) {
      const ops::ArgSpec& a = op.args[k];
      if ((a.kind != ops::kArray && a.kind != ops::kOptionalArray) || good.arrays[k].empty()) continue;
      SCOPED_TRACE(a.name);
      const long n = ops::arg_values(a, m, good.call.n_ee);
      // the bad values of this argument's check, at sample 2
      std::vector<std::pair<long, double>> bad = {{0, NAN}, {n - 1, INFINITY}, {0, 1e20}};  // 1e20: float32's bound
      if (a.check == ops::kWeights) bad.push_back({n - 1, -1.0});
      if (a.check == ops::kUpperBound) bad.push_back({0, good.arrays[k - 1][2 * n] - 1});  // below its lower bound
      if (a.check == ops::kConfiguration || a.check == ops::kMujocoConfiguration) {
        bad.push_back({3, good.arrays[k][2 * n + 3] * 1.01});  // the base quaternion, not unit
        bad.push_back({7, 2e12});                              // a revolute angle past kMaxAngle
      }
      for (const auto& [at, value] : bad)
        for (bool batched : {true, false}) {  // unbatched: sample 2's values for every sample (stride 0)
          Inputs in = good;
          in.arrays[k][2 * n + at] = value;
          if (!batched) in.call.batched[k] = false, in.first[k] = 2;
          for (rbd::Handle* h : {p64.get(), p32.get()}) {
            // (the value's error, or "" where the checks pass it: 1e20 in float64, which may then overflow)
            auto message = [&](bool dev) {
              try {
                if (h->dtype() == "float32") run<float>(*h, e.id, in, ~0u, dev);
                else run<double>(*h, e.id, in, ~0u, dev);
              } catch (const std::invalid_argument& x) {
                return std::string(x.what());
              } catch (const std::runtime_error&) {
              }
              return std::string();
            };
            const std::string host = message(false), device = message(true);
            EXPECT_EQ(device, host) << h->dtype() << ", value " << value << " at " << at
                                    << (batched ? "" : ", unbatched");
            compared += !host.empty();
          }
        }
    }
  }
  EXPECT_GT(compared, 1000);  // (values a check lets through, 1e20 in float64, are not compared)
}

// without interpret mode the backend needs a device (and real kernels): a clear error where there is none
TEST(Cuda, NoDeviceIsAClearError) {
  const Model iiwa = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf", false);
  unsetenv("RBDKIT_CUDA_INTERPRET");
  if (rbd::CudaEngine::cuda_compiled() && rbd::CudaEngine::device_count() > 0) {
    rbd::Handle h(iiwa, {}, rbd::Backend::CUDA);
    EXPECT_FALSE(h.cuda()->interpret());
    return;
  }
  std::string msg;
  try {
    rbd::Handle h(iiwa, {}, rbd::Backend::CUDA);
  } catch (const std::runtime_error& e) {
    msg = e.what();
  }
  EXPECT_NE(msg.find(rbd::CudaEngine::cuda_compiled() ? "no CUDA device" : "no CUDA kernels"), std::string::npos)
      << msg;
  EXPECT_NE(msg.find("RBDKIT_CUDA_INTERPRET=1"), std::string::npos) << msg;
  // a CPU handle refuses device arrays
  rbd::Handle cpu(iiwa);
  const int id = ops::find_op("crba");
  const Inputs in = make_inputs(iiwa, *ops::op_table()[id].spec, 2, 1, false);
  EXPECT_THROW(run<double>(cpu, id, in, ~0u, true), std::invalid_argument);
}
