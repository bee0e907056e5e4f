// cuda/regressor_check.cu — the regressor family inside __global__ kernels.
//
// Compiled (not run) by the build with nvcc, in double, float and dual
// numbers, so that a host-only construct in algorithms/regressor.hpp fails
// the build. The CPU results are checked against Pinocchio in
// tests/python/test_regressor.py.
#include "rbdkit/algorithms/regressor.hpp"
#include "rbdkit/spatial/dual.hpp"

using namespace rbd;

// per sample: Y (nv x 10nb), dY (2nv x nv x 10nb), dqdd/dπ (nv x 10nb), qdd (nv), y_T, y_V (10nb each)
template <typename S>
__global__ void regressor_all(ModelView<S> m, int B, const S* q, const S* qd, const S* qdd, const S* u,
                              unsigned char* scratch, unsigned long ws_bytes, S* out) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= B) return;
  Workspace<S> w = carve_workspace<S>(scratch + s * ws_bytes, m.nb, m.nv);
  const int nv = m.nv, np = 10 * m.nb;
  S* Y = out + static_cast<long>(s) * (3 * nv * np + 2 * nv * nv * np + nv + 2 * np);
  S* dY = Y + nv * np;
  S* G = dY + 2 * nv * nv * np;
  S* acc = G + nv * np;
  S* yT = acc + nv;
  S* yV = yT + np;
  const S g = S(-9.81);
  inverse_dynamics_regressor(m, w, q + s * m.nq, qd + s * nv, qdd + s * nv, g, Y);
  inverse_dynamics_regressor_gradient(m, w, q + s * m.nq, qd + s * nv, qdd + s * nv, g, dY, Y);
  forward_dynamics_parameter_gradient(m, w, q + s * m.nq, qd + s * nv, u + s * nv, g, acc, G);
  kinetic_energy_regressor(m, w, q + s * m.nq, qd + s * nv, yT);
  potential_energy_regressor(m, w, q + s * m.nq, g, yV);
}

template __global__ void regressor_all<double>(ModelView<double>, int, const double*, const double*, const double*,
                                               const double*, unsigned char*, unsigned long, double*);
template __global__ void regressor_all<float>(ModelView<float>, int, const float*, const float*, const float*,
                                              const float*, unsigned char*, unsigned long, float*);
template __global__ void regressor_all<Dual<double>>(ModelView<Dual<double>>, int, const Dual<double>*,
                                                     const Dual<double>*, const Dual<double>*, const Dual<double>*,
                                                     unsigned char*, unsigned long, Dual<double>*);
