// rbdkit/codegen/generate.hpp — `rbdkit generate`: one robot as a readable,
// self-contained C++ header (docs/generated-code.md). The header holds the
// model as constants in code (joint types, parents, axes, placements,
// inertias) and per-robot entry points that instantiate rbdkit's header-only
// per-sample algorithms with them: no second implementation, no library to
// link, host and device (nvcc, inside the user's own kernels).
#pragma once

#include <string>

#include "rbdkit/parsers/model.hpp"

namespace rbd {

// the header for `model` as struct `name` in namespace rbdkit_generated;
// `source` (a path, a robot name) goes in its first comment. runtime_inertias:
// the inertias are not constants but an argument, pi (10·nb, in
// Model::inertial_parameters' layout) first in every entry point (for
// identification). Throws std::invalid_argument for a name that is not a C++
// identifier, a keyword or a member's name, and for a model without bodies.
std::string generate_header(const Model& model, const std::string& name, const std::string& source = "",
                            bool runtime_inertias = false);

}  // namespace rbd
