// URDF reader: XML (tinyxml2) -> Model.
//
// outline:
//   1. read links (inertials) and joints (type, origin, axis, limits, mimic)
//   2. find the single root; reject cycles, second parents, missing links
//   3. walk depth-first from the root, children in document order:
//      fixed joints merge their child into the parent body (a frame remains),
//      planar joints become two prismatic and one revolute sub-joint,
//      every other joint makes a body
//   4. resolve mimic joints (flatten chains, reject cycles)
//   5. assign coordinates and limits
#include <tinyxml2.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

#include "rbdkit/model.hpp"

namespace rbd {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

[[noreturn]] void fail(const std::string& msg) { throw std::invalid_argument("URDF: " + msg); }

std::vector<double> parse_numbers(const char* text, size_t n, const std::string& what) {
  std::vector<double> out;
  if (text) {
    std::istringstream is(text);
    std::string tok;
    while (is >> tok) {
      char* end = nullptr;
      const double x = std::strtod(tok.c_str(), &end);
      if (end == tok.c_str() || *end != '\0' || !std::isfinite(x))
        fail(what + " has '" + tok + "', expected a finite number");
      out.push_back(x);
    }
  }
  if (out.size() != n)
    fail(what + " must have " + std::to_string(n) + " numbers, got '" + (text ? text : "") + "'");
  return out;
}

double parse_number(const tinyxml2::XMLElement* e, const char* attr, const std::string& what, double dflt,
                    bool required = false) {
  const char* t = e ? e->Attribute(attr) : nullptr;
  if (!t) {
    if (required) fail(what + " is missing attribute '" + attr + "'");
    return dflt;
  }
  return parse_numbers(t, 1, what + " attribute '" + std::string(attr) + "'")[0];
}

// X_parent_child from <origin xyz rpy> (fixed-axis roll, pitch, yaw)
Transform<double> parse_origin(const tinyxml2::XMLElement* parent, const std::string& what) {
  const tinyxml2::XMLElement* o = parent->FirstChildElement("origin");
  Transform<double> X = Transform<double>::identity();
  if (!o) return X;
  if (const char* t = o->Attribute("xyz")) {
    auto p = parse_numbers(t, 3, what + " origin xyz");
    X.p = {p[0], p[1], p[2]};
  }
  if (const char* t = o->Attribute("rpy")) {
    auto r = parse_numbers(t, 3, what + " origin rpy");
    const Mat3<double> Rx = axis_angle(Vec3<double>{1, 0, 0}, r[0]);
    const Mat3<double> Ry = axis_angle(Vec3<double>{0, 1, 0}, r[1]);
    const Mat3<double> Rz = axis_angle(Vec3<double>{0, 0, 1}, r[2]);
    X.R = Rz * Ry * Rx;
  }
  return X;
}

struct Link {
  std::string name;
  Inertia<double> I = Inertia<double>::zero();  // in the link frame
  int parent_joint = -1;
  std::vector<int> child_joints;  // document order
};

struct Joint {
  std::string name, type, parent, child;
  Transform<double> X = Transform<double>::identity();
  Vec3<double> axis = {1, 0, 0};
  double pitch = 0;
  double lower = -kInf, upper = kInf, velocity = kInf, effort = kInf;
  bool has_mimic = false;
  std::string mimic_joint;
  double mult = 1, offset = 0;
};

Inertia<double> parse_inertial(const tinyxml2::XMLElement* link, const std::string& lname, bool strict,
                               std::vector<std::string>& warnings) {
  const tinyxml2::XMLElement* in = link->FirstChildElement("inertial");
  if (!in) return Inertia<double>::zero();  // massless, as URDF intends
  const std::string what = "link '" + lname + "' inertial";
  const Transform<double> X = parse_origin(in, what);
  const double mass = parse_number(in->FirstChildElement("mass"), "value", what + " <mass>", 0.0,
                                   in->FirstChildElement("mass") != nullptr);
  if (mass < 0) fail("link '" + lname + "' has negative mass " + std::to_string(mass) + " (mass must be >= 0)");
  Mat3<double> Ic = Mat3<double>::zero();
  if (const tinyxml2::XMLElement* t = in->FirstChildElement("inertia")) {
    const std::string w = what + " <inertia>";
    const double ixx = parse_number(t, "ixx", w, 0, true), ixy = parse_number(t, "ixy", w, 0, true),
                 ixz = parse_number(t, "ixz", w, 0, true), iyy = parse_number(t, "iyy", w, 0, true),
                 iyz = parse_number(t, "iyz", w, 0, true), izz = parse_number(t, "izz", w, 0, true);
    Ic = {{ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz}};
  }
  // moments of inertia must be >= 0; a tensor with a negative principal
  // moment (eigenvalue) is physically impossible but common in published
  // files: an error when strict, else a warning kept on the model
  const char* axes[3] = {"ixx", "iyy", "izz"};
  for (int k = 0; k < 3; ++k)
    if (Ic(k, k) < 0)
      fail("link '" + lname + "' has a negative principal moment of inertia " + axes[k] + "=" +
           std::to_string(Ic(k, k)) + " (moments of inertia must be >= 0)");
  Eigen::Matrix3d E;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) E(r, c) = Ic(r, c);
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(E, Eigen::EigenvaluesOnly).eigenvalues();
  const double scale = std::max(1.0, ev.cwiseAbs().maxCoeff());
  if (ev.minCoeff() < -1e-12 * scale) {
    std::ostringstream os;
    os << "link '" << lname << "' has a rotational inertia with a negative principal moment (eigenvalue "
       << ev.minCoeff() << "); it is not positive semi-definite";
    if (strict) fail(os.str());
    warnings.push_back(os.str());
  }
  // rotate to the link frame and move to its origin: I_o = R Ic Rᵀ - m [c]²
  const Vec3<double> c = X.p;
  const Mat3<double> C = skew(c);
  Inertia<double> I;
  I.m = mass;
  I.h = mass * c;
  I.I = X.R * Ic * transpose(X.R) - mass * (C * C);
  return I;
}

Joint parse_joint(const tinyxml2::XMLElement* e) {
  Joint j;
  const char* name = e->Attribute("name");
  if (!name || !*name) fail("a <joint> has no name");
  j.name = name;
  const std::string what = "joint '" + j.name + "'";
  const char* type = e->Attribute("type");
  if (!type) fail(what + " has no type");
  j.type = type;
  static const std::set<std::string> known = {"revolute", "continuous", "prismatic", "fixed", "floating",
                                              "planar", "spherical", "helical", "screw"};
  if (!known.count(j.type))
    fail(what + " has unknown type '" + j.type +
         "' (expected revolute, continuous, prismatic, fixed, floating, planar, spherical, helical or screw)");
  if (j.type == "screw") j.type = "helical";
  const tinyxml2::XMLElement* p = e->FirstChildElement("parent");
  const tinyxml2::XMLElement* c = e->FirstChildElement("child");
  if (!p || !p->Attribute("link")) fail(what + " has no <parent link=...>");
  if (!c || !c->Attribute("link")) fail(what + " has no <child link=...>");
  j.parent = p->Attribute("link");
  j.child = c->Attribute("link");
  j.X = parse_origin(e, what);
  if (const tinyxml2::XMLElement* a = e->FirstChildElement("axis")) {
    if (const char* t = a->Attribute("xyz")) {
      auto v = parse_numbers(t, 3, what + " axis xyz");
      const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
      if (n < 1e-12) fail(what + " has a zero axis");
      j.axis = {v[0] / n, v[1] / n, v[2] / n};
    }
    j.pitch = parse_number(a, "pitch", what + " axis", 0.0);
  }
  if (j.type == "helical") {
    if (const tinyxml2::XMLElement* s = e->FirstChildElement("pitch")) j.pitch = parse_number(s, "value", what, j.pitch);
  }
  if (const tinyxml2::XMLElement* l = e->FirstChildElement("limit")) {
    j.lower = parse_number(l, "lower", what + " limit", -kInf);
    j.upper = parse_number(l, "upper", what + " limit", kInf);
    j.effort = parse_number(l, "effort", what + " limit", kInf);
    j.velocity = parse_number(l, "velocity", what + " limit", kInf);
    if (j.lower > j.upper) fail(what + " has lower limit > upper limit");
    if (j.effort <= 0) j.effort = kInf;      // 0 means "not given" in many files
    if (j.velocity <= 0) j.velocity = kInf;
  }
  if (j.type == "continuous") j.lower = -kInf, j.upper = kInf;
  if (const tinyxml2::XMLElement* m = e->FirstChildElement("mimic")) {
    const char* t = m->Attribute("joint");
    if (!t) fail(what + " <mimic> has no joint attribute");
    j.has_mimic = true;
    j.mimic_joint = t;
    j.mult = parse_number(m, "multiplier", what + " mimic", 1.0);
    j.offset = parse_number(m, "offset", what + " mimic", 0.0);
  }
  return j;
}

bool one_dof(const std::string& t) {
  return t == "revolute" || t == "continuous" || t == "prismatic" || t == "helical";
}

// a body under construction: its joint, link and the frames fixed to it
struct Builder {
  std::vector<Link> links;
  std::vector<Joint> joints;
  std::map<std::string, int> link_id, joint_id;
  Model model;

  // add body for joint j (child link carries inertia), returns body index
  int add_body(int parent, int type, const Joint& j, const Transform<double>& X_tree, const Vec3<double>& axis,
               const std::string& jname, const std::string& jtype, const std::string& body_name) {
    BodyDesc<double> b{};
    b.parent = parent;
    b.type = type;
    b.axis = axis;
    b.pitch = jtype == "helical" ? j.pitch : 0.0;
    b.mult = 1;
    b.offset = 0;
    b.X_tree = X_tree;
    b.I = Inertia<double>::zero();
    b.nq = type == kFree ? 7 : (type == kSpherical ? 4 : 1);
    b.nv = type == kFree ? 6 : (type == kSpherical ? 3 : 1);
    model.bodies.push_back(b);
    model.body_names.push_back(body_name);
    JointInfo ji;
    ji.name = jname;
    ji.type = jtype;
    ji.body = static_cast<int>(model.bodies.size()) - 1;
    model.joints.push_back(ji);
    return ji.body;
  }

  // attach link l (and everything fixed to it) to body `body` at X_body_link
  void attach(int l, int body, const Transform<double>& X_body_link, const std::string& via_joint) {
    Link& L = links[l];
    if (!via_joint.empty()) model.frames.push_back({via_joint, "joint", body, X_body_link});
    model.frames.push_back({L.name, "link", body, X_body_link});
    if (body >= 0) model.bodies[body].I += transform_inertia(X_body_link, L.I);
    for (int jc : L.child_joints) {
      const Joint& j = joints[jc];
      const int child = link_id.at(j.child);
      const Transform<double> X_tree = X_body_link * j.X;
      if (j.type == "fixed") {
        attach(child, body, X_tree, j.name);
      } else if (j.type == "planar") {
        // the plane is normal to the axis: translate along two in-plane axes, rotate about the axis
        const Vec3<double> n = j.axis;
        Vec3<double> e1 = std::fabs(n.x) < 0.9 ? Vec3<double>{1, 0, 0} : Vec3<double>{0, 1, 0};
        e1 = e1 - dot(e1, n) * n;
        e1 = (1.0 / std::sqrt(dot(e1, e1))) * e1;
        const Vec3<double> e2 = cross(n, e1);
        const int bx = add_body(body, kPrismatic, j, X_tree, e1, j.name + "_x", "prismatic", j.name + "_x");
        const int by = add_body(bx, kPrismatic, j, Transform<double>::identity(), e2, j.name + "_y", "prismatic",
                                j.name + "_y");
        const int br = add_body(by, kRevolute, j, Transform<double>::identity(), n, j.name + "_rot", "revolute",
                                links[child].name);
        model.frames.push_back({j.name, "joint", br, Transform<double>::identity()});
        attach(child, br, Transform<double>::identity(), "");
      } else {
        int type = kRevolute;
        if (j.type == "prismatic") type = kPrismatic;
        if (j.type == "helical") type = kHelical;
        if (j.type == "spherical") type = kSpherical;
        if (j.type == "floating") type = kFree;
        const std::string jtype = j.type == "floating" ? "free" : j.type;
        const int b = add_body(body, type, j, X_tree, j.axis, j.name, jtype, links[child].name);
        attach(child, b, Transform<double>::identity(), j.name);
      }
    }
  }
};

Model build(const tinyxml2::XMLDocument& doc, bool floating_base, bool strict) {
  const tinyxml2::XMLElement* robot = doc.FirstChildElement("robot");
  if (!robot) fail("no <robot> element at the top level");
  Builder B;
  B.model.name = robot->Attribute("name") ? robot->Attribute("name") : "";
  B.model.floating_base = floating_base;

  // 1. links and joints
  for (const tinyxml2::XMLElement* e = robot->FirstChildElement("link"); e; e = e->NextSiblingElement("link")) {
    const char* name = e->Attribute("name");
    if (!name || !*name) fail("a <link> has no name");
    if (B.link_id.count(name)) fail("link '" + std::string(name) + "' is defined twice");
    Link L;
    L.name = name;
    L.I = parse_inertial(e, L.name, strict, B.model.warnings);
    B.link_id[L.name] = static_cast<int>(B.links.size());
    B.links.push_back(L);
  }
  if (B.links.empty()) fail("the robot has no <link>");
  for (const tinyxml2::XMLElement* e = robot->FirstChildElement("joint"); e; e = e->NextSiblingElement("joint")) {
    Joint j = parse_joint(e);
    if (B.joint_id.count(j.name)) fail("joint '" + j.name + "' is defined twice");
    if (!B.link_id.count(j.parent)) fail("joint '" + j.name + "' names parent link '" + j.parent + "', which is not defined");
    if (!B.link_id.count(j.child)) fail("joint '" + j.name + "' names child link '" + j.child + "', which is not defined");
    if (j.parent == j.child) fail("joint '" + j.name + "' connects link '" + j.parent + "' to itself");
    const int id = static_cast<int>(B.joints.size());
    Link& child = B.links[B.link_id[j.child]];
    if (child.parent_joint >= 0)
      fail("link '" + j.child + "' is the child of two joints ('" + B.joints[child.parent_joint].name + "' and '" +
           j.name + "'); a URDF must be a tree");
    child.parent_joint = id;
    B.links[B.link_id[j.parent]].child_joints.push_back(id);
    B.joint_id[j.name] = id;
    B.joints.push_back(j);
  }

  // 2. the root
  std::vector<int> roots;
  for (size_t l = 0; l < B.links.size(); ++l)
    if (B.links[l].parent_joint < 0) roots.push_back(static_cast<int>(l));
  if (roots.empty()) fail("the joints form a cycle: every link has a parent, so there is no root link");
  if (roots.size() > 1)
    fail("the robot has " + std::to_string(roots.size()) + " root links ('" + B.links[roots[0]].name + "' and '" +
         B.links[roots[1]].name + "'); a URDF must be a single tree");
  const int root = roots[0];
  {
    // every link reachable from the root, else the rest form a cycle
    std::vector<int> seen(B.links.size(), 0), stack = {root};
    size_t count = 0;
    while (!stack.empty()) {
      const int l = stack.back();
      stack.pop_back();
      if (seen[l]) continue;
      seen[l] = 1;
      ++count;
      for (int jc : B.links[l].child_joints) stack.push_back(B.link_id[B.joints[jc].child]);
    }
    if (count != B.links.size()) {
      for (size_t l = 0; l < B.links.size(); ++l)
        if (!seen[l]) fail("the joints form a cycle through link '" + B.links[l].name + "'");
    }
  }

  // 3. bodies, depth-first in document order
  Model& m = B.model;
  if (floating_base) {
    Joint free;
    free.name = "root_joint";
    const int b = B.add_body(-1, kFree, free, Transform<double>::identity(), {1, 0, 0}, "root_joint", "free",
                             B.links[root].name);
    B.attach(root, b, Transform<double>::identity(), "root_joint");
  } else {
    B.attach(root, -1, Transform<double>::identity(), "");
  }

  // 4. mimic joints: flatten chains onto a joint that owns its coordinate
  std::map<std::string, int> body_of_joint;
  for (size_t i = 0; i < m.joints.size(); ++i) body_of_joint[m.joints[i].name] = static_cast<int>(i);
  for (size_t i = 0; i < m.joints.size(); ++i) {
    auto it = B.joint_id.find(m.joints[i].name);
    if (it == B.joint_id.end() || !B.joints[it->second].has_mimic) continue;
    const Joint& j = B.joints[it->second];
    if (!one_dof(j.type)) fail("joint '" + j.name + "' is a " + j.type + " joint; only 1-DoF joints can mimic");
    double mult = 1, offset = 0;
    std::string cur = j.name;
    std::set<std::string> visited;
    while (true) {
      const Joint& cj = B.joints[B.joint_id.at(cur)];
      if (!cj.has_mimic) break;
      if (!visited.insert(cur).second) fail("mimic joints form a cycle through joint '" + cur + "'");
      if (!B.joint_id.count(cj.mimic_joint))
        fail("joint '" + cj.name + "' mimics joint '" + cj.mimic_joint + "', which is not defined");
      const Joint& tj = B.joints[B.joint_id.at(cj.mimic_joint)];
      if (!one_dof(tj.type)) fail("joint '" + cj.name + "' mimics '" + tj.name + "', a " + tj.type +
                                  " joint; the target of a mimic must be a 1-DoF joint");
      // q_cur = cj.mult q_t + cj.offset
      offset = offset + mult * cj.offset;
      mult = mult * cj.mult;
      cur = tj.name;
    }
    m.joints[i].mimic_of = cur;
    m.joints[i].multiplier = mult;
    m.joints[i].offset = offset;
  }

  // 5. coordinates and limits, in body order
  int nq = 0, nv = 0;
  for (size_t i = 0; i < m.bodies.size(); ++i) {
    if (!m.joints[i].mimic_of.empty()) continue;
    BodyDesc<double>& b = m.bodies[i];
    b.q_idx = nq;
    b.v_idx = nv;
    m.joints[i].q_idx = nq;
    m.joints[i].v_idx = nv;
    m.joints[i].nq = b.nq;
    m.joints[i].nv = b.nv;
    nq += b.nq;
    nv += b.nv;
    auto it = B.joint_id.find(m.joints[i].name);
    const Joint* src = it != B.joint_id.end() ? &B.joints[it->second] : nullptr;
    const bool planar_part = !src;  // sub-joints of a planar joint and the root joint
    for (int k = 0; k < b.nq; ++k) {
      const bool bounded = src && one_dof(src->type) && !planar_part;
      m.lower.push_back(bounded ? src->lower : -kInf);
      m.upper.push_back(bounded ? src->upper : kInf);
    }
    for (int k = 0; k < b.nv; ++k) {
      m.velocity_limit.push_back(src && !planar_part ? src->velocity : kInf);
      m.effort_limit.push_back(src && !planar_part ? src->effort : kInf);
    }
  }
  for (size_t i = 0; i < m.bodies.size(); ++i) {
    if (m.joints[i].mimic_of.empty()) continue;
    const int t = body_of_joint.at(m.joints[i].mimic_of);
    BodyDesc<double>& b = m.bodies[i];
    b.mimic = 1;
    b.q_idx = m.bodies[t].q_idx;
    b.v_idx = m.bodies[t].v_idx;
    b.nq = 1;
    b.nv = 1;
    b.mult = m.joints[i].multiplier;
    b.offset = m.joints[i].offset;
    m.joints[i].q_idx = b.q_idx;
    m.joints[i].v_idx = b.v_idx;
  }
  m.nq = nq;
  m.nv = nv;
  m.finalize();
  return m;
}

}  // namespace

Model Model::from_urdf_string(const std::string& xml, bool floating_base, bool strict) {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(xml.c_str(), xml.size()) != tinyxml2::XML_SUCCESS) {
    std::ostringstream os;
    os << "malformed XML: " << (doc.ErrorStr() ? doc.ErrorStr() : "parse error");
    fail(os.str());
  }
  return build(doc, floating_base, strict);
}

Model Model::from_urdf_file(const std::string& path, bool floating_base, bool strict) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::invalid_argument("URDF: cannot open file '" + path + "'");
  std::stringstream ss;
  ss << f.rdbuf();
  return from_urdf_string(ss.str(), floating_base, strict);
}

}  // namespace rbd
