// cuda/centroidal_check.cu — the energy and centroidal family inside
// __global__ kernels.
//
// Compiled (not run) by the build with nvcc, in double, float and dual
// numbers, so that a host-only construct in algorithms/energy.hpp or
// algorithms/centroidal.hpp fails the build. The CPU results are checked
// against Pinocchio in tests/python/test_centroidal.py.
#include "rbdkit/algorithms/centroidal.hpp"
#include "rbdkit/algorithms/energy.hpp"
#include "rbdkit/spatial/dual.hpp"

using namespace rbd;

// outputs per sample, in this order: T, V (2), C (nv²), com (3), J_com (3 nv),
// A (6 nv), h (6), h of the one-pass algorithm (6), dA (6 nv²), A of dccrba
// (6 nv), A of cmm_time_variation (6 nv), Ȧ (6 nv), ḣ (6), the four
// centroidal dynamics derivatives (4 x 6 nv)
RBD_HD int centroidal_outputs(int nv) { return 23 + 7 * nv * nv + 51 * nv; }

template <typename S>
__global__ void centroidal_all(ModelView<S> m, int B, const S* q, const S* qd, const S* qdd, S gravity,
                               unsigned char* scratch, unsigned long ws_bytes, S* out) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= B) return;
  Workspace<S> w = carve_workspace<S>(scratch + s * ws_bytes, m.nb, m.nv);
  const int nv = m.nv;
  const S* qs = q + s * m.nq;
  const S* vs = qd + s * nv;
  const S* as = qdd + s * nv;
  S* o = out + s * centroidal_outputs(nv);
  S* C = o + 2;
  S* com = C + nv * nv;
  S* Jcom = com + 3;
  S* A = Jcom + 3 * nv;
  S* h = A + 6 * nv;
  S* h1 = h + 6;
  S* dA = h1 + 6;
  S* A_dA = dA + 6 * nv * nv;
  S* A_dt = A_dA + 6 * nv;
  S* Adot = A_dt + 6 * nv;
  S* hdot = Adot + 6 * nv;
  S* D = hdot + 6;
  // energy and Coriolis
  o[0] = kinetic_energy(m, w, qs, vs);
  o[1] = potential_energy(m, w, qs, gravity);
  coriolis_matrix(m, w, qs, vs, C);
  // centre of mass
  center_of_mass(m, w, qs, com);
  jacobian_com(m, w, qs, Jcom);
  // centroidal momentum, its configuration derivative and time variation
  ccrba(m, w, qs, vs, A, h);
  centroidal_momentum(m, w, qs, vs, h1);
  dccrba(m, w, qs, A_dA, dA);
  cmm_time_variation(m, w, qs, vs, A_dt, Adot);
  centroidal_momentum_time_variation(m, w, qs, vs, as, hdot);
  centroidal_dynamics_derivatives(m, w, qs, vs, as, D, D + 6 * nv, D + 12 * nv, D + 18 * nv);
}

template __global__ void centroidal_all<double>(ModelView<double>, int, const double*, const double*, const double*,
                                                double, unsigned char*, unsigned long, double*);
template __global__ void centroidal_all<float>(ModelView<float>, int, const float*, const float*, const float*, float,
                                               unsigned char*, unsigned long, float*);
template __global__ void centroidal_all<Dual<double>>(ModelView<Dual<double>>, int, const Dual<double>*,
                                                      const Dual<double>*, const Dual<double>*, Dual<double>,
                                                      unsigned char*, unsigned long, Dual<double>*);
