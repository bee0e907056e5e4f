// Model: lookups by name, the neutral configuration and the derived
// per-body sizes the algorithms read.
#include "rbdkit/model.hpp"

#include <algorithm>
#include <stdexcept>

#include "rbdkit/configuration.hpp"

namespace rbd {

bool Model::has_mimic() const {
  for (const auto& b : bodies)
    if (b.mimic) return true;
  return false;
}

void Model::finalize() {
  // velocity coordinates in each subtree (children come after parents)
  for (auto& b : bodies) b.nv_subtree = b.mimic ? 0 : b.nv;
  for (int i = nb() - 1; i >= 0; --i)
    if (bodies[i].parent >= 0) bodies[bodies[i].parent].nv_subtree += bodies[i].nv_subtree;
}

std::vector<std::string> Model::joint_names() const {
  std::vector<std::string> out;
  for (const auto& j : joints)
    if (j.mimic_of.empty()) out.push_back(j.name);
  return out;
}

std::vector<std::string> Model::frame_names() const {
  std::vector<std::string> out;
  for (const auto& f : frames) out.push_back(f.name);
  return out;
}

namespace {
// a short list of known names sharing a prefix with the unknown one
std::string suggestions(const std::string& name, const std::vector<std::string>& known) {
  std::vector<std::string> close;
  for (const auto& k : known) {
    size_t p = 0;
    while (p < k.size() && p < name.size() && k[p] == name[p]) ++p;
    if (p >= 3 || k.find(name) != std::string::npos) close.push_back(k);
  }
  std::string s;
  const auto& list = close.empty() ? known : close;
  for (size_t i = 0; i < list.size() && i < 8; ++i) s += (i ? ", '" : "'") + list[i] + "'";
  if (list.size() > 8) s += ", ...";
  return s;
}
}  // namespace

int Model::frame_index(const std::string& frame) const {
  for (size_t i = 0; i < frames.size(); ++i)
    if (frames[i].name == frame) return static_cast<int>(i);
  throw std::invalid_argument("unknown frame '" + frame + "' in robot '" + name + "'; known frames include " +
                              suggestions(frame, frame_names()));
}

int Model::joint_index(const std::string& joint) const {
  std::vector<std::string> names;
  for (size_t i = 0; i < joints.size(); ++i) {
    if (joints[i].name == joint) return static_cast<int>(i);
    names.push_back(joints[i].name);
  }
  throw std::invalid_argument("unknown joint '" + joint + "' in robot '" + name + "'; known joints include " +
                              suggestions(joint, names));
}

std::vector<double> Model::neutral() const {
  std::vector<double> q(nq);
  rbd::neutral(view(), q.data());
  return q;
}

}  // namespace rbd
