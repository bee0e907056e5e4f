// python/src/bind_jax.cpp — the XLA FFI handler behind rbdkit.jax: one
// handler, `rbdkit_op`, runs any registered operation of an rbd::Handle on
// XLA's buffers, in place (no copy), on the CPU through the handle's batch
// engine. rbdkit/jax.py lays out each call (OpHandle.plan) and passes:
//   arrays   the present array arguments, in argument order, each
//            (*batch, per-sample shape) in the handle's dtype (XLA's row-major
//            layout, the engine's)
//   results  the outputs rbdkit.Handle returns, in output order, (*batch, shape)
//   attributes
//     handle    the rbd::Handle's address (OpHandle.address)
//     op        the operation's id (its index in ops::AllOps)
//     slots     for each array, its argument index k in the spec
//     outputs   for each result, its output index o
//     reals     per argument: kReal / kTimeStep / kPositive values (OpCall::real)
//     choices   per argument: flags, choices, frames, bodies (OpCall::choice)
//     ee        the end effectors' bodies of a kEndEffectors argument (may be empty)
// The batch B is the number of samples in the first array (its size over its
// per-sample size); every array must hold B samples. Errors (a check that
// fails, a failed sample) come back as XLA errors carrying rbdkit's message.
// Built only where jaxlib's headers were found (RBDKIT_HAS_XLA_FFI).
#include <nanobind/nanobind.h>

#ifdef RBDKIT_HAS_XLA_FFI
#include <cstdint>
#include <exception>
#include <stdexcept>
#include <string>
#include <vector>

#include "rbdkit/handle/handle.hpp"
#include "rbdkit/ops/table.hpp"
#include "xla/ffi/api/ffi.h"

namespace ffi = xla::ffi;
namespace ops = rbd::ops;

namespace {

ffi::Error run_op(ffi::RemainingArgs args, ffi::RemainingRets rets, int64_t handle, int64_t op_id,
                  ffi::Span<const int64_t> slots, ffi::Span<const int64_t> outputs, ffi::Span<const double> reals,
                  ffi::Span<const int64_t> choices, ffi::Span<const int64_t> ee) {
  rbd::Handle* h = reinterpret_cast<rbd::Handle*>(handle);
  if (!h || op_id < 0 || op_id >= static_cast<int64_t>(ops::op_table().size()) || !h->has_op(static_cast<int>(op_id)))
    return ffi::Error::InvalidArgument("rbdkit_op: no such operation on this handle");
  const ops::OpSpec& op = *ops::op_table()[op_id].spec;
  const rbd::Model& m = h->model();
  if (slots.size() != args.size() || outputs.size() != rets.size() || reals.size() != size_t(op.n_args) ||
      choices.size() != size_t(op.n_args))
    return ffi::Error::InvalidArgument(std::string(op.name) + ": the XLA call's layout does not match the operation");
  const ffi::DataType want = h->dtype() == "float32" ? ffi::DataType::F32 : ffi::DataType::F64;
  ops::OpCall c;
  std::vector<int> bodies(ee.begin(), ee.end());
  c.ee = bodies.empty() ? nullptr : bodies.data();
  c.n_ee = static_cast<int>(bodies.size());
  for (int k = 0; k < op.n_args; ++k) c.real[k] = reals[k], c.choice[k] = static_cast<int>(choices[k]);
  long B = -1;
  for (size_t j = 0; j < args.size(); ++j) {
    const int k = static_cast<int>(slots[j]);
    ffi::ErrorOr<ffi::AnyBuffer> buf = args.get<ffi::AnyBuffer>(j);
    if (buf.has_error()) return buf.error();
    if (k < 0 || k >= op.n_args) return ffi::Error::InvalidArgument(std::string(op.name) + ": bad argument slot");
    if (buf->element_type() != want)
      return ffi::Error::InvalidArgument(std::string(op.args[k].name) + ": expected the handle's dtype, " + h->dtype());
    const long w = ops::arg_values(op.args[k], m, c.n_ee);
    const long n = static_cast<long>(buf->element_count());
    if (w <= 0 || n % w != 0)
      return ffi::Error::InvalidArgument(std::string(op.args[k].name) + ": " + std::to_string(n) +
                                         " values are not a whole number of samples of " + std::to_string(w));
    if (B >= 0 && n / w != B)
      return ffi::Error::InvalidArgument(std::string(op.args[k].name) + ": " + std::to_string(n / w) +
                                         " samples, where the call has " + std::to_string(B));
    B = n / w;
    c.in[k] = buf->untyped_data();
    c.batched[k] = true;
  }
  for (size_t j = 0; j < rets.size(); ++j) {
    const int o = static_cast<int>(outputs[j]);
    ffi::ErrorOr<ffi::Result<ffi::AnyBuffer>> buf = rets.get<ffi::AnyBuffer>(j);
    if (buf.has_error()) return buf.error();
    if (o < 0 || o >= op.n_out) return ffi::Error::InvalidArgument(std::string(op.name) + ": bad output slot");
    c.out[o] = (*buf)->untyped_data();
  }
  if (B == 0) return ffi::Error::Success();  // an empty batch
  c.B = B < 0 ? 1 : B;
  try {
    h->run(static_cast<int>(op_id), c);
  } catch (const std::invalid_argument& e) {
    return ffi::Error::InvalidArgument(e.what());
  } catch (const std::exception& e) {
    return ffi::Error::Internal(e.what());
  }
  return ffi::Error::Success();
}

}  // namespace

XLA_FFI_DEFINE_HANDLER_SYMBOL(rbdkit_jax_op_cpu, run_op,
                              ffi::Ffi::Bind()
                                  .RemainingArgs()
                                  .RemainingRets()
                                  .Attr<int64_t>("handle")
                                  .Attr<int64_t>("op")
                                  .Attr<ffi::Span<const int64_t>>("slots")
                                  .Attr<ffi::Span<const int64_t>>("outputs")
                                  .Attr<ffi::Span<const double>>("reals")
                                  .Attr<ffi::Span<const int64_t>>("choices")
                                  .Attr<ffi::Span<const int64_t>>("ee"));
#endif

namespace nb = nanobind;

void bind_jax(nb::module_& m) {
  // {platform: PyCapsule of the XLA FFI handler} for jax.ffi.register_ffi_target; None in a build
  // without jaxlib's headers
  m.def("jax_ffi_handlers", []() -> nb::object {
#ifdef RBDKIT_HAS_XLA_FFI
    nb::dict d;
    // a capsule without a name, as jax.ffi.pycapsule makes (XLA reads it with a null name)
    d["cpu"] = nb::steal(PyCapsule_New(reinterpret_cast<void*>(&rbdkit_jax_op_cpu), nullptr, nullptr));
    return d;
#else
    return nb::none();
#endif
  });
}
