// rbdkit/cuda/interpret_routes.hpp — the interpret launches of every registered
// operation for one dtype, instantiated in src/cuda/interpret_<dtype>.cpp (a
// file per dtype, so that a parallel build compiles them side by side), and on a
// robot's constants in a per-robot instance for interpret mode (cuda/instance.cuh)
#pragma once

#include "rbdkit/cuda/team_kernels.cuh"

namespace rbd {
namespace cuda {

// Model: where the kernels' model comes from (kernels.cuh's CallModel, or a per-robot instance's)
template <typename Op, typename T, typename Model = CallModel>
void interpret_launch(const DeviceCall<T>& c, LaunchShape shape, void*) {
  if (shape.team) interpret_team_op<Op, T, Model>(c, shape);  // (the engine asks for a team only where Op has one)
  else interpret_op<Op, T, Model>(c, shape);
}

template <typename T, typename Model = CallModel, typename... Op>
const Launcher<T>* interpret_table(ops::OpList<Op...>) {
  static const Launcher<T> table[] = {&interpret_launch<Op, T, Model>...};
  return table;
}

}  // namespace cuda
}  // namespace rbd
