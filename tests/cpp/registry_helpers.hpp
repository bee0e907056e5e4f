// Helpers of the registry's tests (test_registry.cpp, test_cuda.cpp): a
// call's inputs for any registered operation on any model, a run through a
// handle, and the float32 bounds per family.
#pragma once

#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "rbdkit/batch/kinematics_api.hpp"
#include "rbdkit/handle/handle.hpp"
#include "rbdkit/model/configuration.hpp"
#include "rbdkit/ops/registry.hpp"
#include "rbdkit/ops/table.hpp"
#include "rbdkit/parsers/builder.hpp"

namespace rbd_test {

using rbd::Model;
namespace ops = rbd::ops;

// one call's inputs: arrays of B samples (a configuration drawn by integrate
// from the neutral one), parameters at their defaults (dt = 0.01)
struct Inputs {
  long B;
  std::vector<std::vector<double>> arrays;  // per argument (empty for a parameter or an absent array)
  ops::OpCall call;                         // its array pointers: null (absent) or not; run() points them
  long first[ops::kMaxArgs] = {};           // the sample of arrays[k] the call starts at
  std::vector<int> ee;                      // a kEndEffectors argument: the leaf bodies; run() points the call
};

inline Inputs make_inputs(const Model& m, const ops::OpSpec& op, long B, unsigned seed, bool with_fext) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1, 1);
  Inputs in{B, std::vector<std::vector<double>>(op.n_args), {}};
  in.call.B = B;
  for (int k = 0; k < op.n_args; ++k)
    if (op.args[k].kind == ops::kEndEffectors) in.ee = rbd::leaf_bodies(m);
  in.call.n_ee = static_cast<int>(in.ee.size());
  const std::vector<double> q0 = m.neutral();
  std::vector<double> dv(m.nv);
  for (int k = 0; k < op.n_args; ++k) {
    const ops::ArgSpec& a = op.args[k];
    if (a.kind == ops::kArray || a.kind == ops::kOptionalArray) {
      if (a.kind == ops::kOptionalArray && a.shape.d[0] == ops::kNb && !with_fext) continue;
      const long n = ops::arg_values(a, m, in.call.n_ee);
      std::vector<double>& x = in.arrays[k];
      x.resize(B * n);
      for (long s = 0; s < B; ++s) {
        double* xs = x.data() + s * n;
        for (long j = 0; j < n; ++j) xs[j] = (a.shape.d[0] == ops::kNb ? 0.3 : 1.0) * U(rng);
        if (a.check == ops::kWeights)
          for (long j = 0; j < n; ++j) xs[j] = std::fabs(xs[j]);
        // bounds around [-1, 1], every third one infinite
        if (a.check == ops::kLowerBound || a.check == ops::kUpperBound)
          for (long j = 0; j < n; ++j)
            xs[j] = (a.check == ops::kLowerBound ? -1 : 1) * (j % 3 == 2 ? INFINITY : 2 + std::fabs(xs[j]));
        if (a.check == ops::kConfiguration || a.check == ops::kMujocoConfiguration) {
          // a configuration (the state's first nq values), in MuJoCo's layout where asked
          for (double& d : dv) d = U(rng);
          rbd::integrate(m.view(), q0.data(), dv.data(), xs);
          if (a.check == ops::kMujocoConfiguration) rbd::configuration_to_mujoco(m.view(), xs, xs);
        }
      }
      in.call.in[k] = x.data();
      in.call.batched[k] = true;
    } else if (a.kind == ops::kTimeStep) {
      in.call.real[k] = 0.01;
    } else if (a.kind == ops::kFrame) {
      in.call.choice[k] = static_cast<int>(m.frames.size()) / 2;  // a frame of a body in the middle of the tree
    } else if (a.kind == ops::kReal || a.kind == ops::kPositive) {
      in.call.real[k] = std::isnan(a.value) ? 0.1 : a.value;  // a required one: 0.1
    } else {
      in.call.choice[k] = static_cast<int>(a.value);
    }
  }
  return in;
}

// runs `op` on a handle; the outputs (those in `mask`) per sample concatenated, in T
// device_arrays: through run_device (a Backend::CUDA handle; in interpret mode host memory is its device's)
template <typename T>
std::vector<double> run(rbd::Handle& h, int id, const Inputs& in64, unsigned mask = ~0u, bool device_arrays = false) {
  const Model& m = h.model();
  const ops::OpSpec& op = *ops::op_table()[id].spec;
  ops::OpCall c = in64.call;
  c.ee = in64.ee.empty() ? nullptr : in64.ee.data();
  const int n_ee = c.n_ee;
  std::vector<std::vector<T>> ins(op.n_args);
  for (int k = 0; k < op.n_args; ++k)
    if (c.in[k]) {  // from sample first[k] on
      const auto from = in64.arrays[k].begin() + in64.first[k] * ops::arg_values(op.args[k], m, n_ee);
      ins[k].assign(from, in64.arrays[k].end());
      c.in[k] = ins[k].data();
    }
  std::vector<std::vector<T>> outs(op.n_out);
  long w = 0;
  for (int o = 0; o < op.n_out; ++o) {
    if (!(mask >> o & 1u)) continue;
    outs[o].assign(in64.B * ops::out_values(op.out[o], m, n_ee), T(-1));
    c.out[o] = outs[o].data();
    w += ops::out_values(op.out[o], m, n_ee);
  }
  if (device_arrays) h.run_device(id, c);
  else h.run(id, c);
  std::vector<double> r;
  r.reserve(in64.B * w);
  for (long s = 0; s < in64.B; ++s)
    for (int o = 0; o < op.n_out; ++o) {
      if (!(mask >> o & 1u)) continue;
      const long n = ops::out_values(op.out[o], m, n_ee);
      r.insert(r.end(), outs[o].begin() + s * n, outs[o].begin() + (s + 1) * n);
    }
  return r;
}

inline long sample_width(const Model& m, const ops::OpSpec& op, int n_ee) {
  long w = 0;
  for (int o = 0; o < op.n_out; ++o) w += ops::out_values(op.out[o], m, n_ee);
  return w;
}

inline std::vector<double> sample_of(const std::vector<double>& all, long w, long s) {
  return std::vector<double>(all.begin() + s * w, all.begin() + (s + 1) * w);
}

// float32 against float64, per family: M⁻¹ and what is built on it carry
// cond(M)·ε_float32, FDSVA-SO (M⁻¹ applied to terms that carry it already)
// cond(M)²·ε_float32 (docs/engine.md)
inline double float32_bound(const ops::OpSpec& op) {
  const std::string f = op.family, n = op.name;
  // central differences with eps = 1e-5 in float32: about two digits are left, fewer where the
  // derivative is small against the value (the error is ε|f| / (h|f'|)); up to 0.123 seen here
  if (n.size() > 3 && n.compare(n.size() - 3, 3, "_fd") == 0) return 2e-1;
  if (n == "forward_dynamics_parameter_gradient") return 2e-3;  // M⁻¹ applied, as minv's family
  // cond(M)²·ε_float32: up to 9.3e-2 on the ill-conditioned floating planar model (200 random states)
  if (f == "fdsva_so" || f == "integrator_hessian") return 1.5e-1;
  // (J M⁻¹ Jᵀ)⁻¹: cond(M) and cond(J M⁻¹ Jᵀ) both. Over 5000 random iiwa states float32 Λ's error
  // has median 2e-6 and 99th percentile 7e-4, with a tail to 0.2-0.3 next to singular arms (with M
  // by either CRBA pass); 6e-2 is the largest in these tests' samples
  if (f == "osc") return 1e-1;
  return f == "minv" || f == "aba_derivatives" || f == "integrators" || f == "second_order" ? 2e-3 : 1e-4;
}

// whether at least 6 coordinates move each of these bodies (the operational-space inertia is defined)
inline bool six_dof_reach(const Model& m, const std::vector<int>& bodies) {
  for (int b : bodies) {
    std::vector<char> moves(m.nv, 0);
    for (int k = b; k >= 0; k = m.bodies[k].parent)
      for (int a = 0; a < m.bodies[k].nv; ++a) moves[m.bodies[k].v_idx + a] = 1;
    int dof = 0;
    for (char c : moves) dof += c;
    if (dof < 6) return false;
  }
  return true;
}

}  // namespace rbd_test
