// tests/fuzz/fuzz_builder.cpp — libFuzzer target: ModelBuilder driven by
// bytes (scripts/fuzz.sh builds and runs it).
//
// The input is a program: each operation byte picks add_body, add_inertia,
// add_frame, add_mimic, add_warning or a lookup, and the bytes after it its
// arguments (parents and names from small sets, so that they collide; numbers
// from a table of edge values or raw doubles). An operation may throw
// std::invalid_argument, which must leave the builder as it was (the model
// built at the end shows what stayed: check_model's bounds catch a merged
// inertia that was refused but kept); the rest go on.
// Then build(): a clear std::invalid_argument, or a model that satisfies the
// invariants of check_model.hpp, and an empty builder.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "check_model.hpp"
#include "rbdkit/parsers/builder.hpp"

namespace {

// reads the input front to back; zeros once it is used up
struct Bytes {
  using Vec3 = rbd::Vec3<double>;
  const uint8_t* d;
  size_t n;
  bool empty() const { return n == 0; }
  uint8_t u8() {
    if (!n) return 0;
    --n;
    return *d++;
  }
  // an edge value from the table, or (selector >= 224) a raw double
  double num() {
    static const double kEdge[] = {0, 1, -1, 0.5, -0.5, 2, 0.1, -0.3, 1e-3, 1e-9, 1e-12, 1e-160, 1e-300, 5e-324,
                                   -0.0, 3.141592653589793, 1.5707963267948966, 1e6, 1e12, -1e12, 1.0000001e12,
                                   1e15, -1e15, 1.0000001e15, 1e16, 1e154, 1e300, -1e300,
                                   std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                                   std::numeric_limits<double>::quiet_NaN(), 0.25};
    const uint8_t s = u8();
    if (s < 224) return kEdge[s % (sizeof(kEdge) / sizeof(kEdge[0]))];
    double x = 0;
    uint8_t raw[8] = {};
    for (uint8_t& b : raw) b = u8();
    std::memcpy(&x, raw, sizeof x);
    return x;
  }
  Vec3 vec() {
    const double x = num(), y = num();  // in order: braces would not fix it for a return
    return {x, y, num()};
  }
};

std::string pick_name(Bytes& in, const char* prefix) {
  const uint8_t k = in.u8();
  if (k == 255) return "";  // the empty name: an error
  return prefix + std::to_string(k % 24);
}

// a rotation from roll-pitch-yaw, or (flag bit) nine raw entries (not always orthonormal)
rbd::Transform<double> transform(Bytes& in) {
  rbd::Transform<double> X = rbd::Transform<double>::identity();
  const uint8_t flag = in.u8();
  if (flag & 1) X.p = in.vec();
  if (flag & 2) {
    const double r = in.num(), p = in.num(), y = in.num();
    X.R = rbd::axis_angle(rbd::Vec3<double>{0, 0, 1}, y) * rbd::axis_angle(rbd::Vec3<double>{0, 1, 0}, p) *
          rbd::axis_angle(rbd::Vec3<double>{1, 0, 0}, r);
  } else if (flag & 4) {
    for (double& x : X.R.m) x = in.num();
  }
  return X;
}

// mass, centre of mass and rotational inertia as given (not always physical)
rbd::Inertia<double> inertia(Bytes& in) {
  rbd::Inertia<double> I = rbd::Inertia<double>::zero();
  const uint8_t flag = in.u8();
  if (flag & 1) I.m = in.num();
  if (flag & 2) I.h = I.m * in.vec();
  if (flag & 4) {
    const double xx = in.num(), yy = in.num(), zz = in.num();
    const double xy = (flag & 8) ? in.num() : 0, xz = (flag & 8) ? in.num() : 0, yz = (flag & 8) ? in.num() : 0;
    I.I = {{xx, xy, xz, xy, yy, yz, xz, yz, zz}};
  }
  return I;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const char* kTypes[] = {"revolute", "continuous", "prismatic", "helical", "screw", "spherical",
                                 "free",     "floating",   "fixed",     "planar",  "",      "Revolute"};
  Bytes in{data, size};
  rbd::ModelBuilder b(size ? "fuzz" : "");
  for (int op = 0; op < 96 && !in.empty(); ++op) {
    const int nb_before = b.nb();
    try {
      switch (in.u8() % 6) {
        case 0: {  // add_body
          const int parent = static_cast<int>(in.u8() % (b.nb() + 3)) - 2;  // -2 and nb: errors
          rbd::JointSpec j;
          j.name = pick_name(in, "j");
          j.type = kTypes[in.u8() % 12];
          j.X_parent_joint = transform(in);
          const uint8_t flag = in.u8();
          if (flag & 1) j.axis = in.vec();
          if (flag & 2) j.pitch = in.num();
          if (flag & 4) j.lower = in.num(), j.upper = in.num();
          if (flag & 8) j.velocity = in.num(), j.effort = in.num();
          const std::string body = pick_name(in, "b");
          const int index = b.add_body(parent, j, body, inertia(in));
          RBD_FUZZ_CHECK(index == b.nb() - 1 && b.body_index(body) == index && b.has_joint(j.name));
          break;
        }
        case 1: {  // add_inertia
          const int body = static_cast<int>(in.u8() % (b.nb() + 3)) - 2;
          const rbd::Inertia<double> I = inertia(in);
          b.add_inertia(body, I, transform(in));
          break;
        }
        case 2: {  // add_frame
          const std::string name = pick_name(in, "f");
          const int body = static_cast<int>(in.u8() % (b.nb() + 3)) - 2;
          b.add_frame(name, (in.u8() & 1) ? "link" : "site", body, transform(in));
          break;
        }
        case 3: {  // add_mimic (checked in build)
          const std::string joint = pick_name(in, "j"), target = pick_name(in, "j");
          const double mult = in.num(), offset = in.num();
          b.add_mimic(joint, target, mult, offset);
          break;
        }
        case 4: b.add_warning("w"); break;
        default: {  // lookups agree with each other
          const std::string name = pick_name(in, "b");
          const int i = b.body_index(name);
          RBD_FUZZ_CHECK(b.has_body(name) == (i >= 0) && i < b.nb());
          break;
        }
      }
    } catch (const std::invalid_argument& e) {
      RBD_FUZZ_CHECK(std::strlen(e.what()) > 0 && b.nb() == nb_before);  // a refused body is not added
    }
  }
  rbd::Model m;
  try {
    m = b.build();
  } catch (const std::invalid_argument& e) {
    RBD_FUZZ_CHECK(std::strlen(e.what()) > 0);
    return 0;
  }
  RBD_FUZZ_CHECK(b.nb() == 0);  // build() leaves the builder empty
  rbd_fuzz::check_model(m, false);
  return 0;
}
