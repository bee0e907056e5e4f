// Shared by the parametrised C++ suites: every bundled robot and joint-type
// test model, fixed and floating base, and the error measure they compare with.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <ostream>
#include <string>
#include <vector>

namespace rbd_test {

struct ModelCase {
  std::string path;
  bool floating;
};
inline void PrintTo(const ModelCase& c, std::ostream* os) { *os << c.path << (c.floating ? " floating" : " fixed"); }

// iiwa, hyq, atlas (robots/) and the joint-type models (tests/urdf/), fixed and floating
inline std::vector<ModelCase> all_cases() {
  std::vector<ModelCase> out;
  for (const char* r : {"iiwa", "hyq", "atlas"})
    for (bool f : {false, true}) out.push_back({std::string(RBDKIT_ROBOTS_DIR) + "/" + r + ".urdf", f});
  for (const char* r : {"spherical", "helical", "planar", "mixed", "mimic"})
    for (bool f : {false, true}) out.push_back({std::string(RBDKIT_TEST_URDF_DIR) + "/" + r + ".urdf", f});
  return out;
}

// "atlas_floating" for a test name
inline std::string case_name(const ::testing::TestParamInfo<ModelCase>& info) {
  std::string p = info.param.path;
  p = p.substr(p.find_last_of('/') + 1);
  p = p.substr(0, p.find('.'));
  return p + (info.param.floating ? "_floating" : "_fixed");
}

// max |a - b| / max(1, max |b|)
inline double max_rel_err(const std::vector<double>& a, const std::vector<double>& b) {
  double e = 0, s = 1;
  for (size_t i = 0; i < a.size(); ++i) s = std::max(s, std::fabs(b[i]));
  for (size_t i = 0; i < a.size(); ++i) e = std::max(e, std::fabs(a[i] - b[i]));
  return e / s;
}

// a cooperative team as interpret mode runs one (include/rbdkit/cuda/team_kernels.cuh, SerialTeam): a phase's
// indices one after another, the last first (model/team.hpp's team forms, without a GPU)
struct ReversedTeam {
  static constexpr bool cooperative = true;
  static constexpr int threads = 64;
  template <typename F> void each(long n, F&& f) const {
    for (long k = n - 1; k >= 0; --k) f(k);
  }
  template <typename F> void each2(long rows, long cols, F&& f) const {
    each(rows * cols, [&](long k) { f(k / cols, k % cols); });
  }
  template <typename F> void one(F&& f) const { f(); }
  template <typename F, typename G> void beside(F&& f, G&& g) const { g(), f(*this); }
};

}  // namespace rbd_test
