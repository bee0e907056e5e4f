// rbdkit._core: time integrators (arrays as in bindings.cpp).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>

#include "arrays.hpp"
#include "rbdkit/integrators_api.hpp"

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
  m.def("plant_step_hessian",
        [](const Model& md, In q, In v, In u, double dt, double g, int type, Out x, Out AB, Out H, int conv) {
          nb::gil_scoped_release r;
          rbd::batch::plant_step_hessian(md, static_cast<long>(q.shape(0)), q.data(), v.data(), u.data(), dt, g,
                                         type, x.data(), AB.data(), H.data(), conv);
        },
        "model"_a, "q"_a, "v"_a, "u"_a, "dt"_a, "gravity"_a, "type"_a, "x"_a, "AB"_a, "H"_a, "convention"_a = 0);
}
