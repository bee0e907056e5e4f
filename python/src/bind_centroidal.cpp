// rbdkit._core — bindings of the energy and centroidal family (centroidal_api.hpp).
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
  // ---- energy and Coriolis
  m.def("kinetic_energy", [](const Model& md, In q, In qd, Out out) {
    nb::gil_scoped_release r;
    rbd::batch::kinetic_energy(md, batch_of(q), q.data(), qd.data(), out.data());
  });
  m.def("potential_energy", [](const Model& md, In q, double g, Out out) {
    nb::gil_scoped_release r;
    rbd::batch::potential_energy(md, batch_of(q), q.data(), g, out.data());
  });
  m.def("mechanical_energy", [](const Model& md, In q, In qd, double g, Out out) {
    nb::gil_scoped_release r;
    rbd::batch::mechanical_energy(md, batch_of(q), q.data(), qd.data(), g, out.data());
  });
  m.def("coriolis_matrix", [](const Model& md, In q, In qd, Out C) {
    nb::gil_scoped_release r;
    rbd::batch::coriolis_matrix(md, batch_of(q), q.data(), qd.data(), C.data());
  });

  // ---- centre of mass
  m.def("center_of_mass", [](const Model& md, In q, Out com) {
    nb::gil_scoped_release r;
    rbd::batch::center_of_mass(md, batch_of(q), q.data(), com.data());
  });
  m.def("jacobian_com", [](const Model& md, In q, Out J) {
    nb::gil_scoped_release r;
    rbd::batch::jacobian_com(md, batch_of(q), q.data(), J.data());
  });

  // ---- centroidal momentum, its derivatives and time variation
  m.def("ccrba", [](const Model& md, In q, In qd, Out A, Out h) {
    nb::gil_scoped_release r;
    rbd::batch::ccrba(md, batch_of(q), q.data(), qd.data(), A.data(), h.data());
  });
  m.def("centroidal_momentum", [](const Model& md, In q, In qd, Out h) {
    nb::gil_scoped_release r;
    rbd::batch::centroidal_momentum(md, batch_of(q), q.data(), qd.data(), h.data());
  });
  m.def("dccrba", [](const Model& md, In q, Out dA) {
    nb::gil_scoped_release r;
    rbd::batch::dccrba(md, batch_of(q), q.data(), dA.data());
  });
  m.def("dccrba_fd", [](const Model& md, In q, double eps, Out dA) {
    nb::gil_scoped_release r;
    rbd::batch::dccrba_fd(md, batch_of(q), q.data(), eps, dA.data());
  });
  m.def("cmm_time_variation", [](const Model& md, In q, In qd, Out Adot) {
    nb::gil_scoped_release r;
    rbd::batch::cmm_time_variation(md, batch_of(q), q.data(), qd.data(), Adot.data());
  });
  m.def("cmm_time_variation_fd", [](const Model& md, In q, In qd, double eps, Out Adot) {
    nb::gil_scoped_release r;
    rbd::batch::cmm_time_variation_fd(md, batch_of(q), q.data(), qd.data(), eps, Adot.data());
  });
  m.def("centroidal_momentum_time_variation", [](const Model& md, In q, In qd, In qdd, Out hdot) {
    nb::gil_scoped_release r;
    rbd::batch::centroidal_momentum_time_variation(md, batch_of(q), q.data(), qd.data(), qdd.data(), hdot.data());
  });
  m.def("centroidal_dynamics_derivatives",
        [](const Model& md, In q, In qd, In qdd, Out dh_dq, Out dhdot_dq, Out dhdot_dv, Out dhdot_da) {
          nb::gil_scoped_release r;
          rbd::batch::centroidal_dynamics_derivatives(md, batch_of(q), q.data(), qd.data(), qdd.data(),
                                                      dh_dq.data(), dhdot_dq.data(), dhdot_dv.data(),
                                                      dhdot_da.data());
        });
}
