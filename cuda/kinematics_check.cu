// cuda/kinematics_check.cu — the kinematics family inside __global__ kernels.
//
// Compiled (not run) by the build with nvcc, in double, float and dual
// numbers, so that a host-only construct in algorithms/kinematics.hpp or
// algorithms/osc.hpp fails the build. The CPU results are checked against
// Pinocchio in tests/python/test_kinematics.py.
#include "rbdkit/algorithms/kinematics.hpp"
#include "rbdkit/algorithms/osc.hpp"
#include "rbdkit/model/configuration.hpp"
#include "rbdkit/spatial/dual.hpp"

using namespace rbd;

// per sample: J (6 nv), dJ (6 nv), pose (6), G (6 nv), H (6 nv²), Λ (36) of the last body's origin
template <typename S>
__global__ void kinematics_all(ModelView<S> m, int B, const S* q, const S* qd, unsigned char* scratch,
                               unsigned long ws_bytes, S* out) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= B) return;
  Workspace<S> w = carve_workspace<S>(scratch + s * ws_bytes, m.nb, m.nv);
  const int nv = m.nv, body = m.nb - 1;
  S* o = out + s * (18 * nv + 6 * nv * nv + 42);
  const Transform<S> X = Transform<S>::identity();
  const Vec3<S> offset = Vec3<S>::zero();
  forward_kinematics(m, w, q + s * m.nq, qd + s * nv);
  frame_jacobian(m, w, body, X, kLocal, o);
  frame_jacobian_dot(m, w, body, X, kLocalWorldAligned, o + 6 * nv);
  end_effector_pose(w, body, offset, o + 12 * nv);
  end_effector_pose_gradient(m, w, body, offset, o + 12 * nv + 6);
  end_effector_pose_hessian_analytic(m, w, body, offset, o + 18 * nv + 6);
  if (osc_factor_mass_matrix(m, w, q + s * m.nq)) osc_inertia(m, w, body, offset, o + 18 * nv + 6 * nv * nv + 6);
}

template __global__ void kinematics_all<double>(ModelView<double>, int, const double*, const double*,
                                                unsigned char*, unsigned long, double*);
template __global__ void kinematics_all<float>(ModelView<float>, int, const float*, const float*, unsigned char*,
                                               unsigned long, float*);
template __global__ void kinematics_all<Dual<double>>(ModelView<Dual<double>>, int, const Dual<double>*,
                                                      const Dual<double>*, unsigned char*, unsigned long,
                                                      Dual<double>*);
