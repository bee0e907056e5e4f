// rbdkit._core: the registered operations (include/rbdkit/ops/registry.hpp)
// as Python callables, generated from the registry's table.
//
//   h = _core.OpHandle(model_core, algorithms, threads, dtype)   # an rbd::Handle
//   inverse_dynamics = h.op("inverse_dynamics", False)          # RBD's results
//   tau, v, a, f = inverse_dynamics(q, qd, qdd)                  # (nq,) / (B, nq) ...
//
// One call parses its arguments against the operation's spec (positional or
// by keyword), converts and checks each array in one pass (dtype, shape,
// batch axis; values in C++: rbd::ops::check_call), allocates the outputs
// and runs rbd::Handle::run. Errors name the argument: TypeError for a
// wrong kind of argument, ValueError for a wrong shape or value, RuntimeError
// for a failed computation. The callables use CPython's vectorcall and
// NumPy's C API directly: a call on one sample costs a few hundred
// nanoseconds above the kernel.
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <structmember.h>
#define NPY_NO_DEPRECATED_API NPY_1_21_API_VERSION
#define PY_ARRAY_UNIQUE_SYMBOL rbdkit_ops_ARRAY_API
#include <numpy/arrayobject.h>

#include <nanobind/nanobind.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>

#include "rbdkit/batch/integrators_api.hpp"
#include "rbdkit/batch/kinematics_api.hpp"
#include "rbdkit/batch/mujoco_api.hpp"
#include "rbdkit/handle/handle.hpp"
#include "rbdkit/ops/table.hpp"

namespace nb = nanobind;
using namespace nb::literals;
namespace ops = rbd::ops;

namespace {

// ---------------------------------------------------------------- the handle behind the callables

struct OpHandle {
  std::unique_ptr<rbd::Handle> h;
  int npy_type;  // NPY_DOUBLE or NPY_FLOAT
};

// ---------------------------------------------------------------- messages

std::string dim_name(int d) {
  switch (d) {
    case ops::kNq: return "nq";
    case ops::kNv: return "nv";
    case ops::kNb: return "nb";
    case ops::kNx: return "nq+nv";
    case ops::k2Nv: return "2nv";
    case ops::k3Nv: return "3nv";
    case ops::k10Nb: return "10nb";
    case ops::kNee: return "n_ee";
    default: return std::to_string(d);
  }
}

std::string tuple_str(const npy_intp* d, int n) {
  std::string s = "(";
  for (int k = 0; k < n; ++k) s += (k ? ", " : "") + std::to_string(d[k]);
  return s + (n == 1 ? ",)" : ")");
}

// a Python exception of `type` (owned message); returns null for `return fail(...)`
PyObject* fail(PyObject* type, const std::string& msg) {
  PyErr_SetString(type, msg.c_str());
  return nullptr;
}

const char* type_name(PyObject* o) { return Py_TYPE(o)->tp_name; }

// the UTF-8 text of a str for a message: "?" where it has none (a lone surrogate)
std::string text_of(PyObject* s) {
  const char* t = s ? PyUnicode_AsUTF8(s) : nullptr;
  if (!t) PyErr_Clear();
  return t ? t : "?";
}

// the UTF-8 text of a str argument: false with a ValueError naming `name` where it has none
bool utf8_of(PyObject* s, const char* name, std::string& out) {
  const char* t = PyUnicode_AsUTF8(s);
  if (t) return out = t, true;
  PyErr_Clear();
  fail(PyExc_ValueError, std::string(name) + ": expected a name in valid UTF-8, got a str that has none "
                                             "(a lone surrogate)");
  return false;
}

// ---------------------------------------------------------------- the callable

struct OpFn {
  PyObject_HEAD
  vectorcallfunc vectorcall;
  PyObject* owner;  // the OpHandle's Python object (kept alive)
  OpHandle* handle;
  int op;
  const ops::OpSpec* spec;
  unsigned returns;
  PyObject* names[ops::kMaxArgs];  // interned argument names
};

// keeps the converted arrays of one call alive
struct Refs {
  PyObject* p[4 * ops::kMaxArgs + ops::kMaxOutputs] = {};  // per array: as given, float64, rounded, repeated
  int n = 0;
  ~Refs() {
    for (int k = 0; k < n; ++k) Py_XDECREF(p[k]);
  }
  PyObject* keep(PyObject* o) { return p[n++] = o; }
};

// the argument `o` as a C-contiguous array of `type` (borrowed or kept in refs); null with a TypeError.
// *wide: the values before they were rounded to float32 (float64), when they were
PyArrayObject* as_array(PyObject* o, const char* name, int type, Refs& refs, PyArrayObject** wide) {
  *wide = nullptr;
  if (PyArray_CheckExact(o)) {
    PyArrayObject* a = reinterpret_cast<PyArrayObject*>(o);
    if (PyArray_TYPE(a) == type && PyArray_IS_C_CONTIGUOUS(a) && PyArray_ISALIGNED(a)) return a;
  }
  if (o == Py_None || PyUnicode_Check(o) || PyBytes_Check(o) || PyDict_Check(o) || PyAnySet_Check(o)) {
    fail(PyExc_TypeError, std::string(name) + ": expected a real numeric array, got " + type_name(o));
    return nullptr;
  }
  PyObject* any = PyArray_FromAny(o, nullptr, 0, 0, 0, nullptr);
  if (!any) {
    PyObject *t, *v, *tb;
    PyErr_Fetch(&t, &v, &tb);
    PyObject* s = v ? PyObject_Str(v) : nullptr;
    std::string why = s ? text_of(s) : "not convertible";
    Py_XDECREF(s), Py_XDECREF(t), Py_XDECREF(v), Py_XDECREF(tb);
    fail(PyExc_TypeError, std::string(name) + ": expected a real numeric array (" + why + ")");
    return nullptr;
  }
  refs.keep(any);
  PyArrayObject* a = reinterpret_cast<PyArrayObject*>(any);
  const int t = PyArray_TYPE(a);
  if (t == NPY_BOOL || !(PyTypeNum_ISFLOAT(t) || PyTypeNum_ISINTEGER(t))) {
    PyObject* d = PyObject_Str(reinterpret_cast<PyObject*>(PyArray_DESCR(a)));
    std::string dn = text_of(d);
    Py_XDECREF(d);
    fail(PyExc_TypeError, std::string(name) + ": expected a real numeric array (float or int), got dtype " + dn);
    return nullptr;
  }
  if (type == NPY_FLOAT && t != NPY_FLOAT) {  // float64 values first: rounded once they are checked
    PyObject* w = PyArray_FromAny(any, PyArray_DescrFromType(NPY_DOUBLE), 0, 0, NPY_ARRAY_CARRAY, nullptr);
    if (!w) return nullptr;
    *wide = reinterpret_cast<PyArrayObject*>(refs.keep(w));
    return *wide;
  }
  PyObject* c = PyArray_FromAny(any, PyArray_DescrFromType(type), 0, 0, NPY_ARRAY_CARRAY | NPY_ARRAY_FORCECAST,
                                nullptr);
  if (!c) return nullptr;
  refs.keep(c);
  return reinterpret_cast<PyArrayObject*>(c);
}

// a real number (not a bool): false with a TypeError / ValueError naming it
bool as_real(PyObject* o, const char* name, double& x) {
  if (PyFloat_CheckExact(o)) {
    x = PyFloat_AS_DOUBLE(o);
  } else if (PyBool_Check(o) || PyArray_IsScalar(o, Bool) ||
             !(PyFloat_Check(o) || PyLong_Check(o) || PyArray_IsScalar(o, Floating) || PyArray_IsScalar(o, Integer))) {
    fail(PyExc_TypeError, std::string(name) + ": expected a real number, got " + type_name(o));
    return false;
  } else {
    x = PyFloat_AsDouble(o);
    if (x == -1.0 && PyErr_Occurred()) return false;
  }
  if (!std::isfinite(x)) {
    fail(PyExc_ValueError,
         std::string(name) + ": expected a finite number, got " + (std::isnan(x) ? "nan" : x > 0 ? "inf" : "-inf"));
    return false;
  }
  return true;
}

// a name of `choices` (null-terminated): its index, or -1 with a ValueError in check_choice's words
int as_choice(PyObject* o, const char* name, const char* const* choices) {
  if (PyUnicode_Check(o)) {
    const char* s = PyUnicode_AsUTF8(o);
    for (int k = 0; s && choices[k]; ++k)
      if (std::strcmp(s, choices[k]) == 0) return k;
  }
  std::string list;
  for (int k = 0; choices[k]; ++k) list += std::string(k ? ", " : "") + "'" + choices[k] + "'";
  PyObject* r = PyObject_Repr(o);
  std::string got = text_of(r);
  Py_XDECREF(r);
  fail(PyExc_ValueError, std::string(name) + ": expected one of " + list + ", got " + got);
  return -1;
}

// a parameter of the spec into the call; false with an exception set
bool parse_param(const rbd::Model& m, const ops::ArgSpec& a, PyObject* o, int k, ops::OpCall& c, double bound,
                 std::vector<int>& ee) {
  switch (a.kind) {
    case ops::kEndEffectors: {  // None (the leaf bodies), a joint name, or a list of them
      try {
        if (o == Py_None) {
          if (m.nb() == 0) throw std::invalid_argument("the model has no joints (nq = 0), so it has no end effector");
          ee = rbd::leaf_bodies(m);
        } else {
          std::vector<std::string> names;
          if (PyUnicode_Check(o)) {
            names.emplace_back();
            if (!utf8_of(o, a.name, names.back())) return false;
          } else if (PyList_Check(o) || PyTuple_Check(o)) {
            for (Py_ssize_t j = 0; j < PySequence_Fast_GET_SIZE(o); ++j) {
              PyObject* n = PySequence_Fast_GET_ITEM(o, j);
              if (!PyUnicode_Check(n)) {
                fail(PyExc_TypeError, std::string(a.name) + ": expected joint names (str), got an entry of type " +
                                          type_name(n));
                return false;
              }
              names.emplace_back();
              if (!utf8_of(n, a.name, names.back())) return false;
            }
          } else {
            fail(PyExc_TypeError, std::string(a.name) + ": expected a list of joint names (str), got " + type_name(o));
            return false;
          }
          ee = rbd::end_effector_bodies(m, names);
        }
      } catch (const std::exception& e) {
        std::string msg = e.what();  // end_effector_bodies names the argument ee_joint_names
        const std::string own = "ee_joint_names: ";
        if (msg.rfind(own, 0) == 0) msg = msg.substr(own.size());
        fail(PyExc_ValueError, std::string(a.name) + ": " + msg);
        return false;
      }
      c.ee = ee.data();
      c.n_ee = static_cast<int>(ee.size());
      return true;
    }
    case ops::kFrame:
    case ops::kEndEffector: {
      if (a.kind == ops::kEndEffector && o == Py_None) {
        c.choice[k] = -1;  // the first leaf body
        return true;
      }
      if (!PyUnicode_Check(o)) {
        fail(PyExc_TypeError, std::string(a.name) + (a.kind == ops::kFrame ? ": expected a frame name (str), got "
                                                                           : ": expected a joint name (str), got ") +
                                  type_name(o));
        return false;
      }
      std::string name;
      if (!utf8_of(o, a.name, name)) return false;
      try {
        if (a.kind == ops::kFrame) {
          c.choice[k] = m.frame_index(name);
        } else {
          c.choice[k] = rbd::end_effector_bodies(m, {name}).front();
        }
      } catch (const std::exception& e) {
        // end_effector_bodies names its own argument (ee_joint_names): this one's name instead
        std::string msg = e.what();
        const std::string own = "ee_joint_names: ";
        if (msg.rfind(own, 0) == 0) msg = msg.substr(own.size());
        fail(PyExc_ValueError, std::string(a.name) + ": " + msg);
        return false;
      }
      return true;
    }
    case ops::kReal:
      if (!as_real(o, a.name, c.real[k])) return false;
      if (std::fabs(c.real[k]) > bound) {
        char buf[200];
        std::snprintf(buf, sizeof buf, "%s: expected a magnitude of at most %g (larger ones overflow), got %g", a.name,
                      bound, c.real[k]);
        fail(PyExc_ValueError, buf);
        return false;
      }
      return true;
    case ops::kPositive: return as_real(o, a.name, c.real[k]);  // positive: ops::check_call
    case ops::kTimeStep:
      if (!as_real(o, a.name, c.real[k])) return false;
      if (!(c.real[k] > 0 && c.real[k] <= rbd::kMaxTimeStep)) {
        char buf[160];
        std::snprintf(buf, sizeof buf, "%s: expected a positive time step of at most %g s, got %g", a.name,
                      rbd::kMaxTimeStep, c.real[k]);
        fail(PyExc_ValueError, buf);
        return false;
      }
      return true;
    case ops::kFlag:
      if (!(PyBool_Check(o) || PyArray_IsScalar(o, Bool))) {
        fail(PyExc_TypeError, std::string(a.name) + ": expected a bool, got " + type_name(o));
        return false;
      }
      c.choice[k] = PyObject_IsTrue(o);
      return true;
    case ops::kChoice: return (c.choice[k] = as_choice(o, a.name, a.choices)) >= 0;
    case ops::kIntegrator:
    case ops::kConvention: {
      if (!PyUnicode_Check(o)) {
        fail(PyExc_TypeError, std::string(a.name) + ": expected a string" +
                                  (a.kind == ops::kConvention ? " ('pinocchio' or 'mujoco')" : "") + ", got " +
                                  type_name(o));
        return false;
      }
      std::string s;
      if (!utf8_of(o, a.name, s)) return false;
      try {
        c.choice[k] = a.kind == ops::kIntegrator ? rbd::integrator_from_name(s) : rbd::convention_from_name(s);
      } catch (const std::exception& e) {
        fail(PyExc_ValueError, e.what());
        return false;
      }
      return true;
    }
    default: return true;
  }
}

// the default of a parameter into the call (an output convention: the handle's)
void default_param(const ops::ArgSpec& a, int k, ops::OpCall& c, int convention) {
  if (a.kind == ops::kReal || a.kind == ops::kTimeStep || a.kind == ops::kPositive) c.real[k] = a.value;
  else if (a.kind == ops::kConvention) c.choice[k] = convention;
  else c.choice[k] = static_cast<int>(a.value);
}

bool is_array(const ops::ArgSpec& a) { return a.kind == ops::kArray || a.kind == ops::kOptionalArray; }

// ---------------------------------------------------------------- device arrays (a backend='cuda' handle)

// an array in device memory, described by its __cuda_array_interface__ (CuPy, PyTorch, Numba; in
// interpret mode a NumPy stand-in whose "device" memory is host memory)
struct DeviceArray {
  void* data = nullptr;
  int nd = 0;
  npy_intp dims[ops::kMaxRank + 1] = {};
  unsigned long stream = 0;  // the interface's stream (v3): its producer's work must finish first; 0: none
};

// PyTorch's tensors, read directly: a tensor's __cuda_array_interface__ is a Python property that
// builds a dict (2 µs on the H200 machine's host, 4 on a 2 GHz core), and a call read it twice per
// array, most of a B = 1 call's time outside its kernel (docs/gpu.md, third session). A torch.Tensor
// (the class itself, not a subclass) on a GPU is read through its own attributes (is_cuda,
// requires_grad, dtype, shape, is_contiguous(), data_ptr()), and its outputs made by torch.empty; one
// of another dtype or rank, or a strided one, goes through the interface, whose checks name the
// failure; one that requires grad is refused by name. torch is never imported here: only a process
// that imported it can pass its tensors.
struct TorchApi {
  PyObject* tensor = nullptr;  // the type torch.Tensor
  PyObject *f32 = nullptr, *f64 = nullptr, *empty = nullptr;
  PyObject* empty_keywords = nullptr;  // ("dtype", "device")
  PyObject *is_cuda = nullptr, *requires_grad = nullptr, *dtype = nullptr, *shape = nullptr,
           *is_contiguous = nullptr, *data_ptr = nullptr, *device = nullptr;
};

// the attributes above once torch is imported; null before (or if torch lacks one of them)
const TorchApi* torch_api() {
  static TorchApi api;
  static bool failed = false;
  if (api.tensor) return &api;
  if (failed) return nullptr;
  PyObject* torch = PyDict_GetItemString(PyImport_GetModuleDict(), "torch");  // (borrowed)
  if (!torch) return nullptr;
  TorchApi t;
  t.tensor = PyObject_GetAttrString(torch, "Tensor");
  t.f32 = PyObject_GetAttrString(torch, "float32");
  t.f64 = PyObject_GetAttrString(torch, "float64");
  t.empty = PyObject_GetAttrString(torch, "empty");
  if (!t.tensor || !PyType_Check(t.tensor) || !t.f32 || !t.f64 || !t.empty) {
    PyErr_Clear();  // (a torch without them, or one still importing: the interface, always)
    failed = true;
    return nullptr;
  }
  t.is_cuda = PyUnicode_InternFromString("is_cuda"), t.requires_grad = PyUnicode_InternFromString("requires_grad");
  t.dtype = PyUnicode_InternFromString("dtype"), t.shape = PyUnicode_InternFromString("shape");
  t.is_contiguous = PyUnicode_InternFromString("is_contiguous"), t.data_ptr = PyUnicode_InternFromString("data_ptr");
  t.device = PyUnicode_InternFromString("device");
  t.empty_keywords = PyTuple_Pack(2, t.dtype, t.device);
  if (!t.empty_keywords) {
    PyErr_Clear();
    failed = true;
    return nullptr;
  }
  api = t;
  return &api;
}

// o's boolean attribute: 1, 0, or -1 with an exception set
int attr_true(PyObject* o, PyObject* name) {
  PyObject* v = PyObject_GetAttr(o, name);
  if (!v) return -1;
  const int r = PyObject_IsTrue(v);
  Py_DECREF(v);
  return r;
}

// o as a torch.Tensor: 0 another object (a subclass too), 1 a tensor in host memory, 2 one on a GPU,
// -1 an error set
int torch_tensor_kind(PyObject* o) {
  const TorchApi* t = torch_api();
  if (!t || reinterpret_cast<PyObject*>(Py_TYPE(o)) != t->tensor) return 0;
  const int cuda = attr_true(o, t->is_cuda);
  return cuda < 0 ? -1 : 1 + cuda;
}

bool has_device_interface(PyObject* o) {
  if (PyArray_Check(o)) return false;
  const int kind = torch_tensor_kind(o);
  if (kind > 0) return kind == 2;
  if (kind < 0) PyErr_Clear();  // (as hasattr would see it, below)
  return PyObject_HasAttrString(o, "__cuda_array_interface__");
}

// a CUDA tensor of the handle's dtype, C-contiguous, of rank <= max_nd, into out: 1; 0: another
// object or one that fails a check (the interface's path then names the failure); -1: an error set
// (a tensor that requires grad, named)
int torch_device_array(PyObject* o, const char* name, int type, int max_nd, DeviceArray& out) {
  const int kind = torch_tensor_kind(o);
  if (kind != 2) return kind < 0 ? -1 : 0;
  const TorchApi* t = torch_api();
  const int grad = attr_true(o, t->requires_grad);
  if (grad != 0) {
    if (grad > 0)
      fail(PyExc_TypeError, std::string(name) + ": a tensor that requires grad (a Handle records no gradients): "
                                                "pass it detach()ed, or call rbdkit.torch, whose operations do");
    return -1;
  }
  PyObject* dtype = PyObject_GetAttr(o, t->dtype);
  if (!dtype) return -1;
  Py_DECREF(dtype);  // (compared by identity: torch's dtypes are singletons)
  if (dtype != (type == NPY_FLOAT ? t->f32 : t->f64)) return 0;
  PyObject* shape = PyObject_GetAttr(o, t->shape);
  if (!shape) return -1;
  const bool shape_ok = PyTuple_Check(shape) && PyTuple_GET_SIZE(shape) <= max_nd;
  if (shape_ok) {
    out.nd = static_cast<int>(PyTuple_GET_SIZE(shape));
    for (int j = 0; j < out.nd; ++j) out.dims[j] = PyLong_AsSsize_t(PyTuple_GET_ITEM(shape, j));
  }
  Py_DECREF(shape);
  if (PyErr_Occurred()) return -1;
  if (!shape_ok) return 0;
  PyObject* contiguous = PyObject_CallMethodNoArgs(o, t->is_contiguous);
  if (!contiguous) return -1;
  const int c = PyObject_IsTrue(contiguous);
  Py_DECREF(contiguous);
  if (c != 1) return c;
  PyObject* ptr = PyObject_CallMethodNoArgs(o, t->data_ptr);
  if (!ptr) return -1;
  out.data = PyLong_AsVoidPtr(ptr);
  Py_DECREF(ptr);
  out.stream = 0;  // (as its interface, version 2: no stream to wait for; Handle.set_stream names one)
  return PyErr_Occurred() ? -1 : 1;
}

// o's __cuda_array_interface__: C-contiguous, of the handle's dtype (typestr '<f8' / '<f4'), rank <= max_nd;
// false with a TypeError / ValueError naming the argument
bool as_device_array(PyObject* o, const char* name, int type, int max_nd, DeviceArray& out) {
  const int fast = torch_device_array(o, name, type, max_nd, out);
  if (fast != 0) return fast == 1;
  PyObject* cai = PyObject_GetAttrString(o, "__cuda_array_interface__");
  if (!cai) return false;
  // false with an exception naming the argument (cai released)
  auto bad = [&](PyObject* exc, const std::string& why) {
    Py_DECREF(cai);
    fail(exc, std::string(name) + ": " + why);
    return false;
  };
  if (!PyDict_Check(cai)) return bad(PyExc_TypeError, "__cuda_array_interface__ is not a dict");
  PyObject* shape = PyDict_GetItemString(cai, "shape");
  PyObject* typestr = PyDict_GetItemString(cai, "typestr");
  PyObject* data = PyDict_GetItemString(cai, "data");
  PyObject* strides = PyDict_GetItemString(cai, "strides");
  if (!shape || !PyTuple_Check(shape) || !typestr || !PyUnicode_Check(typestr) || !data || !PyTuple_Check(data) ||
      PyTuple_GET_SIZE(data) < 1)
    return bad(PyExc_TypeError, "a malformed __cuda_array_interface__ (expected shape, typestr and data)");
  const char* want = type == NPY_FLOAT ? "<f4" : "<f8";
  const std::string got = text_of(typestr);
  if (got != want)
    return bad(PyExc_TypeError, std::string("expected a device array of dtype ") +
                                    (type == NPY_FLOAT ? "float32" : "float64") + " (typestr '" + want +
                                    "', the handle's; device arrays are not converted), got typestr '" + got + "'");
  out.nd = static_cast<int>(PyTuple_GET_SIZE(shape));
  if (out.nd > max_nd)
    return bad(PyExc_ValueError, "a device array of rank " + std::to_string(out.nd) + " (expected at most " +
                                     std::to_string(max_nd) + ")");
  for (int j = 0; j < out.nd; ++j) out.dims[j] = PyLong_AsSsize_t(PyTuple_GET_ITEM(shape, j));
  if (PyErr_Occurred()) {
    Py_DECREF(cai);
    return false;
  }
  if (strides && strides != Py_None) {  // C-contiguous strides are allowed, others are not
    npy_intp expect = type == NPY_FLOAT ? 4 : 8;
    bool contiguous = PyTuple_Check(strides) && PyTuple_GET_SIZE(strides) == out.nd;
    for (int j = out.nd - 1; contiguous && j >= 0; --j) {
      if (out.dims[j] > 1 && PyLong_AsSsize_t(PyTuple_GET_ITEM(strides, j)) != expect) contiguous = false;
      expect *= out.dims[j];
    }
    if (!contiguous) return bad(PyExc_ValueError, "expected a C-contiguous device array");
  }
  out.data = PyLong_AsVoidPtr(PyTuple_GET_ITEM(data, 0));
  PyObject* stream = PyDict_GetItemString(cai, "stream");
  if (stream && stream != Py_None) out.stream = PyLong_AsUnsignedLong(stream);
  Py_DECREF(cai);
  return !PyErr_Occurred();
}

// a new device array of `shape` and the handle's dtype, on proto's device, by proto's framework
PyObject* device_empty(PyObject* proto, PyObject* shape, int type) {
  const TorchApi* t = torch_api();
  if (t && reinterpret_cast<PyObject*>(Py_TYPE(proto)) == t->tensor) {  // torch.empty(shape, dtype=, device=)
    PyObject* device = PyObject_GetAttr(proto, t->device);
    if (!device) return nullptr;
    PyObject* args[3] = {shape, type == NPY_FLOAT ? t->f32 : t->f64, device};
    PyObject* a = PyObject_Vectorcall(t->empty, args, 1, t->empty_keywords);
    Py_DECREF(device);
    return a;
  }
  static PyObject* fn = nullptr;
  if (!fn) {
    PyObject* mod = PyImport_ImportModule("rbdkit._handle");
    if (!mod) return nullptr;
    fn = PyObject_GetAttrString(mod, "device_empty");
    Py_DECREF(mod);
    if (!fn) return nullptr;
  }
  return PyObject_CallFunction(fn, "OOs", proto, shape, type == NPY_FLOAT ? "float32" : "float64");
}

// a call's arguments into their slots (position or keyword) and its
// parameters (not its arrays) parsed into c; false with an exception set.
// names: the spec's argument names as Python strings (interned)
bool bind_arguments(const OpHandle& h, const ops::OpSpec& op, PyObject* const* names, PyObject* const* args,
                    size_t nargsf, PyObject* kwnames, PyObject** slot, ops::OpCall& c, std::vector<int>& ee) {
  const rbd::Model& m = h.h->model();
  const Py_ssize_t npos = PyVectorcall_NARGS(nargsf);
  if (npos > op.n_args) {
    fail(PyExc_TypeError, std::string(op.name) + "() takes at most " + std::to_string(op.n_args) + " arguments (" +
                              std::to_string(npos) + " given)");
    return false;
  }
  for (Py_ssize_t k = 0; k < npos; ++k) slot[k] = args[k];
  if (kwnames) {
    const Py_ssize_t nkw = PyTuple_GET_SIZE(kwnames);
    for (Py_ssize_t j = 0; j < nkw; ++j) {
      PyObject* key = PyTuple_GET_ITEM(kwnames, j);
      int k = 0;
      while (k < op.n_args && names[k] != key) ++k;
      if (k == op.n_args) {
        k = 0;
        while (k < op.n_args && PyUnicode_Compare(names[k], key) != 0) ++k;
      }
      // GRAVITY: the reference implementation's spelling of gravity
      bool alias = false;
      if (k == op.n_args && PyUnicode_CompareWithASCIIString(key, "GRAVITY") == 0) {
        k = 0;
        while (k < op.n_args && std::strcmp(op.args[k].name, "gravity") != 0) ++k;
        alias = true;
      }
      if (k == op.n_args) {
        PyObject* r = PyObject_Repr(key);
        std::string s = text_of(r);
        Py_XDECREF(r);
        fail(PyExc_TypeError, std::string(op.name) + "() got an unexpected keyword argument " + s);
        return false;
      }
      if (slot[k]) {
        // gravity given twice under both names (by position or keyword, in either order)
        bool both = alias;
        for (Py_ssize_t i = 0; i < j && !both; ++i)
          both = PyUnicode_CompareWithASCIIString(PyTuple_GET_ITEM(kwnames, i), "GRAVITY") == 0;
        if (both) {
          fail(PyExc_TypeError, std::string(op.name) + "() got both gravity and GRAVITY (its alias); pass one");
          return false;
        }
        fail(PyExc_TypeError, std::string(op.name) + "() got multiple values for argument '" + op.args[k].name + "'");
        return false;
      }
      slot[k] = args[npos + j];
    }
  }
  // parameters (cheap checks first; the arrays are the caller's)
  for (int k = 0; k < op.n_args; ++k) {
    const ops::ArgSpec& a = op.args[k];
    if (is_array(a)) continue;
    if (!slot[k] && a.kind == ops::kEndEffectors) {
      if (!parse_param(m, a, Py_None, k, c, 0, ee)) return false;
    } else if (!slot[k]) {
      if (std::isnan(a.value)) {
        fail(PyExc_TypeError, std::string(op.name) + "() missing required argument '" + a.name + "'");
        return false;
      }
      default_param(a, k, c, h.h->output_convention());
    } else if (!parse_param(m, a, slot[k], k, c, h.npy_type == NPY_FLOAT ? rbd::kMaxInputF32 : rbd::kMaxInput, ee)) {
      return false;
    }
  }
  return true;
}

PyObject* op_call(PyObject* self_, PyObject* const* args, size_t nargsf, PyObject* kwnames) {
  OpFn* self = reinterpret_cast<OpFn*>(self_);
  const ops::OpSpec& op = *self->spec;
  const rbd::Model& m = self->handle->h->model();
  const int type = self->handle->npy_type;

  // ---- the arguments by position and keyword, the parameters parsed
  PyObject* slot[ops::kMaxArgs] = {};
  ops::OpCall c;
  std::vector<int> ee;  // the end effectors' bodies (a kEndEffectors argument)
  if (!bind_arguments(*self->handle, op, self->names, args, nargsf, kwnames, slot, c, ee)) return nullptr;

  // ---- the arrays: dtype, shape, batch axis
  Refs refs;
  long B = -1;
  int source = -1;
  // device arrays (all of a call's arrays, or none): the first one given, whose framework allocates the outputs
  bool device = false;
  PyObject* device_proto = nullptr;
  int first_array = -1;
  unsigned long producers[ops::kMaxArgs] = {};  // the device inputs' streams
  int n_producers = 0;
  for (int k = 0; k < op.n_args; ++k) {
    const ops::ArgSpec& a = op.args[k];
    if (!is_array(a)) continue;
    PyObject* o = slot[k];
    if (!o) {
      if (a.kind == ops::kArray)
        return fail(PyExc_TypeError, std::string(op.name) + "() missing required argument '" + a.name + "'");
      continue;
    }
    if (a.kind == ops::kOptionalArray && (o == Py_None || ((PyList_Check(o) || PyTuple_Check(o)) && PySequence_Size(o) == 0)))
      continue;
    PyArrayObject* wide = nullptr;
    PyArrayObject* arr = nullptr;
    DeviceArray dev;
    const bool on_device = self->handle->h->cuda() && has_device_interface(o);
    if (first_array >= 0 && on_device != device)
      return fail(PyExc_TypeError, std::string(a.name) + ": expected " + (device ? "a device" : "a host") +
                                       " array like " + op.args[first_array].name +
                                       " (a call takes host arrays or device arrays, not both)");
    if (first_array < 0) first_array = k;
    device = on_device;
    if (device) {
      if (!device_proto) device_proto = o;
      if (!as_device_array(o, a.name, type, a.shape.rank + 1, dev)) return nullptr;
      if (dev.stream) producers[n_producers++] = dev.stream;
    } else {
      arr = as_array(o, a.name, type, refs, &wide);
      if (!arr) return nullptr;
    }
    // (shape) or (B, shape)
    const int r = a.shape.rank, nd = device ? dev.nd : PyArray_NDIM(arr);
    const npy_intp* d = device ? dev.dims : PyArray_DIMS(arr);
    npy_intp want[ops::kMaxRank];
    for (int j = 0; j < r; ++j) want[j] = ops::extent(a.shape.d[j], m.nq, m.nv, m.nb(), c.n_ee);
    bool batched = false, ok = false;
    if (nd == r || nd == r + 1) {
      const int o0 = nd - r;
      ok = true;
      for (int j = 0; j < r; ++j) ok &= d[o0 + j] == want[j];
      batched = nd == r + 1;
    }
    if (!ok && r > 1 && a.shape.d[0] == ops::kNee && nd == r - 1 && !device) {  // one row for every end effector
      bool tail = true;
      for (int j = 1; j < r; ++j) tail &= d[j - 1] == want[j];
      if (tail) {
        PyObject* rep = PyArray_SimpleNew(r, want, PyArray_TYPE(arr));
        if (!rep) return nullptr;
        refs.keep(rep);
        const size_t row = PyArray_NBYTES(arr);
        char* dst = static_cast<char*>(PyArray_DATA(reinterpret_cast<PyArrayObject*>(rep)));
        for (npy_intp e = 0; e < want[0]; ++e) std::memcpy(dst + e * row, PyArray_DATA(arr), row);
        arr = reinterpret_cast<PyArrayObject*>(rep);
        if (wide) wide = arr;
        ok = true;
      }
    }
    if (!ok && r > 1 && a.shape.d[0] == ops::kNee) {  // one row for all, one per end effector, or a batch of them
      std::string tail;
      for (int j = 1; j < r; ++j) tail += (j > 1 ? ", " : "") + std::to_string(want[j]);
      return fail(PyExc_ValueError, std::string(a.name) + ": expected shape (" + tail + (r == 2 ? ",)" : ")") +
                                        ", (n_ee, " + tail + ") or (B, n_ee, " + tail + ") with n_ee=" +
                                        std::to_string(want[0]) + ", got shape " + tuple_str(d, nd));
    }
    if (!ok) {
      std::string desc;
      for (int j = 0; j < r; ++j)
        desc += (j ? ", " : "") + dim_name(a.shape.d[j]) + "=" + std::to_string(want[j]);
      std::string wb = "(B, ";
      for (int j = 0; j < r; ++j) wb += (j ? ", " : "") + std::to_string(want[j]);
      return fail(PyExc_ValueError, std::string(a.name) + ": expected shape " + tuple_str(want, r) + " or " + wb +
                                        ") with " + desc + ", got shape " + tuple_str(d, nd));
    }
    if (batched) {
      if (d[0] == 0)
        return fail(PyExc_ValueError, std::string(a.name) + ": the batch is empty (shape " + tuple_str(d, nd) + ")");
      if (B >= 0 && d[0] != B)
        return fail(PyExc_ValueError, std::string(a.name) + ": batch size " + std::to_string(d[0]) +
                                          " does not match " + op.args[source].name + "'s batch size " +
                                          std::to_string(B));
      B = d[0], source = k;
    }
    // float64 values bound for float32: within float32's bounds, then rounded (bounds may be
    // infinite: ops::check_call checks those after rounding, a finite one here)
    if (wide) {
      try {
        const long n = ops::arg_values(a, m, c.n_ee);
        ops::check_bounded(static_cast<const double*>(PyArray_DATA(wide)), batched ? d[0] : 1, n, a.name, batched,
                           rbd::kMaxInputF32, a.check == ops::kLowerBound || a.check == ops::kUpperBound);
      } catch (const std::exception& e) {
        return fail(PyExc_ValueError, e.what());
      }
    }
    if (wide) {
      PyObject* c = PyArray_FromAny(reinterpret_cast<PyObject*>(wide), PyArray_DescrFromType(NPY_FLOAT), 0, 0,
                                    NPY_ARRAY_CARRAY | NPY_ARRAY_FORCECAST, nullptr);
      if (!c) return nullptr;
      arr = reinterpret_cast<PyArrayObject*>(refs.keep(c));
    }
    c.in[k] = device ? dev.data : PyArray_DATA(arr);
    c.batched[k] = batched;
  }
  c.B = B < 0 ? 1 : B;

  // ---- outputs: (shape) for an unbatched call, (B, shape) otherwise; the
  // ones not returned are not computed (null) unless the kernel writes them anyway
  PyObject* outs[ops::kMaxOutputs] = {};
  int nret = 0;
  for (int o = 0; o < op.n_out; ++o) {
    if (!(self->returns >> o & 1u)) continue;
    npy_intp dims[ops::kMaxRank + 1];
    int nd = 0;
    if (B >= 0) dims[nd++] = B;
    for (int j = 0; j < op.out[o].shape.rank; ++j) dims[nd++] = ops::extent(op.out[o].shape.d[j], m.nq, m.nv, m.nb(), c.n_ee);
    if (device) {  // on the inputs' device, by their framework (rbdkit._handle.device_empty)
      PyObject* shape = PyTuple_New(nd);
      if (!shape) return nullptr;
      for (int j = 0; j < nd; ++j) PyTuple_SET_ITEM(shape, j, PyLong_FromSsize_t(dims[j]));
      PyObject* a = device_empty(device_proto, shape, type);
      Py_DECREF(shape);
      if (!a) return nullptr;
      outs[o] = refs.keep(a);
      DeviceArray da;
      if (!as_device_array(a, op.out[o].name, type, nd, da)) return nullptr;
      c.out[o] = da.data;
      ++nret;
      continue;
    }
    PyObject* a = PyArray_SimpleNew(nd, dims, type);
    if (!a) return nullptr;
    outs[o] = refs.keep(a);
    c.out[o] = PyArray_DATA(reinterpret_cast<PyArrayObject*>(a));
    ++nret;
  }

  // ---- run (the GIL released for a batch)
  PyObject* err_type = nullptr;
  std::string msg;
  PyThreadState* ts = c.B > 1 ? PyEval_SaveThread() : nullptr;
  try {
    if (device) {
      for (int j = 0; j < n_producers; ++j) self->handle->h->cuda()->wait_for_stream(producers[j]);
      self->handle->h->run_device(self->op, c);
    } else {
      self->handle->h->run(self->op, c);
    }
  } catch (const std::invalid_argument& e) {
    err_type = PyExc_ValueError, msg = e.what();
  } catch (const std::bad_alloc&) {
    err_type = PyExc_MemoryError, msg = std::string(op.name) + ": out of memory";
  } catch (const std::exception& e) {
    err_type = PyExc_RuntimeError, msg = e.what();
  }
  if (ts) PyEval_RestoreThread(ts);
  if (err_type) return fail(err_type, msg);

  // ---- results: one array, or a tuple in output order; a 0-d one (a
  // scalar output of an unbatched call) as a NumPy scalar
  auto result = [device](PyObject* a) {
    Py_INCREF(a);
    if (device) return a;
    return PyArray_NDIM(reinterpret_cast<PyArrayObject*>(a)) == 0 ? PyArray_Return(reinterpret_cast<PyArrayObject*>(a))
                                                                  : a;
  };
  if (nret == 1) {
    for (int o = 0; o < op.n_out; ++o)
      if (outs[o]) return result(outs[o]);
  }
  PyObject* t = PyTuple_New(nret);
  if (!t) return nullptr;
  for (int o = 0, j = 0; o < op.n_out; ++o)
    if (outs[o]) PyTuple_SET_ITEM(t, j++, result(outs[o]));
  return t;
}

void op_dealloc(PyObject* self_) {
  OpFn* self = reinterpret_cast<OpFn*>(self_);
  PyObject_GC_UnTrack(self_);
  Py_CLEAR(self->owner);
  for (PyObject*& n : self->names) Py_CLEAR(n);
  PyObject_GC_Del(self_);
}

int op_traverse(PyObject* self_, visitproc visit, void* arg) {
  Py_VISIT(reinterpret_cast<OpFn*>(self_)->owner);
  return 0;
}

int op_clear(PyObject* self_) {
  Py_CLEAR(reinterpret_cast<OpFn*>(self_)->owner);
  return 0;
}

// the signature line and the spec's doc
std::string signature_doc(const ops::OpSpec& op) {
  std::string s = std::string(op.name) + "(";
  for (int k = 0; k < op.n_args; ++k) {
    const ops::ArgSpec& a = op.args[k];
    s += (k ? ", " : "") + std::string(a.name);
    if (a.kind == ops::kOptionalArray) s += "=None";
    else if ((a.kind == ops::kReal || a.kind == ops::kPositive) && !std::isnan(a.value)) s += std::string("=") + nb::str(nb::float_(a.value)).c_str();
    else if (a.kind == ops::kFlag) s += a.value != 0 ? "=True" : "=False";
    else if (a.kind == ops::kChoice) s += std::string("='") + a.choices[static_cast<int>(a.value)] + "'";
    else if (a.kind == ops::kIntegrator) s += "='euler'";
    else if (a.kind == ops::kConvention) s += "='pinocchio'";
    else if (a.kind == ops::kEndEffector || a.kind == ops::kEndEffectors) s += "=None";
  }
  return s + ")\n\n" + op.doc;
}

PyObject* op_get_doc(PyObject* self_, void*) {
  return PyUnicode_FromString(signature_doc(*reinterpret_cast<OpFn*>(self_)->spec).c_str());
}
PyObject* op_get_name(PyObject* self_, void*) { return PyUnicode_FromString(reinterpret_cast<OpFn*>(self_)->spec->name); }
PyObject* op_repr(PyObject* self_) {
  return PyUnicode_FromFormat("<rbdkit operation %s>", reinterpret_cast<OpFn*>(self_)->spec->name);
}

PyGetSetDef op_getset[] = {
    {"__doc__", op_get_doc, nullptr, nullptr, nullptr},
    {"__name__", op_get_name, nullptr, nullptr, nullptr},
    {"__qualname__", op_get_name, nullptr, nullptr, nullptr},
    {nullptr, nullptr, nullptr, nullptr, nullptr},
};

PyTypeObject* op_type() {
  static PyTypeObject* t = [] {
    static PyType_Slot slots[] = {
        {Py_tp_dealloc, reinterpret_cast<void*>(op_dealloc)},
        {Py_tp_traverse, reinterpret_cast<void*>(op_traverse)},
        {Py_tp_clear, reinterpret_cast<void*>(op_clear)},
        {Py_tp_call, reinterpret_cast<void*>(PyVectorcall_Call)},
        {Py_tp_getset, op_getset},
        {Py_tp_repr, reinterpret_cast<void*>(op_repr)},
        {0, nullptr},
    };
    static PyMemberDef members[] = {
        {"__vectorcalloffset__", T_PYSSIZET, static_cast<Py_ssize_t>(offsetof(OpFn, vectorcall)), READONLY, nullptr},
        {nullptr, 0, 0, 0, nullptr},
    };
    static PyType_Slot all[8];
    int n = 0;
    for (; slots[n].slot; ++n) all[n] = slots[n];
    all[n++] = {Py_tp_members, members};
    all[n] = {0, nullptr};
    static PyType_Spec spec = {"rbdkit._core.Operation", sizeof(OpFn), 0,
                               Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC | Py_TPFLAGS_HAVE_VECTORCALL, all};
    return reinterpret_cast<PyTypeObject*>(PyType_FromSpec(&spec));
  }();
  return t;
}

}  // namespace

void bind_ops(nb::module_& m) {
  if (_import_array() < 0) throw nb::python_error();
  if (!op_type()) throw nb::python_error();

  // [(name, algorithm, family, doc, [(argument, kind, default)])] in registry
  // order; kind: array, optional, real, dt, flag, choice, integrator, positive, frame, joint, joints,
  // convention; default: None where there is none (a required parameter)
  m.def("registered_operations", [] {
    static const char* kinds[] = {"array", "optional", "real", "dt", "flag", "choice", "integrator", "convention",
                                  "positive", "frame", "joint", "joints"};
    nb::list out;
    for (const ops::OpEntry& e : ops::op_table()) {
      const ops::OpSpec& op = *e.spec;
      nb::list args;
      for (int k = 0; k < op.n_args; ++k) {
        const ops::ArgSpec& a = op.args[k];
        nb::object def = nb::none();
        if ((a.kind == ops::kReal || a.kind == ops::kPositive) && !std::isnan(a.value)) def = nb::float_(a.value);
        else if (a.kind == ops::kFlag) def = nb::bool_(a.value != 0);
        else if (a.kind == ops::kChoice) def = nb::str(a.choices[static_cast<int>(a.value)]);
        else if (a.kind == ops::kIntegrator) def = nb::str("euler");
        else if (a.kind == ops::kConvention) def = nb::str("pinocchio");
        args.append(nb::make_tuple(a.name, kinds[a.kind], def));
      }
      out.append(nb::make_tuple(op.name, op.algorithm, op.family, signature_doc(op), args));
    }
    return out;
  });

  // (whether this build has the real CUDA kernels, the CUDA devices this process sees)
  m.def("cuda_info", [] { return nb::make_tuple(rbd::CudaEngine::cuda_compiled(), rbd::CudaEngine::device_count()); });

  nb::class_<OpHandle>(m, "OpHandle")
      .def(
          "__init__",
          [](OpHandle* self, const rbd::Model& model, const std::vector<std::string>& algorithms, int threads,
             const std::string& dtype, const std::string& output_convention, const std::string& backend) {
            const rbd::Backend b = rbd::backend_from_name(backend);
            auto h = b == rbd::Backend::CUDA
                         ? std::make_unique<rbd::Handle>(model, algorithms, b, dtype, output_convention, threads)
                         : std::make_unique<rbd::Handle>(model, algorithms, threads, dtype, output_convention);
            new (self) OpHandle{std::move(h), dtype == "float32" ? NPY_FLOAT : NPY_DOUBLE};
          },
          "model"_a, "algorithms"_a, "threads"_a, "dtype"_a, "output_convention"_a = "pinocchio",
          "backend"_a = "cpu")
      .def_prop_ro("threads", [](const OpHandle& h) { return h.h->threads(); })
      // the CUDA engine's device ("interpret (CPU)" in interpret mode); None on the CPU backend
      .def_prop_ro("device", [](const OpHandle& h) -> nb::object {
        if (!h.h->cuda()) return nb::none();
        return nb::str(h.h->cuda()->device_name().c_str());
      })
      // the stream a backend='cuda' handle launches on: a cudaStream_t as an int (0: the default
      // stream), or None: a stream of its own
      .def("set_stream", [](OpHandle& h, std::optional<uintptr_t> stream) {
        if (!h.h->cuda()) throw nb::value_error("stream: a stream needs a handle with backend='cuda'");
        if (stream) h.h->cuda()->set_stream(reinterpret_cast<void*>(*stream));
        else h.h->cuda()->use_own_stream();
      }, "stream"_a.none())
      .def_prop_ro("dtype", [](const OpHandle& h) { return h.h->dtype(); })
      // the compiled per-robot instance (Handle::specialize): (in use, why not / its library)
      .def("specialize",
           [](OpHandle& h, const std::string& cache_dir, const std::string& compiler, const std::string& include_dir) {
             rbd::SpecializeOptions o;
             o.cache_dir = cache_dir, o.compiler = compiler, o.include_dir = include_dir;
             bool ok;
             {
               nb::gil_scoped_release nogil;  // a first compilation takes seconds
               ok = h.h->specialize(o);
             }
             return std::make_pair(ok, ok ? h.h->instance_library() : h.h->specialize_error());
           }, "cache_dir"_a, "compiler"_a, "include_dir"_a)
      .def_prop_ro("specialized", [](const OpHandle& h) { return h.h->specialized(); })
      .def("has", [](const OpHandle& h, const std::string& name) { return h.h->has(name); }, "name"_a)
      // the registered operations this handle runs, in registry order
      .def("operations",
           [](const OpHandle& h) {
             std::vector<std::string> out;
             for (const ops::OpEntry& e : ops::op_table())
               if (h.h->has_op(e.id)) out.push_back(e.spec->name);
             return out;
           })
      // the address of the C++ rbd::Handle (the XLA FFI call's `handle` attribute: rbdkit.jax)
      .def_prop_ro("address", [](const OpHandle& h) { return reinterpret_cast<uintptr_t>(h.h.get()); })
      // a call of `name` laid out for a framework that passes the arrays itself (rbdkit.jax): the
      // arguments bound and the parameters parsed as a call of the operation does (same errors);
      // returns (op id, [(k, array argument, per-sample shape)], reals, choices, end-effector bodies,
      // [(o, per-sample output shape)] of rbdkit.Handle's results, or of the outputs of mask `outputs`)
      .def("plan", [](const OpHandle& h, const std::string& name, nb::tuple args, nb::dict kwargs, int outputs) {
        const int id = ops::find_op(name);
        if (id < 0 || !h.h->has_op(id)) throw nb::value_error((name + ": not an operation of this handle").c_str());
        const ops::OpSpec& op = *ops::op_table()[id].spec;
        const rbd::Model& m = h.h->model();
        std::vector<PyObject*> av;
        for (nb::handle a : args) av.push_back(a.ptr());
        nb::list keys;
        for (auto [k, v] : kwargs) keys.append(k), av.push_back(v.ptr());
        nb::tuple kwnames = nb::tuple(keys);
        nb::object names[ops::kMaxArgs];
        PyObject* name_ptrs[ops::kMaxArgs] = {};
        for (int k = 0; k < op.n_args; ++k) names[k] = nb::str(op.args[k].name), name_ptrs[k] = names[k].ptr();
        PyObject* slot[ops::kMaxArgs] = {};
        ops::OpCall c;
        std::vector<int> ee;
        if (!bind_arguments(h, op, name_ptrs, av.data(), args.size(), keys.size() ? kwnames.ptr() : nullptr, slot, c,
                            ee))
          throw nb::python_error();
        auto shape_of = [&](const ops::Shape& sh) {
          nb::list d;
          for (int j = 0; j < sh.rank; ++j) d.append(ops::extent(sh.d[j], m.nq, m.nv, m.nb(), c.n_ee));
          return nb::tuple(d);
        };
        nb::list arrays, reals, choices, outs;
        for (int k = 0; k < op.n_args; ++k) {
          reals.append(c.real[k]);
          choices.append(c.choice[k]);
          const ops::ArgSpec& a = op.args[k];
          if (!is_array(a)) continue;
          PyObject* o = slot[k];
          if (!o) {
            if (a.kind == ops::kArray)
              throw nb::type_error((std::string(op.name) + "() missing required argument '" + a.name + "'").c_str());
            continue;
          }
          if (a.kind == ops::kOptionalArray && o == Py_None) continue;
          arrays.append(nb::make_tuple(k, nb::borrow(o), shape_of(a.shape)));
        }
        const unsigned returns =
            outputs >= 0 ? static_cast<unsigned>(outputs) : (op.handle_returns ? op.handle_returns : op.returns);
        for (int o = 0; o < op.n_out; ++o)
          if (returns >> o & 1u) outs.append(nb::make_tuple(o, shape_of(op.out[o].shape)));
        return nb::make_tuple(id, arrays, reals, choices, nb::cast(ee), outs);
      }, "name"_a, "args"_a, "kwargs"_a, "outputs"_a = -1)
      // the callable of a registered operation; handle_results: rbdkit.Handle's results, else rbdkit.RBD's
      .def("op", [](nb::handle self, const std::string& name, bool handle_results) {
        OpHandle& h = nb::cast<OpHandle&>(self);
        const int id = ops::find_op(name);
        if (id < 0) throw nb::value_error(("op: '" + name + "' is not a registered operation").c_str());
        const ops::OpSpec& spec = *ops::op_table()[id].spec;
        OpFn* f = PyObject_GC_New(OpFn, op_type());
        if (!f) throw nb::python_error();
        f->vectorcall = op_call;
        f->owner = Py_NewRef(self.ptr());
        f->handle = &h;
        f->op = id;
        f->spec = &spec;
        f->returns = handle_results && spec.handle_returns ? spec.handle_returns : spec.returns;
        for (int k = 0; k < ops::kMaxArgs; ++k)
          f->names[k] = k < spec.n_args ? PyUnicode_InternFromString(spec.args[k].name) : nullptr;
        PyObject_GC_Track(f);
        return nb::steal(reinterpret_cast<PyObject*>(f));
      }, "name"_a, "handle_results"_a);
}
