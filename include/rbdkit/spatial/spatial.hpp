// rbdkit/spatial/spatial.hpp — 3D and 6D spatial algebra, fixed size, host/device.
//
// Conventions (docs/conventions.md):
//   * 6D vectors are [linear; angular]. Motion (v, w), Force (f, n).
//   * Transform X_a_b = (R, p) places frame b in frame a: x_a = R x_b + p.
//     X.act(m_b) expresses a motion of frame b in frame a; X.act_inv does
//     the reverse; the same for forces (X.act(f_b), X.act_inv(f_a)).
//   * Inertia (m, h = m·c, I_o): mass, first moment and rotational inertia
//     about the frame origin, all expressed in the body frame.
#pragma once

#include <type_traits>

#include "rbdkit/spatial/config.hpp"

namespace rbd {

// ---------------------------------------------------------------- Vec3, Mat3
template <typename S> struct Vec3 {
  S x, y, z;
  RBD_HD S& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  RBD_HD const S& operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  RBD_HD static Vec3 zero() { return {S(0), S(0), S(0)}; }
};

template <typename S> RBD_HD Vec3<S> operator+(const Vec3<S>& a, const Vec3<S>& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
template <typename S> RBD_HD Vec3<S> operator-(const Vec3<S>& a, const Vec3<S>& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <typename S> RBD_HD Vec3<S> operator-(const Vec3<S>& a) { return {-a.x, -a.y, -a.z}; }
template <typename S> RBD_HD Vec3<S> operator*(const S& s, const Vec3<S>& a) { return {s * a.x, s * a.y, s * a.z}; }
template <typename S> RBD_HD Vec3<S>& operator+=(Vec3<S>& a, const Vec3<S>& b) { a.x += b.x; a.y += b.y; a.z += b.z; return a; }
template <typename S> RBD_HD Vec3<S>& operator-=(Vec3<S>& a, const Vec3<S>& b) { a.x -= b.x; a.y -= b.y; a.z -= b.z; return a; }
template <typename S> RBD_HD S dot(const Vec3<S>& a, const Vec3<S>& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <typename S> RBD_HD Vec3<S> cross(const Vec3<S>& a, const Vec3<S>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
// three values of an array, `st` apart, as a Vec3, and back
template <typename S> RBD_HD Vec3<S> load3(const S* z, long st = 1) { return {z[0], z[st], z[2 * st]}; }
template <typename S> RBD_HD void store3(const Vec3<S>& a, S* z, long st = 1) { z[0] = a.x, z[st] = a.y, z[2 * st] = a.z; }

// row-major 3x3
template <typename S> struct Mat3 {
  S m[9];
  RBD_HD S& operator()(int r, int c) { return m[3 * r + c]; }
  RBD_HD const S& operator()(int r, int c) const { return m[3 * r + c]; }
  RBD_HD static Mat3 identity() { return {{S(1), S(0), S(0), S(0), S(1), S(0), S(0), S(0), S(1)}}; }
  RBD_HD static Mat3 zero() { return {{S(0), S(0), S(0), S(0), S(0), S(0), S(0), S(0), S(0)}}; }
};

template <typename S> RBD_HD Vec3<S> operator*(const Mat3<S>& A, const Vec3<S>& v) {
  return {A.m[0] * v.x + A.m[1] * v.y + A.m[2] * v.z, A.m[3] * v.x + A.m[4] * v.y + A.m[5] * v.z,
          A.m[6] * v.x + A.m[7] * v.y + A.m[8] * v.z};
}
// A^T v
template <typename S> RBD_HD Vec3<S> mul_t(const Mat3<S>& A, const Vec3<S>& v) {
  return {A.m[0] * v.x + A.m[3] * v.y + A.m[6] * v.z, A.m[1] * v.x + A.m[4] * v.y + A.m[7] * v.z,
          A.m[2] * v.x + A.m[5] * v.y + A.m[8] * v.z};
}
template <typename S> RBD_HD Mat3<S> operator*(const Mat3<S>& A, const Mat3<S>& B) {
  Mat3<S> C;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) C(r, c) = A(r, 0) * B(0, c) + A(r, 1) * B(1, c) + A(r, 2) * B(2, c);
  return C;
}
template <typename S> RBD_HD Mat3<S> operator+(const Mat3<S>& A, const Mat3<S>& B) {
  Mat3<S> C;
  for (int i = 0; i < 9; ++i) C.m[i] = A.m[i] + B.m[i];
  return C;
}
template <typename S> RBD_HD Mat3<S> operator-(const Mat3<S>& A, const Mat3<S>& B) {
  Mat3<S> C;
  for (int i = 0; i < 9; ++i) C.m[i] = A.m[i] - B.m[i];
  return C;
}
template <typename S> RBD_HD Mat3<S> operator*(const S& s, const Mat3<S>& A) {
  Mat3<S> C;
  for (int i = 0; i < 9; ++i) C.m[i] = s * A.m[i];
  return C;
}
template <typename S> RBD_HD Mat3<S> transpose(const Mat3<S>& A) {
  return {{A.m[0], A.m[3], A.m[6], A.m[1], A.m[4], A.m[7], A.m[2], A.m[5], A.m[8]}};
}
// [a]x, the cross-product matrix: skew(a) b = a x b
template <typename S> RBD_HD Mat3<S> skew(const Vec3<S>& a) {
  return {{S(0), -a.z, a.y, a.z, S(0), -a.x, -a.y, a.x, S(0)}};
}
// a b^T
template <typename S> RBD_HD Mat3<S> outer(const Vec3<S>& a, const Vec3<S>& b) {
  return {{a.x * b.x, a.x * b.y, a.x * b.z, a.y * b.x, a.y * b.y, a.y * b.z, a.z * b.x, a.z * b.y, a.z * b.z}};
}

// -------------------------------------------------------------- Motion, Force
template <typename S> struct Motion {
  Vec3<S> lin, ang;
  RBD_HD static Motion zero() { return {Vec3<S>::zero(), Vec3<S>::zero()}; }
};
template <typename S> struct Force {
  Vec3<S> lin, ang;
  RBD_HD static Force zero() { return {Vec3<S>::zero(), Vec3<S>::zero()}; }
};

template <typename S> RBD_HD Motion<S> operator+(const Motion<S>& a, const Motion<S>& b) { return {a.lin + b.lin, a.ang + b.ang}; }
template <typename S> RBD_HD Motion<S> operator-(const Motion<S>& a, const Motion<S>& b) { return {a.lin - b.lin, a.ang - b.ang}; }
template <typename S> RBD_HD Motion<S> operator*(const S& s, const Motion<S>& a) { return {s * a.lin, s * a.ang}; }
template <typename S> RBD_HD Motion<S>& operator+=(Motion<S>& a, const Motion<S>& b) { a.lin += b.lin; a.ang += b.ang; return a; }
template <typename S> RBD_HD Force<S> operator+(const Force<S>& a, const Force<S>& b) { return {a.lin + b.lin, a.ang + b.ang}; }
template <typename S> RBD_HD Force<S> operator-(const Force<S>& a, const Force<S>& b) { return {a.lin - b.lin, a.ang - b.ang}; }
template <typename S> RBD_HD Force<S> operator*(const S& s, const Force<S>& a) { return {s * a.lin, s * a.ang}; }
template <typename S> RBD_HD Force<S>& operator+=(Force<S>& a, const Force<S>& b) { a.lin += b.lin; a.ang += b.ang; return a; }
template <typename S> RBD_HD Force<S>& operator-=(Force<S>& a, const Force<S>& b) { a.lin -= b.lin; a.ang -= b.ang; return a; }

// power pairing m·f
template <typename S> RBD_HD S dot(const Motion<S>& m, const Force<S>& f) { return dot(m.lin, f.lin) + dot(m.ang, f.ang); }

// motion cross product a x m  (crm)
template <typename S> RBD_HD Motion<S> cross(const Motion<S>& a, const Motion<S>& m) {
  return {cross(a.ang, m.lin) + cross(a.lin, m.ang), cross(a.ang, m.ang)};
}
// force cross product a x* f  (crf)
template <typename S> RBD_HD Force<S> cross(const Motion<S>& a, const Force<S>& f) {
  return {cross(a.ang, f.lin), cross(a.ang, f.ang) + cross(a.lin, f.lin)};
}

// ------------------------------------------------------------------ Transform
template <typename S> struct Transform {
  Mat3<S> R;
  Vec3<S> p;
  RBD_HD static Transform identity() { return {Mat3<S>::identity(), Vec3<S>::zero()}; }

  // X_a_b * X_b_c = X_a_c
  RBD_HD Transform operator*(const Transform& o) const { return {R * o.R, R * o.p + p}; }
  RBD_HD Transform inverse() const { return {transpose(R), -mul_t(R, p)}; }
  RBD_HD Vec3<S> act_point(const Vec3<S>& x) const { return R * x + p; }

  // motion in b -> motion in a
  RBD_HD Motion<S> act(const Motion<S>& m) const {
    Vec3<S> w = R * m.ang;
    return {R * m.lin + cross(p, w), w};
  }
  // motion in a -> motion in b
  RBD_HD Motion<S> act_inv(const Motion<S>& m) const {
    return {mul_t(R, m.lin - cross(p, m.ang)), mul_t(R, m.ang)};
  }
  // force in b -> force in a
  RBD_HD Force<S> act(const Force<S>& f) const {
    Vec3<S> fl = R * f.lin;
    return {fl, R * f.ang + cross(p, fl)};
  }
  // force in a -> force in b
  RBD_HD Force<S> act_inv(const Force<S>& f) const {
    return {mul_t(R, f.lin), mul_t(R, f.ang - cross(p, f.lin))};
  }
};

// rotation of angle t about unit axis a (Rodrigues)
template <typename S> RBD_HD Mat3<S> axis_angle(const Vec3<S>& a, const S& t) {
  S s, c;
  ssincos(t, s, c);
  const S v = S(1) - c;
  return {{c + v * a.x * a.x, v * a.x * a.y - s * a.z, v * a.x * a.z + s * a.y,
           v * a.x * a.y + s * a.z, c + v * a.y * a.y, v * a.y * a.z - s * a.x,
           v * a.x * a.z - s * a.y, v * a.y * a.z + s * a.x, c + v * a.z * a.z}};
}

// rotation matrix of a unit quaternion stored (x, y, z, w)
template <typename S> RBD_HD Mat3<S> quat_to_matrix(const S* q) {
  const S x = q[0], y = q[1], z = q[2], w = q[3];
  const S tx = S(2) * x, ty = S(2) * y, tz = S(2) * z;
  const S twx = tx * w, twy = ty * w, twz = tz * w;
  const S txx = tx * x, txy = ty * x, txz = tz * x;
  const S tyy = ty * y, tyz = tz * y, tzz = tz * z;
  return {{S(1) - (tyy + tzz), txy - twz, txz + twy,
           txy + twz, S(1) - (txx + tzz), tyz - twx,
           txz - twy, tyz + twx, S(1) - (txx + tyy)}};
}

// ------------------------------------------------------------------- Inertia
template <typename S> struct Inertia {
  S m;         // mass
  Vec3<S> h;   // first moment m·c
  Mat3<S> I;   // rotational inertia about the frame origin (symmetric)

  RBD_HD static Inertia zero() { return {S(0), Vec3<S>::zero(), Mat3<S>::zero()}; }

  // momentum of a body moving with twist v:  I·v
  RBD_HD Force<S> operator*(const Motion<S>& v) const {
    return {m * v.lin - cross(h, v.ang), I * v.ang + cross(h, v.lin)};
  }
  // I e_k, column k of the 6 x 6 [m 1, -[h]x; [h]x, I] (e_k: a unit motion, k < 3 linear): picks, no products
  RBD_HD Force<S> column(int k) const {
    if (k < 3) {
      Force<S> f{Vec3<S>::zero(), Vec3<S>::zero()};
      f.lin[k] = m;
      f.ang = {k == 0 ? S(0) : (k == 1 ? -h.z : h.y), k == 0 ? h.z : (k == 1 ? S(0) : -h.x),
               k == 0 ? -h.y : (k == 1 ? h.x : S(0))};
      return f;
    }
    const int j = k - 3;
    return {{j == 0 ? S(0) : (j == 1 ? h.z : -h.y), j == 0 ? -h.z : (j == 1 ? S(0) : h.x),
             j == 0 ? h.y : (j == 1 ? -h.x : S(0))},
            {I(0, j), I(1, j), I(2, j)}};
  }
  RBD_HD Inertia operator+(const Inertia& o) const { return {m + o.m, h + o.h, I + o.I}; }
  RBD_HD Inertia& operator+=(const Inertia& o) { m += o.m; h += o.h; I = I + o.I; return *this; }
};

#if defined(RBD_HOST_LANES) && defined(__SSE2__)
#define RBD_TRANSFORM_INERTIA_PAIRS 1
// transform_inertia in double on an x86-64 host (the library's SSE2 baseline and an instance's
// -march=native alike; 2-lane vectors serve both better than 4-lane ones, whose gathers and broadcasts
// took 45 of their 120 instructions: 8.9 ns where those took 10.8 under AVX): the 3-vectors as a
// 2-lane vector of their entries 0 and 1 and a scalar entry 2, and I's six entries as three pairs of
// lanes, (0,0) (0,1), then (0,2) (1,2), then (1,1) (2,2), each lane with the scalar form's operations
// in their order (so that in the baseline, which has no fused multiply-add to contract them into, the
// result is the scalar form's bit for bit): 53 vector and 28 scalar operations where the scalar form
// takes about 135
inline Inertia<double> transform_inertia_pairs(const Transform<double>& X, const Inertia<double>& Ib) {
  typedef double V __attribute__((vector_size(16)));
  const double* R = X.R.m;
  const double* I = Ib.I.m;
  const double m = Ib.m, hm = 0.5 * m, f = I[8];
  const double a2 = 0.5 * (I[0] - f), d2 = 0.5 * (I[4] - f), b = I[1], c = I[2], e = I[5];
  // R's columns r0, r1, r2 and p: entries 0 and 1 (v) and entry 2
  const V r0 = {R[0], R[3]}, r1 = {R[1], R[4]}, r2 = {R[2], R[5]}, p = {X.p.x, X.p.y};
  const double r0_2 = R[6], r1_2 = R[7], r2_2 = R[8], p_2 = X.p.z;
  const V hr = (r0 * Ib.h.x + r1 * Ib.h.y) + r2 * Ib.h.z;
  const double hr_2 = (r0_2 * Ib.h.x + r1_2 * Ib.h.y) + r2_2 * Ib.h.z;
  const V g = hr + hm * p, u = (a2 * r0 + b * r1) + c * r2, w = d2 * r1 + e * r2;
  const double g_2 = hr_2 + hm * p_2, u_2 = (a2 * r0_2 + b * r1_2) + c * r2_2, w_2 = d2 * r1_2 + e * r2_2;
  const double diag = f + 2.0 * ((g[0] * X.p.x + g[1] * X.p.y) + g_2 * p_2);
  // entry (r, k): (r0_r u_k + u_r r0_k) + (r1_r w_k + w_r r1_k) - (p_r g_k + g_r p_k) [+ diag]
  const V e00_01 = (((R[0] * u + u[0] * r0) + (R[1] * w + w[0] * r1)) - (X.p.x * g + g[0] * p)) + V{diag, 0.0};
  const V e02_12 = (((r0 * u_2 + u * r0_2) + (r1 * w_2 + w * r1_2)) - (p * g_2 + g * p_2)) + 0.0;
  const V r0_12 = {R[3], r0_2}, r1_12 = {R[4], r1_2}, p_12 = {X.p.y, p_2};
  const V u_12 = {u[1], u_2}, w_12 = {w[1], w_2}, g_12 = {g[1], g_2};
  const V e11_22 =
      (((r0_12 * u_12 + u_12 * r0_12) + (r1_12 * w_12 + w_12 * r1_12)) - (p_12 * g_12 + g_12 * p_12)) + diag;
  const V h = hr + m * p;
  Inertia<double> out;
  out.m = m;
  out.h = {h[0], h[1], hr_2 + m * p_2};
  double* o = out.I.m;
  o[0] = e00_01[0], o[1] = o[3] = e00_01[1], o[2] = o[6] = e02_12[0];
  o[4] = e11_22[0], o[5] = o[7] = e02_12[1], o[8] = e11_22[1];
  return out;
}
#endif

// inertia of frame b re-expressed in frame a (X = X_a_b):  X* I X⁻¹
//   m' = m, h' = R h + m p (h_r = R h, the first moment turned), and about the new origin
//   I' = R I Rᵀ - (p h_rᵀ + h_r pᵀ + m p pᵀ) + (2 h_r·p + m p·p) 1
//      = R I Rᵀ - (p gᵀ + g pᵀ) + 2 (g·p) 1                     g = h_r + (m/2) p
// and, with r_k the columns of R and I = [a b c; b d e; c e f] (Σ r_k r_kᵀ = 1),
//   R I Rᵀ = f 1 + (r_0 uᵀ + u r_0ᵀ) + (r_1 wᵀ + w r_1ᵀ),
//   u = (a - f)/2 r_0 + b r_1 + c r_2,   w = (d - f)/2 r_1 + e r_2,
// so each of the 6 independent entries of I' is three symmetric pairs (6 products): about 70
// multiplies in all, where R I Rᵀ as two 3×3 products and the shift took about 85. The price:
// every entry carries a rounding of the order of ε·max|I_kk|, where the two products were exact
// for a rotation about a frame axis; a small moment next to large ones (a thin rod's about its
// axis) is then relatively less exact (a rod along x turned about x: I_xx to 5e-5 in float32,
// where it was 5e-8; the matrix as a whole to ε·|I| either way)
template <typename S> RBD_HD_INLINE Inertia<S> transform_inertia(const Transform<S>& X, const Inertia<S>& Ib) {
#if defined(RBD_TRANSFORM_INERTIA_PAIRS)
  if constexpr (std::is_same<S, double>::value) return transform_inertia_pairs(X, Ib);
#endif
  const Mat3<S>& R = X.R;
  const S m = Ib.m;
  const Vec3<S> hr = R * Ib.h;
  const Vec3<S> g = hr + (S(0.5) * m) * X.p;
  const S f = Ib.I(2, 2);
  const S a2 = S(0.5) * (Ib.I(0, 0) - f), d2 = S(0.5) * (Ib.I(1, 1) - f);
  const S b = Ib.I(0, 1), c = Ib.I(0, 2), e = Ib.I(1, 2);
  // indexed below (Vec3's [] is a select)
  const S r0[3] = {R(0, 0), R(1, 0), R(2, 0)}, r1[3] = {R(0, 1), R(1, 1), R(2, 1)};
  const S pa[3] = {X.p.x, X.p.y, X.p.z}, ga[3] = {g.x, g.y, g.z};
  S u[3], w[3];
  for (int k = 0; k < 3; ++k) {
    u[k] = a2 * r0[k] + b * r1[k] + c * R(k, 2);
    w[k] = d2 * r1[k] + e * R(k, 2);
  }
  const S diag = f + S(2) * (ga[0] * pa[0] + ga[1] * pa[1] + ga[2] * pa[2]);
  Inertia<S> out;
  out.m = m;
  out.h = hr + m * X.p;
  for (int r = 0; r < 3; ++r)
    for (int k = r; k < 3; ++k) {
      const S v = (r0[r] * u[k] + u[r] * r0[k]) + (r1[r] * w[k] + w[r] * r1[k]) - (pa[r] * ga[k] + ga[r] * pa[k]) +
                  (r == k ? diag : S(0));
      out.I(r, k) = v;
      out.I(k, r) = v;
    }
  return out;
}

// ------------------------------------------------------------- InertiaRate
// B = v ×* I - I v×: the rate of change of a world inertia I (mass m, first
// moment h, rotational inertia I_O) carried along by the twist v = (v_lin, ω).
// B is symmetric with a zero linear-linear block, so nine numbers hold it:
//   B = [  0     -[β]× ]    β = m v_lin + ω × h
//       [ [β]×     C   ]    C = [ω]× I_O - I_O [ω]× - [v_lin]×[h]× - [h]×[v_lin]×   (symmetric)
// Sums of such matrices (subtree composites) and their changes of frame keep
// that form. Bᵀ = B, so B m is also Bᵀ m.
template <typename S> struct InertiaRate {
  Vec3<S> beta;
  Mat3<S> C;  // symmetric, both triangles stored

  // B m, read as a force:  (-β × m_ang, β × m_lin + C m_ang)
  RBD_HD Force<S> operator*(const Motion<S>& m) const { return {cross(m.ang, beta), cross(beta, m.lin) + C * m.ang}; }
  RBD_HD InertiaRate& operator+=(const InertiaRate& o) {
    beta += o.beta;
    for (int i = 0; i < 9; ++i) C.m[i] += o.C.m[i];
    return *this;
  }
};

// B = v ×* I - I v× of a world inertia I moving with v.
//   With P = [ω]× I_O (so I_O [ω]× = -Pᵀ) and [a]×[b]× = b aᵀ - (a·b) 1:
//   C = P + Pᵀ - (h v_linᵀ + v_lin hᵀ) + 2 (h·v_lin) 1
template <typename S> RBD_HD InertiaRate<S> inertia_variation(const Inertia<S>& I, const Motion<S>& v) {
  const Vec3<S>& w = v.ang;
  const Vec3<S>& vl = v.lin;
  Mat3<S> P;  // column c: ω × (column c of I_O)
  for (int c = 0; c < 3; ++c) {
    const Vec3<S> col = cross(w, Vec3<S>{I.I(0, c), I.I(1, c), I.I(2, c)});
    P(0, c) = col.x, P(1, c) = col.y, P(2, c) = col.z;
  }
  const S diag = S(2) * dot(I.h, vl);
  InertiaRate<S> B;
  B.beta = I.m * vl + cross(w, I.h);
  const S ha[3] = {I.h.x, I.h.y, I.h.z}, va[3] = {vl.x, vl.y, vl.z};  // indexed below
  for (int r = 0; r < 3; ++r)
    for (int c = r; c < 3; ++c) {
      const S x = P(r, c) + P(c, r) - (ha[r] * va[c] + va[r] * ha[c]) + (r == c ? diag : S(0));
      B.C(r, c) = x;
      B.C(c, r) = x;
    }
  return B;
}

// X* B X⁻¹ (X = X_a_b: B of frame b re-expressed in frame a):
//   β' = R β,   C' = R C Rᵀ - [β']×[p]× - [p]×[β']× = R C Rᵀ - (p β'ᵀ + β' pᵀ) + 2 (β'·p) 1
template <typename S> RBD_HD InertiaRate<S> transform_rate(const Transform<S>& X, const InertiaRate<S>& B) {
  const Mat3<S>& R = X.R;
  const Vec3<S>& p = X.p;
  InertiaRate<S> out;
  out.beta = R * B.beta;
  const Vec3<S>& b = out.beta;
  const Mat3<S> RC = R * B.C;
  const S diag = S(2) * dot(b, p);
  const S pa[3] = {p.x, p.y, p.z}, ba[3] = {b.x, b.y, b.z};  // indexed below
  for (int r = 0; r < 3; ++r)
    for (int c = r; c < 3; ++c) {
      const S rot = RC(r, 0) * R(c, 0) + RC(r, 1) * R(c, 1) + RC(r, 2) * R(c, 2);
      const S x = rot - (pa[r] * ba[c] + ba[r] * pa[c]) + (r == c ? diag : S(0));
      out.C(r, c) = x;
      out.C(c, r) = x;
    }
  return out;
}

// ------------------------------------------------------------------- Mat6
// dense 6x6 in [linear; angular] blocks, row-major; the articulated inertias
// of ABA and the Minv recursion. It maps motions to forces.
template <typename S> struct Mat6 {
  S m[36];
  RBD_HD S& operator()(int r, int c) { return m[6 * r + c]; }
  RBD_HD const S& operator()(int r, int c) const { return m[6 * r + c]; }
  RBD_HD static Mat6 zero() {
    Mat6 A;
    for (int i = 0; i < 36; ++i) A.m[i] = S(0);
    return A;
  }
  RBD_HD static Mat6 from_inertia(const Inertia<S>& Y) {
    Mat6 A;
    const Mat3<S> H = skew(Y.h);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        A(r, c) = r == c ? Y.m : S(0);
        A(r, c + 3) = -H(r, c);
        A(r + 3, c) = H(r, c);
        A(r + 3, c + 3) = Y.I(r, c);
      }
    return A;
  }
  RBD_HD Force<S> operator*(const Motion<S>& v) const {
    S in[6] = {v.lin.x, v.lin.y, v.lin.z, v.ang.x, v.ang.y, v.ang.z};
    S out[6];
    for (int r = 0; r < 6; ++r) {
      S acc = S(0);
      for (int c = 0; c < 6; ++c) acc += m[6 * r + c] * in[c];
      out[r] = acc;
    }
    return {{out[0], out[1], out[2]}, {out[3], out[4], out[5]}};
  }
  RBD_HD Mat6& operator+=(const Mat6& o) {
    for (int i = 0; i < 36; ++i) m[i] += o.m[i];
    return *this;
  }
};

// 6x6 motion-transform matrix of X_a_b (maps motions of b into a)
template <typename S> RBD_HD Mat6<S> motion_matrix(const Transform<S>& X) {
  Mat6<S> A = Mat6<S>::zero();
  const Mat3<S> PR = skew(X.p) * X.R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      A(r, c) = X.R(r, c);
      A(r, c + 3) = PR(r, c);
      A(r + 3, c + 3) = X.R(r, c);
    }
  return A;
}

// A [p]x: row r is A_r × p (the products by the skew matrix's zeros left out)
template <typename S> RBD_HD Mat3<S> mul_skew(const Mat3<S>& A, const Vec3<S>& p) {
  Mat3<S> C;
  for (int r = 0; r < 3; ++r) {
    C(r, 0) = A(r, 1) * p.z - A(r, 2) * p.y;
    C(r, 1) = A(r, 2) * p.x - A(r, 0) * p.z;
    C(r, 2) = A(r, 0) * p.y - A(r, 1) * p.x;
  }
  return C;
}
// [p]x A: column c is p × A_c
template <typename S> RBD_HD Mat3<S> skew_mul(const Vec3<S>& p, const Mat3<S>& A) {
  Mat3<S> C;
  for (int c = 0; c < 3; ++c) {
    C(0, c) = p.y * A(2, c) - p.z * A(1, c);
    C(1, c) = p.z * A(0, c) - p.x * A(2, c);
    C(2, c) = p.x * A(1, c) - p.y * A(0, c);
  }
  return C;
}

// articulated inertia of frame b expressed in frame a: X* Ib X⁻¹ for
// X = X_a_b. With Ib = [[A, B], [Bᵀ, C]] (linear/angular blocks), rotate each
// block (A' = R A Rᵀ, ...), then shift by p with P = [p]x:
//   A_a = A',  B_a = B' - A' P,  C_a = C' - P A' P + P B' + (P B')ᵀ
template <typename S> RBD_HD Mat6<S> transform_mat6(const Transform<S>& X_a_b, const Mat6<S>& Ib) {
  Mat3<S> A, B, C;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      A(r, c) = Ib(r, c);
      B(r, c) = Ib(r, c + 3);
      C(r, c) = Ib(r + 3, c + 3);
    }
  const Mat3<S>& R = X_a_b.R;
  const Mat3<S> Rt = transpose(R);
  A = R * A * Rt;
  B = R * B * Rt;
  C = R * C * Rt;
  const Vec3<S>& p = X_a_b.p;
  const Mat3<S> AP = mul_skew(A, p), PB = skew_mul(p, B);
  const Mat3<S> Ba = B - AP;
  const Mat3<S> Ca = C - skew_mul(p, AP) + PB + transpose(PB);  // -B'ᵀP = (P B')ᵀ
  Mat6<S> out;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      out(r, c) = A(r, c);
      out(r, c + 3) = Ba(r, c);
      out(r + 3, c) = Ba(c, r);
      out(r + 3, c + 3) = Ca(r, c);
    }
  return out;
}

// Motion/Force <-> 6-array helpers
template <typename S> RBD_HD void store(const Motion<S>& v, S* out) {
  out[0] = v.lin.x; out[1] = v.lin.y; out[2] = v.lin.z; out[3] = v.ang.x; out[4] = v.ang.y; out[5] = v.ang.z;
}
template <typename S> RBD_HD void store(const Force<S>& f, S* out) {
  out[0] = f.lin.x; out[1] = f.lin.y; out[2] = f.lin.z; out[3] = f.ang.x; out[4] = f.ang.y; out[5] = f.ang.z;
}
template <typename S> RBD_HD Motion<S> load_motion(const S* a) { return {{a[0], a[1], a[2]}, {a[3], a[4], a[5]}}; }
template <typename S> RBD_HD Force<S> load_force(const S* a) { return {{a[0], a[1], a[2]}, {a[3], a[4], a[5]}}; }

}  // namespace rbd
