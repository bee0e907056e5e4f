// rbdkit/plant/hessian_forms.hpp — the reference implementation's forms of
// the step and end-effector Hessians, from rbdkit's (form="reference").
//
// Step Hessian. rbdkit's H[i, a, b] = ∂²ψ_i/∂w_a∂w_b is the second derivative
// along one retraction, x ⊕ w, read in the chart at the nominal output; it is
// symmetric in (a, b). The reference differentiates the gradient instead:
// H_ref[i, a, b] = ∂/∂ε_a (G(x ⊕ ε)[i, b]), G = plant_step_gradient, each G
// read in the chart at its own output. Two retractions compose as
// (x ⊕ ε) ⊕ δ = x ⊕ (ε + δ + ½[ε, δ] + …) (Baker–Campbell–Hausdorff), and the
// moving chart at the output adds the output's bracket, so
//   H_ref[:, a, b] = H[:, a, b] + ½ Σ_c G[:, c] [e_a, e_b]_c − ½ [G_a, G_b]
// where G_a is column a of G and the brackets act within each joint's block
// of the configuration tangent (zero across joints and on 1-DoF and velocity
// coordinates):
//   free joint, Pinocchio's SE(3), twist [v; ω]:  [ε, δ] = (ε_ω × δ_v + ε_v × δ_ω, ε_ω × δ_ω)
//   free joint, MuJoCo's R³ × SO(3), [p; θ]:      [ε, δ] = (0, ε_θ × δ_θ)
//   spherical (SO(3), both conventions):          [ε, δ] = ε × δ
// The correction is antisymmetric in (a, b): both forms share their
// symmetric part.
//
// End-effector pose Hessian: rbdkit's H[e, r, j, k] = ∂gradient[e, r, k]/∂δ_j
// is not symmetric inside free-flyer and spherical blocks; the reference
// returns its symmetric part ½ (H + Hᵀ).
#pragma once

#include "rbdkit/model/joint_types.hpp"
#include "rbdkit/plant/mujoco_convention.hpp"

namespace rbd {

enum HessianForm : int {
  kRbdkitForm = 0,     // rbdkit's (the default)
  kReferenceForm = 1,  // the reference implementation's
};

// out = [x, y] for two tangent vectors of one joint's configuration block (d = the joint's nv)
template <typename S> RBD_HD void joint_bracket(int type, int convention, const S* x, const S* y, S* out) {
  visit_joint(type, [&](auto J) {
    if (convention == kMujocoConvention) J.mj_bracket(x, y, out);
    else J.bracket(x, y, out);
  });
}

// whether a body's joint has a bracket (a free or spherical joint of its own)
template <typename S> RBD_HD bool has_bracket(const BodyDesc<S>& b) {
  return !b.mimic && (b.type == kFree || b.type == kSpherical);
}

// H (rows x n x n, n = 3 nv: [δq; δqd; δu]) <- the reference's form, from
// G = AB (rows x n); rows = 2 nv, the output [δq⁺; δqd⁺]
template <typename S>
RBD_HD void step_hessian_reference_form(const ModelView<S>& m, int convention, const S* G, S* H) {
  const int nv = m.nv, n = 3 * nv, rows = 2 * nv;
  for (int i = 0; i < m.nb; ++i) {
    const BodyDesc<S>& b = m.body[i];
    if (!has_bracket(b)) continue;
    const int o = b.v_idx, d = b.nv;
    // input: + ½ Σ_c G[:, o + c] [e_j, e_k]_c for j, k in the joint's δq block
    for (int j = 0; j < d; ++j)
      for (int k = 0; k < d; ++k) {
        S ej[6] = {}, ek[6] = {}, br[6];
        ej[j] = S(1), ek[k] = S(1);
        joint_bracket(b.type, convention, ej, ek, br);
        for (int r = 0; r < rows; ++r) {
          S acc = S(0);
          for (int c = 0; c < d; ++c) acc += G[r * n + o + c] * br[c];
          H[(static_cast<long>(r) * n + o + j) * n + o + k] += S(0.5) * acc;
        }
      }
    // output: − ½ [G_a, G_b] on the joint's rows of δq⁺, for every pair of columns
    for (int a = 0; a < n; ++a)
      for (int c = 0; c < n; ++c) {
        S ga[6], gc[6], br[6];
        for (int r = 0; r < d; ++r) ga[r] = G[(o + r) * n + a], gc[r] = G[(o + r) * n + c];
        joint_bracket(b.type, convention, ga, gc, br);
        for (int r = 0; r < d; ++r) H[(static_cast<long>(o + r) * n + a) * n + c] -= S(0.5) * br[r];
      }
  }
}

// H (n_ee x 6 x nv x nv) <- its symmetric part in the last two axes (the reference's form)
template <typename S> RBD_HD void symmetrize_last_two(S* H, long blocks, int nv) {
  for (long e = 0; e < blocks; ++e) {
    S* Hb = H + e * nv * nv;
    for (int j = 0; j < nv; ++j)
      for (int k = j + 1; k < nv; ++k) {
        const S s = S(0.5) * (Hb[j * nv + k] + Hb[k * nv + j]);
        Hb[j * nv + k] = s;
        Hb[k * nv + j] = s;
      }
  }
}

}  // namespace rbd
