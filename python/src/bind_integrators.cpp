// rbdkit._core: time integrators (arrays as in bindings.cpp).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>

#include "arrays.hpp"
#include "rbdkit/batch/integrators_api.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rbd::Model;
using rbd_py::In;
using rbd_py::Out;
using rbd_py::batch_of;
using rbd_py::opt;
using rbd_py::width;


void bind_integrators(nb::module_& m) {
  m.def("integrator_from_name", &rbd::integrator_from_name, "name"_a);
}
