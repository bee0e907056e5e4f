// tests/fuzz/check_model.hpp — the invariants every Model the reader or the
// builder hands out must satisfy, and a few algorithms run on it. A violation
// is a bug (not an input error): it traps, so that libFuzzer records the input.
//
// outline of check_model():
//   1. table sizes, body order, coordinates owned in body order, mimic
//      bodies on a 1-DoF target, subtree sizes, finite and unit quantities
//   2. names: unique joints and bodies, lookups return what was named
//   3. at the neutral configuration: the checked entry points accept it,
//      forward kinematics, frame placement, RNEA and CRBA give finite values,
//      M is symmetric and ID(q, 0, qdd) with no gravity equals M·qdd
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/batch/kinematics_api.hpp"
#include "rbdkit/parsers/model.hpp"

namespace rbd_fuzz {

// a violated invariant: trap (libFuzzer reports a crash with the input)
#define RBD_FUZZ_CHECK(cond) \
  do {                       \
    if (!(cond)) __builtin_trap(); \
  } while (0)

inline bool finite_all(const double* x, size_t n) {
  for (size_t k = 0; k < n; ++k)
    if (!std::isfinite(x[k])) return false;
  return true;
}

inline bool orthonormal(const rbd::Mat3<double>& R, double tol) {
  const rbd::Mat3<double> E = rbd::transpose(R) * R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      if (!(std::fabs(E(r, c) - (r == c ? 1.0 : 0.0)) <= tol)) return false;
  return true;
}

inline void check_transform(const rbd::Transform<double>& X) {
  RBD_FUZZ_CHECK(finite_all(X.R.m, 9));
  RBD_FUZZ_CHECK(std::isfinite(X.p.x) && std::isfinite(X.p.y) && std::isfinite(X.p.z));
  RBD_FUZZ_CHECK(orthonormal(X.R, 1e-8));
}

// expect_floating: the model was asked for a free-flyer root
inline void check_model(const rbd::Model& m, bool expect_floating) {
  using namespace rbd;
  // ---- 1. structure
  const int nb = m.nb();
  RBD_FUZZ_CHECK(static_cast<int>(m.body_names.size()) == nb && static_cast<int>(m.joints.size()) == nb);
  RBD_FUZZ_CHECK(m.lower.size() == static_cast<size_t>(m.nq) && m.upper.size() == static_cast<size_t>(m.nq));
  RBD_FUZZ_CHECK(m.velocity_limit.size() == static_cast<size_t>(m.nv) &&
                 m.effort_limit.size() == static_cast<size_t>(m.nv));
  if (expect_floating) {
    RBD_FUZZ_CHECK(m.floating_base && nb >= 1 && m.bodies[0].type == kFree && m.bodies[0].parent == -1);
    RBD_FUZZ_CHECK(m.joints[0].name.rfind("root_joint", 0) == 0);
  }
  int nq = 0, nv = 0, n_owners = 0;
  std::vector<int> subtree(nb, 0);
  for (int i = 0; i < nb; ++i) {
    const BodyDesc<double>& b = m.bodies[i];
    const JointInfo& j = m.joints[i];
    RBD_FUZZ_CHECK(b.parent >= -1 && b.parent < i);
    RBD_FUZZ_CHECK(b.type >= kRevolute && b.type <= kFree);
    RBD_FUZZ_CHECK(j.body == i);
    const bool one_dof = b.type != kSpherical && b.type != kFree;
    if (b.mimic) {
      // reads the coordinate of a 1-DoF joint that owns one
      RBD_FUZZ_CHECK(b.mimic == 1 && one_dof && b.nq == 1 && b.nv == 1);
      RBD_FUZZ_CHECK(std::isfinite(b.mult) && std::isfinite(b.offset));
      RBD_FUZZ_CHECK(!j.mimic_of.empty() && j.nq == 0 && j.nv == 0);
      const int t = m.joint_index(j.mimic_of);
      RBD_FUZZ_CHECK(t != i && !m.bodies[t].mimic && m.bodies[t].type != kSpherical && m.bodies[t].type != kFree);
      RBD_FUZZ_CHECK(b.q_idx == m.bodies[t].q_idx && b.v_idx == m.bodies[t].v_idx);
      RBD_FUZZ_CHECK(j.multiplier == b.mult && j.offset == b.offset);
    } else {
      ++n_owners;
      RBD_FUZZ_CHECK(j.mimic_of.empty() && b.mult == 1 && b.offset == 0);
      RBD_FUZZ_CHECK(b.q_idx == nq && b.v_idx == nv && j.q_idx == nq && j.v_idx == nv);
      const int want_nq = b.type == kFree ? 7 : (b.type == kSpherical ? 4 : 1);
      const int want_nv = b.type == kFree ? 6 : (b.type == kSpherical ? 3 : 1);
      RBD_FUZZ_CHECK(b.nq == want_nq && b.nv == want_nv && j.nq == want_nq && j.nv == want_nv);
      nq += b.nq;
      nv += b.nv;
      subtree[i] = b.nv;
    }
    if (one_dof) {
      const double n2 = dot(b.axis, b.axis);
      RBD_FUZZ_CHECK(std::fabs(n2 - 1.0) <= 1e-12);
    }
    RBD_FUZZ_CHECK(std::isfinite(b.pitch) && (b.type == kHelical || b.pitch == 0));
    check_transform(b.X_tree);
    // the builder's bounds: lengths of at most 1e12 m, inertia values of at most 1e15
    RBD_FUZZ_CHECK(std::fabs(b.X_tree.p.x) <= 1e12 && std::fabs(b.X_tree.p.y) <= 1e12 &&
                   std::fabs(b.X_tree.p.z) <= 1e12 && std::fabs(b.pitch) <= 1e12);
    RBD_FUZZ_CHECK(b.I.m >= 0 && b.I.m <= 1e15);
    RBD_FUZZ_CHECK(std::fabs(b.I.h.x) <= 1e15 && std::fabs(b.I.h.y) <= 1e15 && std::fabs(b.I.h.z) <= 1e15);
    for (double x : b.I.I.m) RBD_FUZZ_CHECK(std::fabs(x) <= 1e15);
  }
  RBD_FUZZ_CHECK(nq == m.nq && nv == m.nv);
  for (int i = nb - 1; i >= 0; --i)
    if (m.bodies[i].parent >= 0) subtree[m.bodies[i].parent] += subtree[i];
  for (int i = 0; i < nb; ++i) RBD_FUZZ_CHECK(m.bodies[i].nv_subtree == subtree[i]);
  for (int k = 0; k < m.nq; ++k) RBD_FUZZ_CHECK(!std::isnan(m.lower[k]) && !std::isnan(m.upper[k]));
  for (int k = 0; k < m.nv; ++k) RBD_FUZZ_CHECK(m.velocity_limit[k] > 0 && m.effort_limit[k] > 0);
  for (const FrameInfo& f : m.frames) {
    RBD_FUZZ_CHECK(!f.name.empty() && f.body >= -1 && f.body < nb);
    check_transform(f.X_body_frame);
  }

  // ---- 2. names
  RBD_FUZZ_CHECK(static_cast<int>(m.joint_names().size()) == n_owners);
  std::set<std::string> all_joints, all_bodies;
  for (int i = 0; i < nb; ++i) {
    RBD_FUZZ_CHECK(!m.joints[i].name.empty() && all_joints.insert(m.joints[i].name).second);
    RBD_FUZZ_CHECK(!m.body_names[i].empty() && all_bodies.insert(m.body_names[i]).second);
    RBD_FUZZ_CHECK(m.joint_index(m.joints[i].name) == i);
  }
  for (size_t k = 0; k < m.frames.size(); ++k)
    RBD_FUZZ_CHECK(m.frames[m.frame_index(m.frames[k].name)].name == m.frames[k].name);

  // inertial parameters passed back unchanged keep the model as it is
  const std::vector<double> pi = m.inertial_parameters();
  RBD_FUZZ_CHECK(pi.size() == 10u * nb && finite_all(pi.data(), pi.size()));
  const Model same = m.with_inertial_parameters(pi);
  RBD_FUZZ_CHECK(same.nb() == nb);

  // ---- 3. algorithms at the neutral configuration (a small workspace)
  if (nb > 64) return;  // keep an execution cheap; the structure above is checked at any size
  const std::vector<double> q = m.neutral();
  RBD_FUZZ_CHECK(static_cast<int>(q.size()) == m.nq && finite_all(q.data(), q.size()));
  check_configuration(m, q.data(), "q");  // must not throw on the model's own neutral configuration
  WorkspaceBuffer buf(m);
  Workspace<double>& ws = buf.get();

  std::vector<double> R(9 * nb), p(3 * nb);
  batch::forward_kinematics(m, 1, q.data(), R.data(), p.data(), &ws);
  RBD_FUZZ_CHECK(finite_all(R.data(), R.size()) && finite_all(p.data(), p.size()));
  for (int i = 0; i < nb; ++i) {
    Mat3<double> Ri;
    std::copy(R.begin() + 9 * i, R.begin() + 9 * i + 9, Ri.m);
    RBD_FUZZ_CHECK(orthonormal(Ri, 1e-6));
  }
  if (!m.frames.empty()) {
    double Rf[9], pf[3];
    batch::frame_placement(m, 1, q.data(), static_cast<int>(m.frames.size()) - 1, Rf, pf, &ws);
    RBD_FUZZ_CHECK(finite_all(Rf, 9) && finite_all(pf, 3));
  }

  // RNEA with gravity, then without: ID(q, 0, qdd) = M(q)·qdd
  std::vector<double> zero(nv, 0.0), qdd(nv), tau(nv), tau_g(nv), M(static_cast<size_t>(nv) * nv);
  for (int k = 0; k < nv; ++k) qdd[k] = std::sin(1.0 + k);  // |qdd_k| <= 1, none zero
  batch::inverse_dynamics(m, 1, q.data(), zero.data(), zero.data(), nullptr, -9.81, tau_g.data(), nullptr, nullptr,
                          nullptr, &ws);
  RBD_FUZZ_CHECK(finite_all(tau_g.data(), tau_g.size()));
  batch::inverse_dynamics(m, 1, q.data(), zero.data(), qdd.data(), nullptr, 0.0, tau.data(), nullptr, nullptr, nullptr,
                          &ws);
  RBD_FUZZ_CHECK(finite_all(tau.data(), tau.size()));
  batch::crba(m, 1, q.data(), M.data(), &ws);
  RBD_FUZZ_CHECK(finite_all(M.data(), M.size()));
  // rounding: CRBA works with inertias and columns moved over the tree's lengths
  // (world frame, or each body's frame along the chain), so
  // the tolerance scales with the largest of them, (|I| + 2|h| L + m L²) μ²,
  // L a bound on the distance of a body origin from the world origin (mimic
  // offsets displace bodies at the neutral configuration) and μ the largest
  // mimic multiplier; not with M, which can be far smaller after cancellation
  // (a huge izz about a joint's x axis). hypot: no underflow of tiny squares.
  double L = 1, mu = 1, scale = 0;
  for (const BodyDesc<double>& b : m.bodies) {
    L += std::hypot(b.X_tree.p.x, b.X_tree.p.y, b.X_tree.p.z);
    mu = std::max(mu, std::fabs(b.mult));
  }
  double far = 0;
  for (int i = 0; i < nb; ++i) far = std::max(far, std::hypot(p[3 * i], p[3 * i + 1], p[3 * i + 2]));
  L += far;
  for (const BodyDesc<double>& b : m.bodies) {
    double I_max = 0;
    for (double x : b.I.I.m) I_max = std::max(I_max, std::fabs(x));
    scale += (I_max + 2 * std::hypot(b.I.h.x, b.I.h.y, b.I.h.z) * L + b.I.m * L * L) * mu * mu;
  }
  for (double x : M) scale = std::max(scale, std::fabs(x));
  if (!(scale <= 1e300)) return;  // no meaningful tolerance (huge mimic multipliers)
  // a subnormal inertia (a mass of 5e-324) has no relative precision: each product with it may round
  // by up to the smallest subnormal, which the lever arms then multiply by up to L² μ² (a mass at 1e12
  // gives M ~ 1e-299, where CRBA and RNEA may differ by all of it)
  bool subnormal_inertia = false;
  for (const BodyDesc<double>& b : m.bodies)
    for (double x : {b.I.m, b.I.h.x, b.I.h.y, b.I.h.z, b.I.I.m[0], b.I.I.m[1], b.I.I.m[2], b.I.I.m[4], b.I.I.m[5],
                     b.I.I.m[8]})
      if (x != 0 && std::fabs(x) < std::numeric_limits<double>::min()) subnormal_inertia = true;
  const double subnormal =
      subnormal_inertia ? std::numeric_limits<double>::denorm_min() * 16 * (nb + nv) * L * L * mu * mu : 0.0;
  const double tol = 1e-11 * (nb + nv) * scale + 1e-300 + subnormal;
  for (int r = 0; r < nv; ++r) {
    double Mqdd = 0;
    for (int c = 0; c < nv; ++c) {
      RBD_FUZZ_CHECK(std::fabs(M[r * nv + c] - M[c * nv + r]) <= tol);
      Mqdd += M[r * nv + c] * qdd[c];
    }
    RBD_FUZZ_CHECK(std::fabs(Mqdd - tau[r]) <= tol);
  }
}

}  // namespace rbd_fuzz
