// rbdkit/batch/kinematics_api.hpp — the host API of the kinematics family: name
// lookups and checked, batched entry points over raw row-major arrays (what
// the Python package calls). Host only. The per-sample maths is in
// algorithms/kinematics.hpp and algorithms/osc.hpp.
//
// Every batched function takes B samples stacked on the leading axis:
// q (B x nq), qd (B x nv); outputs have the documented shapes. Inputs are
// checked first (finite values, unit quaternions); a bad one throws
// std::invalid_argument naming the argument.
//
// End-effector pose (6) = [x, y, z, roll, pitch, yaw]: the world position of
// the tool point (an offset in the end-effector body's frame) and the RPY
// angles of the body's orientation, R = Rz(yaw) Ry(pitch) Rx(roll). Its
// derivatives are with respect to tangent perturbations q ⊕ δ (nv columns):
//   gradient  G[e][r][k]     = ∂pose[e][r]/∂δ_k
//   hessian   H[e][r][j][k]  = ∂G[e][r][k]/∂δ_j  at q ⊕ δ
// H is what central differences of G through integrate give; it is not
// symmetric in (j, k) within a free-flyer or spherical joint. The rpy rows are
// singular at pitch = ±π/2 (gimbal lock).
#pragma once

#include <string>
#include <vector>

#include "rbdkit/algorithms/kinematics.hpp"
#include "rbdkit/algorithms/osc.hpp"
#include "rbdkit/batch/dynamics.hpp"

namespace rbd {

// "LOCAL", "WORLD" or "LOCAL_WORLD_ALIGNED" -> ReferenceFrame; throws
// std::invalid_argument (naming reference_frame) for anything else
int reference_frame_from_name(const std::string& name);

// index into Model::frames; throws std::invalid_argument naming frame_name
int frame_from_name(const Model& m, const std::string& name);

// the bodies with no children, in body order (the default end effectors)
std::vector<int> leaf_bodies(const Model& m);

// the bodies moved by the named joints; throws std::invalid_argument naming
// ee_joint_names for an unknown joint (or a fixed one, which moves no body)
std::vector<int> end_effector_bodies(const Model& m, const std::vector<std::string>& joint_names);

// the end effectors of one call
struct EndEffectors {
  std::vector<int> bodies;               // (n_ee) body of each end effector
  const double* offsets = nullptr;       // (B x n_ee x 3) tool points in the body frames, null: zero
  const char* offsets_arg = "ee_offsets";  // names the offsets in error messages
  long size() const { return static_cast<long>(bodies.size()); }
};

// The functions take an optional workspace (WorkspaceBuffer of the same
// model); without one they allocate their own once per call, of the linear
// layout (workspace.hpp) from forward_kinematics to end_effector_pose_gradient,
// the full one for the others.
namespace batch {
// X_world_body of every body: R (B x nb x 3 x 3), p (B x nb x 3)
void forward_kinematics(const Model& m, long B, const double* q, double* R, double* p,
                        Workspace<double>* ws = nullptr);
// X_world_frame of frame `frame` (index into Model::frames): R (B x 3 x 3), p (B x 3)
void frame_placement(const Model& m, long B, const double* q, int frame, double* R, double* p,
                     Workspace<double>* ws = nullptr);
// J (B x 6 x nv) of frame `frame` in reference frame rf (ReferenceFrame)
void frame_jacobian(const Model& m, long B, const double* q, int frame, int rf, double* J,
                    Workspace<double>* ws = nullptr);
// dJ/dt (B x 6 x nv) along qd (B x nv)
void frame_jacobian_dot(const Model& m, long B, const double* q, const double* qd, int frame, int rf, double* dJ,
                        Workspace<double>* ws = nullptr);
// pose (B x n_ee x 6)
void end_effector_pose(const Model& m, long B, const double* q, const EndEffectors& ee, double* pose,
                       Workspace<double>* ws = nullptr);
// G (B x n_ee x 6 x nv), analytic
void end_effector_pose_gradient(const Model& m, long B, const double* q, const EndEffectors& ee, double* G,
                                Workspace<double>* ws = nullptr);
// H (B x n_ee x 6 x nv x nv) in closed form
void end_effector_pose_hessian_analytic(const Model& m, long B, const double* q, const EndEffectors& ee, double* H,
                                        Workspace<double>* ws = nullptr);
// H (B x n_ee x 6 x nv x nv) by forward-mode dual numbers through the analytic
// gradient (one pass per tangent direction); exact, equal to the closed form
void end_effector_pose_hessian(const Model& m, long B, const double* q, const EndEffectors& ee, double* H);
// Λ (B x n_ee x 6 x 6) = (J M⁻¹ Jᵀ)⁻¹, J the kLocalWorldAligned Jacobian of
// each tool point. Throws std::invalid_argument when J M⁻¹ Jᵀ is singular,
// std::runtime_error when M is not positive definite.
void osc_inertia(const Model& m, long B, const double* q, const EndEffectors& ee, double* Lambda,
                 Workspace<double>* ws = nullptr);
}  // namespace batch

}  // namespace rbd
