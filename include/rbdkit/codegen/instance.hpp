// rbdkit/codegen/instance.hpp — the entry points of a compiled per-robot
// instance (codegen/specialize.hpp). An instance's source is the robot's
// generated header, this header and one line:
//
//   RBDKIT_INSTANCE(rbdkit_generated::Robot)
//
// which defines two C functions the loader looks up: the instance ABI, and
// the table of (registered operation's name, per-sample kernel). Each kernel
// is the registry's own Op::run on the robot's bodies as literals (the
// generated struct's bodies<double>): the workspace and the arrays are the
// caller's, as the serial loop (ops::run_serial) passes them; the model view
// it passes is the same robot's and is not read.
#pragma once

#include "rbdkit/ops/registry.hpp"
#include "rbdkit/ops/table.hpp"

namespace rbd {
namespace instance {

// changes whenever the entry points' types or meaning change (a key of the cache, checked on load)
constexpr int kAbi = 1;

struct Entry {
  const char* name;  // the registered operation's name (ops::OpSpec::name)
  ops::Kernel<double> run;
};

// Op::run with the robot R's constants in place of the passed view's
template <class R, class Op>
bool kernel(const ModelView<double>&, Workspace<double>& w, const ops::OpArgs<double>& a) {
  BodyDesc<double> body[R::nb];
  R::template bodies<double>(body);
  const ModelView<double> m{R::nb, R::nq, R::nv, R::has_mimic, body};
  return Op::run(m, w, a);
}

// the operations an instance compiles (Ops<...>::names), and its table for the robot R
template <class... Op> struct Ops {
  static constexpr const char* names[] = {Op::spec.name...};
  template <class R> static constexpr Entry entries[] = {{Op::spec.name, &kernel<R, Op>}...};
};
// the dynamics, the mass matrix and its inverse, their first derivatives and the step: what MPC and
// trajectory optimisation call one sample at a time
using InstanceOps = Ops<ops::InverseDynamics, ops::NonlinearEffects, ops::GeneralizedGravity, ops::Crba, ops::Minv,
                        ops::Aba, ops::ForwardDynamics, ops::InverseDynamicsGradient, ops::ForwardDynamicsGradient,
                        ops::Integrator, ops::IntegratorGradient>;

}  // namespace instance
}  // namespace rbd

// the instance's C entry points for the generated struct R
// (compiled with -fvisibility=hidden: these two are the library's only exported symbols, so that its
// inline functions never bind to another copy in the process)
#define RBDKIT_INSTANCE(R)                                                                                   \
  extern "C" __attribute__((visibility("default"))) int rbdkit_instance_abi() { return rbd::instance::kAbi; } \
  extern "C" __attribute__((visibility("default"))) int rbdkit_instance_entries(                             \
      const rbd::instance::Entry** entries) {                                                                 \
    *entries = rbd::instance::InstanceOps::entries<R>;                                                       \
    return static_cast<int>(sizeof(rbd::instance::InstanceOps::names) / sizeof(const char*));               \
  }
