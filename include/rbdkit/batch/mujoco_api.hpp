// rbdkit/batch/mujoco_api.hpp — host entry points of the MuJoCo output convention
// (batched, checked): the convention's name, configuration checks in either
// layout, state conversions and MuJoCo's ⊕ / ⊖. Layouts in
// plant/mujoco_convention.hpp. Host only.
#pragma once

#include <string>

#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/plant/mujoco_convention.hpp"

namespace rbd {

// "pinocchio" -> kPinocchioConvention, "mujoco" -> kMujocoConvention; anything
// else throws std::invalid_argument naming output_convention and the valid names
int convention_from_name(const std::string& name);
// throws std::invalid_argument unless code is an OutputConvention
void check_convention(int code);
// unit-norm quaternions in the layout of the convention (x y z w or w x y z);
// sample >= 0 labels the error "arg[sample]"
void check_configuration_in(const Model& m, const double* q, const char* arg, long sample, int convention);
void check_configurations_in(const Model& m, long B, const double* q, const char* arg, int convention);

namespace batch {
// x (B x NX) between the conventions: [q; v] Pinocchio <-> [qpos; qvel] MuJoCo
void state_to_mujoco(const Model& m, long B, const double* x, double* out);
void state_from_mujoco(const Model& m, long B, const double* x, double* out);
// generalized forces (B x nv) between the conventions at configurations q (B x nq, MuJoCo layout)
void force_to_mujoco(const Model& m, long B, const double* q_mj, const double* u, double* out);
void force_from_mujoco(const Model& m, long B, const double* q_mj, const double* u, double* out);
// MuJoCo's q ⊕ v (B x nq) and q1 ⊖ q0 (B x nv)
void mujoco_integrate(const Model& m, long B, const double* q, const double* v, double* out);
void mujoco_difference(const Model& m, long B, const double* q0, const double* q1, double* out);
}  // namespace batch
}  // namespace rbd
