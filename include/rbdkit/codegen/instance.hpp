// rbdkit/codegen/instance.hpp — the entry points of a compiled per-robot
// instance (codegen/specialize.hpp). An instance's source is the robot's
// generated header, this header and one line:
//
//   RBDKIT_INSTANCE(rbdkit_generated::Robot)
//
// which defines the C function the loader looks up, rbdkit_instance(): the
// instance ABI, a fingerprint of the types the library and the instance pass
// each other, the robot's sizes and the table of (registered operation's
// name, per-sample kernel). The loader refuses an instance whose ABI,
// fingerprint or sizes differ from its own and its model's. Each kernel
// (but crba's, minv's and forward_dynamics_gradient's: the same passes, CRBA unrolled body by body,
// codegen/unrolled.hpp)
// is the registry's own Op::run on the robot's bodies as a constant table (the
// generated struct's constexpr bodies<double>): the workspace and the arrays are the
// caller's, as the serial loop (ops::run_serial) passes them; the model view
// it passes is the same robot's and is not read.
#pragma once

#include <type_traits>

#include "rbdkit/codegen/robot_model.hpp"
#include "rbdkit/codegen/unrolled.hpp"
#include "rbdkit/ops/registry.hpp"
#include "rbdkit/ops/table.hpp"

namespace rbd {
namespace instance {

// changes whenever the entry point's types or meaning change (a key of the cache, checked on load)
constexpr int kAbi = 2;

struct Entry {
  const char* name;  // the registered operation's name (ops::OpSpec::name)
  ops::Kernel<double> run;
};

// Op::run on the robot R's constant table in place of the passed view (codegen/robot_model.hpp),
// as the engine compiles its kernels (ops::OpKernel): with everything it calls inlined, so that the
// robot's sizes and table reach every pass, or, for a kernel the spec marks kCalled, as written
template <class R, class Op>
bool called_kernel(const ModelView<double>& view, Workspace<double>& w, const ops::OpArgs<double>& a) {
  return Op::run(RobotModel<R>::view(view), w, a);
}
template <class R, class Op>
RBD_FLATTEN bool flattened_kernel(const ModelView<double>& view, Workspace<double>& w,
                                  const ops::OpArgs<double>& a) {
  return Op::run(RobotModel<R>::view(view), w, a);
}
// crba body by body (codegen/unrolled.hpp) on a robot without mimic joints
template <class R>
bool unrolled_crba_kernel(const ModelView<double>&, Workspace<double>&, const ops::OpArgs<double>& a) {
  unrolled_crba<R>(a.in[0], a.out[0]);
  return true;
}
// minv with its crba body by body (codegen/unrolled.hpp) on a robot without mimic joints
template <class R>
bool unrolled_minv_kernel(const ModelView<double>&, Workspace<double>& w, const ops::OpArgs<double>& a) {
  return unrolled_minv<R>(w, a.in[0], a.choice[1] != 0, a.out[0]);
}
// forward_dynamics_gradient with that M⁻¹ (Unrolled::Factored) on a robot without mimic joints
template <class R>
RBD_FLATTEN bool unrolled_fd_gradient_kernel(const ModelView<double>& view, Workspace<double>& w,
                                             const ops::OpArgs<double>& a) {
  return ops::ForwardDynamicsGradient::run(RobotModel<R>::view(view), w, a, typename Unrolled<R>::Factored{});
}
template <class R, class Op> constexpr ops::Kernel<double> kernel() {
  if constexpr (std::is_same<Op, ops::Crba>::value && !R::has_mimic) return &unrolled_crba_kernel<R>;
  else if constexpr (std::is_same<Op, ops::Minv>::value && !R::has_mimic) return &unrolled_minv_kernel<R>;
  else if constexpr (std::is_same<Op, ops::ForwardDynamicsGradient>::value && !R::has_mimic)
    return &unrolled_fd_gradient_kernel<R>;
  else if constexpr (Op::spec.kernel == ops::kCalled) return &called_kernel<R, Op>;
  else return &flattened_kernel<R, Op>;
}

// the operations an instance compiles (Ops<...>::names), and its table for the robot R
template <class... Op> struct Ops {
  static constexpr const char* names[] = {Op::spec.name...};
  template <class R> static constexpr Entry entries[] = {{Op::spec.name, kernel<R, Op>()}...};
};
// the dynamics, the mass matrix and its inverse, their first derivatives and the step: what MPC and
// trajectory optimisation call one sample at a time
using InstanceOps = Ops<ops::InverseDynamics, ops::NonlinearEffects, ops::GeneralizedGravity, ops::Crba, ops::Minv,
                        ops::Aba, ops::ForwardDynamics, ops::InverseDynamicsGradient, ops::ForwardDynamicsGradient,
                        ops::Integrator, ops::IntegratorGradient>;

// FNV-1a (64 bits) over bytes, integers and names: the fingerprint below, and the cache key
// (src/codegen/specialize.cpp)
constexpr unsigned long long kFnvBasis = 1469598103934665603ull;
constexpr unsigned long long mix_byte(unsigned long long h, unsigned char c) { return (h ^ c) * 1099511628211ull; }
constexpr unsigned long long mix(unsigned long long h, unsigned long long v) {
  for (int i = 0; i < 8; ++i) h = mix_byte(h, static_cast<unsigned char>(v >> (8 * i)));
  return h;
}
// a name, then a separator byte (so that ("ab", "c") and ("a", "bc") differ)
constexpr unsigned long long mix(unsigned long long h, const char* s) {
  while (*s) h = mix_byte(h, static_cast<unsigned char>(*s++));
  return mix_byte(h, 0xff);
}
template <class Op> constexpr unsigned long long mix_op(unsigned long long h) {
  h = mix(mix(mix(h, Op::spec.name), static_cast<unsigned>(Op::spec.n_args)), static_cast<unsigned>(Op::spec.n_out));
  for (int k = 0; k < Op::spec.n_args; ++k) h = mix(h, static_cast<unsigned>(Op::spec.args[k].kind));
  return h;
}
template <class... Op> constexpr unsigned long long fingerprint(Ops<Op...>*) {
  unsigned long long h = kFnvBasis;
  h = mix(mix(mix(mix(h, sizeof(Workspace<double>)), sizeof(ops::OpArgs<double>)), sizeof(BodyDesc<double>)),
          sizeof(ModelView<double>));
  h = mix(mix(h, static_cast<unsigned>(ops::kMaxArgs)), static_cast<unsigned>(ops::kMaxOutputs));
  ((h = mix_op<Op>(h)), ...);
  return h;
}
// the types an instance and the library pass each other, and the operations' argument layouts, as
// compiled on each side: equal or the instance is refused (headers of another rbdkit)
constexpr unsigned long long kLayout = fingerprint(static_cast<InstanceOps*>(nullptr));

// what rbdkit_instance() returns (abi first: the loader reads it before the rest)
struct Description {
  int abi;                      // kAbi
  unsigned long long layout;    // kLayout
  int nb, nq, nv;               // the robot's
  int n_entries;
  const Entry* entries;
};

}  // namespace instance
}  // namespace rbd

// the instance's C entry point for the generated struct R (compiled with -fvisibility=hidden: the
// library's only exported symbol, so that its inline functions never bind to another copy in the process)
#define RBDKIT_INSTANCE(R)                                                                                  \
  extern "C" __attribute__((visibility("default"))) const rbd::instance::Description* rbdkit_instance() {   \
    static constexpr rbd::instance::Description d = {                                                       \
        rbd::instance::kAbi, rbd::instance::kLayout, R::nb, R::nq, R::nv,                                   \
        static_cast<int>(sizeof(rbd::instance::InstanceOps::names) / sizeof(const char*)),                  \
        rbd::instance::InstanceOps::entries<R>};                                                            \
    return &d;                                                                                              \
  }
