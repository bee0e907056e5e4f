// bench/bench_dynamics.cpp — rbdkit against Pinocchio's C++ library, in one
// run on one machine (Google Benchmark).
//
// Every benchmark is named  <library>/<operation>/<robot>  (library: rbdkit
// or pinocchio); bench/report.py pairs them into a ratio table. Both sides
// time one call on one thread at one random valid state, with preallocated
// storage: rbdkit's per-sample templates on a WorkspaceBuffer, Pinocchio's
// algorithms on a pinocchio::Data made once per robot.
//
// Before timing, the program checks that both libraries compute the same
// outputs at that state (max |difference| printed on stderr; exit 1 when a
// fixed-base robot differs by more than 1e-8), so the times compare equal work.
//
// Adding an operation: one entry in operations() below — a name, the rbdkit
// call, the Pinocchio call and (optionally) how to compare their outputs.
// An entry whose rbdkit side is empty is timed for Pinocchio alone.
//
// <operation>_generated rows (rnea, crba, minv, aba and the two first-order
// derivatives): the same call through the robot's compiled instance
// (rbd::load_instance, Handle::specialize's kernels: the generated header's
// constants), compiled at start-up into $RBDKIT_CACHE_DIR (default
// build/instances under the working directory) unless cached there. Without a
// compiler the program says so and times the generic rows alone.
//
// Arguments: Google Benchmark's (--benchmark_filter, --benchmark_repetitions,
// --benchmark_out=FILE --benchmark_out_format=json, ...) and
//   --robots_dir=DIR   the URDF folder (default: rbdkit's robots/)
//   --check_only       run the agreement check and exit
//   --count_calls=N    no timing: run every (library, operation, robot) that
//                      --benchmark_filter selects N times, each loop between
//                      callgrind client requests, so that
//                      `valgrind --tool=callgrind --collect-atstart=no` writes
//                      one dump per loop named <library>/<operation>/<robot>
//                      (bench/run.sh's COUNT_CALLS mode runs it; bench/callgrind_report.py turns
//                      the dumps into instructions per call)
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <regex>
#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#define RBDKIT_HAVE_CALLGRIND 1
#endif
#include <rbdkit/algorithms/aba_derivatives.hpp>
#include <rbdkit/algorithms/fdsva_so.hpp>
#include <rbdkit/batch/dynamics.hpp>
#include <rbdkit/codegen/specialize.hpp>
#include <rbdkit/ops/registry.hpp>

#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea-second-order-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>
#include <pinocchio/parsers/urdf.hpp>

#ifndef RBDKIT_ROBOTS_DIR
#define RBDKIT_ROBOTS_DIR "robots"
#endif

namespace {

constexpr double kGravity = -9.81;  // world z; Pinocchio's default model.gravity is (0, 0, -9.81)
constexpr double kTolerance = 1e-8;

using Vec = Eigen::VectorXd;

// Pinocchio's arguments go in as Eigen::Ref<const VectorXd>: the type its
// shared library is explicitly instantiated for (PINOCCHIO_ENABLE_TEMPLATE_
// INSTANTIATION declares those instantiations extern), so every Pinocchio
// algorithm timed here is the code compiled into libpinocchio_default.so.
// A plain VectorXd would instantiate some algorithms (aba, crba, minv) in
// this file instead and others (rnea) not. With RBDKIT_BENCH_PINOCCHIO_INLINE
// (CMake option; undefines PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION) all of
// them are compiled here, by this compiler with these flags, like rbdkit.
using PinIn = Eigen::Ref<const Vec>;
inline PinIn pin(const Vec& x) { return PinIn(x); }

// One robot: both libraries' models of the same URDF, one random state,
// preallocated workspaces and outputs.
struct Robot {
  std::string name;  // iiwa, hyq, atlas, hyq_floating, atlas_floating
  bool floating = false;

  rbd::Model model;
  std::unique_ptr<rbd::WorkspaceBuffer> buf;
  rbd::ModelView<double> mv{};
  rbd::Workspace<double>* w = nullptr;
  std::vector<double> out;   // nv x nv, rbdkit's output of every operation
  std::vector<double> out2;  // nv x nv, the second matrix of the derivatives
  std::vector<double> acc;   // nv, the forward-dynamics acceleration of aba_derivatives
  std::vector<double> so;    // 4 x nv³, the second-order tensors (idsva_so, fdsva_so)

  pinocchio::Model pmodel;
  std::unique_ptr<pinocchio::Data> pdata;

  // the compiled instance's kernels of the _generated rows, each with its arguments on this state
  std::shared_ptr<const rbd::Instance> instance;
  rbd::ops::Kernel<double> kernel[6] = {};
  rbd::ops::OpArgs<double> args[6] = {};
  std::vector<double> scratch;

  Vec q, qd, qdd, tau;  // the state both libraries see

  int nv() const { return model.nv; }
};

// ---- operations
//
// rbdkit: one call writing into r.out (r.w, r.mv prepared).
// pinocchio: one call writing into *r.pdata.
// compare (optional): max |rbdkit - Pinocchio| over the outputs both compute,
// called right after running both sides once at r's state.
struct Operation {
  std::string name;
  std::string note;            // what is computed, printed before the check
  void (*rbdkit)(Robot&);      // nullptr: Pinocchio alone
  void (*pinocchio)(Robot&);
  double (*compare)(Robot&);   // nullptr: not checked
};

double max_abs_diff(const double* a, const double* b, long n) {
  double d = 0;
  for (long k = 0; k < n; ++k) d = std::max(d, std::abs(a[k] - b[k]));
  return d;
}

// upper triangles (diagonal included) of rbdkit's row-major nv x nv output
// and a Pinocchio matrix
template <typename M> double max_abs_diff_upper(const Robot& r, const M& P) {
  const int n = r.nv();
  double d = 0;
  for (int i = 0; i < n; ++i)
    for (int j = i; j < n; ++j) d = std::max(d, std::abs(r.out[i * n + j] - P(i, j)));
  return d;
}

// rbdkit's row-major nv x nv output against a full Pinocchio matrix
template <typename M> double max_abs_diff_rowmajor(const std::vector<double>& a, const M& P) {
  const long n = P.rows();
  double d = 0;
  for (long i = 0; i < n; ++i)
    for (long j = 0; j < n; ++j) d = std::max(d, std::abs(a[i * n + j] - P(i, j)));
  return d;
}

// rbdkit's second-order inverse dynamics into r.so; variant 0 body frame, 1 world frame, 2 idsva_so's choice
void idsva_so_call(Robot& r, int variant) {
  const long n3 = static_cast<long>(r.nv()) * r.nv() * r.nv();
  double* t = r.so.data();
  if (variant == 0)
    rbd::idsva_so_body_frame(r.mv, *r.w, r.q.data(), r.qd.data(), r.qdd.data(), kGravity, t, t + n3, t + 2 * n3,
                             t + 3 * n3);
  else if (variant == 1)
    rbd::idsva_so_world_frame(r.mv, *r.w, r.q.data(), r.qd.data(), r.qdd.data(), kGravity, t, t + n3, t + 2 * n3,
                              t + 3 * n3);
  else
    rbd::idsva_so(r.mv, *r.w, r.q.data(), r.qd.data(), r.qdd.data(), kGravity, t, t + n3, t + 2 * n3, t + 3 * n3);
}

// the four tensors against Pinocchio's (same index order: rbdkit row-major
// [i][j][k] arrays, Pinocchio Eigen tensors (i, j, k)); max |difference|
double compare_so(Robot& r) {
  const int n = r.nv();
  const long n3 = static_cast<long>(n) * n * n;
  const pinocchio::Data& d = *r.pdata;
  double e = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const long x = (static_cast<long>(i) * n + j) * n + k;
        e = std::max(e, std::abs(r.so[x] - d.d2tau_dqdq(i, j, k)));
        e = std::max(e, std::abs(r.so[n3 + x] - d.d2tau_dvdv(i, j, k)));
        e = std::max(e, std::abs(r.so[2 * n3 + x] - d.d2tau_dqdv(i, j, k)));
        e = std::max(e, std::abs(r.so[3 * n3 + x] - d.d2tau_dadq(i, j, k)));
      }
  return e;
}

// ---- the _generated rows: rnea, crba, minv, aba, rnea_derivatives, aba_derivatives through the
// instance's kernels (the registered operations inverse_dynamics, crba, minv, aba,
// inverse_dynamics_gradient, forward_dynamics_gradient), writing what the generic rows write
constexpr const char* kGenerated[6][2] = {{"rnea", "inverse_dynamics"},
                                           {"crba", "crba"},
                                           {"minv", "minv"},
                                           {"aba", "aba"},
                                           {"rnea_derivatives", "inverse_dynamics_gradient"},
                                           {"aba_derivatives", "forward_dynamics_gradient"}};

template <int K> void generated(Robot& r) { r.kernel[K](r.mv, *r.w, r.args[K]); }
constexpr void (*kGeneratedCalls[6])(Robot&) = {generated<0>, generated<1>, generated<2>,
                                                 generated<3>, generated<4>, generated<5>};

// loads r's instance (compiling it first if not cached) and points each row's arguments at r's state
// and outputs; false (with the reason printed) when none could be made. flags: the instance's compiler
// flags, "" for SpecializeOptions' own (under callgrind "-O3": valgrind runs no AVX-512 instruction,
// and -march=native emits them on a machine that has them)
bool load_generated(Robot& r, const char* flags) {
  rbd::SpecializeOptions o;
  if (*flags) o.flags = flags;
  const char* dir = std::getenv("RBDKIT_CACHE_DIR");
  o.cache_dir = dir && *dir ? dir : "build/instances";
  try {
    r.instance = rbd::load_instance(r.model, o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench: %s: no _generated rows: %s\n", r.name.c_str(), e.what());
    return false;
  }
  r.scratch.assign(2ul * r.nv() * r.nv(), 0.0);
  for (int k = 0; k < 6; ++k) {
    r.kernel[k] = rbd::instance_kernel(*r.instance, rbd::ops::find_op(kGenerated[k][1]));
    rbd::ops::OpArgs<double>& a = r.args[k];
    a = {};
    a.scratch = r.scratch.data();
    a.in[0] = r.q.data();
  }
  auto& id = r.args[0];  // (q, qd, qdd, gravity, f_ext) -> tau
  id.in[1] = r.qd.data(), id.in[2] = r.qdd.data(), id.real[3] = kGravity, id.out[0] = r.out.data();
  r.args[1].out[0] = r.out.data();  // crba (q) -> M, the whole matrix (the registered operation's output)
  r.args[2].choice[1] = 0, r.args[2].out[0] = r.out.data();  // minv (q, output_dense = false) -> upper M⁻¹
  auto& aba = r.args[3];  // (q, qd, tau, f_ext, gravity) -> qdd
  aba.in[1] = r.qd.data(), aba.in[2] = r.tau.data(), aba.real[4] = kGravity, aba.out[0] = r.out.data();
  auto& did = r.args[4];  // (q, qd, qdd, gravity, f_ext) -> (_, dtau_dq, dtau_dqd)
  did.in[1] = r.qd.data(), did.in[2] = r.qdd.data(), did.real[3] = kGravity;
  did.out[1] = r.out.data(), did.out[2] = r.out2.data();
  auto& dfd = r.args[5];  // (q, qd, tau, f_ext, gravity) -> (dqdd_dq, dqdd_dqd, qdd)
  dfd.in[1] = r.qd.data(), dfd.in[2] = r.tau.data(), dfd.real[4] = kGravity;
  dfd.out[0] = r.out.data(), dfd.out[1] = r.out2.data(), dfd.out[2] = r.acc.data();
  return true;
}

std::vector<Operation> operations() {
  std::vector<Operation> ops;

  ops.push_back({"rnea", "inverse dynamics tau(q, qd, qdd)",
                 [](Robot& r) {
                   rbd::rnea(r.mv, *r.w, r.q.data(), r.qd.data(), r.qdd.data(), static_cast<const double*>(nullptr),
                             kGravity, r.out.data());
                 },
                 [](Robot& r) { pinocchio::rnea(r.pmodel, *r.pdata, pin(r.q), pin(r.qd), pin(r.qdd)); },
                 [](Robot& r) { return max_abs_diff(r.out.data(), r.pdata->tau.data(), r.nv()); }});

  // both write the upper triangle only (rbdkit: crba<kMassUpper> zeroes the strict lower one)
  ops.push_back({"crba", "mass matrix M(q) (both: upper triangle)",
                 [](Robot& r) { rbd::crba<rbd::kMassUpper>(r.mv, *r.w, r.q.data(), r.out.data()); },
                 [](Robot& r) { pinocchio::crba(r.pmodel, *r.pdata, pin(r.q)); },
                 [](Robot& r) { return max_abs_diff_upper(r, r.pdata->M); }});

  // both the whole symmetric M (Pinocchio: its upper triangle, then mirrored)
  ops.push_back({"crba_dense", "mass matrix M(q) (both: the whole matrix)",
                 [](Robot& r) { rbd::crba(r.mv, *r.w, r.q.data(), r.out.data()); },
                 [](Robot& r) {
                   pinocchio::crba(r.pmodel, *r.pdata, pin(r.q));
                   r.pdata->M.triangularView<Eigen::StrictlyLower>() =
                       r.pdata->M.transpose().triangularView<Eigen::StrictlyLower>();
                 },
                 [](Robot& r) { return max_abs_diff_rowmajor(r.out, r.pdata->M); }});

  // both write the upper triangle only (rbdkit: dense=false zeroes the strict lower one)
  ops.push_back({"minv", "inverse mass matrix M(q)^-1 (both: upper triangle)",
                 [](Robot& r) { rbd::minv(r.mv, *r.w, r.q.data(), false, r.out.data()); },
                 [](Robot& r) { pinocchio::computeMinverse(r.pmodel, *r.pdata, pin(r.q)); },
                 [](Robot& r) { return max_abs_diff_upper(r, r.pdata->Minv); }});

  ops.push_back({"aba", "forward dynamics qdd(q, qd, tau), articulated-body algorithm",
                 [](Robot& r) {
                   rbd::aba(r.mv, *r.w, r.q.data(), r.qd.data(), r.tau.data(), static_cast<const double*>(nullptr),
                            kGravity, r.out.data());
                 },
                 [](Robot& r) { pinocchio::aba(r.pmodel, *r.pdata, pin(r.q), pin(r.qd), pin(r.tau)); },
                 [](Robot& r) { return max_abs_diff(r.out.data(), r.pdata->ddq.data(), r.nv()); }});

  // ---- first-order derivatives (both: full matrices; Pinocchio's ABA
  // derivatives also return M⁻¹ (upper triangle), which rbdkit computes inside)
  ops.push_back({"rnea_derivatives", "d tau / d(q, qd) (Pinocchio: computeRNEADerivatives)",
                 [](Robot& r) {
                   rbd::rnea_derivatives(r.mv, *r.w, r.q.data(), r.qd.data(), r.qdd.data(),
                                         static_cast<const double*>(nullptr), kGravity, r.out.data(), r.out2.data());
                 },
                 [](Robot& r) { pinocchio::computeRNEADerivatives(r.pmodel, *r.pdata, pin(r.q), pin(r.qd), pin(r.qdd)); },
                 [](Robot& r) { return std::max(max_abs_diff_rowmajor(r.out, r.pdata->dtau_dq),
                                                max_abs_diff_rowmajor(r.out2, r.pdata->dtau_dv)); }});
  ops.push_back({"aba_derivatives", "d qdd / d(q, qd) (Pinocchio: computeABADerivatives)",
                 [](Robot& r) {
                   rbd::aba_derivatives(r.mv, *r.w, r.q.data(), r.qd.data(), r.tau.data(),
                                        static_cast<const double*>(nullptr), kGravity, r.acc.data(), r.out.data(),
                                        r.out2.data());
                 },
                 [](Robot& r) { pinocchio::computeABADerivatives(r.pmodel, *r.pdata, pin(r.q), pin(r.qd), pin(r.tau)); },
                 [](Robot& r) { return std::max(max_abs_diff_rowmajor(r.out, r.pdata->ddq_dq),
                                                max_abs_diff_rowmajor(r.out2, r.pdata->ddq_dv)); }});

  // ---- second-order derivatives: four (nv x nv x nv) tensors on both sides
  // (Pinocchio's ComputeRNEASecondOrderDerivatives is not instantiated in its
  // shared library: compiled here, like rbdkit). rbdkit's idsva_so picks the
  // body-frame recursion for a fixed base, the world-frame one for a floating base.
  auto pin_so = [](Robot& r) {
    pinocchio::ComputeRNEASecondOrderDerivatives(r.pmodel, *r.pdata, pin(r.q), pin(r.qd), pin(r.qdd));
  };
  ops.push_back({"idsva_so", "d2 tau / d(q, qd)^2, dM/dq (Pinocchio: ComputeRNEASecondOrderDerivatives)",
                 [](Robot& r) { idsva_so_call(r, 2); }, pin_so, compare_so});
  ops.push_back({"idsva_so_body", "the same, rbdkit's body-frame recursion", [](Robot& r) { idsva_so_call(r, 0); },
                 pin_so, compare_so});
  ops.push_back({"idsva_so_world", "the same, rbdkit's world-frame recursion", [](Robot& r) { idsva_so_call(r, 1); },
                 pin_so, compare_so});
  // no Pinocchio counterpart (its C++ library has no second-order forward dynamics)
  ops.push_back({"fdsva_so", "d2 qdd / d(q, qd, u)^2 at qdd = FD(q, qd, tau)",
                 [](Robot& r) {
                   const long n3 = static_cast<long>(r.nv()) * r.nv() * r.nv();
                   double* t = r.so.data();
                   rbd::fdsva_so(r.mv, *r.w, r.q.data(), r.qd.data(), r.tau.data(), kGravity, t, t + n3, t + 2 * n3,
                                 t + 3 * n3);
                 },
                 nullptr, nullptr});

  // the _generated rows, after the rest: the same Pinocchio call and comparison as the generic row
  for (int k = 0; k < 6; ++k)
    for (size_t j = 0; j < ops.size(); ++j)
      if (ops[j].name == kGenerated[k][0]) {
        Operation g = ops[j];
        g.name += "_generated";
        g.note = "the same through the robot's compiled instance (Handle::specialize)";
        g.rbdkit = kGeneratedCalls[k];
        ops.push_back(g);
        break;
      }
  return ops;
}

// ---- robots

std::unique_ptr<Robot> load_robot(const std::string& dir, const std::string& urdf, bool floating, unsigned seed) {
  auto r = std::make_unique<Robot>();
  r->name = urdf + (floating ? "_floating" : "");
  r->floating = floating;
  const std::string path = dir + "/" + urdf + ".urdf";

  r->model = rbd::Model::from_urdf_file(path, floating);
  r->buf = std::make_unique<rbd::WorkspaceBuffer>(r->model);
  r->w = &r->buf->get();
  r->mv = r->model.view();
  r->out.assign(static_cast<size_t>(r->model.nv) * r->model.nv, 0.0);
  r->out2.assign(r->out.size(), 0.0);
  r->acc.assign(r->model.nv, 0.0);
  r->so.assign(4ul * r->model.nv * r->model.nv * r->model.nv, 0.0);

  if (floating)
    pinocchio::urdf::buildModel(path, pinocchio::JointModelFreeFlyer(), r->pmodel);
  else
    pinocchio::urdf::buildModel(path, r->pmodel);
  r->pdata = std::make_unique<pinocchio::Data>(r->pmodel);

  // the two models must share their coordinates (true for the bundled robots)
  const std::vector<std::string> names = r->model.joint_names();
  bool same = r->model.nq == r->pmodel.nq && r->model.nv == r->pmodel.nv &&
              static_cast<int>(names.size()) == static_cast<int>(r->pmodel.njoints) - 1;
  for (size_t k = 0; same && k < names.size(); ++k) {
    const auto& jm = r->pmodel.joints[k + 1];
    const rbd::JointInfo& ji = r->model.joints[r->model.joint_index(names[k])];
    same = names[k] == r->pmodel.names[k + 1] && ji.q_idx == jm.idx_q() && ji.v_idx == jm.idx_v();
  }
  if (!same) {
    std::fprintf(stderr, "bench: %s: rbdkit and Pinocchio order the joints differently; not comparable\n",
                 r->name.c_str());
    std::exit(1);
  }

  // random valid state: q = integrate(neutral, v) (unit quaternion for the
  // free flyer), qd, qdd, tau uniform in [-1, 1]
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  auto rand_vec = [&](int n) {
    Vec x(n);
    for (int k = 0; k < n; ++k) x[k] = U(gen);
    return x;
  };
  const int nq = r->model.nq, nv = r->model.nv;
  const std::vector<double> q0 = r->model.neutral();
  const Vec dq = rand_vec(nv);
  r->q.resize(nq);
  rbd::integrate(r->mv, q0.data(), dq.data(), r->q.data());
  r->qd = rand_vec(nv);
  r->qdd = rand_vec(nv);
  r->tau = rand_vec(nv);
  return r;
}

// op's rbdkit side on r: none for Pinocchio-alone rows, and for _generated rows of a robot without instance
void (*rbdkit_call(const Operation& op, const Robot& r))(Robot&) {
  const bool gen = op.name.size() > 10 && op.name.compare(op.name.size() - 10, 10, "_generated") == 0;
  return gen && !r.instance ? nullptr : op.rbdkit;
}

// ---- the agreement check; false when a fixed-base robot is off
bool check_agreement(std::vector<std::unique_ptr<Robot>>& robots, const std::vector<Operation>& ops) {
  bool ok = true;
  std::fprintf(stderr, "operations:\n");
  for (const Operation& op : ops)
    std::fprintf(stderr, "  %-17s %s%s\n", op.name.c_str(), op.note.c_str(),
                 op.rbdkit ? (op.pinocchio ? "" : " [rbdkit alone]") : " [Pinocchio alone]");
  std::fprintf(stderr, "agreement check at the benchmarked state, max |rbdkit - Pinocchio| (tolerance %.0e%s):\n",
               kTolerance, ", enforced for fixed-base robots");
  for (auto& rp : robots) {
    Robot& r = *rp;
    std::fprintf(stderr, "  %-16s", r.name.c_str());
    for (const Operation& op : ops) {
      if (!rbdkit_call(op, r) || !op.pinocchio || !op.compare) continue;
      op.rbdkit(r);
      op.pinocchio(r);
      const double d = op.compare(r);
      const bool bad = !(d <= kTolerance);
      if (bad && !r.floating) ok = false;
      std::fprintf(stderr, " %s %.1e%s", op.name.c_str(), d, bad ? (r.floating ? " (!)" : " FAIL") : "");
    }
    std::fprintf(stderr, "\n");
  }
  return ok;
}

// ---- Google Benchmark glue: the same loop for both libraries, one call
// through a function pointer per iteration (a predicted indirect call, about
// a nanosecond, on both sides; Pinocchio's own call also goes through the
// shared library's PLT)
void timed_loop(benchmark::State& st, Robot& r, void (*call)(Robot&), const void* out) {
  for (auto _ : st) {
    call(r);
    benchmark::DoNotOptimize(out);
    benchmark::ClobberMemory();
  }
  st.counters["nv"] = r.nv();
}

void register_benchmarks(std::vector<std::unique_ptr<Robot>>& robots, const std::vector<Operation>& ops) {
  auto add = [](const std::string& name, std::function<void(benchmark::State&)> fn) {
    benchmark::RegisterBenchmark(name.c_str(), fn)
        ->ComputeStatistics("min", [](const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); })
        ->Unit(benchmark::kNanosecond);
  };
  for (const Operation& op : ops) {
    for (auto& rp : robots) {
      Robot* r = rp.get();
      // the two sides of one (operation, robot) are registered next to each other
      if (rbdkit_call(op, *r)) {
        auto call = op.rbdkit;
        add("rbdkit/" + op.name + "/" + r->name,
            [r, call](benchmark::State& st) { timed_loop(st, *r, call, r->out.data()); });
      }
      if (op.pinocchio) {
        auto call = op.pinocchio;
        add("pinocchio/" + op.name + "/" + r->name,
            [r, call](benchmark::State& st) { timed_loop(st, *r, call, r->pdata.get()); });
      }
    }
  }
}

// ---- instruction counts: each selected loop of n calls collected by callgrind
// alone and dumped under its benchmark name (outside valgrind the requests do nothing)
void count_calls(std::vector<std::unique_ptr<Robot>>& robots, const std::vector<Operation>& ops, long n,
                 const std::string& filter) {
#ifdef RBDKIT_HAVE_CALLGRIND
  const std::regex select(filter.empty() ? std::string(".*") : filter);
  auto loop = [&](const std::string& name, Robot& r, void (*call)(Robot&)) {
    if (!std::regex_search(name, select)) return;
    call(r);  // warm: first-touch work stays out of the count
    CALLGRIND_TOGGLE_COLLECT;
    for (long k = 0; k < n; ++k) {
      call(r);
      benchmark::ClobberMemory();
    }
    CALLGRIND_TOGGLE_COLLECT;
    CALLGRIND_DUMP_STATS_AT(name.c_str());
    std::fprintf(stderr, "counted %s\n", name.c_str());
  };
  for (const Operation& op : ops)
    for (auto& rp : robots) {
      if (rbdkit_call(op, *rp)) loop("rbdkit/" + op.name + "/" + rp->name, *rp, op.rbdkit);
      if (op.pinocchio) loop("pinocchio/" + op.name + "/" + rp->name, *rp, op.pinocchio);
    }
#else
  (void)robots, (void)ops, (void)n, (void)filter;
  std::fprintf(stderr, "bench: built without <valgrind/callgrind.h>; --count_calls needs it\n");
  std::exit(1);
#endif
}

}  // namespace

int main(int argc, char** argv) {
  std::string dir = RBDKIT_ROBOTS_DIR;
  bool check_only = false;
  long count = 0;
  std::string filter;
  // our own flags first, the rest to Google Benchmark
  std::vector<char*> rest{argv[0]};
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "--robots_dir=", 13) == 0)
      dir = argv[i] + 13;
    else if (std::strcmp(argv[i], "--check_only") == 0)
      check_only = true;
    else if (std::strncmp(argv[i], "--count_calls=", 14) == 0)
      count = std::atol(argv[i] + 14);
    else {
      if (std::strncmp(argv[i], "--benchmark_filter=", 19) == 0) filter = argv[i] + 19;
      rest.push_back(argv[i]);
    }
  }
  int n = static_cast<int>(rest.size());
  benchmark::Initialize(&n, rest.data());
  if (benchmark::ReportUnrecognizedArguments(n, rest.data())) return 2;

  const std::vector<Operation> ops = operations();
  std::vector<std::unique_ptr<Robot>> robots;
  try {
    unsigned seed = 1;
    for (const char* urdf : {"iiwa", "hyq", "atlas"}) robots.push_back(load_robot(dir, urdf, false, seed++));
    for (const char* urdf : {"hyq", "atlas"}) robots.push_back(load_robot(dir, urdf, true, seed++));
    for (auto& r : robots) load_generated(*r, count > 0 ? "-O3" : "");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench: loading the robots from %s: %s\n", dir.c_str(), e.what());
    return 1;
  }

  if (!check_agreement(robots, ops)) {
    std::fprintf(stderr, "bench: rbdkit and Pinocchio disagree beyond %.0e; not timing\n", kTolerance);
    return 1;
  }
  if (check_only) return 0;
  if (count > 0) {
    count_calls(robots, ops, count, filter);
    return 0;
  }

  register_benchmarks(robots, ops);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
