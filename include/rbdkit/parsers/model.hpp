// rbdkit/parsers/model.hpp — the host-side robot model (immutable once built).
//
// A Model owns the per-body descriptions the algorithms read (BodyDesc, see
// joint.hpp) and everything a person asks for by name: joints, frames,
// limits. It is built by ModelBuilder (builder.hpp), which the URDF reader and
// the MuJoCo importer use. Host only.
#pragma once

#include <string>
#include <vector>

#include "rbdkit/model/joint_types.hpp"

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

  // floating_base: add a free-flyer root joint "root_joint" (or root_joint_1,
  // ... when the file already uses that name).
  // strict: a rotational inertia with a negative eigenvalue or one that breaks
  // the triangle inequality is an error (otherwise a warning in `warnings`).
  // mimic: a <mimic> joint follows its target's coordinate (q = m·q_t + o);
  // false: it is an independent coordinate (Pinocchio's default).
  // Throws std::invalid_argument. Built through ModelBuilder (builder.hpp).
  static Model from_urdf_file(const std::string& path, bool floating_base = false, bool strict = false,
                              bool mimic = true);
  static Model from_urdf_string(const std::string& xml, bool floating_base = false, bool strict = false,
                                bool mimic = true);

  int nb() const { return static_cast<int>(bodies.size()); }
  bool has_mimic() const;
  // the algorithms' general paths (the view's has_mimic flag): mimic joints, or bodies not in
  // depth-first order (a ModelBuilder's added otherwise: subtrees_contiguous)
  bool general_path() const;
  ModelView<double> view() const { return {nb(), nq, nv, general_path() ? 1 : 0, bodies.data()}; }
  // the bodies in another scalar type (float, dual numbers), constants converted;
  // view them with ModelView<S>{nb(), nq, nv, general_path(), converted.data()}
  template <typename S> std::vector<BodyDesc<S>> bodies_as() const;

  // joints that own velocity coordinates, in velocity-coordinate order
  std::vector<std::string> joint_names() const;
  std::vector<std::string> frame_names() const;
  // index into frames; throws std::invalid_argument naming close matches
  int frame_index(const std::string& frame) const;
  // index into joints (bodies); throws std::invalid_argument
  int joint_index(const std::string& joint) const;

  std::vector<double> neutral() const;

  // inertial parameters π (10 nb): per body, in body order, [m, m·c_x, m·c_y,
  // m·c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz], I about the body-frame origin
  // in body axes (Pinocchio's dynamic parameters; docs/conventions.md)
  std::vector<double> inertial_parameters() const;
  // a copy of this model with the inertial parameters pi (10 nb); this model
  // is unchanged. Throws std::invalid_argument (naming the link) for a wrong
  // length or a non-finite value, and, for every body whose 10 values differ
  // from this model's, a physically inconsistent inertia: negative mass, zero
  // mass with a non-zero first moment, or a rotational inertia about the
  // centre of mass that is not positive semi-definite or breaks the triangle
  // inequalities (to 1e-10 of the trace of I). Bodies passed back unchanged
  // keep their values as read (the URDF reader's checks apply to them).
  Model with_inertial_parameters(const std::vector<double>& pi) const;

  // fills nv_subtree of every body; called by the builders
  void finalize();
};

template <typename S> std::vector<BodyDesc<S>> Model::bodies_as() const {
  std::vector<BodyDesc<S>> out(bodies.size());
  for (size_t i = 0; i < bodies.size(); ++i) body_as(bodies[i], out[i]);
  return out;
}

}  // namespace rbd
