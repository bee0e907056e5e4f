// cuda/integrator_hessian_check.cu — the step Hessian inside a __global__ kernel.
//
// Compiled (not run) by the build with nvcc, in double and float, so that a
// host-only construct in plant/integrator_hessian.hpp (or in the nested
// dual numbers of its retraction jet) fails the build. The convention is a
// kernel argument, so both policies (PinocchioStep and MujocoStep, with the
// MuJoCo-coordinate acceleration tensors) are compiled. The CPU results are
// checked in tests/cpp/test_integrator_hessian.cpp,
// tests/python/test_step_hessian.py and tests/python/test_mujoco.py.
#include "rbdkit/plant/integrator_hessian.hpp"

using namespace rbd;

// per sample: x⁺ (nq + nv), AB (2nv x 3nv), H (2nv x 3nv x 3nv) in the convention
// (OutputConvention); scratch holds integrator_hessian_scratch_values(nq, nv)
// values per sample after the workspace
template <typename S>
__global__ void step_hessian(ModelView<S> m, int B, int type, int convention, const S* q, const S* v, const S* u,
                             S dt, S gravity, unsigned char* ws, unsigned long ws_bytes, S* scratch, S* x, S* AB, S* H,
                             int* ok) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= B) return;
  Workspace<S> w = carve_workspace<S>(ws + s * ws_bytes, m.nb, m.nv);
  const int nq = m.nq, nv = m.nv;
  const long n_ab = 6L * nv * nv, n_h = 18L * nv * nv * nv;
  S* xs = x + s * (nq + nv);
  ok[s] = integrator_hessian(m, w, type, q + s * nq, v + s * nv, u + s * nv, dt, gravity, xs, xs + nq,
                             AB + s * n_ab, H + s * n_h, scratch + s * integrator_hessian_scratch_values(nq, nv),
                             convention)
              ? 1
              : 0;
}

template __global__ void step_hessian<double>(ModelView<double>, int, int, int, const double*, const double*,
                                              const double*, double, double, unsigned char*, unsigned long, double*,
                                              double*, double*, double*, int*);
template __global__ void step_hessian<float>(ModelView<float>, int, int, int, const float*, const float*, const float*,
                                             float, float, unsigned char*, unsigned long, float*, float*, float*,
                                             float*, int*);
