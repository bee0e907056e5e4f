// bench/bench_batch.cpp — batched time per knot point: rbdkit's CPU engine
// (engine.hpp: thread pool + SIMD packs, float64 and float32) against a
// per-sample loop of Pinocchio's C++ algorithms over the same batch, on the
// same number of threads (the batch split into contiguous runs, one
// pinocchio::Data per thread, a persistent pool of the same kind).
//
// Benchmark names:  <impl>/<robot>/<op>/<dtype>/B<B>/T<threads>
//   impl   rbdkit | pinocchio
//   robot  iiwa | hyq | atlas | hyq_floating
//   op     rnea | crba | minv | aba | rnea_derivatives | aba_derivatives |
//          integrator_rk4 | integrator_gradient_rk4
//   dtype  f64 | f32 (rbdkit only)
//   B      1, 16, 64, 256, 1024; B0: one sample by the single-sample
//          function, no engine (the single-call latency), T1 only
// Counter per_knot_ns: wall time per knot point (real time / B).
//
// The rk4 step on Pinocchio's side: four aba stages chained by
// pinocchio::integrate exactly as rbdkit's (plant/integrators.hpp);
// its gradient: computeABADerivatives per stage, dIntegrate for the
// retractions and the same chain rule in Eigen products.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Core>
#include <rbdkit/algorithms/aba_derivatives.hpp>
#include <rbdkit/plant/integrators.hpp>
#include <rbdkit/batch/dynamics.hpp>
#include <rbdkit/batch/engine.hpp>

#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody/data.hpp>
#include <pinocchio/multibody/model.hpp>
#include <pinocchio/parsers/urdf.hpp>

#ifndef RBDKIT_ROBOTS_DIR
#define RBDKIT_ROBOTS_DIR "robots"
#endif

namespace {

constexpr double kG = -9.81, kDt = 0.01;
constexpr long kMaxB = 1024;
using Vec = Eigen::VectorXd;
using Mat = Eigen::MatrixXd;
using PinIn = Eigen::Ref<const Vec>;  // the instantiations in libpinocchio_default.so (see bench_dynamics.cpp)

// a persistent pool for the Pinocchio loop: run(n, f) calls f(t) on threads 0..n-1
class Pool {
 public:
  explicit Pool(int n) : n_(n) {
    for (int t = 1; t < n; ++t) th_.emplace_back([this, t] { loop(t); });
  }
  ~Pool() {
    {
      std::lock_guard<std::mutex> lk(mu_);
      stop_ = true;
    }
    cv_.notify_all();
    for (auto& t : th_) t.join();
  }
  void run(const std::function<void(int)>& f) {
    if (n_ > 1) {
      std::lock_guard<std::mutex> lk(mu_);
      f_ = &f, pending_ = n_ - 1, ++gen_;
    }
    cv_.notify_all();
    f(0);
    std::unique_lock<std::mutex> lk(mu_);
    done_.wait(lk, [this] { return pending_ == 0; });
  }

 private:
  void loop(int t) {
    long seen = 0;
    for (;;) {
      const std::function<void(int)>* f;
      {
        std::unique_lock<std::mutex> lk(mu_);
        cv_.wait(lk, [&] { return stop_ || gen_ != seen; });
        if (stop_) return;
        seen = gen_, f = f_;
      }
      (*f)(t);
      std::lock_guard<std::mutex> lk(mu_);
      if (--pending_ == 0) done_.notify_one();
    }
  }
  int n_;
  std::vector<std::thread> th_;
  std::mutex mu_;
  std::condition_variable cv_, done_;
  const std::function<void(int)>* f_ = nullptr;
  int pending_ = 0;
  long gen_ = 0;
  bool stop_ = false;
};

struct Robot {
  std::string name;
  rbd::Model model;
  pinocchio::Model pmodel;
  // kMaxB random valid samples, row-major, both precisions
  std::vector<double> q, qd, a;
  std::vector<float> qf, qdf, af;
  std::vector<Vec> pq, pqd, pa;
  std::map<std::string, std::unique_ptr<rbd::Engine>> engines;  // "f64/T2"
  std::map<int, std::unique_ptr<Pool>> pools;
  std::map<int, std::vector<std::unique_ptr<pinocchio::Data>>> pdata;
};

std::unique_ptr<Robot> load(const std::string& name) {
  auto r = std::make_unique<Robot>();
  r->name = name;
  const bool floating = name.find("_floating") != std::string::npos;
  const std::string file = name.substr(0, name.find('_'));
  const std::string path = std::string(RBDKIT_ROBOTS_DIR) + "/" + file + ".urdf";
  r->model = rbd::Model::from_urdf_file(path, floating);
  if (floating) pinocchio::urdf::buildModel(path, pinocchio::JointModelFreeFlyer(), r->pmodel);
  else pinocchio::urdf::buildModel(path, r->pmodel);
  r->pmodel.gravity.linear() << 0, 0, kG;
  const int nq = r->model.nq, nv = r->model.nv;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-1, 1);
  r->q.resize(kMaxB * nq), r->qd.resize(kMaxB * nv), r->a.resize(kMaxB * nv);
  const std::vector<double> q0 = r->model.neutral();
  std::vector<double> dv(nv);
  const Vec pq0 = pinocchio::neutral(r->pmodel);
  for (long b = 0; b < kMaxB; ++b) {
    for (double& x : dv) x = U(rng);
    rbd::integrate(r->model.view(), q0.data(), dv.data(), r->q.data() + b * nq);
    for (int k = 0; k < nv; ++k) r->qd[b * nv + k] = U(rng), r->a[b * nv + k] = 5 * U(rng);
    const Vec v = Eigen::Map<Vec>(dv.data(), nv);
    r->pq.push_back(pinocchio::integrate(r->pmodel, pq0, v));
    r->pqd.push_back(Eigen::Map<Vec>(r->qd.data() + b * nv, nv));
    r->pa.push_back(Eigen::Map<Vec>(r->a.data() + b * nv, nv));
  }
  r->qf.assign(r->q.begin(), r->q.end());
  r->qdf.assign(r->qd.begin(), r->qd.end());
  r->af.assign(r->a.begin(), r->a.end());
  return r;
}

std::map<std::string, std::unique_ptr<Robot>>& robots() {
  static std::map<std::string, std::unique_ptr<Robot>> r;
  return r;
}
Robot& robot(const std::string& name) {
  auto& m = robots();
  if (!m.count(name)) m[name] = load(name);
  return *m[name];
}

const char* kOps[] = {"rnea", "crba", "minv", "aba", "rnea_derivatives", "aba_derivatives", "integrator_rk4",
                      "integrator_gradient_rk4"};

// ---- rbdkit: the engine on B samples (outputs preallocated for kMaxB)
template <typename T> struct Outs {
  std::vector<T> o1, o2;
};
template <typename T>
void rbdkit_batch(Robot& r, rbd::Engine& e, int op, long B, Outs<T>& o) {
  const T* q;
  const T* qd;
  const T* a;
  if constexpr (sizeof(T) == 8) q = r.q.data(), qd = r.qd.data(), a = r.a.data();
  else q = r.qf.data(), qd = r.qdf.data(), a = r.af.data();
  const T g = T(kG), dt = T(kDt);
  switch (op) {
    case 0: e.inverse_dynamics<T>(B, q, qd, a, g, o.o1.data()); break;
    case 1: e.crba<T>(B, q, o.o1.data()); break;
    case 2: e.minv<T>(B, q, o.o1.data()); break;
    case 3: e.forward_dynamics<T>(B, q, qd, a, g, o.o1.data()); break;
    case 4: e.inverse_dynamics_gradient<T>(B, q, qd, a, g, o.o1.data(), o.o2.data()); break;
    case 5: e.forward_dynamics_gradient<T>(B, q, qd, a, g, o.o1.data(), o.o2.data()); break;
    case 6: e.integrator<T>(B, q, qd, a, dt, g, rbd::kRK4, o.o1.data()); break;
    default: e.integrator_gradient<T>(B, q, qd, a, dt, g, rbd::kRK4, o.o1.data(), o.o2.data()); break;
  }
}

// ---- rbdkit: one sample by the single-sample functions (B0)
template <typename T> struct Single {
  std::vector<rbd::BodyDesc<T>> bodies;
  rbd::ModelView<T> mv;
  std::unique_ptr<rbd::WorkspaceBufferT<T>> buf;
  std::vector<T> q, qd, a, o1, o2, o3, scratch;
  Single(const Robot& r) : bodies(r.model.bodies_as<T>()), buf(new rbd::WorkspaceBufferT<T>(r.model)) {
    const int nq = r.model.nq, nv = r.model.nv;
    mv = {r.model.nb(), nq, nv, r.model.general_path() ? 1 : 0, bodies.data()};
    q.assign(r.q.begin(), r.q.begin() + nq), qd.assign(r.qd.begin(), r.qd.begin() + nv);
    a.assign(r.a.begin(), r.a.begin() + nv);
    o1.resize(6 * nv * nv + nq + nv), o2.resize(6 * nv * nv), o3.resize(nv);
    scratch.resize(rbd::integrator_gradient_scratch_values(nq, nv));
  }
  void run(int op) {
    rbd::Workspace<T>& w = buf->get();
    const T g = T(kG), dt = T(kDt);
    const T* nf = nullptr;
    const int nq = mv.nq;
    switch (op) {
      case 0: rbd::rnea(mv, w, q.data(), qd.data(), a.data(), nf, g, o1.data()); break;
      case 1: rbd::crba(mv, w, q.data(), o1.data()); break;
      case 2: rbd::minv(mv, w, q.data(), true, o1.data()); break;
      case 3: rbd::aba(mv, w, q.data(), qd.data(), a.data(), nf, g, o1.data()); break;
      case 4: rbd::rnea_derivatives(mv, w, q.data(), qd.data(), a.data(), nf, g, o1.data(), o2.data()); break;
      case 5: rbd::aba_derivatives(mv, w, q.data(), qd.data(), a.data(), nf, g, o3.data(), o1.data(), o2.data()); break;
      case 6:
        rbd::integrator_step(mv, w, rbd::kRK4, q.data(), qd.data(), a.data(), nf, dt, g, o1.data(), o1.data() + nq,
                             scratch.data());
        break;
      default:
        rbd::integrator_gradient(mv, w, rbd::kRK4, q.data(), qd.data(), a.data(), nf, dt, g, o1.data(),
                                 o1.data() + nq, o2.data(), scratch.data());
    }
  }
};

// ---- Pinocchio: one sample
struct PinScratch {
  Vec qs, vs, as, vsum, asum, step;
  Mat Dq, Dv, Da, Dvsum, Dasum, Jq, Jv, T1;
};
void pin_rk4(const pinocchio::Model& m, pinocchio::Data& d, const Vec& q, const Vec& v, const Vec& u, PinScratch& s,
             bool gradient, Vec* qn, Vec* vn, Mat* AB) {
  const int nv = m.nv;
  const double c[4] = {0, 0.5, 0.5, 1}, bw[4] = {1.0 / 6, 1.0 / 3, 1.0 / 3, 1.0 / 6};
  // sizes of the outputs Pinocchio writes into (no allocation after the first call)
  qn->resize(m.nq), vn->resize(nv), s.qs.resize(m.nq), s.Jq.resize(nv, nv), s.Jv.resize(nv, nv);
  s.vsum.setZero(nv), s.asum.setZero(nv);
  if (gradient) {
    s.Dq.setZero(nv, 3 * nv), s.Dv.setZero(nv, 3 * nv), s.Dvsum.setZero(nv, 3 * nv), s.Dasum.setZero(nv, 3 * nv);
    s.Dq.leftCols(nv).setIdentity(), s.Dv.middleCols(nv, nv).setIdentity();
  }
  s.qs = q, s.vs = v;
  for (int st = 0; st < 4; ++st) {
    if (st > 0) {
      const double h = c[st] * kDt;
      s.step = h * s.vs;
      if (gradient) {
        // q_s = q ⊕ h v_(s-1): ∂q_s = Jq [1 0 0] + Jv h ∂v_(s-1)
        pinocchio::dIntegrate(m, q, s.step, s.Jq, pinocchio::ARG0);
        pinocchio::dIntegrate(m, q, s.step, s.Jv, pinocchio::ARG1);
        s.Dq.noalias() = h * s.Jv * s.Dv;
        s.Dq.leftCols(nv) += s.Jq;
        s.Dv = h * s.Da;
        s.Dv.middleCols(nv, nv).diagonal().array() += 1;
      }
      pinocchio::integrate(m, q, s.step, s.qs);
      s.vs = v + h * s.as;
    }
    if (gradient) {
      pinocchio::computeABADerivatives(m, d, PinIn(s.qs), PinIn(s.vs), PinIn(u));
      d.Minv.triangularView<Eigen::StrictlyLower>() = d.Minv.transpose().triangularView<Eigen::StrictlyLower>();
      s.as = d.ddq;
      s.Da.noalias() = d.ddq_dq * s.Dq;
      s.Da.noalias() += d.ddq_dv * s.Dv;
      s.Da.rightCols(nv) += d.Minv;
      s.Dvsum += bw[st] * s.Dv, s.Dasum += bw[st] * s.Da;
    } else {
      s.as = pinocchio::aba(m, d, PinIn(s.qs), PinIn(s.vs), PinIn(u));
    }
    s.vsum += bw[st] * s.vs, s.asum += bw[st] * s.as;
  }
  s.step = kDt * s.vsum;
  pinocchio::integrate(m, q, s.step, *qn);
  *vn = v + kDt * s.asum;
  if (gradient) {
    pinocchio::dIntegrate(m, q, s.step, s.Jq, pinocchio::ARG0);
    pinocchio::dIntegrate(m, q, s.step, s.Jv, pinocchio::ARG1);
    AB->topRows(nv).noalias() = kDt * s.Jv * s.Dvsum;
    AB->topLeftCorner(nv, nv) += s.Jq;
    AB->bottomRows(nv) = kDt * s.Dasum;
    AB->bottomRows(nv).middleCols(nv, nv).diagonal().array() += 1;
  }
}

struct PinThread {
  PinScratch s;
  Vec qn, vn;
  Mat AB;
};
void pin_sample(const pinocchio::Model& m, pinocchio::Data& d, int op, const Vec& q, const Vec& v, const Vec& a,
                PinThread& t) {
  switch (op) {
    case 0: pinocchio::rnea(m, d, PinIn(q), PinIn(v), PinIn(a)); break;
    case 1: pinocchio::crba(m, d, PinIn(q)); break;
    case 2: pinocchio::computeMinverse(m, d, PinIn(q)); break;
    case 3: pinocchio::aba(m, d, PinIn(q), PinIn(v), PinIn(a)); break;
    case 4: pinocchio::computeRNEADerivatives(m, d, PinIn(q), PinIn(v), PinIn(a)); break;
    case 5: pinocchio::computeABADerivatives(m, d, PinIn(q), PinIn(v), PinIn(a)); break;
    case 6: pin_rk4(m, d, q, v, a, t.s, false, &t.qn, &t.vn, nullptr); break;
    default: pin_rk4(m, d, q, v, a, t.s, true, &t.qn, &t.vn, &t.AB);
  }
}

void set_counter(benchmark::State& st, long B) {
  st.counters["per_knot_ns"] =
      benchmark::Counter(double(B) * 1e-9, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

void register_all() {
  const char* names[] = {"iiwa", "hyq", "atlas", "hyq_floating"};
  const long Bs[] = {1, 16, 64, 256, 1024};
  for (const char* rn : names)
    for (int op = 0; op < 8; ++op) {
      const std::string base = std::string("/") + rn + "/" + kOps[op] + "/";
      const std::string robot_name = rn;
      // B0: single-call latency
      benchmark::RegisterBenchmark(("rbdkit" + base + "f64/B0/T1").c_str(), [robot_name, op](benchmark::State& st) {
        Single<double> s(robot(robot_name));
        for (auto _ : st) s.run(op), benchmark::DoNotOptimize(s.o1.data());
        set_counter(st, 1);
      });
      benchmark::RegisterBenchmark(("rbdkit" + base + "f32/B0/T1").c_str(), [robot_name, op](benchmark::State& st) {
        Single<float> s(robot(robot_name));
        for (auto _ : st) s.run(op), benchmark::DoNotOptimize(s.o1.data());
        set_counter(st, 1);
      });
      benchmark::RegisterBenchmark(("pinocchio" + base + "f64/B0/T1").c_str(), [robot_name, op](benchmark::State& st) {
        Robot& r = robot(robot_name);
        pinocchio::Data d(r.pmodel);
        PinThread t;
        t.AB.resize(2 * r.pmodel.nv, 3 * r.pmodel.nv);
        for (auto _ : st) pin_sample(r.pmodel, d, op, r.pq[0], r.pqd[0], r.pa[0], t);
        set_counter(st, 1);
      });
      for (int T : {1, 2})
        for (long B : Bs) {
          const std::string tail = "/B" + std::to_string(B) + "/T" + std::to_string(T);
          for (int f32 = 0; f32 < 2; ++f32)
            benchmark::RegisterBenchmark(("rbdkit" + base + (f32 ? "f32" : "f64") + tail).c_str(),
                                         [robot_name, op, T, B, f32](benchmark::State& st) {
                                           Robot& r = robot(robot_name);
                                           const std::string key = std::string(f32 ? "f32" : "f64") + std::to_string(T);
                                           if (!r.engines[key])
                                             r.engines[key].reset(new rbd::Engine(r.model, T, f32 ? "float32" : "float64"));
                                           rbd::Engine& e = *r.engines[key];
                                           const long n = 6L * r.model.nv * r.model.nv + r.model.nq + r.model.nv;
                                           if (f32) {
                                             Outs<float> o{std::vector<float>(B * n), std::vector<float>(B * n)};
                                             for (auto _ : st) rbdkit_batch<float>(r, e, op, B, o);
                                           } else {
                                             Outs<double> o{std::vector<double>(B * n), std::vector<double>(B * n)};
                                             for (auto _ : st) rbdkit_batch<double>(r, e, op, B, o);
                                           }
                                           set_counter(st, B);
                                         })
                ->UseRealTime();
          benchmark::RegisterBenchmark(("pinocchio" + base + "f64" + tail).c_str(),
                                       [robot_name, op, T, B](benchmark::State& st) {
                                         Robot& r = robot(robot_name);
                                         if (!r.pools[T]) r.pools[T].reset(new Pool(T));
                                         auto& datas = r.pdata[T];
                                         while (int(datas.size()) < T) datas.emplace_back(new pinocchio::Data(r.pmodel));
                                         std::vector<PinThread> th(T);
                                         for (auto& t : th) t.AB.resize(2 * r.pmodel.nv, 3 * r.pmodel.nv);
                                         const std::function<void(int)> job = [&](int t) {
                                           const long b0 = B * t / T, b1 = B * (t + 1) / T;
                                           for (long b = b0; b < b1; ++b)
                                             pin_sample(r.pmodel, *datas[t], op, r.pq[b], r.pqd[b], r.pa[b], th[t]);
                                         };
                                         for (auto _ : st) r.pools[T]->run(job);
                                         set_counter(st, B);
                                       })
              ->UseRealTime();
        }
    }
}

}  // namespace

// the rk4 step and its gradient agree between the two sides (iiwa: a chain,
// the same joint order and the same state in both libraries)
void check_rk4() {
  Robot& r = robot("iiwa");
  Single<double> s(r);
  s.run(7);
  pinocchio::Data d(r.pmodel);
  PinThread t;
  const int nq = r.model.nq, nv = r.model.nv;
  t.AB.resize(2 * nv, 3 * nv);
  pin_rk4(r.pmodel, d, r.pq[0], r.pqd[0], r.pa[0], t.s, true, &t.qn, &t.vn, &t.AB);
  double dx = 0, dab = 0;
  for (int k = 0; k < nq; ++k) dx = std::max(dx, std::abs(s.o1[k] - t.qn[k]));
  for (int k = 0; k < nv; ++k) dx = std::max(dx, std::abs(s.o1[nq + k] - t.vn[k]));
  for (int i = 0; i < 2 * nv; ++i)
    for (int j = 0; j < 3 * nv; ++j) dab = std::max(dab, std::abs(s.o2[i * 3 * nv + j] - t.AB(i, j)));
  std::fprintf(stderr, "check iiwa rk4: max |x+ diff| %.2e, max |AB diff| %.2e\n", dx, dab);
  if (dx > 1e-8 || dab > 1e-8) std::exit(1);
}

int main(int argc, char** argv) {
  check_rk4();
  register_all();
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
