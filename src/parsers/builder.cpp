// ModelBuilder: checks each body, joint, inertia and frame as it is added,
// then resolves mimic couplings and assigns coordinates and limits.
//
// outline of build():
//   1. mimic couplings: flatten chains onto a joint that owns its coordinate,
//      reject cycles and joints that are not 1-DoF
//   2. coordinates and limits of the joints that own them, in body order
//   3. mimic bodies share their target's coordinate
//   4. subtree sizes (Model::finalize)
#include "rbdkit/parsers/builder.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace rbd {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// the largest magnitude accepted for a length (m) or a mimic multiplier or
// offset (also after a chain is flattened), and for an inertia value (kg,
// kg·m, kg·m²): beyond them the dynamics of an ordinary state overflow or lose
// every digit (a robot of 1e12 m or 1e15 kg is an input error, not a robot)
constexpr double kMaxLength = 1e12;
constexpr double kMaxInertia = 1e15;

[[noreturn]] void fail(const std::string& msg) { throw std::invalid_argument(msg); }

std::string num(double x) {
  std::ostringstream os;
  os << x;
  return os.str();
}

void check_transform(const Transform<double>& X, const std::string& what) {
  for (int k = 0; k < 9; ++k)
    if (!std::isfinite(X.R.m[k])) fail(what + ": the rotation has a non-finite entry " + num(X.R.m[k]));
  const double p[3] = {X.p.x, X.p.y, X.p.z};
  for (double x : p)
    if (!std::isfinite(x) || std::fabs(x) > kMaxLength)
      fail(what + ": the translation has " + num(x) + ", expected a finite length of at most " + num(kMaxLength) +
           " m");
  const Mat3<double> E = transpose(X.R) * X.R;
  double err = 0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) err = std::fmax(err, std::fabs(E(r, c) - (r == c ? 1.0 : 0.0)));
  if (err > 1e-9) fail(what + ": the rotation is not orthonormal (|RᵀR - 1| = " + num(err) + ")");
  const Mat3<double>& R = X.R;
  const double det = R(0, 0) * (R(1, 1) * R(2, 2) - R(1, 2) * R(2, 1)) -
                     R(0, 1) * (R(1, 0) * R(2, 2) - R(1, 2) * R(2, 0)) +
                     R(0, 2) * (R(1, 0) * R(2, 1) - R(1, 1) * R(2, 0));
  if (det < 0) fail(what + ": the rotation is a reflection (det = " + num(det) + "), not a rotation");
}

void check_inertia(const Inertia<double>& I, const std::string& what) {
  const double vals[13] = {I.m, I.h.x, I.h.y, I.h.z, I.I.m[0], I.I.m[1], I.I.m[2],
                           I.I.m[3], I.I.m[4], I.I.m[5], I.I.m[6], I.I.m[7], I.I.m[8]};
  for (double x : vals)
    if (!std::isfinite(x) || std::fabs(x) > kMaxInertia)
      fail(what + ": the inertia has " + num(x) + ", expected finite values of magnitude at most " + num(kMaxInertia));
  if (I.m < 0) fail(what + ": negative mass " + num(I.m) + " (mass must be >= 0)");
  // the algorithms read I as symmetric (some only its upper triangle)
  double largest = 0, asym = 0;
  for (int k = 0; k < 9; ++k) largest = std::fmax(largest, std::fabs(I.I.m[k]));
  for (int r = 0; r < 3; ++r)
    for (int c = r + 1; c < 3; ++c) asym = std::fmax(asym, std::fabs(I.I(r, c) - I.I(c, r)));
  if (asym > 1e-9 * largest)
    fail(what + ": the rotational inertia is not symmetric (|I - Iᵀ| = " + num(asym) + ")");
}

}  // namespace

Vec3<double> unit_axis(const Vec3<double>& a, const std::string& what) {
  const double s = std::fmax(std::fabs(a.x), std::fmax(std::fabs(a.y), std::fabs(a.z)));
  if (!std::isfinite(a.x) || !std::isfinite(a.y) || !std::isfinite(a.z))
    fail(what + " has a non-finite axis (" + num(a.x) + ", " + num(a.y) + ", " + num(a.z) + ")");
  if (!(s > 0)) fail(what + " has a zero axis; a moving joint needs a direction");
  const Vec3<double> b = {a.x / s, a.y / s, a.z / s};  // 1/s overflows for a subnormal s
  return (1.0 / std::sqrt(dot(b, b))) * b;
}


Inertia<double> rigid_inertia(double mass, const Vec3<double>& com, const Mat3<double>& I_com) {
  const Mat3<double> C = skew(com);
  Inertia<double> I;
  I.m = mass;
  I.h = mass * com;
  I.I = I_com - mass * (C * C);
  return I;
}

ModelBuilder::ModelBuilder(std::string robot_name) { model_.name = std::move(robot_name); }

int ModelBuilder::body_index(const std::string& body_name) const {
  const auto it = body_ids_.find(body_name);
  return it == body_ids_.end() ? -1 : it->second;
}

bool ModelBuilder::has_joint(const std::string& joint_name) const { return joint_ids_.count(joint_name) > 0; }
bool ModelBuilder::has_body(const std::string& body_name) const { return body_ids_.count(body_name) > 0; }

int ModelBuilder::add_body(int parent, const JointSpec& joint, const std::string& body_name,
                           const Inertia<double>& I_body) {
  const std::string what = "joint '" + joint.name + "'";
  if (joint.name.empty()) fail("add_body: the joint has no name");
  if (body_name.empty()) fail("add_body: " + what + ": the body has no name");
  if (joint_ids_.count(joint.name)) fail("add_body: a joint named '" + joint.name + "' already exists");
  if (body_ids_.count(body_name)) fail("add_body: a body named '" + body_name + "' already exists");
  if (parent < -1 || parent >= nb())
    fail("add_body: " + what + ": parent body " + std::to_string(parent) + " does not exist (expected -1 for the world or 0.." +
         std::to_string(nb() - 1) + ")");
  BodyDesc<double> b{};
  b.parent = parent;
  b.mult = 1;
  b.offset = 0;
  b.pitch = 0;
  b.axis = {1, 0, 0};
  std::string type = joint.type == "floating" ? "free" : (joint.type == "screw" ? "helical" : joint.type);
  if (type == "revolute" || type == "continuous") b.type = kRevolute;
  else if (type == "prismatic") b.type = kPrismatic;
  else if (type == "helical") b.type = kHelical;
  else if (type == "spherical") b.type = kSpherical;
  else if (type == "free") b.type = kFree;
  else
    fail("add_body: " + what + " has type '" + joint.type +
         "', expected revolute, continuous, prismatic, helical, spherical or free");
  const bool one_dof = b.type != kSpherical && b.type != kFree;
  if (one_dof) b.axis = unit_axis(joint.axis, what);
  if (b.type == kHelical) {
    if (!std::isfinite(joint.pitch) || std::fabs(joint.pitch) > kMaxLength)
      fail("add_body: " + what + " has pitch " + num(joint.pitch) + ", expected a finite value of magnitude at most " +
           num(kMaxLength));
    b.pitch = joint.pitch;
  }
  check_transform(joint.X_parent_joint, "add_body: " + what + " placement");
  check_inertia(I_body, "add_body: body '" + body_name + "'");
  b.X_tree = joint.X_parent_joint;
  b.I = I_body;
  b.nq = joint_nq(b.type);
  b.nv = joint_nv(b.type);

  JointSpec spec = joint;
  spec.type = type;
  if (std::isnan(spec.lower) || std::isnan(spec.upper) || std::isnan(spec.velocity) || std::isnan(spec.effort))
    fail("add_body: " + what + " has a NaN limit");
  if (!one_dof || type == "continuous") spec.lower = -kInf, spec.upper = kInf;
  if (spec.lower > spec.upper)
    model_.warnings.push_back(what + " has lower limit " + num(spec.lower) + " > upper limit " + num(spec.upper) +
                              "; the limits are kept as given");
  if (!(spec.velocity > 0)) spec.velocity = kInf;  // 0 means "not given" in many files
  if (!(spec.effort > 0)) spec.effort = kInf;

  const int index = nb();
  model_.bodies.push_back(b);
  model_.body_names.push_back(body_name);
  JointInfo ji;
  ji.name = joint.name;
  ji.type = type;
  ji.body = index;
  model_.joints.push_back(ji);
  specs_.push_back(spec);
  joint_ids_[joint.name] = index;
  body_ids_[body_name] = index;
  return index;
}

void ModelBuilder::add_inertia(int body, const Inertia<double>& I_link, const Transform<double>& X_body_link) {
  if (body < -1 || body >= nb()) fail("add_inertia: body " + std::to_string(body) + " does not exist");
  const std::string what = "add_inertia: on body '" + (body >= 0 ? model_.body_names[body] : std::string("world")) + "'";
  check_inertia(I_link, what);
  check_transform(X_body_link, what + " placement");
  if (body < 0) return;
  Inertia<double> merged = model_.bodies[body].I;
  merged += transform_inertia(X_body_link, I_link);
  check_inertia(merged, what + " (merged)");  // refused: the body is left as it was
  model_.bodies[body].I = merged;
}

void ModelBuilder::add_frame(const std::string& name, const std::string& kind, int body,
                             const Transform<double>& X_body_frame) {
  if (name.empty()) fail("add_frame: the frame has no name");
  if (body < -1 || body >= nb()) fail("add_frame: frame '" + name + "': body " + std::to_string(body) + " does not exist");
  check_transform(X_body_frame, "add_frame: frame '" + name + "' placement");
  model_.frames.push_back({name, kind, body, X_body_frame});
}

void ModelBuilder::add_mimic(const std::string& joint, const std::string& target, double multiplier, double offset) {
  if (!std::isfinite(multiplier) || std::fabs(multiplier) > kMaxLength || !std::isfinite(offset) ||
      std::fabs(offset) > kMaxLength)
    fail("add_mimic: joint '" + joint + "' has multiplier " + num(multiplier) + " and offset " + num(offset) +
         ", expected finite values of magnitude at most " + num(kMaxLength));
  mimics_.push_back({joint, target, multiplier, offset});
}

void ModelBuilder::add_warning(const std::string& warning) { model_.warnings.push_back(warning); }

Model ModelBuilder::build() {
  Model& m = model_;
  auto joint_of = [&](const std::string& name, const std::string& role) {
    const auto it = joint_ids_.find(name);
    if (it == joint_ids_.end()) fail("add_mimic: " + role + " '" + name + "' is not a joint of the model");
    return it->second;
  };
  auto is_one_dof = [&](int i) { return m.bodies[i].type != kSpherical && m.bodies[i].type != kFree; };

  // 1. mimic couplings: direct[i] = (target, multiplier, offset), then chains flattened
  std::vector<int> direct(m.bodies.size(), -1);
  std::vector<double> mult(m.bodies.size(), 1.0), offs(m.bodies.size(), 0.0);
  for (const Mimic& c : mimics_) {
    const int i = joint_of(c.joint, "mimic joint"), t = joint_of(c.target, "the target of mimic joint '" + c.joint + "',");
    if (direct[i] >= 0) fail("add_mimic: joint '" + c.joint + "' mimics two joints");
    if (!is_one_dof(i)) fail("add_mimic: joint '" + c.joint + "' is a " + m.joints[i].type + " joint; only 1-DoF joints can mimic");
    if (!is_one_dof(t))
      fail("add_mimic: joint '" + c.joint + "' mimics '" + c.target + "', a " + m.joints[t].type +
           " joint; the target of a mimic must be a 1-DoF joint");
    direct[i] = t;
    mult[i] = c.multiplier;
    offs[i] = c.offset;
  }
  // each mimic joint resolved once, q_j = mu_j·q_root + off_j: follow its
  // chain to a joint that owns its coordinate or one already resolved, then
  // compose back along the chain (O(n) in all; state 1: on the current chain)
  const size_t n = m.bodies.size();
  std::vector<int> root(n, -1), state(n, 0), chain;
  std::vector<double> mu(n, 1.0), off(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    if (direct[i] < 0 || state[i] == 2) continue;
    chain.clear();
    int cur = static_cast<int>(i);
    while (direct[cur] >= 0 && state[cur] != 2) {
      if (state[cur] == 1) fail("mimic joints form a cycle through joint '" + m.joints[cur].name + "'");
      state[cur] = 1;
      chain.push_back(cur);
      cur = direct[cur];
    }
    const bool owns = direct[cur] < 0;
    const int r = owns ? cur : root[cur];
    double M = owns ? 1.0 : mu[cur], O = owns ? 0.0 : off[cur];
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      const int j = *it;
      O = mult[j] * O + offs[j];  // q_j = mult_j·q_next + offs_j, q_next = M·q_r + O
      M = mult[j] * M;
      if (std::fabs(M) > kMaxLength || std::fabs(O) > kMaxLength)
        fail("mimic joint '" + m.joints[j].name + "' follows '" + m.joints[r].name + "' through a chain whose " +
             "multiplier " + num(M) + " or offset " + num(O) + " exceeds " + num(kMaxLength) + " in magnitude");
      root[j] = r, mu[j] = M, off[j] = O, state[j] = 2;
      m.joints[j].mimic_of = m.joints[r].name;
      m.joints[j].multiplier = M;
      m.joints[j].offset = O;
    }
  }

  // 2. coordinates and limits, in body order
  int nq = 0, nv = 0;
  for (size_t i = 0; i < m.bodies.size(); ++i) {
    if (root[i] >= 0) continue;
    BodyDesc<double>& b = m.bodies[i];
    const JointSpec& s = specs_[i];
    b.q_idx = m.joints[i].q_idx = nq;
    b.v_idx = m.joints[i].v_idx = nv;
    m.joints[i].nq = b.nq;
    m.joints[i].nv = b.nv;
    nq += b.nq;
    nv += b.nv;
    for (int k = 0; k < b.nq; ++k) m.lower.push_back(s.lower), m.upper.push_back(s.upper);
    for (int k = 0; k < b.nv; ++k) m.velocity_limit.push_back(s.velocity), m.effort_limit.push_back(s.effort);
  }
  // 3. mimic bodies read their target's coordinate
  for (size_t i = 0; i < m.bodies.size(); ++i) {
    if (root[i] < 0) continue;
    BodyDesc<double>& b = m.bodies[i];
    b.mimic = 1;
    b.q_idx = m.joints[i].q_idx = m.bodies[root[i]].q_idx;
    b.v_idx = m.joints[i].v_idx = m.bodies[root[i]].v_idx;
    b.nq = b.nv = 1;
    b.mult = m.joints[i].multiplier;
    b.offset = m.joints[i].offset;
  }
  m.nq = nq;
  m.nv = nv;
  m.floating_base = !m.bodies.empty() && m.bodies[0].type == kFree && m.bodies[0].parent < 0;
  // 4. subtree sizes
  m.finalize();
  Model out = std::move(m);
  *this = ModelBuilder();
  return out;
}

}  // namespace rbd
