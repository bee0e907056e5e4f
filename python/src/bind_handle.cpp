// rbdkit._core: the operation handles' algorithm table (include/rbdkit/handle/handle.hpp),
// read by the Python rbdkit.Handle so that both languages share one table.
#include <nanobind/nanobind.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include "rbdkit/handle/handle.hpp"

namespace nb = nanobind;
using namespace nb::literals;

void bind_handle(nb::module_& m) {
  // [(name, operations, dependencies)] in table order
  m.def("handle_algorithms", [] {
    std::vector<std::tuple<std::string, std::vector<std::string>, std::vector<std::string>>> out;
    for (const rbd::AlgorithmInfo& a : rbd::handle_algorithms()) out.emplace_back(a.name, a.operations, a.dependencies);
    return out;
  });
  m.def("resolve_algorithms", &rbd::resolve_algorithms, "names"_a);
}
