// Host API of the kinematics family: name lookups, input checks and the
// batched loops over the per-sample kinematics and operational-space passes.
#include "rbdkit/batch/kinematics_api.hpp"

#include <cstdint>
#include <memory>
#include <sstream>
#include <stdexcept>

#include "rbdkit/spatial/dual.hpp"

namespace rbd {

int reference_frame_from_name(const std::string& name) {
  if (name == "LOCAL") return kLocal;
  if (name == "WORLD") return kWorld;
  if (name == "LOCAL_WORLD_ALIGNED") return kLocalWorldAligned;
  throw std::invalid_argument("reference_frame: expected one of 'LOCAL', 'WORLD', 'LOCAL_WORLD_ALIGNED', got '" +
                              name + "'");
}

int frame_from_name(const Model& m, const std::string& name) {
  try {
    return m.frame_index(name);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("frame_name: ") + e.what());
  }
}

std::vector<int> leaf_bodies(const Model& m) {
  std::vector<int> has_child(m.nb(), 0), out;
  for (const auto& b : m.bodies)
    if (b.parent >= 0) has_child[b.parent] = 1;
  for (int i = 0; i < m.nb(); ++i)
    if (!has_child[i]) out.push_back(i);
  return out;
}

std::vector<int> end_effector_bodies(const Model& m, const std::vector<std::string>& joint_names) {
  if (joint_names.empty()) throw std::invalid_argument("ee_joint_names: expected at least one joint name, got none");
  std::vector<int> out;
  for (const auto& name : joint_names) {
    // a joint frame that moves no body of its own: a planar joint (split into
    // <name>_x, <name>_y, <name>_rot) or a fixed joint (merged into a body)
    for (const auto& f : m.frames) {
      if (f.kind != "joint" || f.name != name || (f.body >= 0 && m.joints[f.body].name == name)) continue;
      if (f.body >= 0 && m.joints[f.body].name == name + "_rot")
        throw std::invalid_argument("ee_joint_names: joint '" + name + "' is a planar joint, split into '" + name +
                                    "_x', '" + name + "_y' and '" + name + "_rot'; name '" + name +
                                    "_rot', which moves its child link");
      const std::string carrier = f.body < 0 ? "the world (fixed base)" : "joint '" + m.joints[f.body].name + "'";
      throw std::invalid_argument("ee_joint_names: joint '" + name + "' is fixed (merged into the body of " +
                                  carrier + "); name a moving joint and give the tool point as an offset");
    }
    try {
      out.push_back(m.joint_index(name));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string("ee_joint_names: ") + e.what());
    }
  }
  return out;
}

namespace batch {

namespace {


void check_frame(const Model& m, int frame) {
  if (frame < 0 || frame >= static_cast<int>(m.frames.size())) {
    std::ostringstream os;
    os << "frame: index " << frame << " out of range [0, " << m.frames.size() << ")";
    throw std::invalid_argument(os.str());
  }
}

void check_rf(int rf) {
  if (rf != kLocal && rf != kWorld && rf != kLocalWorldAligned) {
    std::ostringstream os;
    os << "reference_frame: expected LOCAL (0), WORLD (1) or LOCAL_WORLD_ALIGNED (2), got " << rf;
    throw std::invalid_argument(os.str());
  }
}

void check_end_effectors(const Model& m, long B, const EndEffectors& ee) {
  if (ee.bodies.empty()) throw std::invalid_argument("ee_joint_names: expected at least one end effector, got none");
  for (int b : ee.bodies)
    if (b < 0 || b >= m.nb()) {
      std::ostringstream os;
      os << "ee_joint_names: body index " << b << " out of range [0, " << m.nb() << ")";
      throw std::invalid_argument(os.str());
    }
  if (ee.offsets) check_finite(ee.offsets, B * ee.size() * 3, ee.offsets_arg);
}

// tool point of end effector e in sample s
template <typename S> Vec3<S> tool_point(const EndEffectors& ee, long s, long e) {
  if (!ee.offsets) return Vec3<S>::zero();
  const double* o = ee.offsets + (s * ee.size() + e) * 3;
  return {S(o[0]), S(o[1]), S(o[2])};
}

void store_rotation(const Mat3<double>& R, double* out) {
  for (int k = 0; k < 9; ++k) out[k] = R.m[k];
}
void store_point(const Vec3<double>& p, double* out) {
  out[0] = p.x; out[1] = p.y; out[2] = p.z;
}

}  // namespace

void forward_kinematics(const Model& m, long B, const double* q, double* R, double* p, Workspace<double>* ws) {
  check_configurations(m, B, q, "q");
  ScopedWorkspace buf(m, ws, kLinearWorkspace);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const int nb = m.nb();
  for (long s = 0; s < B; ++s) {
    rbd::forward_kinematics(mv, w, q + s * m.nq, static_cast<const double*>(nullptr));
    for (int i = 0; i < nb; ++i) {
      store_rotation(w.X_world[i].R, R + (s * nb + i) * 9);
      store_point(w.X_world[i].p, p + (s * nb + i) * 3);
    }
  }
}

void frame_placement(const Model& m, long B, const double* q, int frame, double* R, double* p,
                     Workspace<double>* ws) {
  check_frame(m, frame);
  check_configurations(m, B, q, "q");
  ScopedWorkspace buf(m, ws, kLinearWorkspace);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const FrameInfo& f = m.frames[frame];
  for (long s = 0; s < B; ++s) {
    rbd::forward_kinematics(mv, w, q + s * m.nq, static_cast<const double*>(nullptr));
    const Transform<double> X = rbd::frame_placement(w, f.body, f.X_body_frame);
    store_rotation(X.R, R + s * 9);
    store_point(X.p, p + s * 3);
  }
}

void frame_jacobian(const Model& m, long B, const double* q, int frame, int rf, double* J, Workspace<double>* ws) {
  check_frame(m, frame);
  check_rf(rf);
  check_configurations(m, B, q, "q");
  ScopedWorkspace buf(m, ws, kLinearWorkspace);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const FrameInfo& f = m.frames[frame];
  for (long s = 0; s < B; ++s) {
    rbd::forward_kinematics(mv, w, q + s * m.nq, static_cast<const double*>(nullptr));
    rbd::frame_jacobian(mv, w, f.body, f.X_body_frame, rf, J + s * 6 * m.nv);
  }
}

void frame_jacobian_dot(const Model& m, long B, const double* q, const double* qd, int frame, int rf, double* dJ,
                        Workspace<double>* ws) {
  check_frame(m, frame);
  check_rf(rf);
  check_configurations(m, B, q, "q");
  check_finite(qd, B * m.nv, "qd");
  ScopedWorkspace buf(m, ws, kLinearWorkspace);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const FrameInfo& f = m.frames[frame];
  for (long s = 0; s < B; ++s) {
    rbd::forward_kinematics(mv, w, q + s * m.nq, qd + s * m.nv);
    rbd::frame_jacobian_dot(mv, w, f.body, f.X_body_frame, rf, dJ + s * 6 * m.nv);
  }
}

void end_effector_pose(const Model& m, long B, const double* q, const EndEffectors& ee, double* pose,
                       Workspace<double>* ws) {
  check_end_effectors(m, B, ee);
  check_configurations(m, B, q, "q");
  ScopedWorkspace buf(m, ws, kLinearWorkspace);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const long n = ee.size();
  for (long s = 0; s < B; ++s) {
    rbd::forward_kinematics(mv, w, q + s * m.nq, static_cast<const double*>(nullptr));
    for (long e = 0; e < n; ++e)
      rbd::end_effector_pose(w, ee.bodies[e], tool_point<double>(ee, s, e), pose + (s * n + e) * 6);
  }
}

void end_effector_pose_gradient(const Model& m, long B, const double* q, const EndEffectors& ee, double* G,
                                Workspace<double>* ws) {
  check_end_effectors(m, B, ee);
  check_configurations(m, B, q, "q");
  ScopedWorkspace buf(m, ws, kLinearWorkspace);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const long n = ee.size(), nv = m.nv;
  for (long s = 0; s < B; ++s) {
    rbd::forward_kinematics(mv, w, q + s * m.nq, static_cast<const double*>(nullptr));
    for (long e = 0; e < n; ++e)
      rbd::end_effector_pose_gradient(mv, w, ee.bodies[e], tool_point<double>(ee, s, e), G + (s * n + e) * 6 * nv);
  }
}

void end_effector_pose_hessian_analytic(const Model& m, long B, const double* q, const EndEffectors& ee, double* H,
                                        Workspace<double>* ws) {
  check_end_effectors(m, B, ee);
  check_configurations(m, B, q, "q");
  ScopedWorkspace buf(m, ws);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const long n = ee.size(), nv = m.nv;
  for (long s = 0; s < B; ++s) {
    rbd::forward_kinematics(mv, w, q + s * m.nq, static_cast<const double*>(nullptr));
    for (long e = 0; e < n; ++e)
      rbd::end_effector_pose_hessian_analytic(mv, w, ee.bodies[e], tool_point<double>(ee, s, e),
                                     H + (s * n + e) * 6 * nv * nv);
  }
}

void end_effector_pose_hessian(const Model& m, long B, const double* q, const EndEffectors& ee, double* H) {
  check_end_effectors(m, B, ee);
  check_configurations(m, B, q, "q");
  using D = Dual<double>;
  const int nq = m.nq, nv = m.nv, nb = m.nb();
  const long n = ee.size();
  // the model and a workspace in dual numbers (constants: zero derivative parts)
  const std::vector<BodyDesc<D>> bodies = m.bodies_as<D>();
  const ModelView<D> mv = {nb, nq, nv, m.general_path() ? 1 : 0, bodies.data()};
  WorkspaceBufferT<D> wbuf(m);
  Workspace<D>& w = wbuf.get();
  std::vector<D> qs(nq), delta(nv), qp(nq), G(6 * nv);
  for (long s = 0; s < B; ++s) {
    for (int i = 0; i < nq; ++i) qs[i] = D(q[s * nq + i]);
    for (int j = 0; j < nv; ++j) {
      // q ⊕ ε e_j, then the analytic gradient at it: its ε parts are row j of ∂G
      for (int i = 0; i < nv; ++i) delta[i] = D(0.0, i == j ? 1.0 : 0.0);
      rbd::integrate(mv, qs.data(), delta.data(), qp.data());
      rbd::forward_kinematics(mv, w, qp.data(), static_cast<const D*>(nullptr));
      for (long e = 0; e < n; ++e) {
        rbd::end_effector_pose_gradient(mv, w, ee.bodies[e], tool_point<D>(ee, s, e), G.data());
        double* He = H + (s * n + e) * 6 * nv * nv;
        for (int r = 0; r < 6; ++r)
          for (int k = 0; k < nv; ++k) He[(r * nv + j) * nv + k] = G[r * nv + k].d;
      }
    }
  }
}

void osc_inertia(const Model& m, long B, const double* q, const EndEffectors& ee, double* Lambda,
                 Workspace<double>* ws) {
  check_end_effectors(m, B, ee);
  check_configurations(m, B, q, "q");
  ScopedWorkspace buf(m, ws);
  Workspace<double>& w = buf.get();
  const ModelView<double> mv = m.view();
  const long n = ee.size();
  for (long s = 0; s < B; ++s) {
    if (!osc_factor_mass_matrix(mv, w, q + s * m.nq))
      throw_not_positive_definite(m, "osc_inertia", q + s * m.nq, B > 1 ? s : -1);
    for (long e = 0; e < n; ++e)
      if (!rbd::osc_inertia(mv, w, ee.bodies[e], tool_point<double>(ee, s, e), Lambda + (s * n + e) * 36)) {
        const int b = ee.bodies[e];
        // coordinates that move the point (mimics share their target's)
        std::vector<char> moves(m.nv, 0);
        for (int k = b; k >= 0; k = m.bodies[k].parent)
          for (int a = 0; a < m.bodies[k].nv; ++a) moves[m.bodies[k].v_idx + a] = 1;
        int dof = 0;
        for (char c : moves) dof += c;
        std::ostringstream os;
        os << "osc_inertia: J M⁻¹ Jᵀ of end effector " << e << " (joint '" << m.joints[b].name
           << "') is singular at sample " << s << ": "
           << (dof < 6 ? "only " + std::to_string(dof) + " DoF reach it (6 are needed)"
                       : std::string("the configuration is singular (its Jacobian has rank < 6)"))
           << ", so the operational-space inertia is undefined";
        throw std::invalid_argument(os.str());
      }
  }
}

}  // namespace batch

}  // namespace rbd
