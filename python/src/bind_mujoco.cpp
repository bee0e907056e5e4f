// rbdkit._core: the MuJoCo output convention (arrays as in bindings.cpp).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>

#include "arrays.hpp"
#include "rbdkit/mujoco_api.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rbd::Model;
using rbd_py::In;
using rbd_py::Out;
using rbd_py::batch_of;

void bind_mujoco(nb::module_& m) {
  m.def("convention_from_name", &rbd::convention_from_name, "name"_a);
  m.def("state_to_mujoco", [](const Model& md, In x, Out o) {
    nb::gil_scoped_release r;
    rbd::batch::state_to_mujoco(md, batch_of(x), x.data(), o.data());
  });
  m.def("state_from_mujoco", [](const Model& md, In x, Out o) {
    nb::gil_scoped_release r;
    rbd::batch::state_from_mujoco(md, batch_of(x), x.data(), o.data());
  });
  m.def("force_to_mujoco", [](const Model& md, In q, In u, Out o) {
    nb::gil_scoped_release r;
    rbd::batch::force_to_mujoco(md, batch_of(q), q.data(), u.data(), o.data());
  });
  m.def("force_from_mujoco", [](const Model& md, In q, In u, Out o) {
    nb::gil_scoped_release r;
    rbd::batch::force_from_mujoco(md, batch_of(q), q.data(), u.data(), o.data());
  });
  m.def("mujoco_integrate", [](const Model& md, In q, In v, Out o) {
    nb::gil_scoped_release r;
    rbd::batch::mujoco_integrate(md, batch_of(q), q.data(), v.data(), o.data());
  });
  m.def("mujoco_difference", [](const Model& md, In q0, In q1, Out o) {
    nb::gil_scoped_release r;
    rbd::batch::mujoco_difference(md, batch_of(q0), q0.data(), q1.data(), o.data());
  });
}
