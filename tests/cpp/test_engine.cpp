// The batched CPU engine (engine.hpp) and its SIMD pack (simd.hpp):
//   * Pack<T, W>: lane-wise arithmetic, functions and branch helpers equal
//     the scalar ones lane by lane (sin and cos within two ulps of libm, and
//     equal to the scalar ssincos bit for bit);
//   * every operation, on every model case: results bit-identical for
//     threads 1, 2, 3 and B in {1, 3, 7, 16, 65}; float64 equal to the
//     single-sample functions (rnea, crba, minv, aba, rnea_derivatives,
//     aba_derivatives, integrator_step, integrator_gradient) bit for bit
//     where the scalar code fuses no multiply-add (x86-64 without FMA), else
//     to 1e-12 (M⁻¹ and ∇FD: 1e-12·cond₁(M)/1e4 where cond₁(M) > 1e4, the
//     amplification of fused roundings);
//     float32 within 1e-4 of float64 (relative to max(1, max |value|); 2e-3
//     for M⁻¹, ∇FD and the step gradients, limited by cond(M)·ε_float32);
//     the same when a batch runs as several pool jobs (set_max_job_packs);
//   * bad arguments (threads, dtype, array type, B, integrator type, dt, job size);
//   * an output that overflows is named (output, first sample) at any thread
//     count; the pool's hand-off under churn (made / destroyed, asleep, two
//     callers) gives the one-thread results; the pool on its own runs every
//     unit of every job once, on the threads the job counts in, across
//     jobs of fewer threads and past the wrap of its claims' epoch tag.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/batch/engine.hpp"
#include "rbdkit/batch/simd.hpp"
#include "rbdkit/plant/integrators.hpp"
#include "rbdkit/spatial/dual.hpp"
#include "pool.hpp"
#include "test_models.hpp"

using rbd::Engine;
using rbd::Model;
using rbd_test::ModelCase;
using rbd_test::max_rel_err;

// ------------------------------------------------------------------ Pack
TEST(Pack, LaneWiseEqualsScalar) {
  using P = rbd::Pack<double, 4>;
  P a, b;
  const double av[4] = {0.3, -1.7, 2.5, 1e-9}, bv[4] = {1.1, 0.4, -3.0, 0.0};
  for (int l = 0; l < 4; ++l) a.set(l, av[l]), b.set(l, bv[l]);
  const P s = a + b, d = a - b, m = a * b, q = a / P(2.0), n = -a;
  const P sn = rbd::ssin(a), cs = rbd::scos(a), sq = rbd::ssqrt(rbd::sabs(a)), at = rbd::satan2(a, b);
  for (int l = 0; l < 4; ++l) {
    EXPECT_EQ(s[l], av[l] + bv[l]);
    EXPECT_EQ(d[l], av[l] - bv[l]);
    EXPECT_EQ(m[l], av[l] * bv[l]);
    EXPECT_EQ(q[l], av[l] / 2.0);
    EXPECT_EQ(n[l], -av[l]);
    EXPECT_NEAR(sn[l], std::sin(av[l]), 4e-16);
    EXPECT_NEAR(cs[l], std::cos(av[l]), 4e-16);
    EXPECT_EQ(sq[l], std::sqrt(std::fabs(av[l])));
    EXPECT_EQ(at[l], std::atan2(av[l], bv[l]));
  }
  const auto lt = rbd::lane_lt(a, 1.0);
  EXPECT_TRUE(rbd::any_lane(lt));
  EXPECT_FALSE(rbd::all_lanes(lt));
  EXPECT_TRUE(rbd::all_lanes(rbd::lane_lt(a, 10.0)));
  EXPECT_FALSE(rbd::any_lane(rbd::lane_gt(a, 10.0)));
  const P sel = rbd::select(lt, a, b);
  for (int l = 0; l < 4; ++l) EXPECT_EQ(sel[l], av[l] < 1.0 ? av[l] : bv[l]);
  // NaN lanes fail a positivity test
  P c(1.0);
  c.set(2, std::nan(""));
  EXPECT_FALSE(rbd::all_lanes(rbd::lane_gt(c, 0)));
  // the series switch of lie.hpp, lane by lane: small and large angles in one pack
  P t2;
  const double tv[4] = {0.0, 0.25, 4.0, 0.999};
  for (int l = 0; l < 4; ++l) t2.set(l, tv[l]);
  const P ca = rbd::coef_a(t2), cc = rbd::coef_c(t2);
  for (int l = 0; l < 4; ++l) {
    EXPECT_EQ(ca[l], rbd::coef_a(tv[l]));
    EXPECT_EQ(cc[l], rbd::coef_c(tv[l]));
  }
  rbd::Pack<float, 8> f(0.5);
  EXPECT_EQ((f * f)[7], 0.25f);
}

// the vectorised sin and cos against libm over many angles (every quadrant,
// negative, near multiples of π/2, large |x| through the libm fallback)
TEST(Pack, SinCosWithinUlps) {
  using P = rbd::Pack<double, 8>;
  using F = rbd::Pack<float, 8>;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> U(-40, 40);
  double worst = 0, worst_f = 0;
  for (int it = 0; it < 20000; ++it) {
    P x;
    F xf;
    for (int l = 0; l < 8; ++l) {
      double v = U(rng);
      if (l == 1) v = std::round(v) * 1.5707963267948966;
      if (l == 2) v = v * 1e4;
      if (l == 3 && it % 7 == 0) v = 3e5 * v;
      x.set(l, v), xf.set(l, float(v));
    }
    P s, c;
    F sf, cf;
    rbd::ssincos(x, s, c);
    rbd::ssincos(xf, sf, cf);
    for (int l = 0; l < 8; ++l) {
      worst = std::max({worst, std::fabs(s[l] - std::sin(x[l])), std::fabs(c[l] - std::cos(x[l]))});
      worst_f = std::max({worst_f, std::fabs(double(sf[l]) - std::sin(double(xf[l]))),
                          std::fabs(double(cf[l]) - std::cos(double(xf[l])))});
      // a lane is the scalar function's result, bit for bit (the serial loop and the packs agree)
      double s1, c1;
      float sf1, cf1;
      rbd::ssincos(x[l], s1, c1);
      rbd::ssincos(xf[l], sf1, cf1);
      const double sl = s[l], cl = c[l];
      const float sfl = sf[l], cfl = cf[l];
      ASSERT_EQ(std::memcmp(&sl, &s1, sizeof sl), 0) << x[l];
      ASSERT_EQ(std::memcmp(&cl, &c1, sizeof cl), 0) << x[l];
      ASSERT_EQ(std::memcmp(&sfl, &sf1, sizeof sfl), 0) << xf[l];
      ASSERT_EQ(std::memcmp(&cfl, &cf1, sizeof cfl), 0) << xf[l];
    }
  }
  EXPECT_LE(worst, 1e-15);
  EXPECT_LE(worst_f, 6e-8);
  // packs live anywhere: one at an element-aligned (not vector-aligned) address
  alignas(64) unsigned char buf[4 * sizeof(P) + 64];
  P* xs = reinterpret_cast<P*>(buf + sizeof(double));
  P* ss = xs + 1;
  P* cs = xs + 2;
  for (int l = 0; l < 8; ++l) xs->set(l, 0.4 * l - 1.3);
  rbd::ssincos(*xs, *ss, *cs);
  for (int l = 0; l < 8; ++l) EXPECT_NEAR((*ss)[l], std::sin((*xs)[l]), 1e-15) << l;
}

// the scalar sin and cos (every joint's rotation on the host) against libm: every quadrant, both
// signs, the rounding ties of x·2/π, multiples of π/2 and π/4, tiny and large |x| (the libm
// fallback past 1e5), inf and NaN, sin(-0) = -0; ssin and scos are its two halves, and dual
// numbers carry cos and -sin as derivatives
TEST(Scalar, SinCosWithinUlps) {
  std::vector<double> xs = {0.0, -0.0, 1e-300, -1e-300, 1e-8, 0.5, -0.5, 1e5, -1e5, 1.0000001e5, 3e7, -1e300};
  for (int k = -40; k <= 40; ++k)
    for (double f : {0.0, 0.25, 0.5, 0.75}) {
      const double x = (k + f) * 1.5707963267948966;
      xs.push_back(x), xs.push_back(std::nextafter(x, 1e9)), xs.push_back(std::nextafter(x, -1e9));
    }
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-60, 60);
  for (int it = 0; it < 100000; ++it) xs.push_back(U(rng) * (it % 5 == 0 ? 1000.0 : 1.0));
  double worst = 0, worst_f = 0;
  for (const double x : xs) {
    double s, c;
    rbd::ssincos(x, s, c);
    ASSERT_TRUE(std::isfinite(s) && std::isfinite(c)) << x;
    worst = std::max({worst, std::fabs(s - std::sin(x)), std::fabs(c - std::cos(x))});
    const double s2 = rbd::ssin(x), c2 = rbd::scos(x);
    ASSERT_EQ(std::memcmp(&s2, &s, sizeof s), 0) << x;
    ASSERT_EQ(std::memcmp(&c2, &c, sizeof c), 0) << x;
    if (std::fabs(x) > 1e30) continue;  // (not a float)
    float sf, cf;
    const float xf = static_cast<float>(x);
    rbd::ssincos(xf, sf, cf);
    ASSERT_TRUE(std::isfinite(sf) && std::isfinite(cf)) << xf;
    worst_f = std::max({worst_f, std::fabs(double(sf) - std::sin(double(xf))), std::fabs(double(cf) - std::cos(double(xf)))});
  }
  double s0, c0;
  rbd::ssincos(-0.0, s0, c0);
  EXPECT_TRUE(std::signbit(s0) && s0 == 0.0 && c0 == 1.0);  // sin(-0) = -0, as libm
  EXPECT_LE(worst, 1e-15);
  EXPECT_LE(worst_f, 6e-8);
  for (const double bad : {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::quiet_NaN()}) {
    double s, c;
    rbd::ssincos(bad, s, c);
    EXPECT_TRUE(std::isnan(s) && std::isnan(c));
  }
  rbd::Dual<double> s, c;
  rbd::ssincos(rbd::Dual<double>{0.7, 2.0}, s, c);
  double s7, c7;
  rbd::ssincos(0.7, s7, c7);
  EXPECT_EQ(s.v, s7);
  EXPECT_EQ(s.d, 2.0 * c7);
  EXPECT_EQ(c.v, c7);
  EXPECT_EQ(c.d, -2.0 * s7);
  EXPECT_NEAR(s7, std::sin(0.7), 2e-16);
}

// ------------------------------------------------------------------ engine
namespace {

constexpr int kOps = 18;  // 0 ID, 1 CRBA, 2 M⁻¹, 3 FD, 4 ∇ID, 5 ∇FD (+ M⁻¹), 6..11 integrator, 12..17 its gradient
const double kDt = 0.01, kG = -9.81;

struct Samples {
  std::vector<double> q, qd, a;  // q (B x nq), qd (B x nv), a: qdd / tau / u (B x nv)
};

Samples make_samples(const Model& m, long B, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1, 1);
  Samples s;
  s.q.resize(B * m.nq), s.qd.resize(B * m.nv), s.a.resize(B * m.nv);
  const std::vector<double> q0 = m.neutral();
  std::vector<double> dv(m.nv);
  for (long b = 0; b < B; ++b) {
    for (double& x : dv) x = U(rng);
    rbd::integrate(m.view(), q0.data(), dv.data(), s.q.data() + b * m.nq);
    for (int k = 0; k < m.nv; ++k) s.qd[b * m.nv + k] = U(rng), s.a[b * m.nv + k] = 5 * U(rng);
  }
  return s;
}

// values per sample of an operation's outputs, concatenated
long out_width(const Model& m, int op) {
  const long nv = m.nv, nn = nv * nv;
  switch (op) {
    case 0: case 3: return nv;
    case 1: case 2: return nn;
    case 4: return 2 * nn;
    case 5: return 3 * nn;
    default: return op < 12 ? m.nq + nv : m.nq + nv + 6 * nn;
  }
}

// the engine on the first B samples; per sample, the outputs concatenated
template <typename T> std::vector<T> run_engine(Engine& e, int op, long B, const Samples& s64) {
  const Model& m = e.model();
  const long nv = m.nv, nn = nv * nv, nq = m.nq;
  std::vector<T> q(s64.q.begin(), s64.q.begin() + B * nq), qd(s64.qd.begin(), s64.qd.begin() + B * nv),
      a(s64.a.begin(), s64.a.begin() + B * nv);
  const long w = out_width(m, op);
  std::vector<T> o1(B * w), o2(B * w), o3(B * w), out(B * w);
  auto pack = [&](std::initializer_list<std::pair<const std::vector<T>*, long>> parts) {
    for (long b = 0; b < B; ++b) {
      long off = 0;
      for (auto& p : parts) {
        for (long k = 0; k < p.second; ++k) out[b * w + off + k] = (*p.first)[b * p.second + k];
        off += p.second;
      }
    }
  };
  const T g = T(kG), dt = T(kDt);
  switch (op) {
    case 0: e.inverse_dynamics<T>(B, q.data(), qd.data(), a.data(), g, o1.data()); pack({{&o1, nv}}); break;
    case 1: e.crba<T>(B, q.data(), o1.data()); pack({{&o1, nn}}); break;
    case 2: e.minv<T>(B, q.data(), o1.data()); pack({{&o1, nn}}); break;
    case 3: e.forward_dynamics<T>(B, q.data(), qd.data(), a.data(), g, o1.data()); pack({{&o1, nv}}); break;
    case 4:
      e.inverse_dynamics_gradient<T>(B, q.data(), qd.data(), a.data(), g, o1.data(), o2.data());
      pack({{&o1, nn}, {&o2, nn}});
      break;
    case 5:
      e.forward_dynamics_gradient<T>(B, q.data(), qd.data(), a.data(), g, o1.data(), o2.data(), o3.data());
      pack({{&o1, nn}, {&o2, nn}, {&o3, nn}});
      break;
    default:
      if (op < 12) {
        e.integrator<T>(B, q.data(), qd.data(), a.data(), dt, g, op - 6, o1.data());
        pack({{&o1, nq + nv}});
      } else {
        e.integrator_gradient<T>(B, q.data(), qd.data(), a.data(), dt, g, op - 12, o1.data(), o2.data());
        pack({{&o1, nq + nv}, {&o2, 6 * nn}});
      }
  }
  return out;
}

// the single-sample functions on sample b
std::vector<double> reference(const Model& m, int op, const Samples& s, long b) {
  rbd::WorkspaceBuffer buf(m);
  rbd::Workspace<double>& w = buf.get();
  const rbd::ModelView<double> mv = m.view();
  const long nv = m.nv, nn = nv * nv, nq = m.nq;
  const double* q = s.q.data() + b * nq;
  const double* qd = s.qd.data() + b * nv;
  const double* a = s.a.data() + b * nv;
  std::vector<double> out(out_width(m, op)), tmp(nv);
  std::vector<double> scratch(rbd::integrator_gradient_scratch_values(m.nq, m.nv));
  bool ok = true;
  switch (op) {
    case 0: rbd::rnea(mv, w, q, qd, a, static_cast<const double*>(nullptr), kG, out.data()); break;
    case 1: rbd::crba(mv, w, q, out.data()); break;
    case 2: ok = rbd::minv(mv, w, q, true, out.data()); break;
    case 3: ok = rbd::aba(mv, w, q, qd, a, static_cast<const double*>(nullptr), kG, out.data()); break;
    case 4: rbd::rnea_derivatives(mv, w, q, qd, a, static_cast<const double*>(nullptr), kG, out.data(), out.data() + nn); break;
    case 5:
      ok = rbd::aba_derivatives(mv, w, q, qd, a, static_cast<const double*>(nullptr), kG, tmp.data(), out.data(),
                                out.data() + nn);
      ok = ok && rbd::minv(mv, w, q, true, out.data() + 2 * nn);  // (∇FD's M⁻¹: minv's, as forward_dynamics takes it)
      break;
    default:
      if (op < 12)
        ok = rbd::integrator_step(mv, w, op - 6, q, qd, a, static_cast<const double*>(nullptr), kDt, kG, out.data(),
                                  out.data() + nq, scratch.data());
      else
        ok = rbd::integrator_gradient(mv, w, op - 12, q, qd, a, static_cast<const double*>(nullptr), kDt, kG,
                                      out.data(), out.data() + nq, out.data() + nq + nv, scratch.data());
  }
  EXPECT_TRUE(ok);
  return out;
}

std::vector<double> sample_of(const std::vector<double>& all, long w, long b) {
  return std::vector<double>(all.begin() + b * w, all.begin() + (b + 1) * w);
}

// 1-norm condition number of M (n x n) from M and M⁻¹
double cond1(const std::vector<double>& M, const std::vector<double>& Minv, int n) {
  auto norm1 = [n](const std::vector<double>& A) {
    double best = 0;
    for (int c = 0; c < n; ++c) {
      double col = 0;
      for (int r = 0; r < n; ++r) col += std::fabs(A[r * n + c]);
      best = std::max(best, col);
    }
    return best;
  };
  return norm1(M) * norm1(Minv);
}

class EngineModels : public ::testing::TestWithParam<ModelCase> {};

}  // namespace

TEST_P(EngineModels, DeterministicAndEqualToSingleSample) {
  const ModelCase& c = GetParam();
  const Model m = Model::from_urdf_file(c.path, c.floating);
  const long Bmax = 65;
  const Samples s = make_samples(m, Bmax, 7);
  Engine e1(m, 1, "float64"), e2(m, 2, "float64"), e3(m, 3, "float64");
  // a batch of more packs than one pool job takes runs as several jobs, one after another: here
  // jobs of one pack and of two (in use, past 2^24 - 1 packs)
  Engine e2_jobs(m, 2, "float64"), e3_jobs(m, 3, "float64");
  e2_jobs.set_max_job_packs(1), e3_jobs.set_max_job_packs(2);
  for (int op = 0; op < kOps; ++op) {
    SCOPED_TRACE("op " + std::to_string(op));
    const long w = out_width(m, op);
    const std::vector<double> full = run_engine<double>(e1, op, Bmax, s);
    // bit-identical whatever the thread count, batch size and job size
    for (Engine* e : {&e1, &e2, &e3, &e2_jobs, &e3_jobs})
      for (long B : {1L, 3L, 7L, 16L, 65L}) {
        const std::vector<double> part = run_engine<double>(*e, op, B, s);
        for (long k = 0; k < B * w; ++k)
          ASSERT_EQ(std::memcmp(&part[k], &full[k], sizeof(double)), 0)
              << "threads " << e->threads() << " B " << B << " value " << k
              << (e == &e2_jobs || e == &e3_jobs ? " (several jobs)" : "");
      }
    // equal to the single-sample functions: bit for bit where this file's scalar code fuses no
    // multiply-add (x86-64 without FMA, CI's build: the engine's lanes do the same IEEE operations,
    // sin and cos included), but for the sign of a zero (the scalar CRBA's column transforms about z
    // drop products by exact zeros, crba_act_columns); elsewhere to 1e-12, and M⁻¹ amplifies a fused
    // rounding by up to cond(M)
    for (long b = 0; b < Bmax; b += 8) {
      const std::vector<double> ref = reference(m, op, s, b);
      double tol = 1e-12;
      if (op == 2 || op == 5) tol *= std::max(1.0, cond1(reference(m, 1, s, b), reference(m, 2, s, b), m.nv) / 1e4);
      EXPECT_LE(max_rel_err(sample_of(full, w, b), ref), tol) << "sample " << b;
#if defined(__x86_64__) && !defined(__FMA__)
      const std::vector<double> got = sample_of(full, w, b);
      ASSERT_EQ(got.size(), ref.size());
      for (size_t k = 0; k < ref.size(); ++k)
        ASSERT_TRUE(got[k] == ref[k] || std::memcmp(&got[k], &ref[k], sizeof(double)) == 0)
            << "sample " << b << " value " << k << ": " << got[k] << " against " << ref[k];
#endif
    }
  }
}

TEST_P(EngineModels, Float32CloseToFloat64) {
  const ModelCase& c = GetParam();
  const Model m = Model::from_urdf_file(c.path, c.floating);
  const long B = 19;
  const Samples s = make_samples(m, B, 11);
  Engine e64(m, 2, "float64"), e32(m, 2, "float32");
  for (int op = 0; op < kOps; ++op) {
    SCOPED_TRACE("op " + std::to_string(op));
    const long w = out_width(m, op);
    const std::vector<double> r64 = run_engine<double>(e64, op, B, s);
    const std::vector<float> r32f = run_engine<float>(e32, op, B, s);
    const std::vector<double> r32(r32f.begin(), r32f.end());
    // M⁻¹ and what is built on it (∇FD, step gradients) carry cond(M)·ε_float32 (docs/engine.md)
    const double tol = op == 2 || op == 5 || op >= 12 ? 2e-3 : 1e-4;
    for (long b = 0; b < B; ++b) EXPECT_LE(max_rel_err(sample_of(r32, w, b), sample_of(r64, w, b)), tol) << "sample " << b;
  }
}

INSTANTIATE_TEST_SUITE_P(Models, EngineModels, ::testing::ValuesIn(rbd_test::all_cases()), rbd_test::case_name);

TEST(Engine, BadArguments) {
  const Model m = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf");
  auto message = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "no exception";
  };
  EXPECT_NE(message([&] { Engine e(m, 0); }).find("threads"), std::string::npos);
  EXPECT_NE(message([&] { Engine e(m, -2); }).find("threads"), std::string::npos);
  EXPECT_NE(message([&] { Engine e(m, 1, "float16"); }).find("dtype"), std::string::npos);
  Engine e(m, 2, "float32");
  EXPECT_EQ(e.threads(), 2);
  EXPECT_EQ(e.dtype(), "float32");
  std::vector<double> q(m.nq), M(m.nv * m.nv);
  std::vector<float> qf(m.nq), Mf(m.nv * m.nv), x(m.nq + m.nv), v(m.nv);
  EXPECT_NE(message([&] { e.crba<double>(1, q.data(), M.data()); }).find("float32"), std::string::npos);
  EXPECT_NE(message([&] { e.crba<float>(0, qf.data(), Mf.data()); }).find("B"), std::string::npos);
  EXPECT_NE(message([&] { e.integrator<float>(1, qf.data(), v.data(), v.data(), 0.01f, -9.81f, 9, x.data()); })
                .find("integrator_type"),
            std::string::npos);
  EXPECT_NE(message([&] { e.integrator<float>(1, qf.data(), v.data(), v.data(), 0.0f, -9.81f, 0, x.data()); })
                .find("dt"),
            std::string::npos);
  EXPECT_NE(message([&] { e.set_max_job_packs(0); }).find("set_max_job_packs: packs: expected 1..16777215, got 0"),
            std::string::npos);
  EXPECT_NE(message([&] { e.set_max_job_packs(1L << 24); }).find("packs"), std::string::npos);
  EXPECT_GE(Engine::default_threads(), 1);
  Engine d(m);
  EXPECT_EQ(d.threads(), Engine::default_threads());
}

// a joint that moves no mass under the fixed world: float64 and float32
// engines name it (the pack's D = 0 used to give inf, then NaN results)
TEST(Engine, JointThatMovesNoMassIsNamed) {
  const Model m = Model::from_urdf_string(R"(<robot name="r"><link name="base"/>
    <link name="arm"><inertial><mass value="2"/><origin xyz="0.3 0 0"/>
      <inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
    <joint name="arm_joint" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/></joint>
    <link name="cam"/>
    <joint name="cam_joint" type="revolute"><parent link="base"/><child link="cam"/><axis xyz="0 1 0"/></joint>
    </robot>)");
  auto message = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "no exception";
  };
  const long B = 5;
  for (const char* dtype : {"float64", "float32"}) {
    Engine e(m, 2, dtype);
    auto run = [&](auto zero) {
      using T = decltype(zero);
      std::vector<T> q(B * m.nq, T(0.2)), v(B * m.nv, T(0.1)), out(B * m.nv), M(B * m.nv * m.nv),
          x(B * (m.nq + m.nv)), AB(B * 6 * m.nv * m.nv);
      for (const std::string& msg :
           {message([&] { e.forward_dynamics<T>(B, q.data(), v.data(), v.data(), T(-9.81), out.data()); }),
            message([&] { e.minv<T>(B, q.data(), M.data()); }),
            message([&] { e.integrator<T>(B, q.data(), v.data(), v.data(), T(0.01), T(-9.81), 3, x.data()); }),
            message([&] {
              e.integrator_gradient<T>(B, q.data(), v.data(), v.data(), T(0.01), T(-9.81), 0, x.data(), AB.data());
            })})
        EXPECT_NE(msg.find("joint 'cam_joint' moves no mass at sample 0"), std::string::npos) << dtype << ": " << msg;
    };
    if (std::string(dtype) == "float64") run(0.0);
    else run(0.0f);
  }
}

// ID, FD and the explicit integrator steps need only the linear workspace
// (O(nb + nv) per knot point): the engine's buffers grow linearly with the
// chain until an operation that needs the full one runs, and the results
// are bit-identical to those of an engine that holds the full one
TEST(Engine, LinearOperationsKeepALinearWorkspace) {
  auto chain = [](int n) {
    std::string s = "<robot name=\"chain\"><link name=\"l0\"/>";
    for (int k = 1; k <= n; ++k) {
      const std::string i = std::to_string(k), p = std::to_string(k - 1);
      s += "<link name=\"l" + i + "\"><inertial><origin xyz=\"0 0.05 0\"/><mass value=\"1\"/>"
           "<inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.01\"/></inertial></link>"
           "<joint name=\"j" + i + "\" type=\"revolute\"><parent link=\"l" + p + "\"/><child link=\"l" + i +
           "\"/><origin xyz=\"0 0.1 0\"/><axis xyz=\"1 0 0\"/></joint>";
    }
    return Model::from_urdf_string(s + "</robot>");
  };
  const long B = 3;
  auto run_linear_ops = [&](Engine& e, const Model& m, std::vector<double>& out) {
    std::vector<double> q(B * m.nq), qd(B * m.nv), u(B * m.nv);
    for (size_t k = 0; k < q.size(); ++k) q[k] = 0.01 * std::sin(0.7 * k), qd[k] = 0.1 * std::cos(0.3 * k);
    for (size_t k = 0; k < u.size(); ++k) u[k] = 0.5 * std::sin(1.3 * k);
    std::vector<double> tau(B * m.nv), qdd(B * m.nv), x(B * (m.nq + m.nv));
    e.inverse_dynamics(B, q.data(), qd.data(), u.data(), -9.81, tau.data());
    e.forward_dynamics(B, q.data(), qd.data(), u.data(), -9.81, qdd.data());
    e.integrator(B, q.data(), qd.data(), u.data(), 0.01, -9.81, rbd::kRK4, x.data());
    out = tau;
    out.insert(out.end(), qdd.begin(), qdd.end());
    out.insert(out.end(), x.begin(), x.end());
  };
  const Model small = chain(150), big = chain(300);
  Engine es(small, 1), eb(big, 1);
  std::vector<double> rs, rb;
  run_linear_ops(es, small, rs);
  run_linear_ops(eb, big, rb);
  const double linear_ratio = double(eb.workspace_bytes()) / double(es.workspace_bytes());
  EXPECT_LT(linear_ratio, 2.3) << es.workspace_bytes() << " -> " << eb.workspace_bytes();
  // an engine that has run CRBA holds the full layout (quadratic) and gives the same bits
  Engine full(big, 1);
  std::vector<double> q(B * big.nq, 0.0), M(B * big.nv * big.nv);
  full.crba(B, q.data(), M.data());
  EXPECT_GT(double(full.workspace_bytes()) / double(eb.workspace_bytes()), 4.0);
  std::vector<double> rf;
  run_linear_ops(full, big, rf);
  ASSERT_EQ(rf.size(), rb.size());
  for (size_t k = 0; k < rf.size(); ++k) ASSERT_EQ(rf[k], rb[k]) << k;
}

// an output that overflows from finite inputs is named: the first output in
// the operation's order, at its first such sample, whatever the thread count
// (each thread checks the packs it ran)
TEST(Engine, OutputThatOverflowsIsNamed) {
  const Model m = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf");
  const long B = 65, nv = m.nv;
  const Samples s = make_samples(m, B, 3);
  auto message = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "no exception";
  };
  for (const char* dtype : {"float64", "float32"})
    for (int threads : {1, 2, 3}) {
      Engine e(m, threads, dtype);
      // with 3 threads, jobs of one pack: the samples are named across jobs
      if (threads == 3) e.set_max_job_packs(1);
      auto run = [&](auto zero) {
        using T = decltype(zero);
        std::vector<T> q(s.q.begin(), s.q.end()), qd(s.qd.begin(), s.qd.end()), a(s.a.begin(), s.a.end()),
            tau(B * nv), d1(B * nv * nv), d2(B * nv * nv);
        // a joint velocity whose square overflows, in three samples of three packs
        for (long b : {50L, 37L, 61L}) qd[b * nv + 1] = std::numeric_limits<T>::max() / 4;
        const std::string id = message([&] { e.inverse_dynamics<T>(B, q.data(), qd.data(), a.data(), T(kG), tau.data()); });
        EXPECT_NE(id.find("inverse_dynamics: output 0 is not finite at sample 37"), std::string::npos)
            << dtype << " threads " << threads << ": " << id;
        // (output 1: dtau_dq, ops::InverseDynamicsGradient's second output)
        const std::string grad = message(
            [&] { e.inverse_dynamics_gradient<T>(B, q.data(), qd.data(), a.data(), T(kG), d1.data(), d2.data()); });
        EXPECT_NE(grad.find("inverse_dynamics_gradient: output 1 is not finite at sample 37"), std::string::npos)
            << dtype << " threads " << threads << ": " << grad;
        // the other samples are computed, and finite
        for (long b = 0; b < 37; ++b)
          for (long k = 0; k < nv; ++k) ASSERT_TRUE(std::isfinite(tau[b * nv + k])) << b;
      };
      if (std::string(dtype) == "float64") run(0.0);
      else run(0.0f);
    }
}

// the pool's hand-off under churn: engines made and destroyed around short
// calls, more threads than cores, calls after the workers have gone to
// sleep, and two callers on one engine (their calls serialise): every result
// bit-identical to the one-thread engine's
TEST(Engine, PoolHandOffUnderChurn) {
  const Model m = Model::from_urdf_file(std::string(RBDKIT_ROBOTS_DIR) + "/iiwa.urdf");
  const long B = 64;
  const Samples s = make_samples(m, B, 5);
  Engine one(m, 1);
  const std::vector<double> want_id = run_engine<double>(one, 0, B, s), want_crba = run_engine<double>(one, 1, B, s);
  auto same = [](const std::vector<double>& got, const std::vector<double>& want) {
    return std::memcmp(got.data(), want.data(), got.size() * sizeof(double)) == 0;
  };
  for (int round = 0; round < 40; ++round) {
    Engine e(m, 1 + round % 4);
    for (long b : {1L, 9L, B}) ASSERT_TRUE(same(run_engine<double>(e, 0, b, s), want_id)) << round << " B " << b;
    if (round % 8 == 0) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));  // the workers are asleep now
      ASSERT_TRUE(same(run_engine<double>(e, 1, B, s), want_crba)) << round;
    }
  }
  Engine shared(m, 2);
  std::atomic<int> wrong{0};
  auto caller = [&](int op) {
    for (int k = 0; k < 100; ++k)
      if (!same(run_engine<double>(shared, op, B, s), op == 0 ? want_id : want_crba)) ++wrong;
  };
  std::thread a(caller, 0), b(caller, 1);
  a.join();
  b.join();
  EXPECT_EQ(wrong.load(), 0);
}

// the pool alone: every unit of a job runs once, on threads 0 .. active - 1
// only, for job sizes around the thread count, jobs of fewer threads than the
// pool (their shares left alone), jobs after the workers have gone to sleep,
// and a share untouched for exactly 2^kTagBits jobs (its claim word then
// carries the current job's tag: the pool must reset it, or that share's
// units would look taken)
TEST(Engine, PoolRunsEveryUnitOnce) {
  using rbd::engine_detail::Pool;
  struct Count {
    std::unique_ptr<std::atomic<int>[]> runs;
    int active;
    std::atomic<int> outside{0};
  };
  const Pool::Fn job = [](void* ctx, int t, Pool::Claims& claims) {
    Count& k = *static_cast<Count*>(ctx);
    if (t >= k.active) ++k.outside;
    long u0, u1;
    while (claims.next(u0, u1))
      for (long u = u0; u < u1; ++u) k.runs[u].fetch_add(1, std::memory_order_relaxed);
  };
  Pool pool(4);
  auto check = [&](int active, long units) {
    Count k{std::unique_ptr<std::atomic<int>[]>(new std::atomic<int>[units]()), static_cast<int>(std::min<long>(active, units))};
    pool.run(active, units, job, &k);
    long wrong = 0;
    for (long u = 0; u < units; ++u) wrong += k.runs[u].load() != 1;
    return wrong == 0 && k.outside.load() == 0;
  };
  for (int round = 0; round < 200; ++round)
    for (int active : {1, 2, 3, 4, 6})
      for (long units : {1L, 2L, 3L, 5L, 64L, 1000L}) ASSERT_TRUE(check(active, units)) << active << " " << units;
  std::this_thread::sleep_for(std::chrono::milliseconds(2));  // the workers are asleep now
  ASSERT_TRUE(check(4, 1000));
  // shares 1..3 exhausted at some job e0, then 2^kTagBits - 1 jobs on thread 0 alone: the next job's
  // tag equals e0's, and its (smaller) shares would read as taken
  ASSERT_TRUE(check(4, 4000));
  Count idle{std::unique_ptr<std::atomic<int>[]>(new std::atomic<int>[1]()), 1};
  for (long j = 0; j < (1L << Pool::kTagBits) - 1; ++j) pool.run(1, 1, job, &idle);
  EXPECT_EQ(idle.runs[0].load(), (1L << Pool::kTagBits) - 1);
  EXPECT_TRUE(check(4, 400));
  EXPECT_TRUE(check(4, 4000));
}
