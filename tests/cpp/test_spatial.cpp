// Spatial algebra: identities that hold for any transform, motion, force and
// inertia, checked on random values.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "test_models.hpp"

#include "rbdkit/algorithms/aba.hpp"
#include "rbdkit/algorithms/dense.hpp"
#include "rbdkit/model/configuration.hpp"
#include "rbdkit/model/team.hpp"
#include "rbdkit/spatial/lie.hpp"
#include "rbdkit/spatial/spatial.hpp"

using namespace rbd;
using rbd_test::ReversedTeam;
using V3 = Vec3<double>;
using Mo = Motion<double>;
using Fo = Force<double>;
using Tr = Transform<double>;

namespace {
std::mt19937 rng(42);
double uni() { return std::uniform_real_distribution<double>(-1, 1)(rng); }
V3 rv() { return {uni(), uni(), uni()}; }
Mo rm() { return {rv(), rv()}; }
Fo rf() { return {rv(), rv()}; }
Tr rt() {
  V3 a = rv();
  a = (1.0 / std::sqrt(dot(a, a))) * a;
  return {axis_angle(a, 3 * uni()), rv()};
}
Inertia<double> ri() {
  // a box-like body at a random offset: PSD rotational inertia
  Inertia<double> I;
  I.m = 1 + uni() * 0.5;
  const V3 c = rv();
  const Mat3<double> Ic = {{0.3, 0.01, 0.02, 0.01, 0.2, 0.03, 0.02, 0.03, 0.25}};
  I.h = I.m * c;
  I.I = Ic - I.m * (skew(c) * skew(c));
  return I;
}
void expect_near(const Mo& a, const Mo& b, double tol = 1e-12) {
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(a.lin[k], b.lin[k], tol);
    EXPECT_NEAR(a.ang[k], b.ang[k], tol);
  }
}
void expect_near(const Fo& a, const Fo& b, double tol = 1e-12) {
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(a.lin[k], b.lin[k], tol);
    EXPECT_NEAR(a.ang[k], b.ang[k], tol);
  }
}
}  // namespace

TEST(Spatial, RotationIsOrthonormal) {
  const Tr X = rt();
  const Mat3<double> RtR = transpose(X.R) * X.R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(RtR(r, c), r == c ? 1.0 : 0.0, 1e-14);
}

TEST(Spatial, TransformActionsInvert) {
  for (int t = 0; t < 20; ++t) {
    const Tr X = rt();
    const Mo m = rm();
    const Fo f = rf();
    expect_near(X.act_inv(X.act(m)), m);
    expect_near(X.act_inv(X.act(f)), f);
    expect_near(X.inverse().act(m), X.act_inv(m));
  }
}

TEST(Spatial, CompositionMatchesSuccessiveActions) {
  const Tr A = rt(), B = rt();
  const Mo m = rm();
  expect_near((A * B).act(m), A.act(B.act(m)));
}

TEST(Spatial, PowerIsFrameInvariant) {
  // (X m)·(X f) = m·f
  for (int t = 0; t < 20; ++t) {
    const Tr X = rt();
    const Mo m = rm();
    const Fo f = rf();
    EXPECT_NEAR(dot(X.act(m), X.act(f)), dot(m, f), 1e-12);
  }
}

TEST(Spatial, CrossProductsAreDual) {
  // (v × m)·f = -m·(v ×* f)
  const Mo v = rm(), m = rm();
  const Fo f = rf();
  EXPECT_NEAR(dot(cross(v, m), f), -dot(m, cross(v, f)), 1e-12);
  // v × v = 0
  const Mo z = cross(v, v);
  expect_near(z, Mo::zero());
}

TEST(Spatial, TransformedInertiaMatchesActions) {
  // (X* I X⁻¹) m = X (I (X⁻¹ m))
  for (int t = 0; t < 20; ++t) {
    const Tr X = rt();
    const Inertia<double> I = ri();
    const Mo m = rm();
    expect_near(transform_inertia(X, I) * m, X.act(I * X.act_inv(m)), 1e-12);
    // the dense 6x6 form agrees with the structured one
    expect_near(transform_mat6(X, Mat6<double>::from_inertia(I)) * m, transform_inertia(X, I) * m, 1e-12);
  }
}

TEST(Spatial, InertiaRateIsTheProductRule) {
  // B = v ×* I - I v× in nine numbers: B m = v ×* (I m) - I (v × m) for every m,
  // B is symmetric, sums keep the form, and X* B X⁻¹ m = X (B (X⁻¹ m))
  for (int t = 0; t < 20; ++t) {
    const Inertia<double> I = ri(), J = ri();
    const Mo v = rm(), u = rm(), m = rm(), n = rm();
    const InertiaRate<double> B = inertia_variation(I, v);
    expect_near(B * m, cross(v, I * m) - I * cross(v, m), 1e-12);
    // B is symmetric (so Bᵀ m = B m): n·(B m) = m·(B n) for the operator itself
    EXPECT_NEAR(dot(n, cross(v, I * m) - I * cross(v, m)), dot(m, cross(v, I * n) - I * cross(v, n)), 1e-12);
    InertiaRate<double> sum = B;
    sum += inertia_variation(J, u);
    expect_near(sum * m, B * m + (cross(u, J * m) - J * cross(u, m)), 1e-12);
    const Tr X = rt();
    expect_near(transform_rate(X, sum) * m, X.act(sum * X.act_inv(m)), 1e-12);
    // one body moved: the rate of the moved inertia under the moved twist
    expect_near(transform_rate(X, B) * m, inertia_variation(transform_inertia(X, I), X.act(v)) * m, 1e-12);
  }
}

TEST(Dense, NegMatmulEqualsThePlainLoopBitForBit) {
  // the host's register-blocked product: every shape of the block, remainder
  // and tail paths, both precisions, against the plain triple loop exactly
  auto check = [](auto zero) {
    using T = decltype(zero);
    for (int n = 1; n <= 9; ++n)
      for (int cols = 0; cols <= 19; ++cols) {
        std::vector<T> A(n * n), B(n * cols), out(n * cols), ref(n * cols);
        for (auto& a : A) a = static_cast<T>(uni());
        for (auto& b : B) b = static_cast<T>(uni());
        neg_matmul(A.data(), B.data(), n, cols, out.data());
        neg_matmul_plain(A.data(), B.data(), n, cols, ref.data());
        for (int k = 0; k < n * cols; ++k) ASSERT_EQ(out[k], ref[k]) << n << " x " << cols << " @ " << k;
      }
  };
  check(0.0);
  check(0.0f);
}

TEST(Dense, TeamMatmulTilesEqualThePlainProduct) {
  // matmul_tiles (2 x 2 and 4 x 4 tiles, edge tiles clamped) against the triple loop in double, in both
  // precisions, with the sign, for products whose tile side is 2 (iiwa's 7 x 7) and 4 (floating
  // Atlas's 36 x 36), and matmul on a team. Within the sum's rounding bound n·eps·Σ|a||b| (the same
  // order of sums, but a compiler may fuse a multiply-add in one loop and not in the other), and
  // every entry written (C starts as NaN)
  auto check = [](auto zero) {
    using T = decltype(zero);
    const double eps = std::numeric_limits<T>::epsilon();
    int sides[2] = {0, 0};
    for (int r : {1, 3, 7, 18, 36})
      for (int n : {1, 5, 36})
        for (int c : {1, 7, 36}) {
          const T nan = std::numeric_limits<T>::quiet_NaN();
          std::vector<T> A(r * n), B1(n * c), B2(n * c), C1(r * c, nan), C2(r * c, nan), P(r * c, nan);
          for (auto& a : A) a = static_cast<T>(uni());
          for (auto& b : B1) b = static_cast<T>(uni());
          for (auto& b : B2) b = static_cast<T>(uni());
          const T* B[2] = {B1.data(), B2.data()};
          T* C[2] = {C1.data(), C2.data()};
          matmul_tiles(ReversedTeam{}, 64, A.data(), B, C, 2, r, n, c, T(-1));
          matmul(ReversedTeam{}, A.data(), B1.data(), P.data(), r, n, c);
          ++sides[team_tile_side(r, c, 2, 64) / 4];
          for (int i = 0; i < r; ++i)
            for (int j = 0; j < c; ++j) {
              double s1 = 0, s2 = 0, bound = 0;
              for (int k = 0; k < n; ++k) {
                s1 += double(A[i * n + k]) * B1[k * c + j], s2 += double(A[i * n + k]) * B2[k * c + j];
                bound += std::abs(double(A[i * n + k])) * (std::abs(double(B1[k * c + j])) + std::abs(double(B2[k * c + j])));
              }
              bound *= n * eps;
              const int e = i * c + j;
              ASSERT_LE(std::abs(C1[e] + s1), bound) << r << " x " << n << " x " << c << " @ " << e;
              ASSERT_LE(std::abs(C2[e] + s2), bound) << r << " x " << n << " x " << c << " @ " << e;
              ASSERT_LE(std::abs(P[e] - s1), bound) << "matmul on a team, " << r << " x " << c << " @ " << e;
            }
        }
    EXPECT_GT(sides[0], 0);  // (some products in 2 x 2 tiles,
    EXPECT_GT(sides[1], 0);  //  some in 4 x 4)
  };
  check(0.0);
  check(0.0f);
}

TEST(Spatial, InertiaColumnIsTheInertiaTimesAUnitMotion) {
  // Inertia::column(k) (picks, no products) against I · e_k for a general inertia (h off the origin)
  const Inertia<double> I{2.5, {0.3, -0.7, 1.1}, {{1.2, 0.1, -0.2, 0.1, 0.9, 0.05, -0.2, 0.05, 1.4}}};
  for (int k = 0; k < 6; ++k) {
    double e[6] = {0, 0, 0, 0, 0, 0}, ref[6], got[6];
    e[k] = 1;
    store(I * load_motion(e), ref);
    store(I.column(k), got);
    for (int r = 0; r < 6; ++r) EXPECT_EQ(got[r], ref[r]) << "column " << k << ", row " << r;
  }
}

TEST(Dense, SpdInverseTimesTheMatrixIsTheIdentity) {
  // A = B Bᵀ + n·1 (SPD, condition ~ 10) for n = 1..8 and the mass-matrix sizes around 36:
  // A A⁻¹ = 1 to rounding, A⁻¹ exactly symmetric; a singular A is refused
  for (int n : {1, 2, 3, 4, 5, 6, 7, 8, 36}) {
    std::vector<double> B(n * n), A(n * n), F(n * n), Ainv(n * n);
    for (double& x : B) x = uni();
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        double s = r == c ? n : 0.0;
        for (int k = 0; k < n; ++k) s += B[r * n + k] * B[c * n + k];
        A[r * n + c] = s;
      }
    F = A;
    ASSERT_TRUE(spd_inverse(F.data(), n, Ainv.data())) << n;
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        double s = 0;
        for (int k = 0; k < n; ++k) s += A[r * n + k] * Ainv[k * n + c];
        EXPECT_NEAR(s, r == c ? 1.0 : 0.0, 1e-13) << "n " << n << " (" << r << ", " << c << ")";
        EXPECT_EQ(Ainv[r * n + c], Ainv[c * n + r]);
      }
  }
  double S[9] = {1, 1, 0, 1, 1, 0, 0, 0, 2}, Sinv[9];  // rank 2
  EXPECT_FALSE(spd_inverse(S, 3, Sinv));
}

TEST(Dense, ArticulatedUpdateIsIaMinusUDinvUt) {
  // IA - U D⁻¹ Uᵀ for 1, 3 and 6 joint DoFs against the dense product, assigned and added
  for (int n : {1, 3, 6}) {
    Mat6<double> IA;
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) IA(r, c) = IA(c, r) = uni() + (r == c ? 6.0 : 0.0);
    Force<double> U[6];
    for (int k = 0; k < n; ++k) U[k] = rf();
    double D[36], Dinv[36];
    for (int r = 0; r < n; ++r)
      for (int c = r; c < n; ++c) D[r * n + c] = D[c * n + r] = uni() + (r == c ? 4.0 : 0.0);
    ASSERT_TRUE(spd_inverse(D, n, Dinv));
    Mat6<double> ref = IA;
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c)
        for (int k = 0; k < n; ++k)
          for (int l = 0; l < n; ++l) {
            double ur[6], uc[6];
            store(U[k], ur), store(U[l], uc);
            ref(r, c) -= ur[r] * Dinv[k * n + l] * uc[c];
          }
    const Mat6<double> Ia = articulated_residual(n, IA, U, Dinv);
    Mat6<double> sum = IA;
    add_articulated_residual(n, IA, U, Dinv, sum);
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c) {
        EXPECT_NEAR(Ia(r, c), ref(r, c), 1e-12) << n;
        EXPECT_NEAR(sum(r, c), IA(r, c) + ref(r, c), 1e-12) << n;
      }
  }
}

TEST(Spatial, InertiaIsSymmetricPositive) {
  const Inertia<double> I = ri();
  const Mo a = rm(), b = rm();
  EXPECT_NEAR(dot(a, I * b), dot(b, I * a), 1e-12);
  EXPECT_GT(dot(a, I * a), 0.0);
}

TEST(Lie, QuaternionMatrixMatchesAxisAngle) {
  V3 a = rv();
  a = (1.0 / std::sqrt(dot(a, a))) * a;
  const double t = 1.3;
  const Quat<double> q = quat_exp(t * a);
  const Mat3<double> R1 = to_matrix(q), R2 = axis_angle(a, t);
  for (int k = 0; k < 9; ++k) EXPECT_NEAR(R1.m[k], R2.m[k], 1e-14);
}

TEST(Lie, LogInvertsExp) {
  for (double scale : {1e-9, 1e-5, 1e-3, 0.5, 2.0, 3.1}) {
    V3 w = rv();
    w = (scale / std::sqrt(dot(w, w))) * w;
    const V3 w2 = quat_log(quat_exp(w));
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(w2[k], w[k], 1e-13 * std::max(1.0, scale));
    const Mo x = {rv(), w};
    const Tr E = exp6(x);
    const Mo x2 = log6(quat_exp(w), E.p);
    expect_near(x2, x, 1e-12);
  }
}

TEST(Lie, JacobiansAreInverse) {
  for (double scale : {1e-6, 0.3, 2.5}) {
    V3 w = rv();
    w = (scale / std::sqrt(dot(w, w))) * w;
    const Mo x = {rv(), w};
    double A[36], B[36];
    jexp6(x, A);
    jlog6(x, B);
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c) {
        double s = 0;
        for (int k = 0; k < 6; ++k) s += A[r * 6 + k] * B[k * 6 + c];
        EXPECT_NEAR(s, r == c ? 1.0 : 0.0, 1e-12);
      }
  }
}

TEST(Lie, SeriesBranchesAreContinuous) {
  // the series and the closed forms agree where they meet (θ = 1)
  const double lo = 1 - 1e-13, hi = 1 + 1e-13;
  EXPECT_NEAR(coef_a(lo), coef_a(hi), 1e-14);
  EXPECT_NEAR(coef_b(lo), coef_b(hi), 1e-14);
  EXPECT_NEAR(coef_c(lo), coef_c(hi), 1e-14);
  EXPECT_NEAR(coef_d(lo), coef_d(hi), 1e-14);
  EXPECT_NEAR(coef_e(lo), coef_e(hi), 1e-14);
}
