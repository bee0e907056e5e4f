// Handle::specialize: the compiled per-robot instance (codegen/specialize.hpp)
// gives what the generic kernels give, for every operation it has, on a serial
// arm, a floating quadruped and a model with mimic joints; a handle runs the
// instance's kernels; the cache is keyed by the model and a library of another
// robot, or one that others may write, is refused; a missing or failing
// compiler and a float32 handle fall back with a message. A CUDA handle's
// instance (cuda/instance.cuh) runs its kernels in interpret mode.
// The instances are compiled into $RBDKIT_CACHE_DIR (./test.sh: build/instances),
// else a folder under the test's temporary directory.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <ostream>

#include "rbdkit/codegen/instance.hpp"
#include "rbdkit/cuda/cuda_engine.hpp"
#include "rbdkit/cuda/instance.cuh"
#include "registry_helpers.hpp"
#include "test_models.hpp"

using rbd::Handle;
using rbd::Model;

namespace {

rbd::SpecializeOptions test_options() {
  rbd::SpecializeOptions o;
  const char* dir = std::getenv("RBDKIT_CACHE_DIR");
  o.cache_dir = dir && *dir ? dir : ::testing::TempDir() + "rbdkit-instances";
  return o;
}

struct Robot {
  const char* file;
  bool floating;
};
void PrintTo(const Robot& r, std::ostream* os) { *os << r.file << (r.floating ? " floating" : " fixed"); }

}  // namespace

class SpecializeModels : public ::testing::TestWithParam<Robot> {};

// every operation of the instance, f_ext given where it is taken, against the generic handle's
TEST_P(SpecializeModels, EveryKernelAgreesWithTheGenericOne) {
  const Model m = Model::from_urdf_file(GetParam().file, GetParam().floating);
  Handle generic(m), spec(m);
  ASSERT_TRUE(spec.specialize(test_options())) << spec.specialize_error();
  EXPECT_TRUE(spec.specialized());
  EXPECT_TRUE(std::filesystem::is_regular_file(spec.instance_library()));
  EXPECT_FALSE(generic.specialized());
  for (const char* name : rbd::instance::InstanceOps::names) {
    const int id = rbd::ops::find_op(name);
    ASSERT_GE(id, 0) << name;
    const rbd::ops::OpSpec& op = *rbd::ops::op_table()[id].spec;
    for (const bool with_fext : {false, true}) {
      // B = 3 on a handle without threads: the serial loop, so the instance, for every sample
      const rbd_test::Inputs in = rbd_test::make_inputs(m, op, 3, 17u + id, with_fext);
      const std::vector<double> want = rbd_test::run<double>(generic, id, in);
      const std::vector<double> got = rbd_test::run<double>(spec, id, in);
      ASSERT_EQ(got.size(), want.size());
      EXPECT_LT(rbd_test::max_rel_err(got, want), 1e-12) << op.name << (with_fext ? " with f_ext" : "");
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Robots, SpecializeModels,
                         ::testing::Values(Robot{RBDKIT_ROBOTS_DIR "/iiwa.urdf", false},
                                           Robot{RBDKIT_ROBOTS_DIR "/hyq.urdf", true},
                                           // (M⁻¹ by the factorisation in the instance, by the passes in the
                                           // generic kernel: minv_factored_pays is false)
                                           Robot{RBDKIT_ROBOTS_DIR "/atlas.urdf", true},
                                           Robot{RBDKIT_TEST_URDF_DIR "/mimic.urdf", false}),
                         [](const ::testing::TestParamInfo<Robot>& info) {
                           std::string p = info.param.file;
                           p = p.substr(p.find_last_of('/') + 1);
                           return p.substr(0, p.find('.')) + (info.param.floating ? "_floating" : "_fixed");
                         });

// a CUDA handle's instance (rbdkit/cuda/instance.cuh), in interpret mode: the backend's kernel source on
// the robot's constants, compiled by the C++ compiler. Each of its operations, by the team and by the
// sample kernel, in float64 and float32, with f_ext, gives what the generic kernels give; the handle
// runs it (the library of another robot in its place computes that robot); an operation it does not
// hold runs the generic kernel; an instance of the other kind is refused
TEST(Specialize, InterpretModeInstanceAgreesWithTheGenericKernels) {
  rbd::SpecializeOptions o = test_options();
  o.flags = "-O2";  // (what it computes, not how fast: a quicker compilation)
  for (const Robot& r : {Robot{RBDKIT_ROBOTS_DIR "/iiwa.urdf", false}, Robot{RBDKIT_ROBOTS_DIR "/hyq.urdf", true}}) {
    const Model m = Model::from_urdf_file(r.file, r.floating);
    SCOPED_TRACE(r.file);
    setenv("RBDKIT_CUDA_INTERPRET", "1", 1);
    Handle g64(m, {}, rbd::Backend::CUDA, "float64"), s64(m, {}, rbd::Backend::CUDA, "float64");
    Handle s32(m, {}, rbd::Backend::CUDA, "float32");
    unsetenv("RBDKIT_CUDA_INTERPRET");
    ASSERT_TRUE(s64.specialize(o)) << s64.specialize_error();
    ASSERT_TRUE(s32.specialize(o)) << s32.specialize_error();
    EXPECT_TRUE(s64.specialized());
    EXPECT_EQ(s64.instance_library(), s32.instance_library());  // (one library holds both dtypes)
    EXPECT_NE(s64.instance_library().find("-cuda-interpret-"), std::string::npos) << s64.instance_library();
    Handle serial(m);
    for (int k = 0; k < rbd::cuda::instance::Names<rbd::cuda::instance::Ops>::count; ++k) {
      const char* name = rbd::cuda::instance::Names<rbd::cuda::instance::Ops>::names[k];
      const int id = rbd::ops::find_op(name);
      ASSERT_GE(id, 0) << name;
      const rbd::ops::OpSpec& op = *rbd::ops::op_table()[id].spec;
      for (const char* kernel : {"team", "sample"}) {
        s64.cuda()->set_kernel(kernel), s32.cuda()->set_kernel(kernel), g64.cuda()->set_kernel(kernel);
        const rbd_test::Inputs in = rbd_test::make_inputs(m, op, 3, 29u + id, true);
        const std::vector<double> want = rbd_test::run<double>(g64, id, in);
        EXPECT_LT(rbd_test::max_rel_err(rbd_test::run<double>(s64, id, in), want), 1e-12) << name << " " << kernel;
        EXPECT_LT(rbd_test::max_rel_err(rbd_test::run<float>(s32, id, in), rbd_test::run<double>(serial, id, in)),
                  rbd_test::float32_bound(op))
            << name << " " << kernel;
      }
    }
    // an operation outside the instance (CRBA) runs the generic kernel
    const int crba = rbd::ops::find_op("crba");
    const rbd_test::Inputs in = rbd_test::make_inputs(m, *rbd::ops::op_table()[crba].spec, 2, 5, false);
    EXPECT_LT(rbd_test::max_rel_err(rbd_test::run<double>(s64, crba, in), rbd_test::run<double>(serial, crba, in)),
              1e-12);
  }
  // the handle runs its instance: with a heavier arm's library put in the cache where iiwa's belongs,
  // an iiwa handle computes the heavier arm's M⁻¹ (a changed inertia is another instance)
  const Model iiwa = Model::from_urdf_file(RBDKIT_ROBOTS_DIR "/iiwa.urdf");
  Model heavier = iiwa;
  heavier.bodies[2].I.m *= 2;
  setenv("RBDKIT_CUDA_INTERPRET", "1", 1);
  Handle a(iiwa, {}, rbd::Backend::CUDA), d(heavier, {}, rbd::Backend::CUDA), e(iiwa, {}, rbd::Backend::CUDA);
  unsetenv("RBDKIT_CUDA_INTERPRET");
  ASSERT_TRUE(a.specialize(o)) << a.specialize_error();
  ASSERT_TRUE(d.specialize(o)) << d.specialize_error();
  EXPECT_NE(d.instance_library(), a.instance_library());
  rbd::SpecializeOptions swapped = o;
  swapped.cache_dir += "-cuda-swapped";
  std::filesystem::remove_all(swapped.cache_dir);
  std::filesystem::create_directories(swapped.cache_dir);
  std::filesystem::copy_file(d.instance_library(), std::filesystem::path(swapped.cache_dir) /
                                                       std::filesystem::path(a.instance_library()).filename());
  ASSERT_TRUE(e.specialize(swapped)) << e.specialize_error();
  const int minv = rbd::ops::find_op("minv");
  const rbd_test::Inputs in = rbd_test::make_inputs(iiwa, *rbd::ops::op_table()[minv].spec, 2, 9, false);
  Handle heavy_serial(heavier);
  EXPECT_LT(rbd_test::max_rel_err(rbd_test::run<double>(e, minv, in), rbd_test::run<double>(heavy_serial, minv, in)),
            1e-12);
  // an interpret engine takes an interpret instance (and lets it go); the loader refuses a library of
  // the other kind in its place: interpret launches asked for as GPU kernels
  rbd::CudaEngine engine(iiwa, "float64", /*interpret=*/true);
  engine.use_instance(rbd::load_cuda_instance(iiwa, o, /*device=*/false));
  EXPECT_TRUE(engine.has_instance());
  engine.use_instance(nullptr);
  EXPECT_FALSE(engine.has_instance());
  try {  // another robot's instance: the engine's work sizes are not the ones its kernels carve
    engine.use_instance(rbd::load_cuda_instance(Model::from_urdf_file(RBDKIT_ROBOTS_DIR "/hyq.urdf", true), o, false));
    ADD_FAILURE() << "use_instance took another robot's instance";
  } catch (const std::invalid_argument& x) {
    EXPECT_NE(std::string(x.what()).find("another robot's"), std::string::npos) << x.what();
  }
  EXPECT_FALSE(engine.has_instance());
  EXPECT_THROW(rbd::load_cuda_instance(iiwa, o, /*device=*/true, ""), std::invalid_argument);  // (the GPU unnamed)
  // (the "CUDA compiler": a script that hands nvcc's command to the C++ compiler, so the library built
  // on the device path holds interpret launches)
  rbd::SpecializeOptions fake = o;
  fake.cache_dir += "-cuda-fake-nvcc";
  std::filesystem::remove_all(fake.cache_dir);
  std::filesystem::create_directories(fake.cache_dir);
  fake.cuda_compiler = fake.cache_dir + "/nvcc";
  {
    std::ofstream f(fake.cuda_compiler);
    f << "#!/bin/sh\nargs=\"\"; skip=0\nfor a in \"$@\"; do\n  if [ $skip = 1 ]; then skip=0; continue; fi\n"
         "  case $a in -Xcompiler) skip=1;; -arch=*) ;; *.cu) args=\"$args -x c++ $a\";; *) args=\"$args $a\";; esac\n"
         "done\nexec c++ -fPIC -fvisibility=hidden $args\n";
  }
  std::filesystem::permissions(fake.cuda_compiler, std::filesystem::perms::owner_all);
  fake.cuda_flags = "-O1";
  std::string why;
  try {
    rbd::load_cuda_instance(iiwa, fake, /*device=*/true, "a GPU");
  } catch (const std::runtime_error& x) {
    why = x.what();
  }
  EXPECT_NE(why.find("holds interpret launches, not GPU kernels"), std::string::npos) << why;
  fake.cuda_compiler = "/nonexistent/nvcc";
  why.clear();
  try {
    rbd::load_cuda_instance(iiwa, fake, /*device=*/true, "a GPU");
  } catch (const std::runtime_error& x) {
    why = x.what();
  }
  EXPECT_NE(why.find("no CUDA compiler"), std::string::npos) << why;
}

// a second handle on the same model loads the cached library; another model has its own
TEST(Specialize, TheCacheIsKeyedByTheModel) {
  const Model iiwa = Model::from_urdf_file(RBDKIT_ROBOTS_DIR "/iiwa.urdf");
  Handle a(iiwa), b(iiwa), c(Model::from_urdf_file(RBDKIT_ROBOTS_DIR "/hyq.urdf", true));
  ASSERT_TRUE(a.specialize(test_options())) << a.specialize_error();
  ASSERT_TRUE(b.specialize(test_options())) << b.specialize_error();
  ASSERT_TRUE(c.specialize(test_options())) << c.specialize_error();
  EXPECT_EQ(a.instance_library(), b.instance_library());
  EXPECT_NE(a.instance_library(), c.instance_library());
  // another model of the same robot (a changed inertia) is another instance
  Model heavier = iiwa;
  heavier.bodies[2].I.m *= 2;
  Handle d(heavier);
  ASSERT_TRUE(d.specialize(test_options())) << d.specialize_error();
  EXPECT_NE(d.instance_library(), a.instance_library());
  // an instance's kernel computes the robot it was compiled for, whatever view it is passed: the
  // heavier arm's M from iiwa's view and workspace
  const auto heavy = rbd::load_instance(heavier, test_options());
  const int id = rbd::ops::find_op("crba");
  const rbd_test::Inputs in = rbd_test::make_inputs(iiwa, *rbd::ops::op_table()[id].spec, 1, 5, false);
  rbd::WorkspaceBuffer buf(iiwa);
  std::vector<double> M(iiwa.nv * iiwa.nv);
  rbd::ops::OpArgs<double> args{};
  args.in[0] = in.arrays[0].data();
  args.out[0] = M.data();
  ASSERT_TRUE(rbd::instance_kernel(*heavy, id)(iiwa.view(), buf.get(), args));
  Handle generic_heavy(heavier), generic_iiwa(iiwa);
  EXPECT_LT(rbd_test::max_rel_err(M, rbd_test::run<double>(generic_heavy, id, in)), 1e-12);
  EXPECT_GT(rbd_test::max_rel_err(M, rbd_test::run<double>(generic_iiwa, id, in)), 1e-3);
  EXPECT_EQ(rbd::instance_kernel(*heavy, rbd::ops::find_op("com")), nullptr);  // not an instance's operation
  // and a handle runs its instance's kernels: with the heavier arm's library put in the cache where
  // iiwa's belongs, an iiwa handle computes the heavier arm's M
  rbd::SpecializeOptions swapped = test_options();
  swapped.cache_dir += "-swapped";
  std::filesystem::remove_all(swapped.cache_dir);
  std::filesystem::create_directories(swapped.cache_dir);
  std::filesystem::copy_file(d.instance_library(), std::filesystem::path(swapped.cache_dir) /
                                                       std::filesystem::path(a.instance_library()).filename());
  Handle e(iiwa);
  ASSERT_TRUE(e.specialize(swapped)) << e.specialize_error();
  EXPECT_LT(rbd_test::max_rel_err(rbd_test::run<double>(e, id, in), M), 1e-12);
  // a library of other sizes (HyQ's) in that place is refused, and so is one that others may write
  const auto iiwa_so = std::filesystem::path(swapped.cache_dir) / std::filesystem::path(a.instance_library()).filename();
  rbd::SpecializeOptions other = swapped;
  other.cache_dir += "-other";
  std::filesystem::remove_all(other.cache_dir);
  std::filesystem::create_directories(other.cache_dir);
  std::filesystem::copy_file(c.instance_library(), std::filesystem::path(other.cache_dir) / iiwa_so.filename());
  Handle f(iiwa);
  EXPECT_FALSE(f.specialize(other));
  EXPECT_NE(f.specialize_error().find("another robot's"), std::string::npos) << f.specialize_error();
  rbd::SpecializeOptions shared = swapped;
  shared.cache_dir += "-shared";
  std::filesystem::remove_all(shared.cache_dir);
  std::filesystem::create_directories(shared.cache_dir);
  const auto shared_so = std::filesystem::path(shared.cache_dir) / iiwa_so.filename();
  std::filesystem::copy_file(a.instance_library(), shared_so);
  std::filesystem::permissions(shared_so, std::filesystem::perms::group_write, std::filesystem::perm_options::add);
  EXPECT_FALSE(f.specialize(shared));
  EXPECT_NE(f.specialize_error().find("is not this user's"), std::string::npos) << f.specialize_error();
}

// no compiler, a compiler that fails (on a CPU and a CUDA handle): false, a message, and the generic
// kernels still run
TEST(Specialize, FallsBackWithAReason) {
  const Model m = Model::from_urdf_file(RBDKIT_ROBOTS_DIR "/iiwa.urdf");
  rbd::SpecializeOptions o = test_options();
  o.cache_dir += "-fallback";
  std::filesystem::remove_all(o.cache_dir);
  Handle h(m);
  o.compiler = "/nonexistent/c++";
  EXPECT_FALSE(h.specialize(o));
  EXPECT_FALSE(h.specialized());
  EXPECT_NE(h.specialize_error().find("no C++ compiler"), std::string::npos) << h.specialize_error();
  o.compiler = "false";  // runs, and fails
  EXPECT_FALSE(h.specialize(o));
  EXPECT_NE(h.specialize_error().find("failed to compile"), std::string::npos) << h.specialize_error();
  o.compiler = "";
  o.include_dir = "/nonexistent";
  EXPECT_FALSE(h.specialize(o));
  EXPECT_NE(h.specialize_error().find("rbdkit's headers are not in"), std::string::npos) << h.specialize_error();
  o.include_dir = "";
  o.compiler = "env c++";  // a compiler command of several words
  EXPECT_TRUE(h.specialize(o)) << h.specialize_error();
  {  // a float32 handle computes on the engine
    Handle f32(m, {}, 1, "float32");
    EXPECT_FALSE(f32.specialize(test_options()));
    EXPECT_NE(f32.specialize_error().find("float32"), std::string::npos) << f32.specialize_error();
  }
  {  // a CUDA handle (interpret mode here) whose instance fails keeps the CUDA backend's kernels
    setenv("RBDKIT_CUDA_INTERPRET", "1", 1);
    Handle cuda(m, {}, rbd::Backend::CUDA);
    unsetenv("RBDKIT_CUDA_INTERPRET");
    rbd::SpecializeOptions bad = o;
    bad.compiler = "false";
    EXPECT_FALSE(cuda.specialize(bad));
    EXPECT_FALSE(cuda.specialized());
    EXPECT_FALSE(cuda.cuda()->has_instance());
    EXPECT_NE(cuda.specialize_error().find("failed to compile"), std::string::npos) << cuda.specialize_error();
  }
  // a handle whose specialize() failed computes with the generic kernels
  Handle g(m);
  o.compiler = "false";
  EXPECT_FALSE(g.specialize(o));
  const int id = rbd::ops::find_op("crba");
  const rbd_test::Inputs in = rbd_test::make_inputs(m, *rbd::ops::op_table()[id].spec, 2, 3, false);
  Handle ref(m);
  EXPECT_EQ(rbd_test::run<double>(g, id, in), rbd_test::run<double>(ref, id, in));
}

// a CUDA instance's entry points (launches, device selection) turn an exception into text, which the
// engine throws on its side: no C++ exception crosses the boundary of a library loaded with dlopen. The
// message cut to the buffer, NUL-terminated; an exception of another type named as such
TEST(Specialize, InstanceEntryPointsReportErrorsAsText) {
  namespace ci = rbd::cuda::instance;
  char small[16];
  EXPECT_EQ(ci::guarded([] {}, small, sizeof small), 0);
  EXPECT_EQ(ci::guarded([] { throw std::runtime_error("kernel launch: out of memory"); }, small, sizeof small), 1);
  EXPECT_STREQ(small, "kernel launch: ");  // (15 characters and the NUL)
  char big[200];
  EXPECT_EQ(ci::guarded([] { throw 7; }, big, sizeof big), 1);
  EXPECT_NE(std::string(big).find("an exception that is not a std::exception"), std::string::npos) << big;
  EXPECT_EQ(ci::activate(0, big, sizeof big), 0);  // (an interpret instance has no device to select)
}
