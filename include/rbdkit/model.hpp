// rbdkit/model.hpp — the host-side robot model (immutable once built).
//
// A Model owns the per-body descriptions the algorithms read (BodyDesc, see
// joint.hpp) and everything a person asks for by name: joints, frames,
// limits. It is built by the URDF reader (urdf.hpp). Host only.
#pragma once

#include <string>
#include <vector>

#include "joint.hpp"

namespace rbd {

// what a named joint is; one per body, in body order
struct JointInfo {
  std::string name;
  std::string type;        // revolute, continuous, prismatic, helical, spherical, free
  int body = -1;           // the body this joint moves
  int q_idx = 0, v_idx = 0;
  int nq = 0, nv = 0;      // 0, 0 for a mimic joint (it owns no coordinate)
  std::string mimic_of;    // the joint whose coordinate this one follows ("" if none)
  double multiplier = 1, offset = 0;
};

// a named frame rigidly attached to a body (-1: the world)
struct FrameInfo {
  std::string name;
  std::string kind;        // "link" or "joint"
  int body = -1;
  Transform<double> X_body_frame = Transform<double>::identity();
};

class Model {
 public:
  std::string name;                      // robot name from the URDF
  int nq = 0, nv = 0;
  bool floating_base = false;
  std::vector<BodyDesc<double>> bodies;  // (nb) topological order
  std::vector<std::string> body_names;   // (nb) the link each body carries
  std::vector<JointInfo> joints;         // (nb) the joint moving each body
  std::vector<FrameInfo> frames;         // every link and joint, fixed ones included
  std::vector<double> lower, upper;      // (nq) position limits (±inf: none)
  std::vector<double> velocity_limit;    // (nv) (inf: none)
  std::vector<double> effort_limit;      // (nv) (inf: none)

  std::vector<std::string> warnings;     // what the reader accepted but doubts (non-PSD inertias)

  // floating_base: add a free-flyer root joint "root_joint".
  // strict: a rotational inertia with a negative eigenvalue is an error
  // (otherwise a warning in `warnings`). Throws std::invalid_argument.
  static Model from_urdf_file(const std::string& path, bool floating_base = false, bool strict = false);
  static Model from_urdf_string(const std::string& xml, bool floating_base = false, bool strict = false);

  int nb() const { return static_cast<int>(bodies.size()); }
  bool has_mimic() const;
  ModelView<double> view() const { return {nb(), nq, nv, has_mimic() ? 1 : 0, bodies.data()}; }

  // joints that own velocity coordinates, in velocity-coordinate order
  std::vector<std::string> joint_names() const;
  std::vector<std::string> frame_names() const;
  // index into frames; throws std::invalid_argument naming close matches
  int frame_index(const std::string& frame) const;
  // index into joints (bodies); throws std::invalid_argument
  int joint_index(const std::string& joint) const;

  std::vector<double> neutral() const;

  // fills nv_subtree of every body; called by the builders
  void finalize();
};

}  // namespace rbd
