// rbdkit/parsers/builder.hpp — a Model built in code: bodies added under their
// parents through joints, rigid inertias and frames attached to them, mimic
// couplings and limits. The URDF reader and the MuJoCo importer build
// through it, and so can a user writing a robot by hand. Host only.
//
//   ModelBuilder b("arm");
//   JointSpec j; j.name = "shoulder"; j.type = "revolute"; j.axis = {0, 0, 1};
//   j.X_parent_joint = {Mat3<double>::identity(), {0, 0, 0.3}};
//   const int upper = b.add_body(-1, j, "upper_arm", I_upper);   // under the world
//   b.add_frame("tool", "link", upper, X_upper_tool);
//   Model m = b.build();
//
// Coordinates are assigned in body order (the order of add_body), so the
// order of the calls is the velocity-coordinate order of the model.
#pragma once

#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "rbdkit/parsers/model.hpp"

namespace rbd {

// the joint that connects a new body to its parent
struct JointSpec {
  std::string name;     // unique among the model's joints
  std::string type;     // revolute, continuous, prismatic, helical, spherical, free
  // the joint frame placed in the parent body's frame (the world for parent -1);
  // the new body's frame is the joint frame moved by the joint
  Transform<double> X_parent_joint = Transform<double>::identity();
  Vec3<double> axis = {0, 0, 1};  // 1-DoF joints, joint frame; normalised here (zero: an error)
  double pitch = 0;     // helical: metres per radian
  // position limits of a 1-DoF joint (continuous, spherical and free joints
  // have none); velocity and effort limits apply to every DoF of the joint
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  double velocity = std::numeric_limits<double>::infinity();
  double effort = std::numeric_limits<double>::infinity();
};

// the spatial inertia of a rigid body in its own frame from its mass, centre
// of mass c (body frame) and rotational inertia I_com about c in body axes:
// m, h = m c, I = I_com - m [c]²
Inertia<double> rigid_inertia(double mass, const Vec3<double>& com, const Mat3<double>& I_com);

// the unit vector along a (a joint axis), scaled first so that huge or
// tiny entries neither overflow nor underflow; std::invalid_argument naming
// `what` for a zero or non-finite one
Vec3<double> unit_axis(const Vec3<double>& a, const std::string& what);

class ModelBuilder {
 public:
  explicit ModelBuilder(std::string robot_name = "");

  // a new body `body_name` moved by `joint` relative to body `parent` (-1: the
  // world); I_body is its spatial inertia in its own frame. Returns the body
  // index. Throws std::invalid_argument for an unknown parent, a name already
  // used by a joint (or body), an unknown type, a zero or non-finite axis, a
  // non-finite placement or a NaN limit (lower > upper is a warning). A free
  // joint may sit under another body (URDF "floating" joints do).
  int add_body(int parent, const JointSpec& joint, const std::string& body_name,
               const Inertia<double>& I_body = Inertia<double>::zero());
  // rigidly attach an inertia to a body (a merged fixed link): I_link in a
  // frame placed at X_body_link in the body's frame. body -1 (the world) drops
  // it: mass fixed to the world does not move.
  void add_inertia(int body, const Inertia<double>& I_link, const Transform<double>& X_body_link);
  // a named frame fixed to a body (-1: the world); kind is "link", "joint" or
  // any word of the caller's ("site", ...)
  void add_frame(const std::string& name, const std::string& kind, int body, const Transform<double>& X_body_frame);
  // joint `joint` follows `target`: q_joint = multiplier·q_target + offset; both
  // 1-DoF; |multiplier|, |offset| <= 1e12. Chains are flattened (the same
  // bound on the result) and cycles rejected in build().
  void add_mimic(const std::string& joint, const std::string& target, double multiplier = 1, double offset = 0);
  void add_warning(const std::string& warning);

  int nb() const { return static_cast<int>(model_.bodies.size()); }
  // -1 if no body has that name
  int body_index(const std::string& body_name) const;
  bool has_joint(const std::string& joint_name) const;
  bool has_body(const std::string& body_name) const;

  // the model: mimic couplings resolved, coordinates and limits assigned in
  // body order. The builder is left empty.
  Model build();

 private:
  struct Mimic {
    std::string joint, target;
    double multiplier, offset;
  };
  Model model_;
  std::vector<JointSpec> specs_;  // (nb) as given
  std::vector<Mimic> mimics_;
  std::unordered_map<std::string, int> joint_ids_, body_ids_;  // name -> body
};

}  // namespace rbd
