// src/cuda/interpret_routes.hpp — the interpret launches of every registered
// operation for one dtype, instantiated in src/cuda/interpret_<dtype>.cpp (a
// file per dtype, so that a parallel build compiles them side by side)
#pragma once

#include "device.hpp"

namespace rbd {
namespace cuda {

template <typename Op, typename T> void interpret_launch(const DeviceCall<T>& c, LaunchShape shape, void*) {
  if (shape.team) interpret_team_op<Op>(c, shape);  // (the engine asks for a team only where Op has one)
  else interpret_op<Op>(c, shape);
}

template <typename T, typename... Op> const Launcher<T>* interpret_table(ops::OpList<Op...>) {
  static const Launcher<T> table[] = {&interpret_launch<Op, T>...};
  return table;
}

}  // namespace cuda
}  // namespace rbd
