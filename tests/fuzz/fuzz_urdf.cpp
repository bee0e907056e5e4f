// tests/fuzz/fuzz_urdf.cpp — libFuzzer target: the URDF reader and the
// ModelBuilder behind it (scripts/fuzz.sh builds and runs it).
//
// The input is the URDF text itself, so any .urdf file is a seed. Each input
// is read four times, with floating_base and mimic on and off; strict is the
// low bit of the last byte. A clear std::invalid_argument is a correct answer
// to a bad file; anything else the reader throws, and every model it accepts
// that breaks an invariant or that the algorithms cannot handle at the
// neutral configuration (check_model.hpp), is a bug and traps.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "check_model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size > (1u << 16)) return 0;  // big inputs only slow the search down
  const std::string xml(reinterpret_cast<const char*>(data), size);
  const bool strict = size > 0 && (data[size - 1] & 1);
  for (int opts = 0; opts < 4; ++opts) {
    const bool floating_base = opts & 1, mimic = opts & 2;
    rbd::Model m;
    try {
      m = rbd::Model::from_urdf_string(xml, floating_base, strict, mimic);
    } catch (const std::invalid_argument& e) {
      // the reader's errors all start with "URDF: " and say something
      RBD_FUZZ_CHECK(std::string(e.what()).rfind("URDF: ", 0) == 0 && std::string(e.what()).size() > 6);
      continue;
    }
    rbd_fuzz::check_model(m, floating_base);
  }
  return 0;
}
