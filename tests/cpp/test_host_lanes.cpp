// The host vector forms of the spatial transforms, each against the scalar form in long double
// (which the double-only vector forms do not take; the instances themselves are checked against the
// library in test_specialize.cpp). This file is compiled twice, headers only:
//   - rbdkit_host_lanes_tests, for x86-64's baseline (SSE2), as the library is: spatial.hpp's
//     transform_inertia_pairs and crba.hpp's crba_act_column_pairs (2-lane vectors, in the frame-axis forms);
//   - rbdkit_host_avx_tests, with -mavx2 (RBD_HOST_AVX: what a per-robot instance compiled with
//     -march=native takes): transform_inertia_pairs again and crba_act_columns_avx (4-lane vectors).
// The AVX forms skip on a processor without AVX2, except under CI=true, where they fail.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <random>
#include <vector>

#include "rbdkit/algorithms/crba.hpp"

#if defined(RBD_HOST_AVX)
#define HOST_LANES HostAvx
#elif defined(RBD_CRBA_COLUMN_PAIRS) && defined(RBD_TRANSFORM_INERTIA_PAIRS)
#define HOST_LANES HostLanes
#else
#error "test_host_lanes.cpp: neither the AVX forms (-mavx2) nor the 2-lane forms (x86-64 with GCC or clang) are compiled"
#endif

using namespace rbd;

namespace {

#if defined(RBD_HOST_AVX)
bool cpu_has_avx2() { return __builtin_cpu_supports("avx2"); }
// the AVX forms cannot run on a processor without AVX2 (an illegal instruction); CI's machines have it,
// so there a missing AVX2 is a failure, not a skip
#define RBD_REQUIRE_AVX2()                                                            \
  do {                                                                                \
    if (!cpu_has_avx2()) {                                                            \
      const char* ci = std::getenv("CI");                                             \
      if (ci && std::string(ci) == "true") FAIL() << "CI's processor has no AVX2";    \
      GTEST_SKIP() << "this processor has no AVX2";                                   \
    }                                                                                 \
  } while (0)
#else
#define RBD_REQUIRE_AVX2() \
  do {                     \
  } while (0)
#endif

template <typename T> Transform<T> transform_as(const Transform<double>& X) {
  Transform<T> o;
  for (int k = 0; k < 9; ++k) o.R.m[k] = T(X.R.m[k]);
  o.p = {T(X.p.x), T(X.p.y), T(X.p.z)};
  return o;
}

// a rotation about a random axis (or, one time in four, a frame axis: the rotations of most URDF
// joints) and an offset of up to a metre
Transform<double> random_transform(std::mt19937& rng) {
  std::uniform_real_distribution<double> U(-1, 1);
  Vec3<double> a = {U(rng), U(rng), U(rng)};
  if (rng() % 4 == 0) a = {0, 0, 1};
  const double n = std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z);
  a = {a.x / n, a.y / n, a.z / n};
  return {axis_angle(a, 3.0 * U(rng)), {U(rng), U(rng), U(rng)}};
}

// a turn by t about frame axis K
Mat3<double> frame_turn(int K, double t) {
  Vec3<double> a = {0, 0, 0};
  a[K] = 1;
  return axis_angle(a, t);
}

// a rotation of quarter turns: a signed permutation of determinant 1, uniformly of the 24
Mat3<double> quarter_turns(std::mt19937& rng) {
  int perm[3] = {0, 1, 2};
  std::shuffle(perm, perm + 3, rng);
  Mat3<double> P = Mat3<double>::zero();
  for (int r = 0; r < 3; ++r) P(r, perm[r]) = rng() % 2 ? 1.0 : -1.0;
  const double det = P(0, 0) * (P(1, 1) * P(2, 2) - P(1, 2) * P(2, 1)) -
                     P(0, 1) * (P(1, 0) * P(2, 2) - P(1, 2) * P(2, 0)) +
                     P(0, 2) * (P(1, 0) * P(2, 1) - P(1, 1) * P(2, 0));
  if (det < 0) P(0, perm[0]) = -P(0, perm[0]);
  return P;
}

// the row of column K's nonzero
int column_row(const Mat3<double>& R, int K) {
  for (int r = 0; r < 3; ++r)
    if (R(r, K) != 0) return r;
  return -1;
}

// a body's inertia: mass 0.1-10 kg, centre of mass within half a metre, principal moments turned
Inertia<double> random_inertia(std::mt19937& rng) {
  std::uniform_real_distribution<double> U(-1, 1);
  const double m = 5.05 + 4.95 * U(rng);
  const Vec3<double> c = {0.5 * U(rng), 0.5 * U(rng), 0.5 * U(rng)};
  const Mat3<double> R = random_transform(rng).R;
  const double d[3] = {0.1 + 0.09 * U(rng), 0.1 + 0.09 * U(rng), 0.02 + 0.01 * U(rng)};
  Inertia<double> I;
  I.m = m;
  I.h = {m * c.x, m * c.y, m * c.z};
  const double cc[3] = {c.x, c.y, c.z};
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) {
      double v = 0;
      for (int j = 0; j < 3; ++j) v += R(r, j) * d[j] * R(k, j);
      // about the frame origin: + m (|c|² 1 - c cᵀ)
      v += m * ((r == k ? cc[0] * cc[0] + cc[1] * cc[1] + cc[2] * cc[2] : 0.0) - cc[r] * cc[k]);
      I.I(r, k) = v;
    }
  return I;
}

}  // namespace

TEST(HOST_LANES, InertiaTransformIsTheScalarForm) {
  RBD_REQUIRE_AVX2();
  std::mt19937 rng(5);
  for (int trial = 0; trial < 2000; ++trial) {
    const Transform<double> X = random_transform(rng);
    const Inertia<double> I = random_inertia(rng);
    const Inertia<double> got = transform_inertia(X, I);  // the 2-lane form (double)
    Inertia<long double> Il;
    Il.m = I.m;
    Il.h = {I.h.x, I.h.y, I.h.z};
    for (int k = 0; k < 9; ++k) Il.I.m[k] = I.I.m[k];
    const Inertia<long double> ref = transform_inertia(transform_as<long double>(X), Il);  // the scalar form
    const double scale = std::fabs(ref.I(0, 0)) + std::fabs(ref.I(1, 1)) + std::fabs(ref.I(2, 2));
    EXPECT_EQ(got.m, I.m);
    EXPECT_NEAR(got.h.x, double(ref.h.x), 1e-14 * I.m);
    EXPECT_NEAR(got.h.y, double(ref.h.y), 1e-14 * I.m);
    EXPECT_NEAR(got.h.z, double(ref.h.z), 1e-14 * I.m);
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(got.I(r, k), double(ref.I(r, k)), 1e-14 * scale) << trial << " (" << r << ", " << k << ")";
        EXPECT_EQ(got.I(r, k), got.I(k, r));  // symmetric exactly, as the scalar form's
      }
  }
}

TEST(HOST_LANES, ColumnTransformsAreForceTransforms) {
  RBD_REQUIRE_AVX2();
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int n = 0; n <= 9; ++n)
    for (int trial = 0; trial < 50; ++trial) {
      Transform<double> X = random_transform(rng);
      int form = -1;
      if (trial % 2 == 1) {  // a frame-axis form, exactly: P R_K(θ) (a joint under a quarter-turn placement)
        const int K = rng() % 3;
        X.R = quarter_turns(rng) * frame_turn(K, 3.0 * U(rng));
        form = 3 * K + column_row(X.R, K);
      }
      if (form >= 0) ASSERT_EQ(frame_turn_form(X.R), form) << "trial " << trial;
      // n columns with a guard entry on either side, which the transform must leave alone
      std::vector<double> buf(6 * n + 2);
      for (auto& x : buf) x = 10 * U(rng);
      const std::vector<double> before = buf;
      crba_act_columns(X, buf.data() + 1, n);  // the vector form (double): AVX or 2-lane
      EXPECT_EQ(buf.front(), before.front());
      EXPECT_EQ(buf.back(), before.back());
      const Transform<long double> Xl = transform_as<long double>(X);
      for (int c = 0; c < n; ++c) {
        const double* f = before.data() + 1 + 6 * c;
        const Force<long double> F = Xl.act(Force<long double>{{f[0], f[1], f[2]}, {f[3], f[4], f[5]}});
        const long double ref[6] = {F.lin.x, F.lin.y, F.lin.z, F.ang.x, F.ang.y, F.ang.z};
        for (int k = 0; k < 6; ++k)
          EXPECT_NEAR(buf[1 + 6 * c + k], double(ref[k]), 1e-13) << "n " << n << ", column " << c << ", entry " << k;
#if !defined(RBD_HOST_AVX) && !defined(__FMA__)
        // the frame-axis forms are the general form's values, but for the sign of a zero: the
        // engine's packs (the general form) and the single-sample code agree bit for bit
        double general[6];
        for (int k = 0; k < 6; ++k) general[k] = f[k];
        crba_act_lanes<-1>(X.R.m, X.p.x, X.p.y, X.p.z, general);
        for (int k = 0; k < 6; ++k) EXPECT_EQ(buf[1 + 6 * c + k], general[k]) << "form " << form << ", entry " << k;
#endif
      }
    }
}

// the forms with_frame_turn_form chooses: the nine frame-axis forms (a quarter-turn placement of a
// joint about each frame axis), each taken only where R has its exact zeros
TEST(HOST_LANES, FrameTurnFormsAreReadOffExactZeros) {
  std::mt19937 rng(8);
  for (int K = 0; K < 3; ++K)
    for (int trial = 0; trial < 48; ++trial) {
      const Mat3<double> P = quarter_turns(rng);
      Mat3<double> R = P * frame_turn(K, 0.7);
      const int rho = column_row(R, K);
      EXPECT_EQ(frame_turn_form(R), 3 * K + rho);
      int got = -2;
      with_frame_turn_form(R, [&](auto f) { got = decltype(f)::value; });
      EXPECT_EQ(got, 3 * K + rho);
      R(rho, K == 0 ? 1 : 0) = 1e-300;  // no longer an exact zero: the general form
      EXPECT_EQ(frame_turn_form(R), -1);
    }
  EXPECT_EQ(frame_turn_form(Mat3<double>::identity()), 8);  // no turn: every form, the first tried taken
  EXPECT_EQ(frame_turn_form(axis_angle(Vec3<double>{0.6, 0.8, 0}, 0.3)), -1);
  EXPECT_EQ(frame_turn_form(axis_angle(Vec3<float>{0, 0, 1}, 0.3f)), 8);
}
