// URDF reader: XML (tinyxml2) -> ModelBuilder -> Model.
//
// outline:
//   1. read links (inertials) and joints (type, origin, axis, limits, mimic)
//   2. find the single root; reject cycles, second parents, missing links
//   3. walk depth-first from the root, children in document order, with an
//      explicit stack (chains of any depth): fixed joints merge their child
//      into the parent body (a frame remains), planar joints become two
//      prismatic and one revolute sub-joint, every other joint makes a body
//   4. mimic couplings (mimic = true) go to the builder, which flattens
//      chains, rejects cycles and assigns coordinates and limits
#include <tinyxml2.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

#include "rbdkit/parsers/builder.hpp"
#include "rbdkit/parsers/model.hpp"

namespace rbd {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// the length of the valid UTF-8 sequence at s[i], 0 if there is none
size_t utf8_length(const std::string& s, size_t i) {
  const unsigned char c = static_cast<unsigned char>(s[i]);
  // continuation bytes after the lead byte c
  const int n = c < 0x80 ? 0 : (c & 0xE0) == 0xC0 ? 1 : (c & 0xF0) == 0xE0 ? 2 : (c & 0xF8) == 0xF0 ? 3 : -1;
  bool ok = n >= 0 && i + n < s.size();
  for (int k = 1; ok && k <= n; ++k) ok = (static_cast<unsigned char>(s[i + k]) & 0xC0) == 0x80;
  if (ok && n > 0) {
    const unsigned char d = static_cast<unsigned char>(s[i + 1]);
    if (n == 1) ok = c >= 0xC2;                                              // overlong
    if (n == 2) ok = !(c == 0xE0 && d < 0xA0) && !(c == 0xED && d >= 0xA0);  // overlong, surrogates
    if (n == 3) ok = c <= 0xF4 && !(c == 0xF0 && d < 0x90) && !(c == 0xF4 && d >= 0x90);
  }
  return ok ? n + 1 : 0;
}

// text of the file quoted in a message or warning, each byte that is not
// valid UTF-8 shown as '?' (Python reads messages as str)
std::string printable(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size();) {
    const size_t n = utf8_length(s, i);
    out.append(n ? s.substr(i, n) : std::string("?"));
    i += n ? n : 1;
  }
  return out;
}

[[noreturn]] void fail(const std::string& msg) { throw std::invalid_argument("URDF: " + printable(msg)); }

// `n` numbers from `text`; errors name `what` (and attribute `attr`, if given),
// a message built only on failure
std::vector<double> parse_numbers(const char* text, size_t n, const std::string& what, const char* attr = nullptr) {
  auto where = [&] { return attr ? what + " attribute '" + attr + "'" : what; };
  std::vector<double> out;
  out.reserve(n);
  std::string tok;  // one whitespace-separated token (no stream: this runs for every attribute)
  for (const char* p = text; p && *p;) {
    const char* start = p + std::strspn(p, " \t\n\r\f\v");
    if (!*start) break;
    p = start + std::strcspn(start, " \t\n\r\f\v");
    tok.assign(start, p);
    char* end = nullptr;
    const double x = std::strtod(tok.c_str(), &end);
    if (end == tok.c_str() || *end != '\0' || !std::isfinite(x))
      fail(where() + " has '" + tok + "', expected a finite number");
    out.push_back(x);
  }
  if (out.size() != n)
    fail(where() + " must have " + std::to_string(n) + " numbers, got '" + (text ? text : "") + "'");
  return out;
}

double parse_number(const tinyxml2::XMLElement* e, const char* attr, const std::string& what, double dflt,
                    bool required = false) {
  const char* t = e ? e->Attribute(attr) : nullptr;
  if (!t) {
    if (required) fail(what + " is missing attribute '" + attr + "'");
    return dflt;
  }
  return parse_numbers(t, 1, what, attr)[0];
}

// R itself, or the signed permutation it is to within 1e-10 in every entry. An rpy of quarter turns
// leaves cos(π/2)'s rounding where the turn has exact zeros: 6e-17 written to double precision
// (1.5707963267948966), 5e-12 to 11 digits (HyQ's 1.57079632679); the exact zeros are what the
// algorithms' frame-axis forms test for (crba_act_columns, frame_turn_form). The snap moves the
// placement by at most 1e-10 rad. A rotation further from one (Atlas's π/2 rounded to float32, 4e-8
// off) is kept as it is
inline Mat3<double> snap_quarter_turns(const Mat3<double>& R) {
  Mat3<double> P = Mat3<double>::zero();
  for (int r = 0; r < 3; ++r) {
    int ones = 0;
    for (int c = 0; c < 3; ++c) {
      const double x = R(r, c);
      if (std::abs(std::abs(x) - 1.0) <= 1e-10) {
        P(r, c) = x > 0 ? 1.0 : -1.0;
        ++ones;
      } else if (std::abs(x) > 1e-10) {
        return R;
      }
    }
    if (ones != 1) return R;
  }
  for (int c = 0; c < 3; ++c)  // one ±1 in each column too: a signed permutation
    if (std::abs(P(0, c)) + std::abs(P(1, c)) + std::abs(P(2, c)) != 1.0) return R;
  return P;
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
    X.R = snap_quarter_turns(Rz * Ry * Rx);
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
  // moments of inertia must be >= 0. A diagonal moment that is negative only
  // by rounding (|I_kk| <= 1e-6 of the largest moment, or 1e-15 kg·m²) is
  // kept with a warning; a clearly negative one is an error. A tensor with a
  // negative principal moment (eigenvalue) or principal moments that break
  // the triangle inequality is physically impossible but common in
  // published files: an error when strict, else a warning kept on the model.
  const char* axes[3] = {"ixx", "iyy", "izz"};
  const double largest = std::max({std::fabs(Ic(0, 0)), std::fabs(Ic(1, 1)), std::fabs(Ic(2, 2))});
  const double rounding = std::max(1e-6 * largest, 1e-15);
  for (int k = 0; k < 3; ++k) {
    if (Ic(k, k) >= 0) continue;
    std::ostringstream os;
    os << "link '" << lname << "' has a negative principal moment of inertia " << axes[k] << "=" << Ic(k, k);
    if (Ic(k, k) < -rounding) fail(os.str() + " (moments of inertia must be >= 0)");
    warnings.push_back(os.str() + ", negative only by rounding; kept as given");
  }
  Eigen::Matrix3d E;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) E(r, c) = Ic(r, c);
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(E, Eigen::EigenvaluesOnly).eigenvalues();
  const double scale = std::max(1.0, ev.cwiseAbs().maxCoeff());
  auto doubt = [&](const std::string& why) {
    std::ostringstream os;
    os << "link '" << lname << "' has a rotational inertia " << why << " (principal moments " << ev(0) << ", "
       << ev(1) << ", " << ev(2) << ")";
    if (strict) fail(os.str());
    warnings.push_back(os.str());
  };
  if (ev.minCoeff() < -1e-12 * scale) doubt("with a negative principal moment; it is not positive semi-definite");
  else if (ev(2) > ev(0) + ev(1) + 1e-10 * std::fabs(E.trace()))
    doubt("that violates the triangle inequality (the largest principal moment exceeds the sum of the other two)");
  // rotated to the link frame, moved to its origin: I_o = R Ic Rᵀ - m [c]²
  return rigid_inertia(mass, X.p, X.R * Ic * transpose(X.R));
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
    // kept as written: the builder normalises it on a moving joint and
    // rejects a zero one there; a fixed joint's axis is never read
    if (const char* t = a->Attribute("xyz")) {
      auto v = parse_numbers(t, 3, what + " axis xyz");
      j.axis = {v[0], v[1], v[2]};
    }
    j.pitch = parse_number(a, "pitch", what + " axis", 0.0);
  }
  if (j.type == "helical") {
    if (const tinyxml2::XMLElement* s = e->FirstChildElement("pitch")) j.pitch = parse_number(s, "value", what, j.pitch);
  }
  if (const tinyxml2::XMLElement* l = e->FirstChildElement("limit")) {
    // lower > upper is kept with a warning (ModelBuilder), as Pinocchio keeps it
    j.lower = parse_number(l, "lower", what + " limit", -kInf);
    j.upper = parse_number(l, "upper", what + " limit", kInf);
    j.effort = parse_number(l, "effort", what + " limit", kInf);
    j.velocity = parse_number(l, "velocity", what + " limit", kInf);
  }
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

// a name is read back by Python as str: it must be valid UTF-8
void check_utf8(const std::string& s, const std::string& what) {
  for (size_t i = 0; i < s.size();) {
    const size_t n = utf8_length(s, i);
    if (!n) fail(what + " is not valid UTF-8 (at byte " + std::to_string(i) + ")");
    i += n;
  }
}

// the URDF's links and joints, and the walk that hands them to a ModelBuilder
struct Reader {
  std::vector<Link> links;
  std::vector<Joint> joints;
  std::unordered_map<std::string, int> link_id, joint_id;
  std::unordered_set<std::string> taken;  // every name in the file and every name generated so far
  ModelBuilder builder;

  // base, or base_1, base_2, ... : a generated name never equals a name of
  // the file (a user joint "root_joint" keeps its name)
  std::string unique_name(const std::string& base) {
    std::string n = base;
    for (int k = 1; taken.count(n); ++k) n = base + "_" + std::to_string(k);
    taken.insert(n);
    return n;
  }

  // a body for the moving joint j under `parent`, placed at X_parent_joint
  int add_body(int parent, const Joint& j, const std::string& name, const std::string& type,
               const Transform<double>& X_parent_joint, const Vec3<double>& axis, const std::string& body_name,
               bool limits) {
    JointSpec s;
    s.name = name;
    s.type = type;
    s.X_parent_joint = X_parent_joint;
    s.axis = axis;
    s.pitch = j.pitch;
    if (limits) s.lower = j.lower, s.upper = j.upper, s.velocity = j.velocity, s.effort = j.effort;
    return builder.add_body(parent, s, body_name);
  }

  // the frames and inertia of link l, fixed to `body` at X_body_link
  void visit_link(int l, int body, const Transform<double>& X_body_link, const std::string& via_joint) {
    const Link& L = links[l];
    if (!via_joint.empty()) builder.add_frame(via_joint, "joint", body, X_body_link);
    builder.add_frame(L.name, "link", body, X_body_link);
    if (body >= 0) builder.add_inertia(body, L.I, X_body_link);
  }

  // depth-first from link `root` on `root_body`, children in document order
  void walk(int root, int root_body, const std::string& root_via) {
    struct Edge {
      int joint, body;                // the joint to the child, the body its parent link is fixed to
      Transform<double> X_body_link;  // the parent link in that body
    };
    std::vector<Edge> stack;
    auto visit = [&](int l, int body, const Transform<double>& X, const std::string& via) {
      visit_link(l, body, X, via);
      const std::vector<int>& ch = links[l].child_joints;
      for (auto it = ch.rbegin(); it != ch.rend(); ++it) stack.push_back({*it, body, X});
    };
    visit(root, root_body, Transform<double>::identity(), root_via);
    while (!stack.empty()) {
      const Edge e = stack.back();
      stack.pop_back();
      const Joint& j = joints[e.joint];
      const int child = link_id.at(j.child);
      const Transform<double> X_tree = e.X_body_link * j.X;
      if (j.type == "fixed") {
        visit(child, e.body, X_tree, j.name);
      } else if (j.type == "planar") {
        // the plane is normal to the axis: translate along two in-plane axes, rotate about the axis
        const Vec3<double> n = unit_axis(j.axis, "joint '" + j.name + "' (planar: the axis is the plane's normal)");
        Vec3<double> e1 = std::fabs(n.x) < 0.9 ? Vec3<double>{1, 0, 0} : Vec3<double>{0, 1, 0};
        e1 = e1 - dot(e1, n) * n;
        e1 = (1.0 / std::sqrt(dot(e1, e1))) * e1;
        const Vec3<double> e2 = cross(n, e1);
        const Transform<double> I = Transform<double>::identity();
        const std::string nx = unique_name(j.name + "_x"), ny = unique_name(j.name + "_y");
        const std::string nr = unique_name(j.name + "_rot");
        const int bx = add_body(e.body, j, nx, "prismatic", X_tree, e1, nx, false);
        const int by = add_body(bx, j, ny, "prismatic", I, e2, ny, false);
        const int br = add_body(by, j, nr, "revolute", I, n, links[child].name, false);
        builder.add_frame(j.name, "joint", br, I);
        visit(child, br, I, "");
      } else {
        const std::string type = j.type == "floating" ? "free" : j.type;
        const int b = add_body(e.body, j, j.name, type, X_tree, j.axis, links[child].name, true);
        visit(child, b, Transform<double>::identity(), j.name);
      }
    }
  }
};

Model build(const tinyxml2::XMLDocument& doc, bool floating_base, bool strict, bool mimic) {
  const tinyxml2::XMLElement* robot = doc.FirstChildElement("robot");
  if (!robot) fail("no <robot> element at the top level");
  const std::string robot_name = robot->Attribute("name") ? robot->Attribute("name") : "";
  check_utf8(robot_name, "the robot name");
  Reader R;
  R.builder = ModelBuilder(robot_name);
  std::vector<std::string> warnings;

  // 1. links and joints
  for (const tinyxml2::XMLElement* e = robot->FirstChildElement("link"); e; e = e->NextSiblingElement("link")) {
    const char* name = e->Attribute("name");
    if (!name || !*name) fail("a <link> has no name");
    check_utf8(name, "a link name");
    if (R.link_id.count(name)) fail("link '" + std::string(name) + "' is defined twice");
    Link L;
    L.name = name;
    L.I = parse_inertial(e, L.name, strict, warnings);
    R.link_id[L.name] = static_cast<int>(R.links.size());
    R.links.push_back(L);
    R.taken.insert(L.name);
  }
  if (R.links.empty()) fail("the robot has no <link>");
  for (const tinyxml2::XMLElement* e = robot->FirstChildElement("joint"); e; e = e->NextSiblingElement("joint")) {
    Joint j = parse_joint(e);
    check_utf8(j.name, "a joint name");
    if (R.joint_id.count(j.name)) fail("joint '" + j.name + "' is defined twice");
    if (!R.link_id.count(j.parent)) fail("joint '" + j.name + "' names parent link '" + j.parent + "', which is not defined");
    if (!R.link_id.count(j.child)) fail("joint '" + j.name + "' names child link '" + j.child + "', which is not defined");
    if (j.parent == j.child) fail("joint '" + j.name + "' connects link '" + j.parent + "' to itself");
    const int id = static_cast<int>(R.joints.size());
    Link& child = R.links[R.link_id[j.child]];
    if (child.parent_joint >= 0)
      fail("link '" + j.child + "' is the child of two joints ('" + R.joints[child.parent_joint].name + "' and '" +
           j.name + "'); a URDF must be a tree");
    child.parent_joint = id;
    R.links[R.link_id[j.parent]].child_joints.push_back(id);
    R.joint_id[j.name] = id;
    R.joints.push_back(j);
    R.taken.insert(j.name);
  }
  for (const std::string& w : warnings) R.builder.add_warning(w);

  // 2. the root
  std::vector<int> roots;
  for (size_t l = 0; l < R.links.size(); ++l)
    if (R.links[l].parent_joint < 0) roots.push_back(static_cast<int>(l));
  if (roots.empty()) fail("the joints form a cycle: every link has a parent, so there is no root link");
  if (roots.size() > 1)
    fail("the robot has " + std::to_string(roots.size()) + " root links ('" + R.links[roots[0]].name + "' and '" +
         R.links[roots[1]].name + "'); a URDF must be a single tree");
  const int root = roots[0];
  {
    // every link reachable from the root, else the rest form a cycle
    std::vector<int> seen(R.links.size(), 0), stack = {root};
    size_t count = 0;
    while (!stack.empty()) {
      const int l = stack.back();
      stack.pop_back();
      if (seen[l]) continue;
      seen[l] = 1;
      ++count;
      for (int jc : R.links[l].child_joints) stack.push_back(R.link_id[R.joints[jc].child]);
    }
    if (count != R.links.size()) {
      for (size_t l = 0; l < R.links.size(); ++l)
        if (!seen[l]) fail("the joints form a cycle through link '" + R.links[l].name + "'");
    }
  }

  // 3. bodies, depth-first in document order
  if (floating_base) {
    const std::string name = R.unique_name("root_joint");
    if (name != "root_joint")
      R.builder.add_warning("the file has a joint or link named 'root_joint'; the free-flyer added by floating_base "
                            "is named '" + name + "'");
    JointSpec free;
    free.name = name;
    free.type = "free";
    const int b = R.builder.add_body(-1, free, R.links[root].name);
    R.walk(root, b, name);
  } else {
    R.walk(root, -1, "");
  }

  // 4. mimic couplings: folded into their target's coordinate (mimic), or
  // independent coordinates (Pinocchio's default)
  for (const Joint& j : R.joints) {
    if (!j.has_mimic || !mimic) continue;
    if (!R.joint_id.count(j.mimic_joint)) {
      R.builder.add_warning("joint '" + j.name + "' mimics joint '" + printable(j.mimic_joint) +
                            "', which is not defined; it is kept as an independent joint");
      continue;
    }
    const Joint& t = R.joints[R.joint_id.at(j.mimic_joint)];
    if (j.type == "fixed") {
      // a fixed joint has no coordinate to couple (Pinocchio ignores it too)
      R.builder.add_warning("joint '" + j.name + "' is fixed; its <mimic> of joint '" + printable(j.mimic_joint) +
                            "' is ignored");
      continue;
    }
    if (!one_dof(j.type)) fail("joint '" + j.name + "' is a " + j.type + " joint; only 1-DoF joints can mimic");
    if (!one_dof(t.type))
      fail("joint '" + j.name + "' mimics '" + t.name + "', a " + t.type +
           " joint; the target of a mimic must be a 1-DoF joint");
    R.builder.add_mimic(j.name, t.name, j.mult, j.offset);
  }
  Model m = R.builder.build();
  m.floating_base = floating_base;
  return m;
}

}  // namespace

Model Model::from_urdf_string(const std::string& xml, bool floating_base, bool strict, bool mimic) {
  tinyxml2::XMLDocument doc;
  if (doc.Parse(xml.c_str(), xml.size()) != tinyxml2::XML_SUCCESS) {
    std::ostringstream os;
    os << "malformed XML: " << (doc.ErrorStr() ? doc.ErrorStr() : "parse error");
    fail(os.str());
  }
  try {
    return build(doc, floating_base, strict, mimic);
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    if (msg.rfind("URDF: ", 0) == 0) throw;
    fail(msg);
  }
}

Model Model::from_urdf_file(const std::string& path, bool floating_base, bool strict, bool mimic) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::invalid_argument("URDF: cannot open file '" + path + "'");
  std::stringstream ss;
  ss << f.rdbuf();
  return from_urdf_string(ss.str(), floating_base, strict, mimic);
}

}  // namespace rbd
