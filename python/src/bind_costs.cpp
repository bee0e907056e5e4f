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
  m.def("ee_pos_cost",
        [](const Model& md, In q, In pd, In W, int body, std::optional<In> off, Out v, Out g, Out H, int conv) {
          nb::gil_scoped_release r;
          rbd::batch::ee_pos_cost(md, batch_of(q), q.data(), pd.data(), W.data(), body, off ? off->data() : nullptr,
                                  v.data(), g.data(), H.data(), conv);
        },
        "model"_a, "q"_a, "p_des"_a, "W"_a, "body"_a, "offset"_a.none(), "value"_a, "grad"_a, "H"_a,
        "convention"_a = 0);
  m.def("log_barrier", [](In x, In lo, In hi, double mu, Out v, Out g, Out h, const std::string& xn) {
    nb::gil_scoped_release r;
    rbd::batch::log_barrier(batch_of(x), width(x), x.data(), lo.data(), hi.data(), mu, v.data(), g.data(), h.data(),
                            xn.c_str());
  });
}
