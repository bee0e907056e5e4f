// rbdkit._core: ModelBuilder (models built in code). Placements come as a
// row-major rotation (9) and a translation (3), inertias as mass, centre of
// mass (3) and rotational inertia about it (9, row-major); the Python class
// rbdkit.ModelBuilder (python/rbdkit/_builder.py) checks shapes and values and
// accepts the friendlier forms. Errors from the builder are ValueErrors.
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "rbdkit/parsers/builder.hpp"

namespace nb = nanobind;
using namespace nb::literals;
using rbd::Mat3;
using rbd::Transform;
using rbd::Vec3;

namespace {

using List = std::vector<double>;

void need(const List& a, size_t n, const char* what) {
  if (a.size() != n)
    throw std::invalid_argument(std::string(what) + ": expected " + std::to_string(n) + " values, got " +
                                std::to_string(a.size()));
}

Vec3<double> vec3(const List& a, const char* what) {
  need(a, 3, what);
  return {a[0], a[1], a[2]};
}

Mat3<double> mat3(const List& a, const char* what) {
  need(a, 9, what);
  Mat3<double> M;
  for (int k = 0; k < 9; ++k) M.m[k] = a[k];
  return M;
}

Transform<double> transform(const List& R, const List& p) { return {mat3(R, "rotation"), vec3(p, "translation")}; }

}  // namespace

void bind_builder(nb::module_& m) {
  nb::class_<rbd::ModelBuilder>(m, "ModelBuilder")
      .def(nb::init<std::string>(), "name"_a = "")
      .def(
          "add_body",
          [](rbd::ModelBuilder& b, int parent, const std::string& joint_name, const std::string& joint_type,
             const std::string& body_name, const List& R, const List& p, const List& axis, double pitch, double lower,
             double upper, double velocity, double effort, double mass, const List& com, const List& I_com) {
            rbd::JointSpec s;
            s.name = joint_name;
            s.type = joint_type;
            s.X_parent_joint = transform(R, p);
            s.axis = vec3(axis, "axis");
            s.pitch = pitch;
            s.lower = lower;
            s.upper = upper;
            s.velocity = velocity;
            s.effort = effort;
            return b.add_body(parent, s, body_name,
                              rbd::rigid_inertia(mass, vec3(com, "com"), mat3(I_com, "inertia")));
          },
          "parent"_a, "joint_name"_a, "joint_type"_a, "body_name"_a, "R"_a, "p"_a, "axis"_a, "pitch"_a, "lower"_a,
          "upper"_a, "velocity"_a, "effort"_a, "mass"_a, "com"_a, "I_com"_a)
      .def(
          "add_inertia",
          [](rbd::ModelBuilder& b, int body, double mass, const List& com, const List& I_com, const List& R,
             const List& p) {
            b.add_inertia(body, rbd::rigid_inertia(mass, vec3(com, "com"), mat3(I_com, "inertia")), transform(R, p));
          },
          "body"_a, "mass"_a, "com"_a, "I_com"_a, "R"_a, "p"_a)
      .def(
          "add_frame",
          [](rbd::ModelBuilder& b, const std::string& name, const std::string& kind, int body, const List& R,
             const List& p) { b.add_frame(name, kind, body, transform(R, p)); },
          "name"_a, "kind"_a, "body"_a, "R"_a, "p"_a)
      .def("add_mimic", &rbd::ModelBuilder::add_mimic, "joint"_a, "target"_a, "multiplier"_a, "offset"_a)
      .def("add_warning", &rbd::ModelBuilder::add_warning, "warning"_a)
      .def_prop_ro("nb", &rbd::ModelBuilder::nb)
      .def("body_index", &rbd::ModelBuilder::body_index, "body_name"_a)
      .def("has_joint", &rbd::ModelBuilder::has_joint, "joint_name"_a)
      .def("has_body", &rbd::ModelBuilder::has_body, "body_name"_a)
      .def("build", &rbd::ModelBuilder::build);
}
