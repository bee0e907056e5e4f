// cuda/mujoco_check.cu — the MuJoCo output convention inside __global__ kernels.
//
// Compiled (not run) with nvcc in double and float, so that a host-only
// construct in plant/mujoco_convention.hpp or the MujocoStep path of
// plant/integrators.hpp fails the build. The CPU results are checked
// against the mujoco package in tests/python/test_mujoco.py.
#include "rbdkit/model/workspace.hpp"
#include "rbdkit/plant/costs.hpp"
#include "rbdkit/plant/integrators.hpp"

using namespace rbd;

// per sample: one step with its Jacobian in MuJoCo coordinates, the state cost
// along MuJoCo's ⊖, and the acceleration's derivatives on their own
template <typename S>
__global__ void mujoco_steps(ModelView<S> m, int B, int type, const S* q, const S* v, const S* u, S dt,
                             unsigned char* scratch, unsigned long ws_bytes, S* values, long n_values, S* x_next,
                             S* AB, S* cost, S* F, int* ok) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= B) return;
  Workspace<S> w = carve_workspace<S>(scratch + s * ws_bytes, m.nb, m.nv);
  const int nq = m.nq, nv = m.nv;
  const long nn = static_cast<long>(nv) * nv;
  S* xs = x_next + s * (nq + nv);
  S* vals = values + s * n_values;
  bool good = integrator_gradient(m, w, type, q + s * nq, v + s * nv, u + s * nv, static_cast<const S*>(nullptr),
                                  dt, S(-9.81), xs, xs + nq, AB + s * 6L * nv * nv, vals, kMujocoConvention);
  S* Fs = F + s * 3 * nn;
  good = good && mujoco_acceleration_derivatives(m, w, q + s * nq, v + s * nv, u + s * nv,
                                                 static_cast<const S*>(nullptr), S(-9.81), vals, Fs, Fs + nn,
                                                 Fs + 2 * nn, vals + nv);
  S* Q = vals;  // unit weights (2nv)
  for (int k = 0; k < 2 * nv; ++k) Q[k] = S(1);
  S* xq = vals + 2 * nv;  // [q; v] (nq + nv)
  for (int k = 0; k < nq; ++k) xq[k] = q[s * nq + k];
  for (int k = 0; k < nv; ++k) xq[nq + k] = v[s * nv + k];
  cost[s] = quadratic_state_cost_tangent(m, xq, xs, Q, Fs, Fs + 2 * nv, vals + 2 * nv + nq + nv, kMujocoConvention);
  ok[s] = good ? 1 : 0;
}
template __global__ void mujoco_steps<double>(ModelView<double>, int, int, const double*, const double*,
                                              const double*, double, unsigned char*, unsigned long, double*, long,
                                              double*, double*, double*, double*, int*);
template __global__ void mujoco_steps<float>(ModelView<float>, int, int, const float*, const float*, const float*,
                                             float, unsigned char*, unsigned long, float*, long, float*, float*,
                                             float*, float*, int*);
