// rbdkit._core — the nanobind extension under the rbdkit Python package.
//
// Thin: the Python layer (python/rbdkit/) checks shapes and dtypes and
// allocates outputs; these functions take C-contiguous float64 arrays with
// the batch on axis 0, check values (finite, unit quaternions) in C++ and
// run the batched loops with the GIL released.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "arrays.hpp"
#include "rbdkit/batch/dynamics.hpp"
#include "rbdkit/codegen/generate.hpp"

namespace nb = nanobind;
using namespace nb::literals;

using rbd::Model;
using rbd_py::In;
using rbd_py::Out;
using rbd_py::batch_of;
using rbd_py::opt;
using rbd_py::width;

void bind_kinematics(nb::module_& m);  // bind_kinematics.cpp
void bind_handle(nb::module_& m);  // bind_handle.cpp
void bind_solver(nb::module_& m);  // bind_solver.cpp
void bind_engine(nb::module_& m);  // bind_engine.cpp
void bind_builder(nb::module_& m);  // bind_builder.cpp
void bind_ops(nb::module_& m);  // bind_ops.cpp
void bind_jax(nb::module_& m);  // bind_jax.cpp: the XLA FFI handler of rbdkit.jax


namespace {



// seconds per call of `fn`, the best of `repeats` runs of `iters` calls
template <typename Fn> double seconds_per_call(Fn&& fn, int iters, int repeats = 5) {
  double best = 1e30;
  for (int r = 0; r < repeats; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < iters; ++i) fn();
    const auto t1 = std::chrono::steady_clock::now();
    best = std::min(best, std::chrono::duration<double>(t1 - t0).count() / iters);
  }
  return best;
}

nb::dict joint_dict(const rbd::JointInfo& j) {
  nb::dict d;
  d["name"] = j.name;
  d["type"] = j.type;
  d["body"] = j.body;
  d["q_index"] = j.q_idx;
  d["v_index"] = j.v_idx;
  d["nq"] = j.nq;
  d["nv"] = j.nv;
  d["mimic_of"] = j.mimic_of.empty() ? nb::none() : nb::cast(j.mimic_of);
  d["multiplier"] = j.multiplier;
  d["offset"] = j.offset;
  return d;
}

}  // namespace

NB_MODULE(_core, m) {
  m.doc() = "rbdkit compiled core";
  // the documented input bounds (dynamics.hpp)
  m.attr("MAX_INPUT") = rbd::kMaxInput;
  m.attr("MAX_ANGLE") = rbd::kMaxAngle;
  m.attr("MAX_TIME_STEP") = rbd::kMaxTimeStep;

  nb::class_<Model>(m, "Model")
      .def_static("from_urdf_file", &Model::from_urdf_file, "path"_a, "floating_base"_a = false, "strict"_a = false,
                  "mimic"_a = true)
      .def_static("from_urdf_string", &Model::from_urdf_string, "xml"_a, "floating_base"_a = false,
                  "strict"_a = false, "mimic"_a = true)
      .def_ro("name", &Model::name)
      .def_ro("nq", &Model::nq)
      .def_ro("nv", &Model::nv)
      .def_ro("floating_base", &Model::floating_base)
      .def_prop_ro("nb", &Model::nb)
      .def_prop_ro("has_mimic", &Model::has_mimic)
      .def_prop_ro("joint_names", &Model::joint_names)
      .def_prop_ro("frame_names", &Model::frame_names)
      .def_ro("body_names", &Model::body_names)
      .def_ro("warnings", &Model::warnings)
      .def_ro("lower", &Model::lower)
      .def_ro("upper", &Model::upper)
      .def_ro("velocity_limit", &Model::velocity_limit)
      .def_ro("effort_limit", &Model::effort_limit)
      .def_prop_ro("body_parents",
                   [](const Model& md) {
                     std::vector<int> p;
                     for (const auto& b : md.bodies) p.push_back(b.parent);
                     return p;
                   })
      .def_prop_ro("joints",
                   [](const Model& md) {
                     nb::list out;
                     for (const auto& j : md.joints) out.append(joint_dict(j));
                     return out;
                   })
      .def("frame_index", &Model::frame_index, "name"_a)
      .def("joint_index", &Model::joint_index, "name"_a)
      .def("frame_placement",
           [](const Model& md, int i) {
             // (body, R row-major 9, p 3) of frame i in its body
             const rbd::FrameInfo& f = md.frames.at(i);
             std::vector<double> R(f.X_body_frame.R.m, f.X_body_frame.R.m + 9);
             std::vector<double> p = {f.X_body_frame.p.x, f.X_body_frame.p.y, f.X_body_frame.p.z};
             return nb::make_tuple(f.body, f.kind, R, p);
           })
      .def("neutral", &Model::neutral)
      .def("inertial_parameters", &Model::inertial_parameters)
      .def("with_inertial_parameters", &Model::with_inertial_parameters, "pi"_a);

  // ---- per-robot generated code (`rbdkit generate`, rbdkit/codegen/generate.hpp)
  m.def("generate_header", &rbd::generate_header, "model"_a, "name"_a, "source"_a = "", "runtime_inertias"_a = false);

  // ---- configuration space (the registered operations are bound by bind_ops.cpp;
  // Model.random_configuration takes this one before any RBD exists)
  m.def("integrate", [](const Model& md, In q, In v, Out out) {
    nb::gil_scoped_release r;
    rbd::batch::integrate(md, batch_of(q), q.data(), v.data(), out.data());
  });

  // ---- per-call timing of the core algorithms, no checks, no Python in the loop
  m.def("time_per_call",
        [](const Model& md, const std::string& op, In q, In qd, In tau, int iters) {
          nb::gil_scoped_release r;
          // the workspace and output the operation needs: linear and (nv) for the O(n) ones
          const bool quadratic = op == "crba" || op == "minv";
          const rbd::WorkspaceLayout layout = op == "inverse_dynamics" ? rbd::kLinearWorkspace
                                              : op == "aba"            ? rbd::aba_layout(md)
                                                                       : rbd::kFullWorkspace;
          rbd::WorkspaceBuffer buf(md, layout);
          rbd::Workspace<double>& w = buf.get();
          const rbd::ModelView<double> mv = md.view();
          std::vector<double> out(quadratic ? size_t(md.nv) * md.nv : size_t(md.nv));
          const double* fx = nullptr;
          if (op == "inverse_dynamics")
            return seconds_per_call([&] { rbd::rnea(mv, w, q.data(), qd.data(), tau.data(), fx, -9.81, out.data()); }, iters);
          if (op == "crba") return seconds_per_call([&] { rbd::crba(mv, w, q.data(), out.data()); }, iters);
          if (op == "minv") return seconds_per_call([&] { rbd::minv(mv, w, q.data(), true, out.data()); }, iters);
          if (op == "aba")
            return seconds_per_call([&] { rbd::aba(mv, w, q.data(), qd.data(), tau.data(), fx, -9.81, out.data()); }, iters);
          if (op == "forward_dynamics")
            return seconds_per_call(
                [&] { rbd::forward_dynamics(mv, w, q.data(), qd.data(), tau.data(), fx, -9.81, out.data()); }, iters);
          throw std::invalid_argument("op: unknown operation '" + op +
                                      "' (expected inverse_dynamics, crba, minv, aba or forward_dynamics)");
        },
        "model"_a, "op"_a, "q"_a, "qd"_a, "tau"_a, "iters"_a);

  bind_kinematics(m);
  bind_handle(m);
  bind_solver(m);
  bind_engine(m);
  bind_builder(m);
  bind_ops(m);
  bind_jax(m);
}
