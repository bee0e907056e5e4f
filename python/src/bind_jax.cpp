// python/src/bind_jax.cpp — the framework calls: rbdkit_run_raw, one call of
// any registered operation on raw arrays (rbdkit.torch's kernel, `run_raw`),
// and the XLA FFI handlers behind rbdkit.jax: one
// target, `rbdkit_op`, runs any registered operation of an rbd::Handle on
// XLA's buffers, in place (no copy): on the CPU platform through the handle's
// batch engine, on the CUDA platform (builds with the real kernels) through a
// backend="cuda" handle's kernels on XLA's stream. rbdkit/jax.py lays out
// each call (OpHandle.plan) and passes:
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
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <cstdint>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "rbdkit/cuda/cuda_engine.hpp"
#include "rbdkit/handle/handle.hpp"
#include "rbdkit/ops/table.hpp"

namespace ops = rbd::ops;

// one call of a registered operation of handle h on raw row-major arrays in
// its dtype: ins[j] (in_counts[j] values) is argument slots[j], outs[j]
// (out_counts[j] values) is output outputs[j]; reals and choices per
// argument; ee the end effectors' bodies. B: the samples (-1: the first
// array's; every array must hold B, every output B of its shape).
// value_bytes: the arrays' element size (the handle's dtype's). device: the
// arrays are device arrays of a backend="cuda" handle (Handle::run_device, on
// its stream), else host arrays (Handle::run). Returns "" or
// the error (invalid: a bad argument rather than a failed computation). The
// XLA FFI handler (rbdkit.jax) and rbdkit.torch's kernel call it.
std::string rbdkit_run_raw(rbd::Handle* h, int64_t op_id, const int64_t* slots, const void* const* ins,
                           const long* in_counts, size_t n_in, const int64_t* outputs, void* const* outs,
                           const long* out_counts, size_t n_out, const double* reals, size_t n_reals,
                           const int64_t* choices, size_t n_choices, const int64_t* ee, size_t n_ee, long B,
                           size_t value_bytes, bool device, bool& invalid) {
  invalid = true;
  if (!h || op_id < 0 || op_id >= static_cast<int64_t>(ops::op_table().size()) || !h->has_op(static_cast<int>(op_id)))
    return "rbdkit: no such operation on this handle";
  if (value_bytes != (h->dtype() == "float32" ? sizeof(float) : sizeof(double)))
    return "rbdkit: the arrays are not in the handle's dtype, " + h->dtype();
  const ops::OpSpec& op = *ops::op_table()[op_id].spec;
  const rbd::Model& m = h->model();
  if (n_reals != size_t(op.n_args) || n_choices != size_t(op.n_args) || n_in > size_t(op.n_args) ||
      n_out > size_t(op.n_out))
    return std::string(op.name) + ": the call's layout does not match the operation";
  ops::OpCall c;
  std::vector<int> bodies(ee, ee + n_ee);
  c.ee = bodies.empty() ? nullptr : bodies.data();
  c.n_ee = static_cast<int>(bodies.size());
  for (int k = 0; k < op.n_args; ++k) c.real[k] = reals[k], c.choice[k] = static_cast<int>(choices[k]);
  for (size_t j = 0; j < n_in; ++j) {
    const int k = static_cast<int>(slots[j]);
    if (k < 0 || k >= op.n_args) return std::string(op.name) + ": bad argument slot";
    const long w = ops::arg_values(op.args[k], m, c.n_ee);
    // (an array of no values per sample, q of a model without joints, says nothing of B)
    if (w > 0 && B < 0 && in_counts[j] % w == 0) B = in_counts[j] / w;
    if (w == 0 ? in_counts[j] != 0 : in_counts[j] != B * w)
      return std::string(op.args[k].name) + ": " + std::to_string(in_counts[j]) + " values, where " +
             std::to_string(B) + " samples of " + std::to_string(w) + " were expected";
    c.in[k] = ins[j];
    c.batched[k] = true;
  }
  if (B < 0) B = 1;
  for (size_t j = 0; j < n_out; ++j) {
    const int o = static_cast<int>(outputs[j]);
    if (o < 0 || o >= op.n_out) return std::string(op.name) + ": bad output slot";
    if (out_counts[j] != B * ops::out_values(op.out[o], m, c.n_ee))
      return std::string(op.out[o].name) + ": the output holds " + std::to_string(out_counts[j]) + " values, not " +
             std::to_string(B) + " samples of " + std::to_string(ops::out_values(op.out[o], m, c.n_ee));
    c.out[o] = outs[j];
  }
  if (B == 0) return "";  // an empty batch
  c.B = B;
  try {
    if (device)
      h->run_device(static_cast<int>(op_id), c);
    else
      h->run(static_cast<int>(op_id), c);
  } catch (const std::invalid_argument& e) {
    return e.what();
  } catch (const std::exception& e) {
    invalid = false;
    return e.what();
  }
  return "";
}

#ifdef RBDKIT_HAS_XLA_FFI
#include "xla/ffi/api/ffi.h"

namespace ffi = xla::ffi;

namespace {

// one custom call: the buffers' addresses and sizes handed to rbdkit_run_raw (device: XLA's GPU
// buffers, run on the handle's CUDA engine)
ffi::Error run_op(ffi::RemainingArgs args, ffi::RemainingRets rets, rbd::Handle* h, int64_t op_id,
                  ffi::Span<const int64_t> slots, ffi::Span<const int64_t> outputs, ffi::Span<const double> reals,
                  ffi::Span<const int64_t> choices, ffi::Span<const int64_t> ee, bool device) {
  if (!h) return ffi::Error::InvalidArgument("rbdkit_op: no handle");
  const ffi::DataType want = h->dtype() == "float32" ? ffi::DataType::F32 : ffi::DataType::F64;
  if (slots.size() != args.size() || outputs.size() != rets.size())
    return ffi::Error::InvalidArgument("rbdkit_op: the arrays and their slots differ in number");
  std::vector<const void*> ins(args.size());
  std::vector<long> in_counts(args.size()), out_counts(rets.size());
  std::vector<void*> outs(rets.size());
  for (size_t j = 0; j < args.size(); ++j) {
    ffi::ErrorOr<ffi::AnyBuffer> buf = args.get<ffi::AnyBuffer>(j);
    if (buf.has_error()) return buf.error();
    if (buf->element_type() != want)
      return ffi::Error::InvalidArgument("rbdkit_op: an array is not in the handle's dtype, " + h->dtype());
    ins[j] = buf->untyped_data();
    in_counts[j] = static_cast<long>(buf->element_count());
  }
  for (size_t j = 0; j < rets.size(); ++j) {
    ffi::ErrorOr<ffi::Result<ffi::AnyBuffer>> buf = rets.get<ffi::AnyBuffer>(j);
    if (buf.has_error()) return buf.error();
    if ((*buf)->element_type() != want)
      return ffi::Error::InvalidArgument("rbdkit_op: a result is not in the handle's dtype, " + h->dtype());
    outs[j] = (*buf)->untyped_data();
    out_counts[j] = static_cast<long>((*buf)->element_count());
  }
  bool invalid = false;
  const std::string err = rbdkit_run_raw(
      h, op_id, slots.begin(), ins.data(), in_counts.data(), ins.size(), outputs.begin(), outs.data(),
      out_counts.data(), outs.size(), reals.begin(), reals.size(), choices.begin(), choices.size(), ee.begin(),
      ee.size(), -1, want == ffi::DataType::F32 ? sizeof(float) : sizeof(double), device, invalid);
  if (err.empty()) return ffi::Error::Success();
  return invalid ? ffi::Error::InvalidArgument(err) : ffi::Error::Internal(err);
}

// on the CPU platform: host buffers, through the handle's batch engine (or, on a backend="cuda"
// handle, copied to its device and back)
ffi::Error run_op_cpu(ffi::RemainingArgs args, ffi::RemainingRets rets, int64_t handle, int64_t op_id,
                      ffi::Span<const int64_t> slots, ffi::Span<const int64_t> outputs, ffi::Span<const double> reals,
                      ffi::Span<const int64_t> choices, ffi::Span<const int64_t> ee) {
  return run_op(args, rets, reinterpret_cast<rbd::Handle*>(handle), op_id, slots, outputs, reals, choices, ee, false);
}

// CUDA's stream type, declared so that this file needs no CUDA header (the handler only passes it on)
struct CudaStreamOpaque;
using CudaStream = CudaStreamOpaque*;

// on the CUDA platform: XLA's device buffers, read and written in place by the handle's kernels on
// XLA's stream (no copy to the host; the call waits for its kernels, and copies back one failure flag).
// The handle must be a backend="cuda" one, on the device XLA runs the call on.
ffi::Error run_op_cuda(CudaStream stream, int32_t device_ordinal, ffi::RemainingArgs args, ffi::RemainingRets rets,
                       int64_t handle, int64_t op_id, ffi::Span<const int64_t> slots, ffi::Span<const int64_t> outputs,
                       ffi::Span<const double> reals, ffi::Span<const int64_t> choices, ffi::Span<const int64_t> ee) {
  rbd::Handle* h = reinterpret_cast<rbd::Handle*>(handle);
  if (!h) return ffi::Error::InvalidArgument("rbdkit_op: no handle");
  if (h->backend() != rbd::Backend::CUDA || !h->cuda())
    return ffi::Error::InvalidArgument(
        "rbdkit.jax: the arrays are on a GPU, and this handle runs on the CPU: make it with "
        "rbdkit.jax.Handle(model, backend='cuda'), or put the arrays on the CPU (jax.device_put(x, "
        "jax.devices('cpu')[0]))");
  if (h->cuda()->interpret())
    return ffi::Error::InvalidArgument(
        "rbdkit.jax: the arrays are on a GPU, and this backend='cuda' handle runs in interpret mode "
        "(RBDKIT_CUDA_INTERPRET=1: the kernels on the CPU, which take host arrays): make it without "
        "RBDKIT_CUDA_INTERPRET, or put the arrays on the CPU");
  if (device_ordinal != h->cuda()->device_ordinal())
    return ffi::Error::InvalidArgument("rbdkit.jax: the arrays are on GPU " + std::to_string(device_ordinal) +
                                       ", and the handle's CUDA engine on GPU " +
                                       std::to_string(h->cuda()->device_ordinal()) +
                                       ": a backend='cuda' handle runs on the device that was current when it was made");
  // XLA's stream is the engine's for the length of the call, then the engine's own again
  static std::mutex stream_lock;
  std::lock_guard<std::mutex> lk(stream_lock);
  void* const before = h->cuda()->stream();
  h->cuda()->set_stream(stream);
  ffi::Error e = run_op(args, rets, h, op_id, slots, outputs, reals, choices, ee, true);
  h->cuda()->set_stream(before);
  return e;
}

// the attributes both handlers take (header comment), after a handler's own context
template <class Binding> auto call_binding(Binding b) {
  return std::move(b)
      .RemainingArgs()
      .RemainingRets()
      .template Attr<int64_t>("handle")
      .template Attr<int64_t>("op")
      .template Attr<ffi::Span<const int64_t>>("slots")
      .template Attr<ffi::Span<const int64_t>>("outputs")
      .template Attr<ffi::Span<const double>>("reals")
      .template Attr<ffi::Span<const int64_t>>("choices")
      .template Attr<ffi::Span<const int64_t>>("ee");
}

}  // namespace

XLA_FFI_DEFINE_HANDLER_SYMBOL(rbdkit_jax_op_cpu, run_op_cpu, call_binding(ffi::Ffi::Bind()));
XLA_FFI_DEFINE_HANDLER_SYMBOL(rbdkit_jax_op_cuda, run_op_cuda,
                              call_binding(ffi::Ffi::Bind().Ctx<ffi::PlatformStream<CudaStream>>().Ctx<ffi::DeviceOrdinal>()));
#endif

namespace nb = nanobind;
using namespace nb::literals;

namespace {

// rbdkit_run_raw with the GIL released, its error raised: ValueError for a bad argument, RuntimeError for a
// failed computation (RawCall and run_raw below)
void run_raw_or_raise(uintptr_t handle, int64_t op, const int64_t* slots, const void* const* ins, const long* in_counts,
                      size_t n_in, const int64_t* outputs, void* const* outs, const long* out_counts, size_t n_out,
                      const std::vector<double>& reals, const std::vector<int64_t>& choices,
                      const std::vector<int64_t>& ee, long B, size_t value_bytes, bool device) {
  bool invalid = false;
  std::string err;
  {
    nb::gil_scoped_release nogil;
    err = rbdkit_run_raw(reinterpret_cast<rbd::Handle*>(handle), op, slots, ins, in_counts, n_in, outputs, outs,
                         out_counts, n_out, reals.data(), reals.size(), choices.data(), choices.size(), ee.data(),
                         ee.size(), B, value_bytes, device, invalid);
  }
  if (!err.empty()) {
    if (invalid) throw nb::value_error(err.c_str());
    throw std::runtime_error(err);
  }
}

// a call's layout fixed once (rbdkit.torch's eager calls, cached per operation and parameters):
// calling it with the arrays' addresses (inputs, then outputs) and B runs rbdkit_run_raw, each array
// B samples of its per-sample values (B = -1: one sample, no batch axis). The caller has checked the
// arrays' shapes, dtype and contiguity.
struct RawCall {
  uintptr_t handle;
  int64_t op;
  std::vector<int64_t> slots, outputs, choices, ee;
  std::vector<double> reals;
  std::vector<long> in_values, out_values;  // per sample
  size_t value_bytes;

  RawCall(uintptr_t handle, int64_t op, std::vector<int64_t> slots, std::vector<int64_t> outputs,
          std::vector<int64_t> choices, std::vector<int64_t> ee, std::vector<double> reals, std::vector<long> in_values,
          std::vector<long> out_values, size_t value_bytes)
      : handle(handle), op(op), slots(std::move(slots)), outputs(std::move(outputs)), choices(std::move(choices)),
        ee(std::move(ee)), reals(std::move(reals)), in_values(std::move(in_values)), out_values(std::move(out_values)),
        value_bytes(value_bytes) {
    if (this->slots.size() != this->in_values.size() || this->outputs.size() != this->out_values.size())
      throw std::invalid_argument("RawCall: one per-sample size per input and per output");
  }

  void operator()(const std::vector<uintptr_t>& ptrs, long B, bool device) const {
    const size_t n_in = slots.size(), n_out = outputs.size();
    if (ptrs.size() != n_in + n_out) throw nb::value_error("RawCall: expected one address per input and output");
    if (n_in > size_t(ops::kMaxArgs) || n_out > size_t(ops::kMaxOutputs))
      throw nb::value_error("RawCall: too many arrays");
    const long samples = B < 0 ? 1 : B;
    const void* in_p[ops::kMaxArgs];
    void* out_p[ops::kMaxOutputs];
    long in_c[ops::kMaxArgs], out_c[ops::kMaxOutputs];
    for (size_t j = 0; j < n_in; ++j)
      in_p[j] = reinterpret_cast<const void*>(ptrs[j]), in_c[j] = samples * in_values[j];
    for (size_t j = 0; j < n_out; ++j)
      out_p[j] = reinterpret_cast<void*>(ptrs[n_in + j]), out_c[j] = samples * out_values[j];
    run_raw_or_raise(handle, op, slots.data(), in_p, in_c, n_in, outputs.data(), out_p, out_c, n_out, reals, choices,
                     ee, B, value_bytes, device);
  }
};

}  // namespace

void bind_jax(nb::module_& m) {
  // rbdkit.jax and rbdkit.torch keep their handles for the life of the process (compiled calls hold
  // their addresses), and the frameworks' caches may hold them past the atexit release: nanobind's
  // leak report at exit would name them
  m.def("disable_leak_warnings", [] { nb::set_leak_warnings(false); });
  // rbdkit.torch's kernel: run_raw on arrays given as addresses (data_ptr()) and value counts (device:
  // CUDA tensors of a backend="cuda" handle, on its stream); raises ValueError (a bad argument) or
  // RuntimeError (a failed computation) with rbdkit's message
  m.def("run_raw", [](uintptr_t handle, int64_t op, const std::vector<int64_t>& slots,
                      const std::vector<uintptr_t>& ins, const std::vector<long>& counts,
                      const std::vector<int64_t>& outputs, const std::vector<uintptr_t>& outs,
                      const std::vector<long>& out_counts, const std::vector<double>& reals,
                      const std::vector<int64_t>& choices, const std::vector<int64_t>& ee, long B,
                      size_t value_bytes, bool device) {
    if (slots.size() != ins.size() || counts.size() != ins.size() || outputs.size() != outs.size() ||
        out_counts.size() != outs.size())
      throw nb::value_error("run_raw: the arrays and their slots differ in number");
    std::vector<const void*> in_p(ins.size());
    std::vector<void*> out_p(outs.size());
    for (size_t j = 0; j < ins.size(); ++j) in_p[j] = reinterpret_cast<const void*>(ins[j]);
    for (size_t j = 0; j < outs.size(); ++j) out_p[j] = reinterpret_cast<void*>(outs[j]);
    run_raw_or_raise(handle, op, slots.data(), in_p.data(), counts.data(), in_p.size(), outputs.data(), out_p.data(),
                     out_counts.data(), out_p.size(), reals, choices, ee, B, value_bytes, device);
  }, "handle"_a, "op"_a, "slots"_a, "ins"_a, "counts"_a, "outputs"_a, "outs"_a, "out_counts"_a, "reals"_a,
     "choices"_a, "ee"_a, "B"_a, "value_bytes"_a, "device"_a = false);

  nb::class_<RawCall>(m, "RawCall")
      .def(nb::init<uintptr_t, int64_t, std::vector<int64_t>, std::vector<int64_t>, std::vector<int64_t>,
                    std::vector<int64_t>, std::vector<double>, std::vector<long>, std::vector<long>, size_t>(),
           "handle"_a, "op"_a, "slots"_a, "outputs"_a, "choices"_a, "ee"_a, "reals"_a, "in_values"_a,
           "out_values"_a, "value_bytes"_a)
      .def("__call__", &RawCall::operator(), "ptrs"_a, "B"_a, "device"_a = false);

  // {platform: PyCapsule of the XLA FFI handler} for jax.ffi.register_ffi_target; None in a build
  // without jaxlib's headers
  m.def("jax_ffi_handlers", []() -> nb::object {
#ifdef RBDKIT_HAS_XLA_FFI
    nb::dict d;
    // a capsule without a name, as jax.ffi.pycapsule makes (XLA reads it with a null name)
    d["cpu"] = nb::steal(PyCapsule_New(reinterpret_cast<void*>(&rbdkit_jax_op_cpu), nullptr, nullptr));
    // XLA's GPU buffers, where this build has the real kernels (backend="cuda" handles)
    if (rbd::CudaEngine::cuda_compiled())
      d["CUDA"] = nb::steal(PyCapsule_New(reinterpret_cast<void*>(&rbdkit_jax_op_cuda), nullptr, nullptr));
    return d;
#else
    return nb::none();
#endif
  });
}
