// rbdkit._core — bindings of the kinematics family (kinematics_api.hpp).
//
// end_effector_pose_hessian (dual numbers), which is not a registered
// operation (the others: ops/registry.hpp, bind_ops.cpp). Thin, like bindings.cpp: the
// Python layer (python/rbdkit/_kinematics.py) checks shapes and resolves
// names once per call; these functions take
// C-contiguous float64 arrays with the batch on axis 0, check values in C++
// and run the batched loops with the GIL released.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "arrays.hpp"
#include "rbdkit/kinematics_api.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rbd::Model;
using rbd_py::In;
using rbd_py::Out;
using rbd_py::batch_of;
using rbd_py::opt;
using rbd_py::width;

namespace {

// end effectors from body indices and optional offsets (B x n_ee x 3)
rbd::EndEffectors end_effectors(const std::vector<int>& bodies, const std::optional<In>& offsets, const char* arg) {
  rbd::EndEffectors ee;
  ee.bodies = bodies;
  ee.offsets = offsets ? offsets->data() : nullptr;
  ee.offsets_arg = arg;
  return ee;
}

}  // namespace

void bind_kinematics(nb::module_& m) {
  // ---- names
  m.def("leaf_bodies", &rbd::leaf_bodies, "model"_a);
  m.def("end_effector_bodies", &rbd::end_effector_bodies, "model"_a, "joint_names"_a);

  // ---- end effectors: bodies (n_ee), offsets (B x n_ee x 3) or None
  m.def("end_effector_pose_hessian",
        [](const Model& md, In q, std::vector<int> bodies, std::optional<In> offsets, const std::string& arg,
           Out H) {
          const rbd::EndEffectors ee = end_effectors(bodies, offsets, arg.c_str());
          nb::gil_scoped_release r;
          rbd::batch::end_effector_pose_hessian(md, batch_of(q), q.data(), ee, H.data());
        },
        "model"_a, "q"_a, "bodies"_a, "offsets"_a.none(), "offsets_arg"_a, "H"_a);
}
