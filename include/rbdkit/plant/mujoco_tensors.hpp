// rbdkit/plant/mujoco_tensors.hpp — the derivative tensors of forward
// dynamics (acceleration_tensors, integrator_hessian.hpp: a (nv), Fq, Fv, Fu
// (nv x nv), T (nv x 2nv x 2nv), Aqu (nv x nv x nv)) carried from Pinocchio's
// coordinates to MuJoCo's (mujoco_convention.hpp) through the free-joint
// conversion maps, exactly (closed form): tensors_to_mujoco, in place, with
// its row packing and per-free-joint helpers.
#pragma once

#include "rbdkit/plant/mujoco_convention.hpp"

namespace rbd {

// ---------------------------------------------------------------- the tensors in MuJoCo coordinates
// Per free joint (v offset o, R its rotation at the stage, θ = ξ[o+3..o+5]),
// with x = [ξ; v; u] (3nv) in MuJoCo coordinates and y the same in ours:
//   ξ_lin = V(θ)⁻¹ Rᵀ ξ_mj,lin   (SE(3) log of (Exp θ, Rᵀ δp)),  ξ_ang = θ
//   v_lin = Exp(-θ) Rᵀ v_mj,lin,  u_lin = Exp(-θ) Rᵀ u_mj,lin,  angular parts equal
// then a_mj,lin = R Exp(θ) (a_lin + ω × v_lin), a_mj,ang = a_ang. The input
// map's Jacobian Φ and second derivatives (at θ = 0, vl = v_lin, ul = u_lin):
//   ∂ξ_lin/∂ξ_mj,lin = Rᵀ;  ∂v_lin/∂θ = [vl]×, ∂v_lin/∂v_mj,lin = Rᵀ (u alike)
//   ∂²ξ_lin/∂ξ_mj,lin_a∂θ_b = -½ e_b × r_a                  (r_a = Rᵀ e_a)
//   ∂²v_lin/∂θ_b∂θ_c = ½ (e_b × (e_c × vl) + e_c × (e_b × vl)),
//   ∂²v_lin/∂θ_b∂v_mj,lin_a = -e_b × r_a                    (u alike)
// so that F_mj = F Φ and A_mj[i] = Φᵀ A[i] Φ + Σ_c F[i, c] ∂²y_c on the input
// side; the output map then adds its own first and second derivatives.

// scratch values of tensors_to_mujoco
RBD_HD long tensors_to_mujoco_scratch_values(int nv) { return 27L * nv * nv + 9L * nv; }

// row i of (T, Aqu) as the full symmetric Hessian over x = [ξ; v; u] (3nv x 3nv), and back
template <typename S> RBD_HD void tensor_row_unpack(int nv, const S* T, const S* Aqu, int i, S* Mf) {
  const int p = 2 * nv, n3 = 3 * nv;
  const S* Ti = T + static_cast<long>(i) * p * p;
  const S* Ai = Aqu + static_cast<long>(i) * nv * nv;
  for (int r = 0; r < n3; ++r)
    for (int c = 0; c < n3; ++c) {
      S x = S(0);
      if (r < p && c < p) x = Ti[r * p + c];
      else if (r < nv && c >= p) x = Ai[r * nv + c - p];
      else if (c < nv && r >= p) x = Ai[c * nv + r - p];
      Mf[static_cast<long>(r) * n3 + c] = x;
    }
}
template <typename S> RBD_HD void tensor_row_pack(int nv, const S* Mf, int i, S* T, S* Aqu) {
  const int p = 2 * nv, n3 = 3 * nv;
  S* Ti = T + static_cast<long>(i) * p * p;
  S* Ai = Aqu + static_cast<long>(i) * nv * nv;
  for (int r = 0; r < p; ++r)
    for (int c = 0; c < p; ++c) Ti[r * p + c] = Mf[static_cast<long>(r) * n3 + c];
  for (int r = 0; r < nv; ++r)
    for (int c = 0; c < nv; ++c) Ai[r * nv + c] = Mf[static_cast<long>(r) * n3 + p + c];
}

// the symmetric pair (j, k), (k, j) of a full (n3 x n3) matrix += x
template <typename S> RBD_HD void add_sym(S* Mf, int n3, int j, int k, S x) {
  Mf[static_cast<long>(j) * n3 + k] += x;
  if (j != k) Mf[static_cast<long>(k) * n3 + j] += x;
}

// z <- Φᵀ z on one free joint's entries of a line z over x (its ξ, v, u parts
// at zq, zv, zu, stride st): z_θ += z_vlin × vl + z_ulin × ul, then the
// ξ_lin, v_lin and u_lin parts <- R (·)
template <typename S>
RBD_HD void free_input_transpose(int o, const Mat3<S>& R, const Vec3<S>& vl, const Vec3<S>& ul, S* zq, S* zv,
                                 S* zu, long st) {
  const Vec3<S> zvl = load3(zv + o * st, st), zul = load3(zu + o * st, st);
  store3(load3(zq + (o + 3) * st, st) + cross(zvl, vl) + cross(zul, ul), zq + (o + 3) * st, st);
  store3(R * load3(zq + o * st, st), zq + o * st, st);
  store3(R * zvl, zv + o * st, st);
  store3(R * zul, zu + o * st, st);
}

// The tensors of a (acceleration_tensors at the converted point q, v, u in
// our coordinates) -> those of a_mj in MuJoCo coordinates at q_mj, in place:
// a (nv), Fq, Fv, Fu, T, Aqu. A no-op without free joints.
template <typename S>
RBD_HD void tensors_to_mujoco(const ModelView<S>& m, const S* q_mj, const S* v, const S* u, S* a, S* Fq, S* Fv,
                              S* Fu, S* T, S* Aqu, S* scratch) {
  const int nv = m.nv, n3 = 3 * nv;
  const long nn3 = static_cast<long>(n3) * n3;
  bool any = false;
  for (int i = 0; i < m.nb; ++i) any = any || (!m.body[i].mimic && m.body[i].type == kFree);
  if (!any) return;
  S* Mf = scratch;         // three full Hessians (3 x 3nv x 3nv)
  S* Ds = Mf + 3 * nn3;    // ∂s (3 x 3nv)
  const Vec3<S> E[3] = {{S(1), S(0), S(0)}, {S(0), S(1), S(0)}, {S(0), S(0), S(1)}};

  // input side, row by row: A[i] <- Φᵀ A[i] Φ + Σ_c F[i, c] ∂²y_c, then F[i] <- F[i] Φ
  for (int i = 0; i < nv; ++i) {
    tensor_row_unpack(nv, T, Aqu, i, Mf);
    for (int j = 0; j < m.nb; ++j) {
      const BodyDesc<S>& b = m.body[j];
      if (b.mimic || b.type != kFree) continue;
      const int o = b.v_idx;
      const Mat3<S> R = free_rotation_mj(b, q_mj);
      const Vec3<S> vl = load3(v + o, 1), ul = load3(u + o, 1);
      // Φᵀ on the rows, then on the columns
      for (int c = 0; c < n3; ++c)
        free_input_transpose(o, R, vl, ul, Mf + c, Mf + nv * n3 + c, Mf + 2 * nv * n3 + c, n3);
      for (int r = 0; r < n3; ++r) {
        S* z = Mf + r * n3;
        free_input_transpose(o, R, vl, ul, z, z + nv, z + 2 * nv, 1);
      }
      // the input map's second derivatives weighted by row i of F (ours)
      const Vec3<S> wq = load3(Fq + i * nv + o, 1), wv = load3(Fv + i * nv + o, 1), wu = load3(Fu + i * nv + o, 1);
      for (int ia = 0; ia < 3; ++ia) {
        const Vec3<S> ra = {R(ia, 0), R(ia, 1), R(ia, 2)};
        const Vec3<S> cq = S(-0.5) * cross(ra, wq), cv = S(-1) * cross(ra, wv), cu = S(-1) * cross(ra, wu);
        for (int ib = 0; ib < 3; ++ib) {
          add_sym(Mf, n3, o + ia, o + 3 + ib, cq[ib]);
          add_sym(Mf, n3, nv + o + ia, o + 3 + ib, cv[ib]);
          add_sym(Mf, n3, 2 * nv + o + ia, o + 3 + ib, cu[ib]);
        }
      }
      const S dv = dot(wv, vl), du = dot(wu, ul);
      for (int ib = 0; ib < 3; ++ib)
        for (int ic = 0; ic < 3; ++ic) {
          const S x = S(0.5) * (wv[ic] * vl[ib] + wv[ib] * vl[ic] + wu[ic] * ul[ib] + wu[ib] * ul[ic]) -
                      (ib == ic ? dv + du : S(0));
          Mf[static_cast<long>(o + 3 + ib) * n3 + o + 3 + ic] += x;
        }
      free_input_transpose(o, R, vl, ul, Fq + i * nv, Fv + i * nv, Fu + i * nv, 1);
    }
    tensor_row_pack(nv, Mf, i, T, Aqu);
  }

  // output side per free joint: rows o..o+2 <- R Exp(θ) s, s = a_lin + ω × v_lin
  for (int j = 0; j < m.nb; ++j) {
    const BodyDesc<S>& b = m.body[j];
    if (b.mimic || b.type != kFree) continue;
    const int o = b.v_idx;
    const Mat3<S> R = free_rotation_mj(b, q_mj);
    const Vec3<S> vl = load3(v + o, 1), om = load3(v + o + 3, 1);
    const Vec3<S> s = load3(a + o, 1) + cross(om, vl);
    // value, the rows' jets of s: ∂s = F_mj[lin rows] + ∂(ω × v_lin)
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < nv; ++k) {
        Ds[r * n3 + k] = Fq[(o + r) * nv + k];
        Ds[r * n3 + nv + k] = Fv[(o + r) * nv + k];
        Ds[r * n3 + 2 * nv + k] = Fu[(o + r) * nv + k];
      }
      tensor_row_unpack(nv, T, Aqu, o + r, Mf + r * nn3);
    }
    auto add3 = [&](int jj, int kk, const Vec3<S>& x) {  // the three rows' (jj, kk) and (kk, jj) += x
      for (int r = 0; r < 3; ++r) add_sym(Mf + r * nn3, n3, jj, kk, x[r]);
    };
    for (int ib = 0; ib < 3; ++ib) {
      const Vec3<S> ra = {R(ib, 0), R(ib, 1), R(ib, 2)};  // r_a for a = ib
      store3(load3(Ds + o + 3 + ib, n3) + cross(om, cross(vl, E[ib])), Ds + o + 3 + ib, n3);
      store3(load3(Ds + nv + o + 3 + ib, n3) + cross(E[ib], vl), Ds + nv + o + 3 + ib, n3);
      store3(load3(Ds + nv + o + ib, n3) + cross(om, ra), Ds + nv + o + ib, n3);
    }
    for (int ib = 0; ib < 3; ++ib)
      for (int ic = 0; ic < 3; ++ic) {
        const Vec3<S> ra = {R(ic, 0), R(ic, 1), R(ic, 2)};  // a = ic
        add3(nv + o + 3 + ib, o + 3 + ic, cross(E[ib], cross(vl, E[ic])));   // ω-θ
        add3(nv + o + 3 + ib, nv + o + ic, cross(E[ib], ra));                // ω-v_lin
        add3(o + 3 + ib, nv + o + ic, S(-1) * cross(om, cross(E[ib], ra)));  // θ-v_lin
        if (ic >= ib) {  // θ-θ: ω × ∂²v_lin
          const Vec3<S> Q = S(0.5) * (cross(E[ib], cross(E[ic], vl)) + cross(E[ic], cross(E[ib], vl)));
          add3(o + 3 + ib, o + 3 + ic, cross(om, Q));
        }
      }
    // R Exp(θ) s: θ-θ, θ-x terms with ∂s, then ∂ gets e_b × s on the θ columns
    for (int ib = 0; ib < 3; ++ib) {
      for (int ic = ib; ic < 3; ++ic)
        add3(o + 3 + ib, o + 3 + ic,
             S(0.5) * (cross(E[ib], cross(E[ic], s)) + cross(E[ic], cross(E[ib], s))));
      for (int k = 0; k < n3; ++k) {
        const Vec3<S> x = cross(E[ib], load3(Ds + k, n3));
        for (int r = 0; r < 3; ++r) {
          Mf[r * nn3 + static_cast<long>(o + 3 + ib) * n3 + k] += x[r];
          Mf[r * nn3 + static_cast<long>(k) * n3 + o + 3 + ib] += x[r];
        }
      }
    }
    for (int ib = 0; ib < 3; ++ib) store3(load3(Ds + o + 3 + ib, n3) + cross(E[ib], s), Ds + o + 3 + ib, n3);
    // rotate the three rows by R and write them back
    for (long k = 0; k < nn3; ++k) store3(R * load3(Mf + k, nn3), Mf + k, nn3);
    for (int k = 0; k < n3; ++k) store3(R * load3(Ds + k, n3), Ds + k, n3);
    store3(R * s, a + o, 1);
    for (int r = 0; r < 3; ++r) {
      tensor_row_pack(nv, Mf + r * nn3, o + r, T, Aqu);
      for (int k = 0; k < nv; ++k) {
        Fq[(o + r) * nv + k] = Ds[r * n3 + k];
        Fv[(o + r) * nv + k] = Ds[r * n3 + nv + k];
        Fu[(o + r) * nv + k] = Ds[r * n3 + 2 * nv + k];
      }
    }
  }
}

}  // namespace rbd
