// src/cuda/interpret_f64.cpp — the interpret launches on double (interpret_routes.hpp)
#include "device.hpp"
#include "rbdkit/cuda/interpret_routes.hpp"

namespace rbd {
namespace cuda {
template <> const Launcher<double>* interpret_routes<double>() { return interpret_table<double>(ops::AllOps{}); }
}  // namespace cuda
}  // namespace rbd
