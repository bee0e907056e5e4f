// src/cuda/interpret_f32.cpp — the interpret launches on float (interpret_routes.hpp)
#include "device.hpp"
#include "rbdkit/cuda/interpret_routes.hpp"

namespace rbd {
namespace cuda {
template <> const Launcher<float>* interpret_routes<float>() { return interpret_table<float>(ops::AllOps{}); }
}  // namespace cuda
}  // namespace rbd
