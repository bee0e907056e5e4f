// rbdkit/model/workspace.hpp — the per-sample scratch every algorithm writes into.
//
// One contiguous buffer carved into typed arrays, so that a CPU thread or a
// CUDA thread owns one workspace and nothing is allocated inside an algorithm.
// nb = bodies, nv = velocity coordinates. Shapes, frames and writers below;
// names ending in _world are in world axes (X_parent and X_world: the
// placements X_parent_body and X_world_body).
// The layout is described once, workspace_arrays, which both counts
// (workspace_bytes) and carves (carve_workspace) it.
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

#include <type_traits>

#include "rbdkit/model/joint_types.hpp"

namespace rbd {

enum WorkspaceLayout : int { kFullWorkspace = 0, kLinearWorkspace = 1 };

template <typename S> struct Workspace {
  Transform<S>* X_parent; // (nb)        X_parent_body at q            — every forward pass
  Transform<S>* X_world; // (nb)        X_world_body at q             — minv, derivatives, kinematics (crba on the general path)
  Motion<S>* v;          // (nb)        body velocity: body frame (rnea, aba, kinematics) or world axes
                         //             (world_motion: derivatives, centroidal, the Coriolis matrix)
  Motion<S>* a;          // (nb)        body acceleration incl. -g, in the frame of v
  Force<S>* f;           // (nb)        rnea: joint force (subtree), aba: bias force pA
  Motion<S>* c;          // (nb)        aba: velocity-product acceleration v × vJ
  Mat6<S>* IA;           // (nb)        aba, minv: articulated inertia
  Inertia<S>* Ic;        // (nb)        crba: composite rigid-body inertia (body frame; world frame with mimics)
  Force<S>* U;           // (nb x 6)    aba, minv: U = IA·S, one force per joint DoF (minv: reference frame; a free root's unset)
  Motion<S>* S_world;    // (nb x 6)    minv, derivatives (crba on the general path): motion subspace columns in the
                         //             reference frame (world.hpp: the world's, or a free root's)
  S* Dinv;               // (nb x 36)   aba, minv: (Sᵀ·IA·S)⁻¹, row-major nv_j x nv_j
  Motion<S>* dVdq;       // (nb x 6)    rnea_derivatives: v_λ × s per joint DoF (reference frame)
  Motion<S>* dAdq;       // (nb x 6)    rnea_derivatives: a_λ × s + v_λ × dVdq
  Motion<S>* dAdv;       // (nb x 6)    rnea_derivatives: v × s + dVdq
  Force<S>* h;           // (nb)        rnea_derivatives: momentum I·v, then its subtree sum (reference frame)
  InertiaRate<S>* B;     // (nb)        rnea_derivatives: v ×* I - I v×, then its subtree sum (reference frame)
  S* u;                  // (nv)        aba: u = tau - Sᵀ·pA
  S* F;                  // (6 nv)      minv: force sensitivities ∂pA/∂tau, reference frame, 6 x nv (row r of every tau
                         //             column at r·nv); crba: the columns Ic s riding up the tree, nv x 6
  S* P;                  // (6 nv nb)   minv: acceleration sensitivities ∂a/∂tau, reference frame, per body 6 x nv in the
                         //             serial pass, nv x 6 in minv_column (full layout only)
  // ---- second order (algorithms/idsva_so.hpp, fdsva_so.hpp); nc = nv + nb bounds the joint DoFs
  // on one root path (a mimic body adds a DoF of its own there)
  Motion<S>* so_m;       // (nc x 4)    idsva_so: s, ψ̇, ψ̈, σ of the DoFs from the current body to the root, its frame
  Force<S>* so_f;        // (nc x 8)    idsva_so: their products with the current body's composites, and per-DoF terms
  int* so_i;             // (nc x 2)    idsva_so: column and depth below the current body of each of those DoFs
  // ---- quadratic in nv (full layout only)
  S* so_dense;           // (4 nv² + nv) fdsva_so: ∂qdd/∂q, ∂qdd/∂qd, M⁻¹, a block, qdd; aba_derivatives
                         //             borrows the third and fourth for its products' scratch
  S* dense;              // (nv x nv + 2 nv) dense path (mimic models) and solves
  S* dense2;             // (nv x max(nv, 6)) aba_derivatives: a copy of the matrix M⁻¹ multiplies
};

// the layout, described once: every array in carving order, its element type
// (the field's) and count, and whether the layout has it. take(field, count,
// present) is called for each: workspace_bytes counts with it, carve_workspace
// points the fields with it
template <typename S, typename Take>
RBD_HD void workspace_arrays(Workspace<S>& w, int nb, int nv, WorkspaceLayout layout, Take&& take) {
  const bool full = layout == kFullWorkspace;
  const unsigned long b = static_cast<unsigned long>(nb), v = static_cast<unsigned long>(nv);
  take(w.X_parent, b, true);
  take(w.X_world, b, true);
  take(w.v, b, true);
  take(w.a, b, true);
  take(w.f, b, true);
  take(w.c, b, true);
  take(w.IA, b, true);
  take(w.Ic, b, true);
  take(w.U, 6 * b, true);
  take(w.S_world, 6 * b, true);
  take(w.Dinv, 36 * b, true);
  take(w.dVdq, 6 * b, true);
  take(w.dAdq, 6 * b, true);
  take(w.dAdv, 6 * b, true);
  take(w.h, b, true);
  take(w.B, b, true);
  take(w.u, v, true);
  take(w.F, 6 * v, true);
  take(w.P, 6 * v * b, full);
  take(w.so_m, 4 * (v + b), true);
  take(w.so_f, 8 * (v + b), true);
  take(w.so_i, 2 * (v + b), true);
  take(w.so_dense, 4 * v * v + v, full);
  take(w.dense, v * v + 2 * v, full);
  take(w.dense2, v * (v > 6 ? v : 6), full);
}

// bytes of one array in a buffer: each starts 16-byte aligned
template <typename T> RBD_HD unsigned long workspace_array_bytes(unsigned long count) {
  return (sizeof(T) * count + 15ul) & ~15ul;
}

// bytes needed for one workspace of a layout
template <typename S>
RBD_HD unsigned long workspace_bytes(int nb, int nv, WorkspaceLayout layout = kFullWorkspace) {
  Workspace<S> w{};
  unsigned long n = 0;
  workspace_arrays(w, nb, nv, layout, [&n](auto*& field, unsigned long count, bool present) {
    using T = typename std::remove_reference<decltype(*field)>::type;
    if (present) n += workspace_array_bytes<T>(count);
  });
  return n;
}

// carve a workspace out of a buffer of workspace_bytes(nb, nv, layout)
// bytes, 16-byte aligned; the arrays a layout lacks are null
template <typename S>
RBD_HD Workspace<S> carve_workspace(void* buffer, int nb, int nv, WorkspaceLayout layout = kFullWorkspace) {
  Workspace<S> w{};
  unsigned char* p = static_cast<unsigned char*>(buffer);
  workspace_arrays(w, nb, nv, layout, [&p](auto*& field, unsigned long count, bool present) {
    using T = typename std::remove_reference<decltype(*field)>::type;
    field = present ? reinterpret_cast<T*>(p) : nullptr;
    if (present) p += workspace_array_bytes<T>(count);
  });
  return w;
}

}  // namespace rbd
