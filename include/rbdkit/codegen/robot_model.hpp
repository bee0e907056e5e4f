// rbdkit/codegen/robot_model.hpp — a generated robot (codegen/generate.hpp's
// struct R: static constexpr nb, nq, nv, has_mimic and a constexpr bodies<S>)
// as a model view whose sizes and bodies are compile-time constants. The
// per-robot instances (codegen/instance.hpp on the CPU, the CUDA kernels'
// Model parameter in rbdkit/cuda/kernels.cuh) build their view with it.
//
// The bodies are one constant table per robot and scalar, filled at compile
// time: in host code a constexpr variable, in device code a __constant__ one.
// Built inside a kernel with RobotModel<R>::view, the view's sizes are
// constants, so nvcc unrolls the algorithms' body loops (RBD_UNROLL) and
// folds each body's joint type, parent and placement into the code.
#pragma once

#include "rbdkit/model/joint.hpp"

namespace rbd {
namespace instance {

// the robot R's bodies in scalar S, filled at compile time by its bodies<S>
template <class R, class S = double> struct BodyTable {
  BodyDesc<S> body[R::nb];
  constexpr BodyTable() : body{} { R::template bodies<S>(body); }
};
template <class R, class S = double> inline constexpr BodyTable<R, S> kBodies{};
#if defined(__CUDACC__)
template <class R, class S> __constant__ const BodyTable<R, S> kDeviceBodies{};
#endif

// the view of robot R (the argument, another view of the same robot, is not read): its sizes as
// constants and its bodies' table, in device memory in device code
template <class R> struct RobotModel {
  template <typename S> RBD_HD static ModelView<S> view(const ModelView<S>&) {
#if defined(__CUDA_ARCH__)
    return {R::nb, R::nq, R::nv, R::has_mimic, kDeviceBodies<R, S>.body};
#else
    return {R::nb, R::nq, R::nv, R::has_mimic, kBodies<R, S>.body};
#endif
  }
};

}  // namespace instance
}  // namespace rbd
