// src/codegen/generate.cpp — rbd::generate_header (codegen/generate.hpp).
//
// Outline of the header it writes:
//   struct NAME
//     nq, nv, nb, has_mimic                      compile-time sizes
//     workspace_bytes<S>(full), step_scratch     the scratch one call needs, counted by the library here
//     bodies<S>(b)                               every BodyDesc as an aggregate of literals, one per body
//     inverse_dynamics ... integrator_gradient   one function template per entry point, each a stack
//                                                workspace (Call) and one call of the library's algorithm
#include "rbdkit/codegen/generate.hpp"

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <sstream>
#include <stdexcept>

#include "rbdkit/model/workspace.hpp"
#include "rbdkit/plant/integrators.hpp"

namespace rbd {
namespace {

// a double as its shortest literal that round-trips, wrapped as S(...)
std::string lit(double x) {
  char buf[40];
  for (int digits = 1; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, x);
    if (std::strtod(buf, nullptr) == x) break;
  }
  std::string s(buf);
  if (s.find_first_of(".en") == std::string::npos) s += ".0";  // (a double literal, not an int)
  return "S(" + s + ")";
}

std::string vec3(const Vec3<double>& v) { return "{" + lit(v.x) + ", " + lit(v.y) + ", " + lit(v.z) + "}"; }

std::string mat3(const Mat3<double>& m) {
  std::string s = "{{";
  for (int k = 0; k < 9; ++k) s += (k ? ", " : "") + lit(m.m[k]);
  return s + "}}";
}

const char* joint_type_name(int type) {
  switch (type) {
    case kRevolute: return "rbd::kRevolute";
    case kPrismatic: return "rbd::kPrismatic";
    case kHelical: return "rbd::kHelical";
    case kSpherical: return "rbd::kSpherical";
    case kFree: return "rbd::kFree";
  }
  throw std::invalid_argument("generate_header: unknown joint type " + std::to_string(type));
}

bool is_identifier(const std::string& s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  return true;
}

// names the struct cannot take: C++ keywords and alternative tokens, and its own members
bool is_reserved(const std::string& s) {
  static const std::set<std::string> reserved = {
      "alignas", "alignof", "and", "and_eq", "asm", "auto", "bitand", "bitor", "bool", "break", "case", "catch",
      "char", "char16_t", "char32_t", "char8_t", "class", "compl", "concept", "const", "consteval", "constexpr",
      "constinit", "const_cast", "continue", "co_await", "co_return", "co_yield", "decltype", "default", "delete",
      "do", "double", "dynamic_cast", "else", "enum", "explicit", "export", "extern", "false", "float", "for",
      "friend", "goto", "if", "inline", "int", "long", "mutable", "namespace", "new", "noexcept", "not", "not_eq",
      "nullptr", "operator", "or", "or_eq", "private", "protected", "public", "register", "reinterpret_cast",
      "requires", "return", "short", "signed", "sizeof", "static", "static_assert", "static_cast", "struct",
      "switch", "template", "this", "thread_local", "throw", "true", "try", "typedef", "typeid", "typename",
      "union", "unsigned", "using", "virtual", "void", "volatile", "wchar_t", "while", "xor", "xor_eq",
      // the struct's members and the namespaces it uses
      "nq", "nv", "nb", "has_mimic", "workspace_bytes", "step_scratch", "bodies", "inverse_dynamics", "aba", "crba",
      "minv", "inverse_dynamics_gradient", "forward_dynamics_gradient", "integrator_gradient", "Call", "rbd",
      "rbdkit_generated"};
  return reserved.count(s) > 0;
}

// text from the model (names, a path) made safe for a // comment: one line, printable ASCII
std::string comment_text(const std::string& s) {
  std::string out;
  for (char c : s) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  return out;
}

// body i's inertia read from pi (Model::inertial_parameters' layout: m, m·c, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)
std::string runtime_inertia(int i) {
  const std::string b = "pi[" + std::to_string(10 * i);
  auto at = [&](int k) { return k ? b + " + " + std::to_string(k) + "]" : b + "]"; };
  return "{" + at(0) + ", {" + at(1) + ", " + at(2) + ", " + at(3) + "}, {{" + at(4) + ", " + at(5) + ", " + at(7) +
         ", " + at(5) + ", " + at(6) + ", " + at(8) + ", " + at(7) + ", " + at(8) + ", " + at(9) + "}}}";
}

}  // namespace

std::string generate_header(const Model& model, const std::string& name, const std::string& source,
                            bool runtime_inertias) {
  if (!is_identifier(name) || is_reserved(name))
    throw std::invalid_argument("name: expected a C++ identifier (letters, digits, _; not starting with a digit) "
                                "that is not a keyword or one of the struct's members, got '" + comment_text(name) +
                                "'");
  const int nb = model.nb(), nq = model.nq, nv = model.nv;
  if (nb == 0) throw std::invalid_argument("model: has no moving body; there is nothing to generate");
  std::ostringstream o;
  o << "// " << name << ".hpp — generated by `rbdkit generate`"
    << (source.empty() ? "" : " from " + comment_text(source)) << ". Do not edit; generate again.\n"
       "//\n"
       "// The robot '" << comment_text(model.name) << "' as compile-time constants and per-robot entry points\n"
       "// over rbdkit's header-only per-sample algorithms (the library's own templates, instantiated with\n"
       "// these constants):\n"
       "// compile with -I <rbdkit>/include, C++17, nothing to link. Every function is host and device code\n"
       "// (nvcc: call it from your own kernels, one sample per call). Arrays are raw pointers in S (float or\n"
       "// double); matrices are row-major; q (nq), velocities and torques (nv); quaternions x y z w;\n"
       "// derivatives in the tangent space (docs/conventions.md). Each call keeps its workspace on the\n"
       "// stack: workspace_bytes<S>(full) bytes, and integrator_gradient step_scratch values more (a CUDA\n"
       "// thread's stack is at most 512 KiB: too little for that of a humanoid in double).\n"
       "#pragma once\n\n"
       "#include \"rbdkit/algorithms/aba_derivatives.hpp\"\n"
       "#include \"rbdkit/algorithms/crba.hpp\"\n"
       "#include \"rbdkit/algorithms/minv.hpp\"\n"
       "#include \"rbdkit/algorithms/rnea.hpp\"\n"
       "#include \"rbdkit/algorithms/rnea_derivatives.hpp\"\n"
       "#include \"rbdkit/plant/integrators.hpp\"\n\n"
       "namespace rbdkit_generated {\n\n"
       "struct " << name << " {\n"
       "  static constexpr int nq = " << nq << ", nv = " << nv << ", nb = " << nb << ";\n"
       "  static constexpr int has_mimic = " << (model.has_mimic() ? 1 : 0) << ";\n\n"
       "  // bytes of one call's workspace (rbd::workspace_bytes): the O(n) layout (inverse_dynamics, aba\n"
       "  // without mimic joints) or the full one\n"
       "  template <class S> static constexpr unsigned long workspace_bytes(bool full) {\n"
       "    return sizeof(S) == sizeof(float)\n"
       "               ? (full ? " << workspace_bytes<float>(nb, nv) << "ul : "
    << workspace_bytes<float>(nb, nv, kLinearWorkspace) << "ul)\n"
       "               : (full ? " << workspace_bytes<double>(nb, nv) << "ul : "
    << workspace_bytes<double>(nb, nv, kLinearWorkspace) << "ul);\n"
       "  }\n"
       "  // values of integrator_gradient's scratch (rbd::integrator_gradient_scratch_values)\n"
       "  static constexpr long step_scratch = " << integrator_gradient_scratch_values(nq, nv) << ";\n\n"
       "  // the bodies in topological order (rbd::BodyDesc): parent, joint type, q and v index, nq, nv,\n"
       "  // nv of the subtree, mimic (multiplier, offset), helical pitch, axis (and k + 1 when it is ±e_k),\n"
       "  // X_parent_joint (R, p),\n"
    << (runtime_inertias
            ? "  // inertia in the body frame from pi, 10 per body (m, m·c, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz\n"
              "  // about the body origin: rbdkit.Model.inertial_parameters' layout; no consistency check here)\n"
              "  template <class S> RBD_HD static void bodies(rbd::BodyDesc<S>* b, const S* pi) {\n"
            : "  // inertia in the body frame (m, m·c, I about the body origin)\n"
              "  template <class S> RBD_HD static void bodies(rbd::BodyDesc<S>* b) {\n");
  for (int i = 0; i < nb; ++i) {
    const BodyDesc<double>& d = model.bodies[i];
    const std::string parent = d.parent < 0 ? "world" : model.body_names[d.parent];
    o << "    // " << i << " " << comment_text(model.body_names[i]) << ": joint '" << comment_text(model.joints[i].name)
      << "' (" << comment_text(model.joints[i].type) << "), parent " << comment_text(parent) << "\n"
      << "    b[" << i << "] = {" << d.parent << ", " << joint_type_name(d.type) << ", " << d.q_idx << ", " << d.v_idx
      << ", " << d.nq << ", " << d.nv << ", " << d.nv_subtree << ", " << d.mimic << ", " << lit(d.mult) << ", "
      << lit(d.offset) << ", " << lit(d.pitch) << ",\n"
      << "            " << vec3(d.axis) << ", " << d.axis_k << ",\n"
      << "            {" << mat3(d.X_tree.R) << ", " << vec3(d.X_tree.p) << "},\n"
      << "            "
      << (runtime_inertias ? runtime_inertia(i) : "{" + lit(d.I.m) + ", " + vec3(d.I.h) + ", " + mat3(d.I.I) + "}")
      << "};\n";
  }
  // with runtime inertias, pi (10·nb) is every entry point's first parameter and each call's Call reads it
  const std::string P = runtime_inertias ? "const S* pi, " : "";
  const std::string C = runtime_inertias ? " c(pi);\n" : " c;\n";
  o << "  }\n\n"
       "  // tau (nv) = M qdd + C qd + g(q): RNEA (qdd may be null: zero)\n"
       "  template <class S>\n"
       "  RBD_HD static void inverse_dynamics(" << P << "const S* q, const S* qd, const S* qdd, S gravity, S* tau) {\n"
       "    Call<S, false>" << C <<
       "    rbd::rnea(c.m, c.w, q, qd, qdd, static_cast<const S*>(nullptr), gravity, tau);\n"
       "  }\n\n"
       "  // qdd (nv): the articulated-body algorithm; false if a joint-space inertia is singular\n"
       "  template <class S>\n"
       "  RBD_HD static bool aba(" << P << "const S* q, const S* qd, const S* tau, S gravity, S* qdd) {\n"
       "    Call<S, bool(has_mimic)>" << C <<
       "    return rbd::aba(c.m, c.w, q, qd, tau, static_cast<const S*>(nullptr), gravity, qdd);\n"
       "  }\n\n"
       "  // M (nv x nv): the composite-rigid-body algorithm\n"
       "  template <class S> RBD_HD static void crba(" << P << "const S* q, S* M) {\n"
       "    Call<S, true>" << C <<
       "    rbd::crba(c.m, c.w, q, M);\n"
       "  }\n\n"
       "  // M⁻¹ (nv x nv, dense); false if M is singular\n"
       "  template <class S> RBD_HD static bool minv(" << P << "const S* q, S* Minv) {\n"
       "    Call<S, true>" << C <<
       "    return rbd::minv(c.m, c.w, q, true, Minv);\n"
       "  }\n\n"
       "  // ∂tau/∂q, ∂tau/∂qd (nv x nv each) of inverse_dynamics (qdd may be null: zero)\n"
       "  template <class S>\n"
       "  RBD_HD static void inverse_dynamics_gradient(" << P << "const S* q, const S* qd, const S* qdd, S gravity,\n"
       "                                               S* dtau_dq, S* dtau_dqd) {\n"
       "    Call<S, true>" << C <<
       "    rbd::rnea_derivatives(c.m, c.w, q, qd, qdd, static_cast<const S*>(nullptr), gravity, dtau_dq, dtau_dqd);\n"
       "  }\n\n"
       "  // ∂qdd/∂q, ∂qdd/∂qd (nv x nv each) of qdd = aba(q, qd, tau); false if M is singular\n"
       "  template <class S>\n"
       "  RBD_HD static bool forward_dynamics_gradient(" << P << "const S* q, const S* qd, const S* tau, S gravity,\n"
       "                                               S* dqdd_dq, S* dqdd_dqd) {\n"
       "    Call<S, true>" << C <<
       "    S qdd[nv];\n"
       "    return rbd::aba_derivatives(c.m, c.w, q, qd, tau, static_cast<const S*>(nullptr), gravity, qdd, dqdd_dq,\n"
       "                                dqdd_dqd);\n"
       "  }\n\n"
       "  // one step x⁺ = [q⁺; qd⁺] (nq + nv) of scheme `type` (rbd::IntegratorType: 0 euler, 1\n"
       "  // semi_implicit_euler, 2 midpoint, 3 rk4, 4 trapezoidal, 5 constant_acceleration) and its\n"
       "  // [A | B] = ∂x⁺/∂(x, u) (2 nv x 3 nv, tangent space; AB may be null); false if a step fails\n"
       "  template <class S>\n"
       "  RBD_HD static bool integrator_gradient(" << P << "const S* q, const S* qd, const S* u, S dt, int type,\n"
       "                                         S* x_next, S* AB, S gravity = S(-9.81)) {\n"
       "    Call<S, true>" << C <<
       "    S scratch[step_scratch];\n"
       "    return rbd::integrator_gradient(c.m, c.w, type, q, qd, u, static_cast<const S*>(nullptr), dt, gravity,\n"
       "                                    x_next, x_next + nq, AB, scratch);\n"
       "  }\n\n"
       " private:\n"
       "  // one call's model view and workspace, on the stack, not zero-filled: these algorithms write every\n"
       "  // array before they read it (tests/python/test_generate.py runs them under valgrind)\n"
       "  template <class S, bool Full> struct Call {\n"
       "    rbd::BodyDesc<S> body[nb];\n"
       "    alignas(16) unsigned char buffer[workspace_bytes<S>(Full)];\n"
       "    rbd::ModelView<S> m;\n"
       "    rbd::Workspace<S> w;\n"
    << (runtime_inertias ? "    RBD_HD explicit Call(const S* pi) : m{nb, nq, nv, has_mimic, body} {\n"
                           "      bodies(body, pi);\n"
                         : "    RBD_HD Call() : m{nb, nq, nv, has_mimic, body} {\n"
                           "      bodies(body);\n")
    << "      w = rbd::carve_workspace<S>(buffer, nb, nv, Full ? rbd::kFullWorkspace : rbd::kLinearWorkspace);\n"
       "    }\n"
       "  };\n"
       "};\n\n"
       "}  // namespace rbdkit_generated\n";
  return o.str();
}

}  // namespace rbd
