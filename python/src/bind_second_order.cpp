// rbdkit._core: second-order dynamics derivatives (second_order_api.hpp).
// Arrays as in bindings.cpp: C-contiguous float64, batch on axis 0, outputs
// (B, nv, nv, nv) preallocated by the Python layer (python/rbdkit/_second_order.py).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include "arrays.hpp"
#include "rbdkit/second_order_api.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rbd::Model;
using rbd_py::In;
using rbd_py::Out;
using rbd_py::batch_of;
using rbd_py::opt;
using rbd_py::width;


void bind_second_order(nb::module_& m) {
  m.def("idsva_so",
        [](const Model& md, In q, In qd, In qdd, double g, int frame, Out d2q, Out d2v, Out d2qv, Out dM) {
          nb::gil_scoped_release r;
          rbd::batch::idsva_so(md, batch_of(q), q.data(), qd.data(), qdd.data(), g, frame, d2q.data(), d2v.data(),
                               d2qv.data(), dM.data());
        },
        "model"_a, "q"_a, "qd"_a, "qdd"_a, "gravity"_a, "frame"_a, "d2q"_a, "d2v"_a, "d2qv"_a, "dM"_a);
  m.def("fdsva_so",
        [](const Model& md, In q, In qd, In u, double g, Out d2q, Out d2v, Out d2qv, Out d2qu) {
          nb::gil_scoped_release r;
          rbd::batch::fdsva_so(md, batch_of(q), q.data(), qd.data(), u.data(), g, d2q.data(), d2v.data(),
                               d2qv.data(), d2qu.data());
        },
        "model"_a, "q"_a, "qd"_a, "u"_a, "gravity"_a, "d2q"_a, "d2v"_a, "d2qv"_a, "d2qu"_a);
}
