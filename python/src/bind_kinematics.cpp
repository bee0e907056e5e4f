// rbdkit._core — the kinematics family's name lookups (kinematics_api.hpp);
// its operations are registered (ops/registry.hpp) and bound by bind_ops.cpp.
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "rbdkit/batch/kinematics_api.hpp"

namespace nb = nanobind;
using namespace nb::literals;

void bind_kinematics(nb::module_& m) {
  m.def("leaf_bodies", &rbd::leaf_bodies, "model"_a);
  m.def("end_effector_bodies", &rbd::end_effector_bodies, "model"_a, "joint_names"_a);
}
