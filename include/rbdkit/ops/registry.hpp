// rbdkit/ops/registry.hpp — the operation registry: every operation that the
// generated surfaces call, each described once (ops/op.hpp) with its
// per-sample kernel, and the list they are generated from (OpList below).
// Host/device: the kernels are Scalar-templated and run on double (the
// checked serial loop), on Pack<T, W> lanes (the batch engine, float64 and
// float32) and, through the same headers, on a CUDA thread.
//
// Generated from OpList, in its order (an operation's index is its id):
//   ops::op_table()        the runtime table (ops/table.hpp, src/ops/ops.cpp)
//   Engine::run_op          the engine's routes (src/batch/engine/engine_impl.hpp)
//   Handle::run             checks, the serial loop or the engine (src/handle/handle.cpp)
//   rbdkit._core op calls   the Python bindings and their checks (python/src/bind_ops.cpp)
//   the CUDA kernels        one thread per sample, and their interpret mode (rbdkit/cuda/kernels.cuh)
//
// Shapes below are per sample; every surface adds a leading batch axis B.
#pragma once

#include "rbdkit/algorithms/aba.hpp"
#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/algorithms/centroidal.hpp"
#include "rbdkit/algorithms/crba.hpp"
#include "rbdkit/algorithms/energy.hpp"
#include "rbdkit/algorithms/fdsva_so.hpp"
#include "rbdkit/algorithms/kinematics.hpp"
#include "rbdkit/algorithms/minv.hpp"
#include "rbdkit/algorithms/osc.hpp"
#include "rbdkit/algorithms/regressor.hpp"
#include "rbdkit/algorithms/rnea.hpp"
#include "rbdkit/algorithms/rnea_derivatives.hpp"
#include "rbdkit/model/configuration.hpp"
#include "rbdkit/ops/op.hpp"
#include "rbdkit/plant/costs.hpp"
#include "rbdkit/plant/hessian_forms.hpp"
#include "rbdkit/plant/integrator_hessian.hpp"
#include "rbdkit/plant/integrators.hpp"
#include "rbdkit/plant/mujoco_convention.hpp"

#include <cstdint>
#include <new>
#include <type_traits>

namespace rbd {
namespace ops {

constexpr double kGravity = -9.81;  // the default gravity (m/s², along world z)
constexpr double kRequired = __builtin_nan("");  // a parameter without default
inline constexpr const char* kWrtQV[] = {"q", "v", nullptr};
inline constexpr const char* kWrtFromTo[] = {"from", "to", nullptr};
inline constexpr const char* kFdStepName[] = {"finite-difference step", nullptr};
inline constexpr const char* kBarrierWeightName[] = {"barrier weight", nullptr};
inline constexpr const char* kReferenceFrames[] = {"LOCAL", "WORLD", "LOCAL_WORLD_ALIGNED", nullptr};  // ReferenceFrame
inline constexpr const char* kHessianForms[] = {"rbdkit", "reference", nullptr};  // HessianForm

// ---------------------------------------------------------------- dynamics (rnea, crba, minv, aba)

struct InverseDynamics {
  static constexpr OpSpec spec = {
      "inverse_dynamics", "inverse_dynamics", "rnea",
      "RNEA. Returns (c, v, a, f): joint forces c (nv,) = M qdd + C qd + g - Σ Jᵀ f_ext, and per body (nb, 6): "
      "velocity v, acceleration a (gravity not included) and the force f transmitted by its joint (body frame).",
      5,
      {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), optional_array("qdd", shape(kNv)),
       real("gravity", kGravity), optional_array("f_ext", shape(kNb, 6))},
      4,
      {{"tau", shape(kNv)}, {"v", shape(kNb, 6)}, {"a", shape(kNb, 6)}, {"f", shape(kNb, 6)}},
      0b1111, 0b0001, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    rnea(m, w, a.in[0], a.in[1], a.in[2], a.in[4], a.real[3], a.out[0]);
    if (a.out[1])
      for (int i = 0; i < m.nb; ++i) store(w.v[i], a.out[1] + 6 * i);
    if (a.out[3])
      for (int i = 0; i < m.nb; ++i) store(w.f[i], a.out[3] + 6 * i);
    if (a.out[2]) {
      remove_gravity(m, w, a.real[3], w.c);  // w.c is free after RNEA
      for (int i = 0; i < m.nb; ++i) store(w.c[i], a.out[2] + 6 * i);
    }
    return true;
  }
};

struct GeneralizedGravity {
  static constexpr OpSpec spec = {
      "generalized_gravity", "inverse_dynamics", "rnea", "g(q) (nv,): the joint forces that hold the robot still.",
      2, {array("q", shape(kNq), kConfiguration), real("gravity", kGravity)},
      1, {{"tau", shape(kNv)}}, 0b1, 0, kLinear, kScratchNv, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    for (int k = 0; k < m.nv; ++k) a.scratch[k] = S(0);  // qd = 0
    rnea(m, w, a.in[0], static_cast<const S*>(a.scratch), static_cast<const S*>(nullptr),
         static_cast<const S*>(nullptr), a.real[1], a.out[0]);
    return true;
  }
};

struct NonlinearEffects {
  static constexpr OpSpec spec = {
      "nonlinear_effects", "inverse_dynamics", "rnea", "c(q, qd) = C(q, qd) qd + g(q) (nv,).",
      3, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), real("gravity", kGravity)},
      1, {{"tau", shape(kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    rnea(m, w, a.in[0], a.in[1], static_cast<const S*>(nullptr), static_cast<const S*>(nullptr), a.real[2],
         a.out[0]);
    return true;
  }
};

struct Crba {
  static constexpr OpSpec spec = {
      "crba", "crba", "crba", "Joint-space mass matrix M (nv, nv) by the composite rigid-body algorithm.",
      1, {array("q", shape(kNq), kConfiguration)},
      1, {{"M", shape(kNv, kNv)}}, 0b1, 0, kFull, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    crba(m, w, a.in[0], a.out[0]);
    return true;
  }
};

struct Minv {
  static constexpr OpSpec spec = {
      "minv", "minv", "minv",
      "M⁻¹ (nv, nv): directly in O(n²), or on small and branched trees by CRBA and M's tree-sparse "
      "factorisation, whichever the model makes cheaper. output_dense=False returns the upper triangle "
      "(zeros below).",
      2, {array("q", shape(kNq), kConfiguration), param("output_dense", kFlag, 1)},
      1, {{"Minv", shape(kNv, kNv)}}, 0b1, 0, kFull, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return minv(m, w, a.in[0], a.choice[1] != 0, a.out[0]);
  }
};

struct Aba {
  static constexpr OpSpec spec = {
      "aba", "aba", "aba",
      "Forward dynamics: qdd (nv,), by the articulated-body algorithm, or on a small tree in double precision "
      "by M's tree-sparse factorisation.",
      5,
      {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), array("tau", shape(kNv)),
       optional_array("f_ext", shape(kNb, 6)), real("gravity", kGravity)},
      1, {{"qdd", shape(kNv)}}, 0b1, 0, kLinearUnlessMimic, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return aba(m, w, a.in[0], a.in[1], a.in[2], a.in[3], a.real[4], a.out[0]);
  }
};

struct ForwardDynamics {
  static constexpr OpSpec spec = {
      "forward_dynamics", "forward_dynamics", "minv",
      "Forward dynamics through the inverse mass matrix: qdd = M⁻¹ (u - c) (nv,).",
      5,
      {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), array("u", shape(kNv)),
       optional_array("f_ext", shape(kNb, 6)), real("gravity", kGravity)},
      1, {{"qdd", shape(kNv)}}, 0b1, 0, kFull, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return forward_dynamics(m, w, a.in[0], a.in[1], a.in[2], a.in[3], a.real[4], a.out[0]);
  }
};

// ---------------------------------------------------------------- first-order derivatives

struct InverseDynamicsGradient {
  static constexpr OpSpec spec = {
      "inverse_dynamics_gradient", "inverse_dynamics_gradient", "rnea_derivatives",
      "[∂c/∂q | ∂c/∂qd] (nv, 2·nv) of c = inverse_dynamics(q, qd, qdd)[0], tangent space.",
      5,
      {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), optional_array("qdd", shape(kNv)),
       real("gravity", kGravity), optional_array("f_ext", shape(kNb, 6))},
      3, {{"dtau", shape(kNv, k2Nv)}, {"dtau_dq", shape(kNv, kNv)}, {"dtau_dqd", shape(kNv, kNv)}},
      0b001, 0, kFull, kScratch2NvNv, kNotPositiveDefinite, kAnyModel, kFiniteOutputs, 0b001};
  // dtau = [dtau_dq | dtau_dqd]; the halves alone when asked for them (Engine::inverse_dynamics_gradient)
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    const int nv = m.nv;
    S* dq = a.out[1] ? a.out[1] : a.scratch;
    S* dv = a.out[2] ? a.out[2] : a.scratch + nv * nv;
    rnea_derivatives(m, w, a.in[0], a.in[1], a.in[2], a.in[4], a.real[3], dq, dv);
    if (a.out[0])
      for (int r = 0; r < nv; ++r)
        for (int c = 0; c < nv; ++c) a.out[0][r * 2 * nv + c] = dq[r * nv + c], a.out[0][r * 2 * nv + nv + c] = dv[r * nv + c];
    return true;
  }
};

struct ForwardDynamicsGradient {
  static constexpr OpSpec spec = {
      "forward_dynamics_gradient", "forward_dynamics_gradient", "aba_derivatives",
      "(∂qdd/∂q, ∂qdd/∂qd), each (nv, nv), of qdd = forward_dynamics(q, qd, u): -M⁻¹ ∂ID/∂(q, qd) at the "
      "forward-dynamics acceleration qdd (nv,, the third output).",
      5,
      {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), array("u", shape(kNv)),
       optional_array("f_ext", shape(kNb, 6)), real("gravity", kGravity)},
      4, {{"dqdd_dq", shape(kNv, kNv)}, {"dqdd_dqd", shape(kNv, kNv)}, {"qdd", shape(kNv)}, {"Minv", shape(kNv, kNv)}},
      0b0011, 0, kFull, kScratchNv, kNotPositiveDefinite};
  // M⁻¹ too when asked for it (computed on the way; Engine::forward_dynamics_gradient). factored:
  // aba_derivatives's (a compiled instance's own, codegen/instance.hpp)
  template <typename S, typename Factored = FactoredMinv<S>>
  RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a,
                         const Factored& factored = Factored{}) {
    S* qdd = a.out[2] ? a.out[2] : a.scratch;
    if (!aba_derivatives(m, w, a.in[0], a.in[1], a.in[2], a.in[3], a.real[4], qdd, a.out[0], a.out[1], factored))
      return false;
    if (a.out[3]) {
      if (m.has_mimic) return minv(m, w, a.in[0], true, a.out[3]);  // w.dense holds a Cholesky factor there
      for (long i = 0; i < long(m.nv) * m.nv; ++i) a.out[3][i] = w.dense[i];
    }
    return true;
  }
};

struct FExtGradient {
  static constexpr OpSpec spec = {
      "f_ext_gradient", "f_ext_gradient", "aba_derivatives",
      "(∂c/∂f_ext, ∂qdd/∂f_ext), each (nb, nv, 6): per body b, -J_bᵀ and M⁻¹ J_bᵀ with J_b the body's Jacobian in "
      "its own frame (f_ext is expressed in the body frame, [linear; angular]).",
      1, {array("q", shape(kNq), kConfiguration)},
      2, {{"dtau_dfext", shape(kNb, kNv, 6)}, {"dqdd_dfext", shape(kNb, kNv, 6)}}, 0b11, 0, kFull, kNoScratch,
      kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return fext_derivatives(m, w, a.in[0], a.out[0], a.out[1]);
  }
};

// ---------------------------------------------------------------- per-pass helpers
// The passes of RNEA, M⁻¹ and ∂ID one at a time, so that a port (an
// accelerator's kernels) can be checked pass by pass. Per-body columns are
// (nb, 6, 6): [b, :, a] is column a of body b's joint (zeros beyond its nv).

#define RBD_STATE_ARGS                                                                                  \
  array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), optional_array("qdd", shape(kNv))

struct InverseDynamicsFpass {
  static constexpr OpSpec spec = {
      "inverse_dynamics_fpass", "inverse_dynamics", "rnea",
      "RNEA forward pass: per body (nb, 6), body frame: velocity v, acceleration a (with the fictitious gravity "
      "acceleration -g) and the net body force f = I a + v ×* I v - f_ext.",
      5, {RBD_STATE_ARGS, real("gravity", kGravity), optional_array("f_ext", shape(kNb, 6))},
      3, {{"v", shape(kNb, 6)}, {"a", shape(kNb, 6)}, {"f", shape(kNb, 6)}}, 0b111, 0, kLinear, kNoScratch,
      kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    rnea_forward_pass(m, w, a.in[0], a.in[1], a.in[2], a.in[4], a.real[3]);
    for (int i = 0; i < m.nb; ++i) {
      if (a.out[0]) store(w.v[i], a.out[0] + 6 * i);
      if (a.out[1]) store(w.a[i], a.out[1] + 6 * i);
      if (a.out[2]) store(w.f[i], a.out[2] + 6 * i);
    }
    return true;
  }
};

struct ApplyExternalForces {
  static constexpr OpSpec spec = {
      "apply_external_forces", "inverse_dynamics", "rnea",
      "f_in - f_ext per body, both (nb, 6) in body frames: the net body forces once the external forces are taken "
      "away (the step RNEA's forward pass ends with).",
      2, {array("f_in", shape(kNb, 6)), array("f_ext", shape(kNb, 6))},
      1, {{"f", shape(kNb, 6)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    for (int k = 0; k < 6 * m.nb; ++k) a.out[0][k] = a.in[0][k] - a.in[1][k];
    return true;
  }
};

struct InverseDynamicsBpass {
  static constexpr OpSpec spec = {
      "inverse_dynamics_bpass", "inverse_dynamics", "rnea",
      "RNEA backward pass from net body forces f (nb, 6): (c (nv,), the joint forces (nb, 6), body frame). "
      "inverse_dynamics_bpass(q, inverse_dynamics_fpass(...)[2]) is inverse_dynamics.",
      2, {array("q", shape(kNq), kConfiguration), array("f", shape(kNb, 6))},
      2, {{"tau", shape(kNv)}, {"f_joint", shape(kNb, 6)}}, 0b11, 0, kLinear, kScratchNv, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    place_joints(m, w.X_parent, a.in[0]);
    for (int i = 0; i < m.nb; ++i) w.f[i] = load_force(a.in[1] + 6 * i);
    rnea_backward_pass(m, w, a.out[0] ? a.out[0] : a.scratch);
    if (a.out[1])
      for (int i = 0; i < m.nb; ++i) store(w.f[i], a.out[1] + 6 * i);
    return true;
  }
};

struct MinvBpass {
  static constexpr OpSpec spec = {
      "minv_bpass", "minv", "minv",
      "Backward pass of the direct M⁻¹: the rows of each joint over its subtree's columns (nv, nv; zeros "
      "elsewhere). Models without mimic joints.",
      1, {array("q", shape(kNq), kConfiguration)},
      1, {{"Minv_b", shape(kNv, kNv)}}, 0b1, 0, kFull, kNoScratch, kNotPositiveDefinite, kNoMimic};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return minv_backward_pass(m, w, a.in[0], a.out[0]);
  }
};

struct MinvFpass {
  static constexpr OpSpec spec = {
      "minv_fpass", "minv", "minv",
      "Forward pass of the direct M⁻¹ from minv_bpass's result minv_b (nv, nv): the upper triangle of M⁻¹ "
      "(nv, nv; zeros below). Models without mimic joints.",
      2, {array("q", shape(kNq), kConfiguration), array("minv_b", shape(kNv, kNv))},
      1, {{"Minv", shape(kNv, kNv)}}, 0b1, 0, kFull, kNoScratch, kNotPositiveDefinite, kNoMimic};
  // the backward pass's articulated quantities (U, D⁻¹, S), then the forward pass on the given rows
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    const int nv = m.nv;
    S* out = a.out[0];
    if (!minv_backward_pass(m, w, a.in[0], out)) return false;
    for (int k = 0; k < nv * nv; ++k) out[k] = a.in[1][k];
    minv_forward_pass(m, w, out);
    for (int r = 1; r < nv; ++r)
      for (int c = 0; c < r; ++c) out[r * nv + c] = S(0);
    return true;
  }
};

// the forward pass of ∂ID: the DoF columns with respect to q (dV_dq, dA_dq) or qd (S, dA_dqd), world frame
template <int Wrt> struct InverseDynamicsGradientFpass {
  static constexpr OpSpec spec = {
      Wrt == 0 ? "inverse_dynamics_gradient_fpass_dq" : "inverse_dynamics_gradient_fpass_dqd",
      "inverse_dynamics_gradient", "rnea_derivatives",
      Wrt == 0 ? "Forward pass of ∂ID/∂q: per body (nb, 6, 6), [b, :, a] the world-frame column of DoF a of body "
                 "b's joint: (dV_dq = v_λ × s, dA_dq = a_λ × s + v_λ × dV_dq)."
               : "Forward pass of ∂ID/∂qd: per body (nb, 6, 6): (S = s, the world-frame motion subspace, "
                 "dA_dqd = v × s + v_λ × s).",
      4, {RBD_STATE_ARGS, real("gravity", kGravity)},
      2, {{Wrt == 0 ? "dV_dq" : "S", shape(kNb, 6, 6)}, {Wrt == 0 ? "dA_dq" : "dA_dqd", shape(kNb, 6, 6)}},
      0b11, 0, kFull, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    rnea_derivatives_forward_pass(m, w, a.in[0], a.in[1], a.in[2], static_cast<const S*>(nullptr), a.real[3], false,
                                  true);  // (world coordinates: its outputs are world quantities)
    if (a.out[0]) store_dof_columns(m, Wrt == 0 ? w.dVdq : w.S_world, a.out[0]);
    if (a.out[1]) store_dof_columns(m, Wrt == 0 ? w.dAdq : w.dAdv, a.out[1]);
    return true;
  }
};

// the backward pass of ∂ID from the caller's DoF columns (the forward pass's outputs)
template <int Wrt> struct InverseDynamicsGradientBpass {
  static constexpr OpSpec spec = {
      Wrt == 0 ? "inverse_dynamics_gradient_bpass_dq" : "inverse_dynamics_gradient_bpass_dqd",
      "inverse_dynamics_gradient", "rnea_derivatives",
      Wrt == 0 ? "Backward pass of ∂ID/∂q from the forward pass's columns: ∂c/∂q (nv, nv)."
               : "Backward pass of ∂ID/∂qd from the forward pass's columns: ∂c/∂qd (nv, nv).",
      6,
      {RBD_STATE_ARGS, array(Wrt == 0 ? "dV_dq" : "S", shape(kNb, 6, 6)),
       array(Wrt == 0 ? "dA_dq" : "dA_dqd", shape(kNb, 6, 6)), real("gravity", kGravity)},
      1, {{Wrt == 0 ? "dtau_dq" : "dtau_dqd", shape(kNv, kNv)}}, 0b1, 0, kFull, kScratchNvNv, kNotPositiveDefinite};
  // the composites from the state, the DoF columns from the caller
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    rnea_derivatives_forward_pass(m, w, a.in[0], a.in[1], a.in[2], static_cast<const S*>(nullptr), a.real[5], false,
                                  true);  // (world coordinates, as the forward passes' outputs)
    load_dof_columns(m, a.in[3], Wrt == 0 ? w.dVdq : w.S_world);
    load_dof_columns(m, a.in[4], Wrt == 0 ? w.dAdq : w.dAdv);
    if (Wrt == 0) rnea_derivatives_backward_pass(m, w, a.out[0], a.scratch, static_cast<S*>(nullptr));
    else rnea_derivatives_backward_pass(m, w, a.scratch, a.out[0], static_cast<S*>(nullptr));
    return true;
  }
};
using InverseDynamicsGradientFpassDq = InverseDynamicsGradientFpass<0>;
using InverseDynamicsGradientFpassDqd = InverseDynamicsGradientFpass<1>;
using InverseDynamicsGradientBpassDq = InverseDynamicsGradientBpass<0>;
using InverseDynamicsGradientBpassDqd = InverseDynamicsGradientBpass<1>;
#undef RBD_STATE_ARGS

// ---------------------------------------------------------------- second-order derivatives (IDSVA-SO, FDSVA-SO)
// Each tensor is (nv, nv, nv), index order [i, j, k]; rbdkit/algorithms/idsva_so.hpp and fdsva_so.hpp.

#define RBD_SO_ARGS(third)                                                                              \
  4, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), array(third, shape(kNv)),       \
      real("gravity", kGravity)}
#define RBD_SO_IDSVA_OUTS                                                                                \
  4, {{"d2tau_dq2", shape(kNv, kNv, kNv)}, {"d2tau_dqd2", shape(kNv, kNv, kNv)},                       \
      {"d2tau_dqdqd", shape(kNv, kNv, kNv)}, {"dM_dq", shape(kNv, kNv, kNv)}},                          \
      0b1111, 0, kFull, kNoScratch, kNotPositiveDefinite

struct IdsvaSoBodyFrame {
  static constexpr OpSpec spec = {
      "idsva_so_body_frame", "idsva_so", "second_order",
      "(d2tau_dq2, d2tau_dqd2, d2tau_dqdqd, dM_dq), each (nv, nv, nv), of tau = inverse_dynamics(q, qd, qdd)[0], "
      "by the body-frame recursion (body-frame propagation, inertias and motion subspaces).",
      RBD_SO_ARGS("qdd"), RBD_SO_IDSVA_OUTS};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    idsva_so_body_frame(m, w, a.in[0], a.in[1], a.in[2], a.real[3], a.out[0], a.out[1], a.out[2], a.out[3]);
    return true;
  }
};

struct IdsvaSoWorldFrame {
  static constexpr OpSpec spec = {
      "idsva_so_world_frame", "idsva_so", "second_order",
      "The same tensors as idsva_so_body_frame by the world-frame recursion (world-frame propagation with gravity "
      "in the sweep; composites add without transforms). Equal to the body-frame variant to rounding.",
      RBD_SO_ARGS("qdd"), RBD_SO_IDSVA_OUTS};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    idsva_so_world_frame(m, w, a.in[0], a.in[1], a.in[2], a.real[3], a.out[0], a.out[1], a.out[2], a.out[3]);
    return true;
  }
};

struct IdsvaSo {
  static constexpr OpSpec spec = {
      "idsva_so", "idsva_so", "second_order",
      "(d2tau_dq2, d2tau_dqd2, d2tau_dqdqd, dM_dq): the body-frame variant for a fixed base, the world-frame one "
      "for a floating base.",
      RBD_SO_ARGS("qdd"), RBD_SO_IDSVA_OUTS};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    idsva_so(m, w, a.in[0], a.in[1], a.in[2], a.real[3], a.out[0], a.out[1], a.out[2], a.out[3]);
    return true;
  }
};

struct FdsvaSo {
  static constexpr OpSpec spec = {
      "fdsva_so", "fdsva_so", "fdsva_so",
      "(d2qdd_dq2, d2qdd_dqd2, d2qdd_dqdqd, d2qdd_dqdu), each (nv, nv, nv), of qdd = forward_dynamics(q, qd, u): "
      "-M⁻¹ times the second-order inverse-dynamics terms plus the ∂M/∂q·∂qdd terms, at qdd = FD(q, qd, u).",
      RBD_SO_ARGS("u"),
      4, {{"d2qdd_dq2", shape(kNv, kNv, kNv)}, {"d2qdd_dqd2", shape(kNv, kNv, kNv)},
          {"d2qdd_dqdqd", shape(kNv, kNv, kNv)}, {"d2qdd_dqdu", shape(kNv, kNv, kNv)}},
      0b1111, 0, kFull, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return fdsva_so(m, w, a.in[0], a.in[1], a.in[2], a.real[3], a.out[0], a.out[1], a.out[2], a.out[3]);
  }
};

#undef RBD_SO_ARGS
#undef RBD_SO_IDSVA_OUTS

// ---------------------------------------------------------------- configuration space (Lie-group operations)

struct Integrate {
  static constexpr OpSpec spec = {
      "integrate", "configuration", "configuration",
      "q ⊕ v (nq,): SE(3) exponential on a free-flyer joint (twist in the local frame), SO(3) on spherical "
      "joints, q + v elsewhere.",
      2, {array("q", shape(kNq), kConfiguration), array("v", shape(kNv))},
      1, {{"q_next", shape(kNq)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    integrate(m, a.in[0], a.in[1], a.out[0]);
    return true;
  }
};

struct Difference {
  static constexpr OpSpec spec = {
      "difference", "configuration", "configuration",
      "q1 ⊖ q0 (nv,): the tangent step v with integrate(q0, v) = q1.",
      2, {array("q0", shape(kNq), kConfiguration), array("q1", shape(kNq), kConfiguration)},
      1, {{"v", shape(kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    difference(m, a.in[0], a.in[1], a.out[0]);
    return true;
  }
};

struct DIntegrate {
  static constexpr OpSpec spec = {
      "dIntegrate", "configuration", "configuration",
      "Tangent Jacobian (nv, nv) of integrate(q, v) with respect to 'q' or 'v'.",
      3, {array("q", shape(kNq), kConfiguration), array("v", shape(kNv)), param("with_respect_to", kChoice, 0, kWrtQV)},
      1, {{"J", shape(kNv, kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    dintegrate(m, a.in[0], a.in[1], a.choice[2], a.out[0]);
    return true;
  }
};

struct D2Integrate {
  static constexpr OpSpec spec = {
      "d2Integrate", "configuration", "configuration",
      "Second derivative of integrate: H (nv, nv, nv) with H[i, j, k] = ∂ dIntegrate(q, v, arg1)[i, j] / ∂x_k, x = "
      "arg2 ('q': a tangent step through integrate(q, ·), 'v': v itself). Exact (dual numbers through the "
      "closed-form Jacobians).",
      4,
      {array("q", shape(kNq), kConfiguration), array("v", shape(kNv)), param("arg1", kChoice, 1, kWrtQV),
       param("arg2", kChoice, 1, kWrtQV)},
      1, {{"H", shape(kNv, kNv, kNv)}}, 0b1, 0, kLinear, kScratchD2Integrate, kNotPositiveDefinite, kAnyModel,
      kFiniteOutputs, 0, kCalled};
  // one dual pass per direction k of arg2: the ε parts of dIntegrate are H[:, :, k]
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    using D = Dual<S>;
    const int nq = m.nq, nv = m.nv, arg1 = a.choice[2], arg2 = a.choice[3];
    D* q = reinterpret_cast<D*>(a.scratch);  // (nq) q, then q ⊕ ε e_k (nq), v + ε e_k (nv), the step (nv), J (nv²)
    D* qk = q + nq;
    D* vk = qk + nq;
    D* step = vk + nv;
    D* J = step + nv;
    for (int i = 0; i < nq; ++i) q[i] = D(a.in[0][i]);
    for (int k = 0; k < nv; ++k) {
      for (int i = 0; i < nv; ++i) vk[i] = D(a.in[1][i], arg2 == 1 && i == k ? S(1) : S(0));
      if (arg2 == 0) {
        for (int i = 0; i < nv; ++i) step[i] = D(S(0), i == k ? S(1) : S(0));
        integrate(m, static_cast<const D*>(q), static_cast<const D*>(step), qk);
      } else {
        for (int i = 0; i < nq; ++i) qk[i] = q[i];
      }
      dintegrate(m, static_cast<const D*>(qk), static_cast<const D*>(vk), arg1, J);
      for (int i = 0; i < nv * nv; ++i) a.out[0][i * nv + k] = J[i].d;
    }
    return true;
  }
};

struct DDifference {
  static constexpr OpSpec spec = {
      "dDifference", "configuration", "configuration",
      "Tangent Jacobian (nv, nv) of difference(q0, q1) with respect to 'from' (q0) or 'to' (q1).",
      3,
      {array("q0", shape(kNq), kConfiguration), array("q1", shape(kNq), kConfiguration),
       param("with_respect_to", kChoice, 1, kWrtFromTo)},
      1, {{"J", shape(kNv, kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    ddifference(m, a.in[0], a.in[1], a.choice[2], a.out[0]);
    return true;
  }
};

// ---------------------------------------------------------------- integrators and the plant step

// the arguments after the state: u, dt, integrator_type, f_ext, gravity, output_convention
#define RBD_STEP_ARGS                                                                                   \
  array("u", shape(kNv)), param("dt", kTimeStep, kRequired), param("integrator_type", kIntegrator, 0),  \
      optional_array("f_ext", shape(kNb, 6)), real("gravity", kGravity), param("output_convention", kConvention, 0)

struct Integrator {
  static constexpr OpSpec spec = {
      "integrator", "integrator", "integrators",
      "x⁺ = [q⁺; qd⁺] (nq + nv,) after one step of length dt with constant controls u and body-local external "
      "forces f_ext.",
      8, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), RBD_STEP_ARGS},
      1, {{"x_next", shape(kNx)}}, 0b1, 0, kLinearUnlessMimic, kScratchIntegrator, kStepFailed, kAnyModel,
      kFiniteOutputs, 0, kFlattened};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return integrator_step(m, w, a.choice[4], a.in[0], a.in[1], a.in[2], a.in[5], a.real[3], a.real[6], a.out[0],
                           a.out[0] + m.nq, a.scratch, a.choice[7]);
  }
};

struct IntegratorGradient {
  static constexpr OpSpec spec = {
      "integrator_gradient", "integrator_gradient", "integrators",
      "[A | B] = ∂x⁺/∂(x, u) (2·nv, 3·nv) in the tangent space: rows [δq⁺; δqd⁺], columns [δq | δqd | δu] "
      "(x⁺ (nq + nv,) is the first output).",
      8, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), RBD_STEP_ARGS},
      2, {{"x_next", shape(kNx)}, {"AB", shape(k2Nv, k3Nv)}}, 0b10, 0, kFull, kScratchIntegratorGrad, kStepFailed, kAnyModel, kFiniteOutputs,
      0, kCalled};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    S* x = a.out[0] ? a.out[0] : a.scratch + integrator_gradient_scratch_values(m.nq, m.nv);
    return integrator_gradient(m, w, a.choice[4], a.in[0], a.in[1], a.in[2], a.in[5], a.real[3], a.real[6], x,
                               x + m.nq, a.out[1], a.scratch, a.choice[7]);
  }
};

struct IntegratorFExtGradient {
  static constexpr OpSpec spec = {
      "integrator_f_ext_gradient", "integrator_gradient", "integrators",
      "∂x⁺/∂f_ext (2·nv, nb, 6) of integrator: rows [δq⁺; δqd⁺] in the tangent space, [:, b, c] the derivative "
      "with respect to component c of body b's wrench (body frame, as f_ext). Every scheme: each stage applies "
      "the forces at its own configuration. x⁺ and [A | B] (integrator_gradient's) are the first two outputs.",
      8, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), RBD_STEP_ARGS},
      3, {{"x_next", shape(kNx)}, {"AB", shape(k2Nv, k3Nv)}, {"dx_df", shape(k2Nv, kNb, 6)}}, 0b100, 0, kFull,
      kScratchIntegratorFExtGrad, kStepFailed, kAnyModel, kFiniteOutputs, 0, kCalled};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    // x⁺ and AB in the scratch when not asked for (after the step's own)
    S* spare = a.scratch + integrator_fext_gradient_scratch_values(m.nq, m.nv, m.nb);
    S* x = a.out[0] ? a.out[0] : spare;
    S* AB = a.out[1] ? a.out[1] : spare + m.nq + m.nv;
    return integrator_fext_gradient(m, w, a.choice[4], a.in[0], a.in[1], a.in[2], a.in[5], a.real[3], a.real[6],
                                     x, x + m.nq, AB, a.out[2], a.scratch, a.choice[7]);
  }
};

struct PlantStep {
  static constexpr OpSpec spec = {
      "plant_step", "integrator", "integrators", "x⁺ (nq + nv,) for x = [q; qd] (nq + nv,).",
      7, {array("x", shape(kNx), kConfiguration), RBD_STEP_ARGS},
      1, {{"x_next", shape(kNx)}}, 0b1, 0, kLinearUnlessMimic, kScratchIntegrator, kStepFailed, kAnyModel,
      kFiniteOutputs, 0, kFlattened};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return integrator_step(m, w, a.choice[3], a.in[0], a.in[0] + m.nq, a.in[1], a.in[4], a.real[2], a.real[5],
                           a.out[0], a.out[0] + m.nq, a.scratch, a.choice[6]);
  }
};

struct PlantStepGradient {
  static constexpr OpSpec spec = {
      "plant_step_gradient", "integrator_gradient", "integrators",
      "[A | B] (2·nv, 3·nv) of plant_step, tangent space (x⁺ is the first output).",
      7, {array("x", shape(kNx), kConfiguration), RBD_STEP_ARGS},
      2, {{"x_next", shape(kNx)}, {"AB", shape(k2Nv, k3Nv)}}, 0b10, 0, kFull, kScratchIntegratorGrad, kStepFailed, kAnyModel, kFiniteOutputs,
      0, kCalled};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    S* x = a.out[0] ? a.out[0] : a.scratch + integrator_gradient_scratch_values(m.nq, m.nv);
    return integrator_gradient(m, w, a.choice[3], a.in[0], a.in[0] + m.nq, a.in[1], a.in[4], a.real[2], a.real[5],
                               x, x + m.nq, a.out[1], a.scratch, a.choice[6]);
  }
};

struct PlantStepHessian {
  static constexpr OpSpec spec = {
      "plant_step_hessian", "plant_step_hessian", "integrator_hessian",
      "H (2·nv, 3·nv, 3·nv): the second-order sensitivity of plant_step. With z = [δq; δqd; δu] (3·nv), the input "
      "q = q0 ⊕ δq, qd = qd0 + δqd, u = u0 + δu, and the output read in the chart at the nominal output, ψ(z) = "
      "[q⁺(z) ⊖ q⁺(0); qd⁺(z) - qd⁺(0)], H[i, j, k] = ∂²ψ_i/∂z_j∂z_k (symmetric in j, k), so that x⁺(z) = x⁺(0) ⊕ "
      "(AB z + ½ H[z, z] + O(|z|³)) with AB = plant_step_gradient (x⁺ and AB are the first two outputs). "
      "output_convention=\"mujoco\": x, u in MuJoCo's qpos/qvel layout and ⊕ / ⊖ MuJoCo's. No f_ext (the "
      "second-order forward dynamics take no external forces). form=\"reference\": the reference "
      "implementation's H[i, j, k] = ∂AB[i, k]/∂z_j, AB differentiated along x ⊕ δ with each AB read at its own "
      "output; it differs from the default by the Lie brackets of free-flyer and spherical joints, an "
      "antisymmetric part (docs/conventions.md).",
      7,
      {array("x", shape(kNx), kConfiguration), array("u", shape(kNv)), param("dt", kTimeStep, kRequired),
       param("integrator_type", kIntegrator, 0), real("gravity", kGravity), param("output_convention", kConvention, 0),
       param("form", kChoice, 0, kHessianForms)},
      3, {{"x_next", shape(kNx)}, {"AB", shape(k2Nv, k3Nv)}, {"H", shape(k2Nv, k3Nv, k3Nv)}}, 0b100, 0, kFull,
      kScratchIntegratorHessian, kStepFailed, kAnyModel, kFiniteOutputs, 0, kCalled};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    S* x = a.out[0] ? a.out[0] : a.scratch + integrator_hessian_scratch_values(m.nq, m.nv);
    S* AB = a.out[1] ? a.out[1] : x + m.nq + m.nv;
    if (!integrator_hessian(m, w, a.choice[3], a.in[0], a.in[0] + m.nq, a.in[1], a.real[2], a.real[4], x, x + m.nq,
                            AB, a.out[2], a.scratch, a.choice[5]))
      return false;
    if (a.choice[6] == kReferenceForm) step_hessian_reference_form(m, a.choice[5], AB, a.out[2]);
    return true;
  }
};

#undef RBD_STEP_ARGS

// ---------------------------------------------------------------- the MuJoCo convention's conversions
// (plant/mujoco_convention.hpp); qpos: a configuration in MuJoCo's layout

struct StateToMujoco {
  static constexpr OpSpec spec = {
      "state_to_mujoco", "mujoco_convention", "mujoco_convention",
      "x = [q; qd] (nq + nv,) in our convention -> [qpos; qvel] in MuJoCo's.",
      1, {array("x", shape(kNx), kConfiguration)},
      1, {{"x_mj", shape(kNx)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    configuration_to_mujoco(m, a.in[0], a.out[0]);
    rotate_to_mujoco(m, static_cast<const S*>(a.out[0]), a.in[0] + m.nq, a.out[0] + m.nq);
    return true;
  }
};

struct StateFromMujoco {
  static constexpr OpSpec spec = {
      "state_from_mujoco", "mujoco_convention", "mujoco_convention",
      "[qpos; qvel] (nq + nv,) in MuJoCo's convention -> x = [q; qd] in ours.",
      1, {array("x", shape(kNx), kMujocoConfiguration)},
      1, {{"x_pin", shape(kNx)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    rotate_from_mujoco(m, a.in[0], a.in[0] + m.nq, a.out[0] + m.nq);
    configuration_from_mujoco(m, a.in[0], a.out[0]);
    return true;
  }
};

struct ForceToMujoco {
  static constexpr OpSpec spec = {
      "force_to_mujoco", "mujoco_convention", "mujoco_convention",
      "generalized force u (nv,) in our frames -> MuJoCo's (qfrc) at qpos (nq,, MuJoCo layout).",
      2, {array("qpos", shape(kNq), kMujocoConfiguration), array("u", shape(kNv))},
      1, {{"u_mj", shape(kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    rotate_to_mujoco(m, a.in[0], a.in[1], a.out[0]);
    return true;
  }
};

struct ForceFromMujoco {
  static constexpr OpSpec spec = {
      "force_from_mujoco", "mujoco_convention", "mujoco_convention",
      "generalized force u (nv,) in MuJoCo's frames (qfrc) at qpos -> ours.",
      2, {array("qpos", shape(kNq), kMujocoConfiguration), array("u", shape(kNv))},
      1, {{"u_pin", shape(kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    rotate_from_mujoco(m, a.in[0], a.in[1], a.out[0]);
    return true;
  }
};

struct MujocoIntegrate {
  static constexpr OpSpec spec = {
      "mujoco_integrate", "mujoco_convention", "mujoco_convention",
      "MuJoCo's qpos ⊕ v (mj_integratePos with a unit step): (nq,).",
      2, {array("qpos", shape(kNq), kMujocoConfiguration), array("v", shape(kNv))},
      1, {{"qpos_next", shape(kNq)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    mj_integrate(m, a.in[0], a.in[1], a.out[0]);
    return true;
  }
};

struct MujocoDifference {
  static constexpr OpSpec spec = {
      "mujoco_difference", "mujoco_convention", "mujoco_convention",
      "MuJoCo's qpos1 ⊖ qpos0 (mj_differentiatePos with a unit step): (nv,).",
      2, {array("qpos0", shape(kNq), kMujocoConfiguration), array("qpos1", shape(kNq), kMujocoConfiguration)},
      1, {{"v", shape(kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    mj_difference(m, a.in[0], a.in[1], a.out[0]);
    return true;
  }
};

// ---------------------------------------------------------------- energy and the Coriolis matrix

struct KineticEnergy {
  static constexpr OpSpec spec = {
      "kinetic_energy", "energy", "energy", "T = ½ qdᵀ M(q) qd (a scalar).",
      2, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv))},
      1, {{"T", scalar()}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    a.out[0][0] = kinetic_energy(m, w, a.in[0], a.in[1]);
    return true;
  }
};

struct PotentialEnergy {
  static constexpr OpSpec spec = {
      "potential_energy", "energy", "energy",
      "V = -Σ m_i g·c_i with g = (0, 0, gravity): the potential energy of the bodies' mass in the world, zero at "
      "z = 0 (a scalar).",
      2, {array("q", shape(kNq), kConfiguration), real("gravity", kGravity)},
      1, {{"V", scalar()}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    a.out[0][0] = potential_energy(m, w, a.in[0], a.real[1]);
    return true;
  }
};

struct MechanicalEnergy {
  static constexpr OpSpec spec = {
      "mechanical_energy", "energy", "energy", "T + V (a scalar): kinetic_energy plus potential_energy.",
      3, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), real("gravity", kGravity)},
      1, {{"E", scalar()}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    const S T = kinetic_energy(m, w, a.in[0], a.in[1]);
    a.out[0][0] = T + potential_energy(m, w, a.in[0], a.real[2]);
    return true;
  }
};

struct CoriolisMatrix {
  static constexpr OpSpec spec = {
      "coriolis_matrix", "coriolis_matrix", "energy",
      "Coriolis matrix C (nv, nv) of Pinocchio's computeCoriolisMatrix: the Christoffel-consistent factorisation, "
      "with C·qd + g = nonlinear_effects and Ṁ - 2C skew-symmetric.",
      2, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv))},
      1, {{"C", shape(kNv, kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    coriolis_matrix(m, w, a.in[0], a.in[1], a.out[0]);
    return true;
  }
};

// ---------------------------------------------------------------- centre of mass and centroidal momentum
// [linear; angular] about the centre of mass, world-aligned axes (algorithms/centroidal.hpp); a robot of
// total mass 0 has no centre of mass (kNoMass)

struct Com {
  static constexpr OpSpec spec = {
      "com", "com", "centroidal", "Centre of mass (3,) in the world frame.",
      1, {array("q", shape(kNq), kConfiguration)},
      1, {{"c", shape(3)}}, 0b1, 0, kLinear, kNoScratch, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return center_of_mass(m, w, a.in[0], a.out[0]);
  }
};

struct JacobianCom {
  static constexpr OpSpec spec = {
      "jacobian_com", "com", "centroidal",
      "Jacobian of the centre of mass (3, nv): ċ = J_com·qd; also ∂c/∂δ along tangent steps. Equal to A[:3] / "
      "total mass.",
      1, {array("q", shape(kNq), kConfiguration)},
      1, {{"J", shape(3, kNv)}}, 0b1, 0, kLinear, kNoScratch, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return jacobian_com(m, w, a.in[0], a.out[0]);
  }
};

struct Ccrba {
  static constexpr OpSpec spec = {
      "ccrba", "ccrba", "centroidal",
      "Centroidal momentum matrix and momentum (A (6, nv), h (6,)), h = A·qd, by the composite rigid-body "
      "algorithm (Pinocchio's ccrba: data.Ag, data.hg).",
      2, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv))},
      2, {{"A", shape(6, kNv)}, {"h", shape(6)}}, 0b11, 0, kLinear, kNoScratch, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return ccrba(m, w, a.in[0], a.in[1], a.out[0], a.out[1]);
  }
};

struct CentroidalMomentum {
  static constexpr OpSpec spec = {
      "centroidal_momentum", "ccrba", "centroidal", "Centroidal momentum h (6,) = A·qd, in one O(n) pass (no A).",
      2, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv))},
      1, {{"h", shape(6)}}, 0b1, 0, kLinear, kNoScratch, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return centroidal_momentum(m, w, a.in[0], a.in[1], a.out[0]);
  }
};

struct Dccrba {
  static constexpr OpSpec spec = {
      "dccrba", "dccrba", "centroidal",
      "Analytic configuration derivative of A: dA (6, nv, nv) with dA[r, j, k] = ∂A[r, j]/∂δ_k along the tangent "
      "step q ← integrate(q, δ·e_k).",
      1, {array("q", shape(kNq), kConfiguration)},
      1, {{"dA", shape(6, kNv, kNv)}}, 0b1, 0, kLinear, kScratch6Nv, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return dccrba(m, w, a.in[0], a.scratch, a.out[0]);  // A in scratch
  }
};

struct CmmTimeVariation {
  static constexpr OpSpec spec = {
      "cmm_time_variation", "dccrba", "centroidal",
      "Ȧ (6, nv) = Σ_k dA[:, :, k]·qd_k, the time variation of A along qd, in O(n) (Pinocchio's "
      "computeCentroidalMapTimeVariation: data.dAg).",
      2, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv))},
      1, {{"Adot", shape(6, kNv)}}, 0b1, 0, kLinear, kScratch6Nv, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return cmm_time_variation(m, w, a.in[0], a.in[1], a.scratch, a.out[0]);  // A in scratch
  }
};

struct DccrbaFd {
  static constexpr OpSpec spec = {
      "dccrba_fd", "dccrba", "centroidal",
      "dccrba by central finite differences of ccrba through integrate (step eps): a cross-check of the analytic "
      "dccrba, not for production. dA (6, nv, nv).",
      2, {array("q", shape(kNq), kConfiguration), positive("eps", 1e-5, kFdStepName)},
      1, {{"dA", shape(6, kNv, kNv)}}, 0b1, 0, kLinear, kScratchDccrbaFd, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return dccrba_fd(m, w, a.in[0], a.real[1], a.out[0], a.scratch);
  }
};

struct CmmTimeVariationFd {
  static constexpr OpSpec spec = {
      "cmm_time_variation_fd", "dccrba", "centroidal",
      "cmm_time_variation from dccrba_fd (finite differences, step eps): a cross-check only. Ȧ (6, nv).",
      3, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), positive("eps", 1e-5, kFdStepName)},
      1, {{"Adot", shape(6, kNv)}}, 0b1, 0, kLinear, kScratchCmmFd, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return cmm_time_variation_fd(m, w, a.in[0], a.in[1], a.real[2], a.out[0], a.scratch);
  }
};

struct CentroidalMomentumTimeVariation {
  static constexpr OpSpec spec = {
      "centroidal_momentum_time_variation", "dccrba", "centroidal",
      "ḣ (6,) = A·qdd + Ȧ·qd, the rate of the centroidal momentum (gravity not included), in one O(n) pass "
      "(Pinocchio's computeCentroidalMomentumTimeVariation: data.dhg).",
      3, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), array("qdd", shape(kNv))},
      1, {{"hdot", shape(6)}}, 0b1, 0, kLinear, kNoScratch, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return centroidal_momentum_time_variation(m, w, a.in[0], a.in[1], a.in[2], a.out[0]);
  }
};

struct CentroidalDynamicsDerivatives {
  static constexpr OpSpec spec = {
      "centroidal_dynamics_derivatives", "centroidal_dynamics_derivatives", "centroidal",
      "(dh_dq, dhdot_dq, dhdot_dv, dhdot_da), each (6, nv), in O(n) (Pinocchio's "
      "computeCentroidalDynamicsDerivatives): dh_dq = ∂h/∂δ at fixed qd (the true tangent derivative of ccrba's h, "
      "the moving centre of mass included), dhdot_dq = ∂ḣ/∂δ, dhdot_dv = ∂ḣ/∂qd, dhdot_da = ∂ḣ/∂qdd = A.",
      3, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), array("qdd", shape(kNv))},
      4,
      {{"dh_dq", shape(6, kNv)}, {"dhdot_dq", shape(6, kNv)}, {"dhdot_dv", shape(6, kNv)},
       {"dhdot_da", shape(6, kNv)}},
      0b1111, 0, kLinear, kNoScratch, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return centroidal_dynamics_derivatives(m, w, a.in[0], a.in[1], a.in[2], a.out[0], a.out[1], a.out[2], a.out[3]);
  }
};

// ---------------------------------------------------------------- inertial-parameter regressors
// π = model.inertial_parameters() (10·nb,): per body [m, m·c, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz], I about the
// body-frame origin in body axes (algorithms/regressor.hpp)

struct InverseDynamicsRegressor {
  static constexpr OpSpec spec = {
      "inverse_dynamics_regressor", "regressor", "regressor",
      "Y (nv, 10·nb) with inverse_dynamics(q, qd, qdd)[0] = Y @ π (no external forces); qdd=None means zero. "
      "O(n·d).",
      4,
      {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), optional_array("qdd", shape(kNv)),
       real("gravity", kGravity)},
      1, {{"Y", shape(kNv, k10Nb)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    inverse_dynamics_regressor(m, w, a.in[0], a.in[1], a.in[2], a.real[3], a.out[0]);
    return true;
  }
};

struct KineticEnergyRegressor {
  static constexpr OpSpec spec = {
      "kinetic_energy_regressor", "regressor", "regressor",
      "y (10·nb,) with kinetic energy ½ qdᵀ M qd = y @ π (Pinocchio's computeKineticEnergyRegressor).",
      2, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv))},
      1, {{"y", shape(k10Nb)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    kinetic_energy_regressor(m, w, a.in[0], a.in[1], a.out[0]);
    return true;
  }
};

struct PotentialEnergyRegressor {
  static constexpr OpSpec spec = {
      "potential_energy_regressor", "regressor", "regressor",
      "y (10·nb,) with potential energy -Σ m_b g·c_b = y @ π, g = (0, 0, gravity), zero at the world origin "
      "(Pinocchio's computePotentialEnergyRegressor).",
      2, {array("q", shape(kNq), kConfiguration), real("gravity", kGravity)},
      1, {{"y", shape(k10Nb)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    potential_energy_regressor(m, w, a.in[0], a.real[1], a.out[0]);
    return true;
  }
};

struct InverseDynamicsRegressorGradient {
  static constexpr OpSpec spec = {
      "inverse_dynamics_regressor_gradient", "regressor_gradient", "regressor",
      "dY_dx (2·nv, nv, 10·nb): dY_dx[c] = ∂Y/∂x_c for x = [q (tangent step through integrate); qd], so "
      "dY_dx[c] @ π is column c of inverse_dynamics_gradient(q, qd, qdd); qdd=None means zero. O(10·n·d²) after "
      "one forward pass.",
      4,
      {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), optional_array("qdd", shape(kNv)),
       real("gravity", kGravity)},
      1, {{"dY", shape(k2Nv, kNv, k10Nb)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    inverse_dynamics_regressor_gradient(m, w, a.in[0], a.in[1], a.in[2], a.real[3], a.out[0]);
    return true;
  }
};

struct ForwardDynamicsParameterGradient {
  static constexpr OpSpec spec = {
      "forward_dynamics_parameter_gradient", "forward_dynamics_parameter_gradient", "regressor",
      "∂qdd/∂π (nv, 10·nb) of qdd = forward_dynamics(q, qd, u): -M⁻¹ Y with Y evaluated at that qdd (nv,, the "
      "second output).",
      4,
      {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), array("u", shape(kNv)),
       real("gravity", kGravity)},
      2, {{"dqdd_dpi", shape(kNv, k10Nb)}, {"qdd", shape(kNv)}}, 0b01, 0, kFull, kScratchNv, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return forward_dynamics_parameter_gradient(m, w, a.in[0], a.in[1], a.in[2], a.real[3],
                                               a.out[1] ? a.out[1] : a.scratch, a.out[0]);
  }
};

// ---------------------------------------------------------------- kinematics (algorithms/kinematics.hpp)
// Placements X_world_* as (R (3, 3), p (3,)), x_world = R x + p. Frame Jacobians in Pinocchio's reference
// frames: "LOCAL" (the frame's velocity in its own axes), "WORLD" (at the world origin, world axes),
// "LOCAL_WORLD_ALIGNED" (the frame origin's velocity, world axes); rows [linear; angular].

// R (3 x 3, row-major) and p (3) of a placement
template <typename S> RBD_HD void store_placement(const Transform<S>& X, S* R, S* p) {
  if (R)
    for (int k = 0; k < 9; ++k) R[k] = X.R.m[k];
  if (p) p[0] = X.p.x, p[1] = X.p.y, p[2] = X.p.z;
}

struct ForwardKinematics {
  static constexpr OpSpec spec = {
      "forward_kinematics", "kinematics", "kinematics",
      "Placements X_world_body of every body: (R (nb, 3, 3), p (nb, 3)), x_world = R x_body + p; a body's frame is "
      "its joint's child frame.",
      1, {array("q", shape(kNq), kConfiguration)},
      2, {{"R", shape(kNb, 3, 3)}, {"p", shape(kNb, 3)}}, 0b11, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    forward_kinematics(m, w, a.in[0], static_cast<const S*>(nullptr));
    for (int i = 0; i < m.nb; ++i)
      store_placement(w.X_world[i], a.out[0] ? a.out[0] + 9 * i : nullptr, a.out[1] ? a.out[1] + 3 * i : nullptr);
    return true;
  }
};

struct FramePlacement {
  static constexpr OpSpec spec = {
      "frame_placement", "kinematics", "kinematics",
      "Placement of a named frame (link or joint, fixed ones included) in the world: (R (3, 3), p (3,)), x_world = "
      "R x_frame + p (Pinocchio's data.oMf).",
      2, {array("q", shape(kNq), kConfiguration), frame("frame_name")},
      2, {{"R", shape(3, 3)}, {"p", shape(3)}}, 0b11, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    forward_kinematics(m, w, a.in[0], static_cast<const S*>(nullptr));
    store_placement(frame_placement(w, a.choice[1], frame_transform(a.in[1])), a.out[0], a.out[1]);
    return true;
  }
};

struct FrameJacobian {
  static constexpr OpSpec spec = {
      "frame_jacobian", "kinematics", "kinematics",
      "Geometric Jacobian J (6, nv) of a named frame, rows [linear; angular], in reference_frame \"LOCAL\", "
      "\"WORLD\" or \"LOCAL_WORLD_ALIGNED\" (Pinocchio's getFrameJacobian): J·v is the frame's velocity in that "
      "frame.",
      3, {array("q", shape(kNq), kConfiguration), frame("frame_name"), param("reference_frame", kChoice, 0, kReferenceFrames)},
      1, {{"J", shape(6, kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    forward_kinematics(m, w, a.in[0], static_cast<const S*>(nullptr));
    frame_jacobian(m, w, a.choice[1], frame_transform(a.in[1]), a.choice[2], a.out[0]);
    return true;
  }
};

struct FrameJacobianDot {
  static constexpr OpSpec spec = {
      "frame_jacobian_dot", "kinematics", "kinematics",
      "Time variation dJ/dt (6, nv) of frame_jacobian(q, frame_name, reference_frame) along qd (Pinocchio's "
      "getFrameJacobianTimeVariation): the frame's acceleration in that frame is J·qdd + dJ·qd.",
      4,
      {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), frame("frame_name"),
       param("reference_frame", kChoice, 0, kReferenceFrames)},
      1, {{"dJ", shape(6, kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    forward_kinematics(m, w, a.in[0], a.in[1]);
    frame_jacobian_dot(m, w, a.choice[2], frame_transform(a.in[2]), a.choice[3], a.out[0]);
    return true;
  }
};

// End effectors: the bodies of the joints named in ee_joint_names (default: the leaf bodies, in body order),
// n_ee of them, each at its tool point (an offset in its body frame: (n_ee, 3), or (3,) for all; default
// zero). Pose = [x, y, z, roll, pitch, yaw] with R = Rz(yaw) Ry(pitch) Rx(roll); derivatives along the tangent
// q ⊕ δ. At pitch = ±π/2 (gimbal lock) the rpy rows of the derivatives are singular.

#define RBD_EE_ARGS(offsets)                                                                           \
  3, {array("q", shape(kNq), kConfiguration), end_effectors("ee_joint_names"),                       \
      optional_array(offsets, shape(kNee, 3))}

// the tool point of end effector e (a.in[2]: the offsets, or null)
template <typename S> RBD_HD Vec3<S> tool_point(const OpArgs<S>& a, int e) {
  return a.in[2] ? Vec3<S>{a.in[2][3 * e], a.in[2][3 * e + 1], a.in[2][3 * e + 2]} : Vec3<S>::zero();
}

struct EndEffectorPose {
  static constexpr OpSpec spec = {
      "end_effector_pose", "kinematics", "kinematics",
      "Pose (n_ee, 6) = [x, y, z, roll, pitch, yaw] of each end effector: the world position of its tool point "
      "and the roll-pitch-yaw angles of its body's orientation (pitch in [-π/2, π/2]).",
      RBD_EE_ARGS("ee_offsets"),
      1, {{"pose", shape(kNee, 6)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    forward_kinematics(m, w, a.in[0], static_cast<const S*>(nullptr));
    for (int e = 0; e < a.n_ee; ++e) end_effector_pose(w, a.ee[e], tool_point(a, e), a.out[0] + 6 * e);
    return true;
  }
};

struct EndEffectorPoseGradient {
  static constexpr OpSpec spec = {
      "end_effector_pose_gradient", "kinematics", "kinematics",
      "Analytic gradient (n_ee, 6, nv) of end_effector_pose with respect to tangent perturbations: G[e, r, k] = "
      "∂pose[e, r]/∂δ_k. Position rows are the tool point's world-frame Jacobian; rpy rows E(rpy)⁻¹ times the "
      "world angular Jacobian, E mapping rpy rates to angular velocity.",
      RBD_EE_ARGS("ee_offsets"),
      1, {{"G", shape(kNee, 6, kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    forward_kinematics(m, w, a.in[0], static_cast<const S*>(nullptr));
    for (int e = 0; e < a.n_ee; ++e)
      end_effector_pose_gradient(m, w, a.ee[e], tool_point(a, e), a.out[0] + 6L * m.nv * e);
    return true;
  }
};

// scratch of the dual-number end-effector Hessian, in values of any kernel scalar S (sizeof(S) >= 4, so that
// float counts the most values): the model and a linear workspace in Dual<S> (twice their float bytes, the
// padding of its 16-byte-aligned arrays and the alignment of the start), then 2 nq + 7 nv dual values
RBD_HD long ee_hessian_dual_scratch(int nb, int nq, int nv) {
  const unsigned long bytes = workspace_bytes<float>(nb, nv, kLinearWorkspace) + sizeof(BodyDesc<float>) * nb;
  return static_cast<long>(2 * bytes / 4) + 160 + 2L * (2 * nq + 7 * nv);
}

struct EndEffectorPoseHessian {
  static constexpr OpSpec spec = {
      "end_effector_pose_hessian", "end_effector_pose_hessian", "kinematics",
      "Hessian (n_ee, 6, nv, nv) of end_effector_pose, H[e, r, j, k] = ∂gradient[e, r, k]/∂δ_j, by forward-mode "
      "dual numbers through the analytic gradient (exact; one pass per tangent direction). Not symmetric within "
      "free-flyer and spherical joints; form=\"reference\": its symmetric part ½ (H + Hᵀ) in (j, k), the "
      "reference implementation's. Note the argument order: offsets before ee_joint_names.",
      4,
      {array("q", shape(kNq), kConfiguration), optional_array("offsets", shape(kNee, 3)),
       end_effectors("ee_joint_names"), param("form", kChoice, 0, kHessianForms)},
      1, {{"H", shape(kNee, 6, kNv, kNv)}}, 0b1, 0, kLinear, kScratchEeHessianDual, kNotPositiveDefinite, kAnyModel,
      kFiniteOutputs, 0, kCalled};
  // direction j: the gradient at q ⊕ ε e_j in dual numbers; its ε parts are H[e, :, j, :]
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    using D = Dual<S>;
    const int nb = m.nb, nq = m.nq, nv = m.nv;
    // carve the scratch (16-byte aligned): the model in dual numbers, its workspace, the dual arrays
    std::uintptr_t at = (reinterpret_cast<std::uintptr_t>(a.scratch) + 15u) & ~std::uintptr_t(15);
    BodyDesc<D>* body = reinterpret_cast<BodyDesc<D>*>(at);
    for (int i = 0; i < nb; ++i) body_as(m.body[i], *new (body + i) BodyDesc<D>());
    at += (sizeof(BodyDesc<D>) * nb + 15ul) & ~15ul;
    const ModelView<D> md = {nb, nq, nv, m.has_mimic, body};
    Workspace<D> w = carve_workspace<D>(reinterpret_cast<void*>(at), nb, nv, kLinearWorkspace);
    at += workspace_bytes<D>(nb, nv, kLinearWorkspace);
    D* q = reinterpret_cast<D*>(at);  // q (nq), q ⊕ ε e_j (nq), the step (nv), G (6 nv)
    D* qj = q + nq;
    D* step = qj + nq;
    D* G = step + nv;
    for (int i = 0; i < nq; ++i) q[i] = D(a.in[0][i]);
    for (int j = 0; j < nv; ++j) {
      for (int i = 0; i < nv; ++i) step[i] = D(S(0), i == j ? S(1) : S(0));
      integrate(md, static_cast<const D*>(q), static_cast<const D*>(step), qj);
      forward_kinematics(md, w, static_cast<const D*>(qj), static_cast<const D*>(nullptr));
      for (int e = 0; e < a.n_ee; ++e) {
        const S* o = a.in[1] ? a.in[1] + 3 * e : nullptr;
        const Vec3<D> p = o ? Vec3<D>{D(o[0]), D(o[1]), D(o[2])} : Vec3<D>{D(S(0)), D(S(0)), D(S(0))};
        end_effector_pose_gradient(md, w, a.ee[e], p, G);
        S* He = a.out[0] + 6L * nv * nv * e;
        for (int r = 0; r < 6; ++r)
          for (int k = 0; k < nv; ++k) He[(r * nv + j) * nv + k] = G[r * nv + k].d;
      }
    }
    if (a.choice[3] == kReferenceForm) symmetrize_last_two(a.out[0], 6L * a.n_ee, nv);
    return true;
  }
};

struct EndEffectorPoseHessianAnalytic {
  static constexpr OpSpec spec = {
      "end_effector_pose_hessian_analytic", "end_effector_pose_hessian", "kinematics",
      "Hessian (n_ee, 6, nv, nv) of end_effector_pose in closed form, H[e, r, j, k] = ∂gradient[e, r, k]/∂δ_j: for "
      "support-chain columns s_j, s_k with j an ancestor of k (or in the same joint), ∂s_k/∂δ_j = s_j × s_k, and "
      "the tool point moves with s_j. Not symmetric within free-flyer and spherical joints; form=\"reference\": "
      "its symmetric part, the reference implementation's. Equal to the dual-number end_effector_pose_hessian to "
      "rounding. Note the argument order: offsets before ee_joint_names.",
      4,
      {array("q", shape(kNq), kConfiguration), optional_array("offsets", shape(kNee, 3)),
       end_effectors("ee_joint_names"), param("form", kChoice, 0, kHessianForms)},
      1, {{"H", shape(kNee, 6, kNv, kNv)}}, 0b1, 0, kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    forward_kinematics(m, w, a.in[0], static_cast<const S*>(nullptr));
    for (int e = 0; e < a.n_ee; ++e) {
      const Vec3<S> o = a.in[1] ? Vec3<S>{a.in[1][3 * e], a.in[1][3 * e + 1], a.in[1][3 * e + 2]} : Vec3<S>::zero();
      end_effector_pose_hessian_analytic(m, w, a.ee[e], o, a.out[0] + 6L * m.nv * m.nv * e);
    }
    if (a.choice[3] == kReferenceForm) symmetrize_last_two(a.out[0], 6L * a.n_ee, m.nv);
    return true;
  }
};
struct OscInertia {
  static constexpr OpSpec spec = {
      "osc_inertia", "osc_inertia", "osc",
      "Operational-space inertia Λ (n_ee, 6, 6) = (J M⁻¹ Jᵀ)⁻¹ of each end effector, J (6, nv) the "
      "LOCAL_WORLD_ALIGNED Jacobian of its tool point (rows [linear; angular]). An error when J M⁻¹ Jᵀ is "
      "singular: fewer than 6 DoF reach the end effector, or a singular configuration.",
      RBD_EE_ARGS("ee_offsets"),
      1, {{"Lambda", shape(kNee, 6, 6)}}, 0b1, 0, kFull, kNoScratch, kOscSingular};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    if (!osc_factor_mass_matrix(m, w, a.in[0])) return false;
    for (int e = 0; e < a.n_ee; ++e)
      if (!osc_inertia(m, w, a.ee[e], tool_point(a, e), a.out[0] + 36 * e)) return false;
    return true;
  }
};
#undef RBD_EE_ARGS

struct EePosCost {
  static constexpr OpSpec spec = {
      "ee_pos_cost", "ee_pos_cost", "costs",
      "½ Σ W (p_ee(q) - p_des)² for the end effector (the named joint's body; default the first leaf body) at "
      "tool point ee_offset (3,) in its frame (default zero): (value, grad (nq + nv,), Gauss–Newton H (nq + nv, "
      "nq + nv)), tangent blocks embedded as in com_cost.",
      6,
      {array("q", shape(kNq), kConfiguration), array("p_des", shape(3)), array("W", shape(3), kWeights),
       end_effector("ee_joint_name"), optional_array("ee_offset", shape(3)), param("output_convention", kConvention, 0)},
      3, {{"value", scalar()}, {"grad", shape(kNx)}, {"H", shape(kNx, kNx)}}, 0b111, 0, kLinear, kScratchEePosCost,
      kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    ee_pos_cost(m, w, a.in[0], a.in[1], a.in[2], a.choice[3], a.in[4], a.choice[5], a.out[0], a.out[1], a.out[2],
                a.scratch);
    return true;
  }
};

// ---------------------------------------------------------------- costs (the plant layer: plant/costs.hpp)
// (value, gradient, Hessian) per knot point, NX = nq + nv. Weights are diagonal, given as vectors of
// non-negative values. output_convention="mujoco": x, q, qd in MuJoCo's qpos/qvel layout and frames, the
// tangent error and the tangent blocks of the derivatives along MuJoCo's ⊖ / ⊕; the quadratic costs act on
// the given vectors coordinate by coordinate, so there only the layout of the targets changes.

#define RBD_COST_OUTS(n) 3, {{"value", scalar()}, {"grad", shape(n)}, {"H", shape(n, n)}}, 0b111, 0

struct QuadraticStateCost {
  static constexpr OpSpec spec = {
      "quadratic_state_cost", "state_costs", "costs",
      "½ Σ Q (x - x_des)² on x = [q; qd] (nq + nv,): (value, grad (nq + nv,), H (nq + nv, nq + nv)), exact, in "
      "ambient coordinates.",
      4, {array("x", shape(kNx)), array("x_des", shape(kNx)), array("Q", shape(kNx), kWeights),
          param("output_convention", kConvention, 0)},
      RBD_COST_OUTS(kNx), kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    a.out[0][0] = quadratic_cost(m.nq + m.nv, a.in[0], a.in[1], a.in[2], a.out[1], a.out[2]);
    return true;
  }
};

struct QuadraticInputCost {
  static constexpr OpSpec spec = {
      "quadratic_input_cost", "state_costs", "costs",
      "½ Σ R (u - u_des)²: (value, grad (nv,), H (nv, nv)), exact.",
      4, {array("u", shape(kNv)), array("u_des", shape(kNv)), array("R", shape(kNv), kWeights),
          param("output_convention", kConvention, 0)},
      RBD_COST_OUTS(kNv), kLinear, kNoScratch, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    a.out[0][0] = quadratic_cost(m.nv, a.in[0], a.in[1], a.in[2], a.out[1], a.out[2]);
    return true;
  }
};

struct QuadraticStateCostTangent {
  static constexpr OpSpec spec = {
      "quadratic_state_cost_tangent", "state_costs", "costs",
      "½ eᵀ diag(Q) e with the log-map error e = [difference(q_des, q); qd - qd_des], Q (2·nv,): (value, "
      "grad Jᵀ Q e (2·nv,), Gauss–Newton H = Jᵀ Q J (2·nv, 2·nv)).",
      4, {array("x", shape(kNx), kConfiguration), array("x_des", shape(kNx), kConfiguration),
          array("Q", shape(k2Nv), kWeights), param("output_convention", kConvention, 0)},
      RBD_COST_OUTS(k2Nv), kLinear, kScratch2NvNv, kNotPositiveDefinite};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    a.out[0][0] = quadratic_state_cost_tangent(m, a.in[0], a.in[1], a.in[2], a.out[1], a.out[2], a.scratch,
                                               a.choice[3]);
    return true;
  }
};

struct ComCost {
  static constexpr OpSpec spec = {
      "com_cost", "com_cost", "costs",
      "½ Σ W (com(q) - p_des)², p_des and W (3,): (value, grad (nq + nv,), Gauss–Newton H (nq + nv, nq + nv)); "
      "the tangent δq in entries [0, nv), the extra quaternion coordinates [nv, nq) and the velocities [nq, nq + "
      "nv) zero.",
      4, {array("q", shape(kNq), kConfiguration), array("p_des", shape(3)), array("W", shape(3), kWeights),
          param("output_convention", kConvention, 0)},
      RBD_COST_OUTS(kNx), kLinear, kScratchComCost, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return com_cost(m, w, a.in[0], a.in[1], a.in[2], a.choice[3], a.out[0], a.out[1], a.out[2], a.scratch);
  }
};

struct MomentumCost {
  static constexpr OpSpec spec = {
      "momentum_cost", "momentum_cost", "costs",
      "½ Σ W r² with r = A(q)·qd - h_des (6,), W (6,): (value, grad Jᵀ W r (2·nv,), Gauss–Newton H = Jᵀ W J "
      "(2·nv, 2·nv)) in tangent [δq | δqd] coordinates, J = [(∂A/∂q)·qd | A] from dccrba (the configuration "
      "dependence is kept, only the residual's curvature is dropped).",
      5, {array("q", shape(kNq), kConfiguration), array("qd", shape(kNv)), array("h_des", shape(6)),
          array("W", shape(6), kWeights), param("output_convention", kConvention, 0)},
      RBD_COST_OUTS(k2Nv), kLinear, kScratchMomentumCost, kNoMass};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>& w, const OpArgs<S>& a) {
    return momentum_cost(m, w, a.in[0], a.in[1], a.in[2], a.in[3], a.choice[4], a.out[0], a.out[1], a.out[2],
                         a.scratch);
  }
};
#undef RBD_COST_OUTS

// the log barriers: -mu Σ [log(x - lower) + log(upper - x)] over the finite bounds, (value, grad, Hessian
// diagonal); outside the open interval the value is +inf and that coordinate's derivatives NaN
template <int Which> struct JointBarrier {
  static constexpr int kN = Which == 0 ? kNq : kNv;
  static constexpr OpSpec spec = {
      Which == 0 ? "joint_position_barrier" : Which == 1 ? "joint_velocity_barrier" : "joint_torque_barrier",
      "barriers", "costs",
      Which == 0 ? "Log barrier on q (nq,) with bounds lower, upper (nq,) in the same layout (infinite ones add "
                   "nothing): (value, grad (nq,), Hessian diagonal (nq,)); outside the open interval the value is "
                   "+inf and that coordinate's derivatives NaN."
      : Which == 1 ? "Log barrier on qd (nv,) with bounds lower, upper (nv,) (infinite ones add nothing): (value, "
                     "grad (nv,), Hessian diagonal (nv,)); outside the open interval +inf and NaN derivatives."
                   : "Log barrier on u (nv,) with bounds lower, upper (nv,) (infinite ones add nothing): (value, "
                     "grad (nv,), Hessian diagonal (nv,)); outside the open interval +inf and NaN derivatives.",
      5,
      {array(Which == 0 ? "q" : Which == 1 ? "qd" : "u", shape(kN)), array("lower", shape(kN), kLowerBound),
       array("upper", shape(kN), kUpperBound), positive("mu", kRequired, kBarrierWeightName),
       param("output_convention", kConvention, 0)},
      3, {{"value", scalar()}, {"grad", shape(kN)}, {"Hdiag", shape(kN)}}, 0b111, 0, kLinear, kNoScratch,
      kNotPositiveDefinite, kAnyModel, kInfiniteOutside};
  template <typename S> RBD_HD static bool run(const ModelView<S>& m, Workspace<S>&, const OpArgs<S>& a) {
    a.out[0][0] = log_barrier(Which == 0 ? m.nq : m.nv, a.in[0], a.in[1], a.in[2], a.real[3], a.out[1], a.out[2]);
    return true;
  }
};
using JointPositionBarrier = JointBarrier<0>;
using JointVelocityBarrier = JointBarrier<1>;
using JointTorqueBarrier = JointBarrier<2>;


// ---------------------------------------------------------------- the list

template <typename... Op> struct OpList {
  static constexpr int size = sizeof...(Op);
};

// the index of Op in a list (its id in AllOps)
template <typename Op, typename First, typename... Rest> constexpr int index_of(OpList<First, Rest...>) {
  if constexpr (std::is_same<Op, First>::value) return 0;
  else return 1 + index_of<Op>(OpList<Rest...>{});
}

// every registered operation; an operation's id is its index here
using AllOps = OpList<InverseDynamics, GeneralizedGravity, NonlinearEffects, Crba, Minv, Aba, ForwardDynamics,
                      InverseDynamicsGradient, ForwardDynamicsGradient, FExtGradient, IdsvaSoBodyFrame,
                      IdsvaSoWorldFrame, IdsvaSo, FdsvaSo, Integrate, Difference, DIntegrate,
                      DDifference, Integrator, IntegratorGradient, IntegratorFExtGradient, PlantStep,
                      PlantStepGradient, KineticEnergy, PotentialEnergy, MechanicalEnergy, CoriolisMatrix, Com,
                      JacobianCom, Ccrba, CentroidalMomentum,
                      Dccrba, CmmTimeVariation, CentroidalMomentumTimeVariation, CentroidalDynamicsDerivatives,
                      InverseDynamicsRegressor,
                      KineticEnergyRegressor, PotentialEnergyRegressor, StateToMujoco, StateFromMujoco,
                      ForceToMujoco, ForceFromMujoco, MujocoIntegrate, MujocoDifference, InverseDynamicsFpass,
                      ApplyExternalForces, InverseDynamicsBpass, MinvBpass, MinvFpass, InverseDynamicsGradientFpassDq,
                      InverseDynamicsGradientFpassDqd, InverseDynamicsGradientBpassDq,
                      InverseDynamicsGradientBpassDqd, DccrbaFd, CmmTimeVariationFd,
                      InverseDynamicsRegressorGradient, ForwardDynamicsParameterGradient, QuadraticStateCost,
                      QuadraticInputCost, QuadraticStateCostTangent, ComCost, MomentumCost, JointPositionBarrier,
                      JointVelocityBarrier, JointTorqueBarrier, ForwardKinematics, FramePlacement, FrameJacobian,
                      FrameJacobianDot, EePosCost, EndEffectorPose, EndEffectorPoseGradient,
                      EndEffectorPoseHessianAnalytic, OscInertia, PlantStepHessian, D2Integrate,
                      EndEffectorPoseHessian>;

}  // namespace ops
}  // namespace rbd
