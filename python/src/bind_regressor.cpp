// rbdkit._core: the inertial-parameter regressors that are not registered
// operations (the registered ones: ops/registry.hpp, bind_ops.cpp). Arrays as
// in bindings.cpp: C-contiguous float64, batch on axis 0, outputs
// preallocated by the Python layer.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>

#include "arrays.hpp"
#include "rbdkit/regressor_api.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rbd::Model;
using rbd_py::In;
using rbd_py::Out;
using rbd_py::batch_of;
using rbd_py::opt;
using rbd_py::width;


void bind_regressor(nb::module_& m) {
  m.def("inverse_dynamics_regressor_gradient",
        [](const Model& md, In q, In qd, std::optional<In> qdd, double g, Out dY) {
          nb::gil_scoped_release r;
          rbd::batch::inverse_dynamics_regressor_gradient(md, batch_of(q), q.data(), qd.data(), opt(qdd), g,
                                                          dY.data());
        },
        "model"_a, "q"_a, "qd"_a, "qdd"_a.none(), "gravity"_a, "dY"_a);
  m.def("forward_dynamics_parameter_gradient", [](const Model& md, In q, In qd, In u, double g, Out out) {
    nb::gil_scoped_release r;
    rbd::batch::forward_dynamics_parameter_gradient(md, batch_of(q), q.data(), qd.data(), u.data(), g, out.data());
  });
}
