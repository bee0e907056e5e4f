// python/src/arrays.hpp — the array types and small helpers every binding
// file of rbdkit._core uses: C-contiguous float64 CPU arrays, batch on axis 0.
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>

#include <optional>

namespace rbd_py {

using In = nanobind::ndarray<const double, nanobind::c_contig, nanobind::device::cpu>;
using Out = nanobind::ndarray<double, nanobind::c_contig, nanobind::device::cpu>;

// pointer of an optional input (None -> null)
inline const double* opt(const std::optional<In>& a) { return a ? a->data() : nullptr; }

// the batch size of a (B, ...) array (a 0-d array counts as one sample)
inline long batch_of(const In& a) { return a.ndim() == 0 ? 1 : static_cast<long>(a.shape(0)); }

// the width of a (B, n) array
inline int width(const In& a) { return static_cast<int>(a.size() / a.shape(0)); }

}  // namespace rbd_py
