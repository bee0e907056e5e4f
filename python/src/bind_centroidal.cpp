// rbdkit._core — bindings of the energy and centroidal family (centroidal_api.hpp)
// that are not registered operations (the registered ones: ops/registry.hpp,
// bind_ops.cpp).
//
// Thin, like bindings.cpp: the Python layer (python/rbdkit/_centroidal.py)
// checks shapes and allocates outputs; these functions take C-contiguous
// float64 arrays with the batch on axis 0, check values in C++ and run the
// batched loops with the GIL released.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include "arrays.hpp"
#include "rbdkit/centroidal_api.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rbd::Model;
using rbd_py::In;
using rbd_py::Out;
using rbd_py::batch_of;
using rbd_py::opt;
using rbd_py::width;


void bind_centroidal(nb::module_& m) {
  // ---- the finite-difference cross-checks
  m.def("dccrba_fd", [](const Model& md, In q, double eps, Out dA) {
    nb::gil_scoped_release r;
    rbd::batch::dccrba_fd(md, batch_of(q), q.data(), eps, dA.data());
  });
  m.def("cmm_time_variation_fd", [](const Model& md, In q, In qd, double eps, Out Adot) {
    nb::gil_scoped_release r;
    rbd::batch::cmm_time_variation_fd(md, batch_of(q), q.data(), qd.data(), eps, Adot.data());
  });
}
