// rbdkit/workspace.hpp — the per-sample scratch every algorithm writes into.
//
// One contiguous buffer carved into typed arrays, so that a CPU thread or a
// CUDA thread owns one workspace and nothing is allocated inside an algorithm.
// nb = bodies, nv = velocity coordinates. Shapes and writers below.
//
// Two layouts of the same struct:
//   kFullWorkspace    every array: what any algorithm may need, O(nb·nv + nv²)
//   kLinearWorkspace  the O(nb + nv) arrays only; P, so_dense, dense and dense2
//                     are null. Enough for the O(n) family: rnea (and
//                     remove_gravity), aba on a model without mimic joints
//                     (mimic models take the dense path), forward kinematics,
//                     frame placements, Jacobians and their time variation,
//                     end-effector poses and their gradients, and the explicit
//                     integrator steps (integrators.hpp, through aba)
// A linear buffer need not be zero-filled: the O(n) family writes an array
// before it reads it (tests/cpp/test_workspace.cpp runs it on poisoned
// memory); WorkspaceBuffer zero-fills the full one, as it always has.
#pragma once

#include "joint_types.hpp"

namespace rbd {

enum WorkspaceLayout : int { kFullWorkspace = 0, kLinearWorkspace = 1 };

template <typename S> struct Workspace {
  Transform<S>* X;   // (nb)        X_parent_body at q            — every forward pass
  Transform<S>* Xw;  // (nb)        X_world_body at q             — crba, minv, derivatives, kinematics
  Motion<S>* v;      // (nb)        body velocity, body frame     — rnea, aba
  Motion<S>* a;      // (nb)        body acceleration incl. -g    — rnea, aba
  Force<S>* f;       // (nb)        rnea: joint force (subtree), aba: bias force pA
  Motion<S>* c;      // (nb)        aba: velocity-product acceleration v × vJ
  Mat6<S>* IA;       // (nb)        aba, minv: articulated inertia
  Inertia<S>* Ic;    // (nb)        crba: composite rigid-body inertia (world frame)
  Force<S>* U;       // (nb x 6)    aba, minv: U = IA·S, one force per joint DoF (minv: world frame)
  Motion<S>* Sw;     // (nb x 6)    crba, minv, derivatives: motion subspace columns, world frame
  S* Dinv;           // (nb x 36)   aba, minv: (Sᵀ·IA·S)⁻¹, row-major nv_j x nv_j
  Motion<S>* dVdq;   // (nb x 6)    rnea_derivatives: v_λ × s per joint DoF (world frame)
  Motion<S>* dAdq;   // (nb x 6)    rnea_derivatives: a_λ × s + v_λ × dVdq
  Motion<S>* dAdv;   // (nb x 6)    rnea_derivatives: v × s + dVdq
  Force<S>* h;       // (nb)        rnea_derivatives: momentum I·v, then its subtree sum (world)
  Mat6<S>* B;        // (nb)        rnea_derivatives: v ×* I - I v×, then its subtree sum (world)
  S* u;              // (nv)        aba: u = tau - Sᵀ·pA
  S* F;              // (nv x 6)    minv: force sensitivities ∂pA/∂tau, world frame, one 6D column per tau
  S* P;              // (nb x nv x 6) minv: acceleration sensitivities ∂a/∂tau, world frame (full layout only)
  // ---- second order (algorithms/idsva_so.hpp, fdsva_so.hpp); nc = nv + nb bounds the joint DoFs
  // on one root path (a mimic body adds a DoF of its own there)
  Motion<S>* so_m;   // (nc x 4)    idsva_so: s, ψ̇, ψ̈, σ of the DoFs from the current body to the root, its frame
  Force<S>* so_f;    // (nc x 8)    idsva_so: their products with the current body's composites, and per-DoF terms
  int* so_i;         // (nc x 2)    idsva_so: column and depth below the current body of each of those DoFs
  // ---- quadratic in nv (full layout only)
  S* so_dense;       // (4 nv² + nv) fdsva_so: ∂qdd/∂q, ∂qdd/∂qd, M⁻¹, a block, qdd
  S* dense;          // (nv x nv + 2 nv) dense path (mimic models) and solves
  S* dense2;         // (nv x max(nv, 6)) aba_derivatives: a copy of the matrix M⁻¹ multiplies
};

// bytes needed for one workspace of a layout (each array aligned to 16 bytes)
template <typename S>
RBD_HD unsigned long workspace_bytes(int nb, int nv, WorkspaceLayout layout = kFullWorkspace) {
  // the quadratic arrays count once in the full layout, not at all in the linear one
  const unsigned long full = layout == kFullWorkspace ? 1ul : 0ul;
  const unsigned long b = static_cast<unsigned long>(nb), v = static_cast<unsigned long>(nv);
  unsigned long n = 0;
  auto add = [&n](unsigned long bytes) { n += (bytes + 15ul) & ~15ul; };
  add(sizeof(Transform<S>) * b);
  add(sizeof(Transform<S>) * b);
  add(sizeof(Motion<S>) * b);
  add(sizeof(Motion<S>) * b);
  add(sizeof(Force<S>) * b);
  add(sizeof(Motion<S>) * b);
  add(sizeof(Mat6<S>) * b);
  add(sizeof(Inertia<S>) * b);
  add(sizeof(Force<S>) * 6 * b);
  add(sizeof(Motion<S>) * 6 * b);
  add(sizeof(S) * 36 * b);
  add(sizeof(Motion<S>) * 6 * b);
  add(sizeof(Motion<S>) * 6 * b);
  add(sizeof(Motion<S>) * 6 * b);
  add(sizeof(Force<S>) * b);
  add(sizeof(Mat6<S>) * b);
  add(sizeof(S) * v);
  add(sizeof(S) * 6 * v);
  add(full * sizeof(S) * 6 * v * b);
  add(sizeof(Motion<S>) * 4 * (v + b));
  add(sizeof(Force<S>) * 8 * (v + b));
  add(sizeof(int) * 2 * (v + b));
  add(full * sizeof(S) * (4 * v * v + v));
  add(full * sizeof(S) * (v * v + 2 * v));
  add(full * sizeof(S) * v * (v > 6 ? v : 6));
  return n;
}

// carve a workspace out of a buffer of workspace_bytes(nb, nv, layout)
// bytes, 16-byte aligned
template <typename S>
RBD_HD Workspace<S> carve_workspace(void* buffer, int nb, int nv, WorkspaceLayout layout = kFullWorkspace) {
  const bool full = layout == kFullWorkspace;
  const unsigned long b = static_cast<unsigned long>(nb), v = static_cast<unsigned long>(nv);
  unsigned char* p = static_cast<unsigned char*>(buffer);
  auto take = [&p](unsigned long bytes) {
    unsigned char* r = p;
    p += (bytes + 15ul) & ~15ul;
    return static_cast<void*>(r);
  };
  Workspace<S> w;
  w.X = static_cast<Transform<S>*>(take(sizeof(Transform<S>) * b));
  w.Xw = static_cast<Transform<S>*>(take(sizeof(Transform<S>) * b));
  w.v = static_cast<Motion<S>*>(take(sizeof(Motion<S>) * b));
  w.a = static_cast<Motion<S>*>(take(sizeof(Motion<S>) * b));
  w.f = static_cast<Force<S>*>(take(sizeof(Force<S>) * b));
  w.c = static_cast<Motion<S>*>(take(sizeof(Motion<S>) * b));
  w.IA = static_cast<Mat6<S>*>(take(sizeof(Mat6<S>) * b));
  w.Ic = static_cast<Inertia<S>*>(take(sizeof(Inertia<S>) * b));
  w.U = static_cast<Force<S>*>(take(sizeof(Force<S>) * 6 * b));
  w.Sw = static_cast<Motion<S>*>(take(sizeof(Motion<S>) * 6 * b));
  w.Dinv = static_cast<S*>(take(sizeof(S) * 36 * b));
  w.dVdq = static_cast<Motion<S>*>(take(sizeof(Motion<S>) * 6 * b));
  w.dAdq = static_cast<Motion<S>*>(take(sizeof(Motion<S>) * 6 * b));
  w.dAdv = static_cast<Motion<S>*>(take(sizeof(Motion<S>) * 6 * b));
  w.h = static_cast<Force<S>*>(take(sizeof(Force<S>) * b));
  w.B = static_cast<Mat6<S>*>(take(sizeof(Mat6<S>) * b));
  w.u = static_cast<S*>(take(sizeof(S) * v));
  w.F = static_cast<S*>(take(sizeof(S) * 6 * v));
  w.P = full ? static_cast<S*>(take(sizeof(S) * 6 * v * b)) : nullptr;
  w.so_m = static_cast<Motion<S>*>(take(sizeof(Motion<S>) * 4 * (v + b)));
  w.so_f = static_cast<Force<S>*>(take(sizeof(Force<S>) * 8 * (v + b)));
  w.so_i = static_cast<int*>(take(sizeof(int) * 2 * (v + b)));
  w.so_dense = full ? static_cast<S*>(take(sizeof(S) * (4 * v * v + v))) : nullptr;
  w.dense = full ? static_cast<S*>(take(sizeof(S) * (v * v + 2 * v))) : nullptr;
  w.dense2 = full ? static_cast<S*>(take(sizeof(S) * v * (v > 6 ? v : 6))) : nullptr;
  return w;
}

}  // namespace rbd
