// cuda/second_order_check.cu — the second-order derivatives inside __global__ kernels.
//
// Compiled (not run) by the build with nvcc, in double, float and dual
// numbers, so that a host-only construct in algorithms/idsva_so.hpp or
// algorithms/fdsva_so.hpp fails the build. The CPU results are checked
// against finite differences and Pinocchio in tests/cpp/test_second_order.cpp,
// tests/python/test_second_order.py and tests/pinocchio_so/.
#include "rbdkit/algorithms/fdsva_so.hpp"
#include "rbdkit/algorithms/idsva_so.hpp"
#include "rbdkit/spatial/dual.hpp"

using namespace rbd;

// per sample: the four IDSVA-SO tensors by each recursion and the four FDSVA-SO
// tensors (12 nv³), then qdd (nv)
template <typename S>
__global__ void second_order_all(ModelView<S> m, int B, const S* q, const S* qd, const S* qdd, const S* u,
                                 S gravity, unsigned char* scratch, unsigned long ws_bytes, S* out, int* ok) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= B) return;
  Workspace<S> w = carve_workspace<S>(scratch + s * ws_bytes, m.nb, m.nv);
  const int nv = m.nv;
  const long n3 = static_cast<long>(nv) * nv * nv;
  S* o = out + s * (12 * n3 + nv);
  const S* qs = q + s * m.nq;
  const S *vs = qd + s * nv, *as = qdd + s * nv, *us = u + s * nv;
  idsva_so_body_frame(m, w, qs, vs, as, gravity, o, o + n3, o + 2 * n3, o + 3 * n3);
  idsva_so_world_frame(m, w, qs, vs, as, gravity, o + 4 * n3, o + 5 * n3, o + 6 * n3, o + 7 * n3);
  ok[s] = fdsva_so(m, w, qs, vs, us, gravity, o + 8 * n3, o + 9 * n3, o + 10 * n3, o + 11 * n3, o + 12 * n3) ? 1 : 0;
}

template __global__ void second_order_all<double>(ModelView<double>, int, const double*, const double*,
                                                  const double*, const double*, double, unsigned char*,
                                                  unsigned long, double*, int*);
template __global__ void second_order_all<float>(ModelView<float>, int, const float*, const float*, const float*,
                                                 const float*, float, unsigned char*, unsigned long, float*, int*);
template __global__ void second_order_all<Dual<double>>(ModelView<Dual<double>>, int, const Dual<double>*,
                                                        const Dual<double>*, const Dual<double>*,
                                                        const Dual<double>*, Dual<double>, unsigned char*,
                                                        unsigned long, Dual<double>*, int*);
