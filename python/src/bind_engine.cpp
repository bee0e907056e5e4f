// rbdkit._core.Engine: the batched CPU engine (rbdkit/batch/engine.hpp).
//
// Every array is C-contiguous, of the engine's dtype (float64 or float32),
// with the batch B on axis 0 and the documented trailing size (q: nq,
// qd/qdd/tau/u: nv, matrices: nv·nv, x: nq + nv, AB: 2nv·3nv; trailing axes
// may be flattened or not). Outputs are passed in and overwritten. Arrays
// are checked here (dtype, contiguity, B, size) and the GIL is released
// for the batched call.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>

#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

#include "rbdkit/batch/engine.hpp"
#include "rbdkit/batch/integrators_api.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace {

using Arr = nb::ndarray<nb::device::cpu>;

std::string dtype_name(const nb::dlpack::dtype& d) {
  const char* kind = d.code == uint8_t(nb::dlpack::dtype_code::Float) ? "float"
                     : d.code == uint8_t(nb::dlpack::dtype_code::Int) ? "int"
                     : d.code == uint8_t(nb::dlpack::dtype_code::UInt) ? "uint"
                     : d.code == uint8_t(nb::dlpack::dtype_code::Bool) ? "bool"
                                                                      : "complex";
  return std::string(kind) + std::to_string(d.bits);
}

// checks one array of the call and hands out its data pointer
class Call {
 public:
  Call(const rbd::Engine& e, const char* op) : e_(e), op_(op) {}

  // the batch size from the first array (q), which must be (B, ...)
  template <typename T> T* get(const Arr& a, const char* name, long width, bool writable = false) {
    const bool f64 = sizeof(T) == 8;
    if (a.dtype() != nb::dtype<T>()) {
      std::ostringstream os;
      os << op_ << ": " << name << ": expected a " << (f64 ? "float64" : "float32") << " array (the engine's dtype is "
         << e_.dtype() << "), got " << dtype_name(a.dtype());
      throw nb::type_error(os.str().c_str());
    }
    if (a.ndim() == 0) fail(name, "expected an array with the batch on axis 0, got a 0-d array");
    // C-contiguous
    long expect = 1;
    for (long d = static_cast<long>(a.ndim()) - 1; d >= 0; --d) {
      if (a.shape(d) != 1 && a.stride(d) != expect) fail(name, "expected a C-contiguous array");
      expect *= static_cast<long>(a.shape(d));
    }
    const long b = static_cast<long>(a.shape(0));
    if (B_ < 0) {
      if (b <= 0) fail(name, "the batch is empty (B = 0)");
      B_ = b, source_ = name;
    } else if (b != B_) {
      std::ostringstream os;
      os << "batch size " << b << " does not match " << source_ << "'s batch size " << B_;
      fail(name, os.str());
    }
    if (static_cast<long>(a.size()) != B_ * width) {
      std::ostringstream os;
      os << "expected " << width << " values per sample (B = " << B_ << "), got an array of shape (";
      for (size_t d = 0; d < a.ndim(); ++d) os << (d ? ", " : "") << a.shape(d);
      os << ")";
      fail(name, os.str());
    }
    (void)writable;
    return static_cast<T*>(a.data());
  }
  long B() const { return B_; }

 private:
  [[noreturn]] void fail(const char* name, const std::string& what) {
    throw nb::value_error((std::string(op_) + ": " + name + ": " + what).c_str());
  }
  const rbd::Engine& e_;
  const char* op_;
  long B_ = -1;
  const char* source_ = "";
};

bool is_f64(const rbd::Engine& e) { return e.dtype() == "float64"; }

int integrator_type(const nb::handle& t) {
  if (nb::isinstance<nb::str>(t)) return rbd::integrator_from_name(nb::cast<std::string>(t));
  if (nb::isinstance<nb::int_>(t) && !nb::isinstance<nb::bool_>(t)) return nb::cast<int>(t);
  throw nb::type_error("integrator_type: expected an integrator name (str) or code (int)");
}

template <typename T> void id_impl(rbd::Engine& e, const Arr& q, const Arr& qd, const std::optional<Arr>& qdd, double g,
                                   const Arr& tau) {
  const rbd::Model& m = e.model();
  Call c(e, "inverse_dynamics");
  const T* pq = c.get<T>(q, "q", m.nq);
  const T* pv = c.get<T>(qd, "qd", m.nv);
  const T* pa = qdd ? c.get<T>(*qdd, "qdd", m.nv) : nullptr;
  T* out = c.get<T>(tau, "tau", m.nv, true);
  nb::gil_scoped_release r;
  e.inverse_dynamics<T>(c.B(), pq, pv, pa, T(g), out);
}

template <typename T> void mat_impl(rbd::Engine& e, const Arr& q, const Arr& M, bool inverse) {
  const rbd::Model& m = e.model();
  Call c(e, inverse ? "minv" : "crba");
  const T* pq = c.get<T>(q, "q", m.nq);
  T* out = c.get<T>(M, inverse ? "Minv" : "M", long(m.nv) * m.nv, true);
  nb::gil_scoped_release r;
  if (inverse) e.minv<T>(c.B(), pq, out);
  else e.crba<T>(c.B(), pq, out);
}

template <typename T> void fd_impl(rbd::Engine& e, const Arr& q, const Arr& qd, const Arr& tau, double g, const Arr& qdd) {
  const rbd::Model& m = e.model();
  Call c(e, "forward_dynamics");
  const T* pq = c.get<T>(q, "q", m.nq);
  const T* pv = c.get<T>(qd, "qd", m.nv);
  const T* pt = c.get<T>(tau, "tau", m.nv);
  T* out = c.get<T>(qdd, "qdd", m.nv, true);
  nb::gil_scoped_release r;
  e.forward_dynamics<T>(c.B(), pq, pv, pt, T(g), out);
}

template <typename T>
void idg_impl(rbd::Engine& e, const Arr& q, const Arr& qd, const std::optional<Arr>& qdd, double g, const Arr& dq,
              const Arr& dv) {
  const rbd::Model& m = e.model();
  const long nn = long(m.nv) * m.nv;
  Call c(e, "inverse_dynamics_gradient");
  const T* pq = c.get<T>(q, "q", m.nq);
  const T* pv = c.get<T>(qd, "qd", m.nv);
  const T* pa = qdd ? c.get<T>(*qdd, "qdd", m.nv) : nullptr;
  T* o1 = c.get<T>(dq, "dtau_dq", nn, true);
  T* o2 = c.get<T>(dv, "dtau_dqd", nn, true);
  nb::gil_scoped_release r;
  e.inverse_dynamics_gradient<T>(c.B(), pq, pv, pa, T(g), o1, o2);
}

template <typename T>
void fdg_impl(rbd::Engine& e, const Arr& q, const Arr& qd, const Arr& tau, double g, const Arr& dq, const Arr& dv,
              const std::optional<Arr>& Minv) {
  const rbd::Model& m = e.model();
  const long nn = long(m.nv) * m.nv;
  Call c(e, "forward_dynamics_gradient");
  const T* pq = c.get<T>(q, "q", m.nq);
  const T* pv = c.get<T>(qd, "qd", m.nv);
  const T* pt = c.get<T>(tau, "tau", m.nv);
  T* o1 = c.get<T>(dq, "dqdd_dq", nn, true);
  T* o2 = c.get<T>(dv, "dqdd_dqd", nn, true);
  T* o3 = Minv ? c.get<T>(*Minv, "Minv", nn, true) : nullptr;
  nb::gil_scoped_release r;
  e.forward_dynamics_gradient<T>(c.B(), pq, pv, pt, T(g), o1, o2, o3);
}

template <typename T>
void int_impl(rbd::Engine& e, const Arr& q, const Arr& qd, const Arr& u, double dt, double g, int type, const Arr& x,
              const Arr* AB) {
  const rbd::Model& m = e.model();
  const long nv = m.nv;
  Call c(e, AB ? "integrator_gradient" : "integrator");
  const T* pq = c.get<T>(q, "q", m.nq);
  const T* pv = c.get<T>(qd, "qd", nv);
  const T* pu = c.get<T>(u, "u", nv);
  T* px = c.get<T>(x, "x", m.nq + nv, true);
  T* pab = AB ? c.get<T>(*AB, "AB", 6 * nv * nv, true) : nullptr;
  nb::gil_scoped_release r;
  if (AB) e.integrator_gradient<T>(c.B(), pq, pv, pu, T(dt), T(g), type, px, pab);
  else e.integrator<T>(c.B(), pq, pv, pu, T(dt), T(g), type, px);
}

}  // namespace

void bind_engine(nb::module_& m) {
  nb::class_<rbd::Engine>(m, "Engine",
                          "Batched CPU engine: a persistent thread pool and SIMD lanes over the batch (axis 0); "
                          "dtype 'float64' or 'float32'.")
      .def(
          "__init__",
          [](rbd::Engine* self, const rbd::Model& model, std::optional<int> threads, const std::string& dtype) {
            new (self) rbd::Engine(model, threads ? *threads : rbd::Engine::default_threads(), dtype);
          },
          "model"_a, "threads"_a.none() = nb::none(), "dtype"_a = "float64")
      .def_prop_ro("threads", &rbd::Engine::threads)
      .def_prop_ro("dtype", &rbd::Engine::dtype)
      .def_prop_ro("simd_width", &rbd::Engine::simd_width)
      .def_prop_ro("workspace_bytes", &rbd::Engine::workspace_bytes)
      .def(
          "inverse_dynamics",
          [](rbd::Engine& e, const Arr& q, const Arr& qd, std::optional<Arr> qdd, double g, const Arr& tau) {
            is_f64(e) ? id_impl<double>(e, q, qd, qdd, g, tau) : id_impl<float>(e, q, qd, qdd, g, tau);
          },
          "q"_a, "qd"_a, "qdd"_a.none(), "gravity"_a, "tau"_a)
      .def(
          "crba",
          [](rbd::Engine& e, const Arr& q, const Arr& M) {
            is_f64(e) ? mat_impl<double>(e, q, M, false) : mat_impl<float>(e, q, M, false);
          },
          "q"_a, "M"_a)
      .def(
          "minv",
          [](rbd::Engine& e, const Arr& q, const Arr& Minv) {
            is_f64(e) ? mat_impl<double>(e, q, Minv, true) : mat_impl<float>(e, q, Minv, true);
          },
          "q"_a, "Minv"_a)
      .def(
          "forward_dynamics",
          [](rbd::Engine& e, const Arr& q, const Arr& qd, const Arr& tau, double g, const Arr& qdd) {
            is_f64(e) ? fd_impl<double>(e, q, qd, tau, g, qdd) : fd_impl<float>(e, q, qd, tau, g, qdd);
          },
          "q"_a, "qd"_a, "tau"_a, "gravity"_a, "qdd"_a)
      .def(
          "inverse_dynamics_gradient",
          [](rbd::Engine& e, const Arr& q, const Arr& qd, std::optional<Arr> qdd, double g, const Arr& dq,
             const Arr& dv) {
            is_f64(e) ? idg_impl<double>(e, q, qd, qdd, g, dq, dv) : idg_impl<float>(e, q, qd, qdd, g, dq, dv);
          },
          "q"_a, "qd"_a, "qdd"_a.none(), "gravity"_a, "dtau_dq"_a, "dtau_dqd"_a)
      .def(
          "forward_dynamics_gradient",
          [](rbd::Engine& e, const Arr& q, const Arr& qd, const Arr& tau, double g, const Arr& dq, const Arr& dv,
             std::optional<Arr> Minv) {
            is_f64(e) ? fdg_impl<double>(e, q, qd, tau, g, dq, dv, Minv)
                      : fdg_impl<float>(e, q, qd, tau, g, dq, dv, Minv);
          },
          "q"_a, "qd"_a, "tau"_a, "gravity"_a, "dqdd_dq"_a, "dqdd_dqd"_a, "Minv"_a.none() = nb::none())
      .def(
          "integrator",
          [](rbd::Engine& e, const Arr& q, const Arr& qd, const Arr& u, double dt, double g, nb::handle type,
             const Arr& x) {
            const int t = integrator_type(type);
            is_f64(e) ? int_impl<double>(e, q, qd, u, dt, g, t, x, nullptr)
                      : int_impl<float>(e, q, qd, u, dt, g, t, x, nullptr);
          },
          "q"_a, "qd"_a, "u"_a, "dt"_a, "gravity"_a, "type"_a, "x"_a)
      .def(
          "integrator_gradient",
          [](rbd::Engine& e, const Arr& q, const Arr& qd, const Arr& u, double dt, double g, nb::handle type,
             const Arr& x, const Arr& AB) {
            const int t = integrator_type(type);
            is_f64(e) ? int_impl<double>(e, q, qd, u, dt, g, t, x, &AB)
                      : int_impl<float>(e, q, qd, u, dt, g, t, x, &AB);
          },
          "q"_a, "qd"_a, "u"_a, "dt"_a, "gravity"_a, "type"_a, "x"_a, "AB"_a);
}
