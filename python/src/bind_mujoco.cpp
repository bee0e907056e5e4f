// rbdkit._core: the MuJoCo output convention's names (its conversions are
// registered operations: bind_ops.cpp).
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>

#include "rbdkit/batch/mujoco_api.hpp"

namespace nb = nanobind;
using namespace nb::literals;

void bind_mujoco(nb::module_& m) {
  m.def("convention_from_name", &rbd::convention_from_name, "name"_a);
}
