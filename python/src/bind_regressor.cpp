// rbdkit._core: the inertial-parameter regressors. Arrays as in bindings.cpp:
// C-contiguous float64, batch on axis 0, outputs preallocated by the Python layer.
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
  m.def("inverse_dynamics_regressor",
        [](const Model& md, In q, In qd, std::optional<In> qdd, double g, Out Y) {
          nb::gil_scoped_release r;
          rbd::batch::inverse_dynamics_regressor(md, batch_of(q), q.data(), qd.data(), opt(qdd), g, Y.data());
        },
        "model"_a, "q"_a, "qd"_a, "qdd"_a.none(), "gravity"_a, "Y"_a);
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
  m.def("kinetic_energy_regressor", [](const Model& md, In q, In qd, Out y) {
    nb::gil_scoped_release r;
    rbd::batch::kinetic_energy_regressor(md, batch_of(q), q.data(), qd.data(), y.data());
  });
  m.def("potential_energy_regressor", [](const Model& md, In q, double g, Out y) {
    nb::gil_scoped_release r;
    rbd::batch::potential_energy_regressor(md, batch_of(q), q.data(), g, y.data());
  });
}
