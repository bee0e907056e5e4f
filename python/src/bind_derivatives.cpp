// rbdkit._core: first-order dynamics derivatives and the per-pass helpers.
// Arrays as in bindings.cpp: C-contiguous float64, batch on axis 0,
// outputs preallocated by the Python layer.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>

#include "arrays.hpp"
#include "rbdkit/derivatives_api.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rbd::Model;
using rbd_py::In;
using rbd_py::Out;
using rbd_py::batch_of;
using rbd_py::opt;
using rbd_py::width;


void bind_derivatives(nb::module_& m) {
  m.def("inverse_dynamics_fpass",
        [](const Model& md, In q, In qd, std::optional<In> qdd, std::optional<In> fext, double g, Out v, Out a,
           Out f) {
          nb::gil_scoped_release r;
          rbd::batch::inverse_dynamics_fpass(md, batch_of(q), q.data(), qd.data(), opt(qdd), opt(fext), g, v.data(),
                                             a.data(), f.data());
        },
        "model"_a, "q"_a, "qd"_a, "qdd"_a.none(), "fext"_a.none(), "gravity"_a, "v"_a, "a"_a, "f"_a);
  m.def("inverse_dynamics_bpass", [](const Model& md, In q, In f, Out tau, Out fo) {
    nb::gil_scoped_release r;
    rbd::batch::inverse_dynamics_bpass(md, batch_of(q), q.data(), f.data(), tau.data(), fo.data());
  });
  m.def("minv_bpass", [](const Model& md, In q, Out out) {
    nb::gil_scoped_release r;
    rbd::batch::minv_bpass(md, batch_of(q), q.data(), out.data());
  });
  m.def("minv_fpass", [](const Model& md, In q, In mb, Out out) {
    nb::gil_scoped_release r;
    rbd::batch::minv_fpass(md, batch_of(q), q.data(), mb.data(), out.data());
  });
  m.def("inverse_dynamics_gradient_fpass",
        [](const Model& md, In q, In qd, std::optional<In> qdd, double g, int wrt, Out o1, Out o2) {
          nb::gil_scoped_release r;
          rbd::batch::inverse_dynamics_gradient_fpass(md, batch_of(q), q.data(), qd.data(), opt(qdd), g, wrt,
                                                      o1.data(), o2.data());
        },
        "model"_a, "q"_a, "qd"_a, "qdd"_a.none(), "gravity"_a, "wrt"_a, "o1"_a, "o2"_a);
  m.def("inverse_dynamics_gradient_bpass",
        [](const Model& md, In q, In qd, std::optional<In> qdd, double g, int wrt, In i1, In i2, Out out) {
          nb::gil_scoped_release r;
          rbd::batch::inverse_dynamics_gradient_bpass(md, batch_of(q), q.data(), qd.data(), opt(qdd), g, wrt,
                                                      i1.data(), i2.data(), out.data());
        },
        "model"_a, "q"_a, "qd"_a, "qdd"_a.none(), "gravity"_a, "wrt"_a, "i1"_a, "i2"_a, "out"_a);
}
