// rbdkit._core: the plant layer's costs and barriers (arrays as in bindings.cpp).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>

#include "arrays.hpp"
#include "rbdkit/costs_api.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rbd::Model;
using rbd_py::In;
using rbd_py::Out;
using rbd_py::batch_of;
using rbd_py::opt;
using rbd_py::width;


void bind_costs(nb::module_& m) {
  m.def("quadratic_cost",
        [](In x, In xd, In W, Out v, Out g, Out H, const std::string& xn, const std::string& dn, const std::string& wn) {
          nb::gil_scoped_release r;
          rbd::batch::quadratic_cost(batch_of(x), width(x), x.data(), xd.data(), W.data(), v.data(), g.data(), H.data(),
                                     xn.c_str(), dn.c_str(), wn.c_str());
        });
  m.def("quadratic_state_cost_tangent", [](const Model& md, In x, In xd, In Q, Out v, Out g, Out H, int conv) {
    nb::gil_scoped_release r;
    rbd::batch::quadratic_state_cost_tangent(md, batch_of(x), x.data(), xd.data(), Q.data(), v.data(), g.data(),
                                             H.data(), conv);
  }, "model"_a, "x"_a, "x_des"_a, "Q"_a, "value"_a, "grad"_a, "H"_a, "convention"_a = 0);
  m.def("ee_pos_cost",
        [](const Model& md, In q, In pd, In W, int body, std::optional<In> off, Out v, Out g, Out H, int conv) {
          nb::gil_scoped_release r;
          rbd::batch::ee_pos_cost(md, batch_of(q), q.data(), pd.data(), W.data(), body, off ? off->data() : nullptr,
                                  v.data(), g.data(), H.data(), conv);
        },
        "model"_a, "q"_a, "p_des"_a, "W"_a, "body"_a, "offset"_a.none(), "value"_a, "grad"_a, "H"_a,
        "convention"_a = 0);
  m.def("com_cost", [](const Model& md, In q, In pd, In W, Out v, Out g, Out H, int conv) {
    nb::gil_scoped_release r;
    rbd::batch::com_cost(md, batch_of(q), q.data(), pd.data(), W.data(), v.data(), g.data(), H.data(), conv);
  }, "model"_a, "q"_a, "p_des"_a, "W"_a, "value"_a, "grad"_a, "H"_a, "convention"_a = 0);
  m.def("momentum_cost", [](const Model& md, In q, In qd, In hd, In W, Out v, Out g, Out H, int conv) {
    nb::gil_scoped_release r;
    rbd::batch::momentum_cost(md, batch_of(q), q.data(), qd.data(), hd.data(), W.data(), v.data(), g.data(), H.data(),
                              conv);
  }, "model"_a, "q"_a, "qd"_a, "h_des"_a, "W"_a, "value"_a, "grad"_a, "H"_a, "convention"_a = 0);
  m.def("log_barrier", [](In x, In lo, In hi, double mu, Out v, Out g, Out h, const std::string& xn) {
    nb::gil_scoped_release r;
    rbd::batch::log_barrier(batch_of(x), width(x), x.data(), lo.data(), hi.data(), mu, v.data(), g.data(), h.data(),
                            xn.c_str());
  });
}
