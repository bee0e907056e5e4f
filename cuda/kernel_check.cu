// cuda/kernel_check.cu — the per-sample maths inside __global__ kernels.
//
// Built by the test command with nvcc (no GPU needed to compile), so that a
// host-only construct in the shared algorithm headers fails the build. Run
// on a machine with a GPU, it evaluates every algorithm on B samples of the
// bundled iiwa14 (and a floating-base HyQ) on the device, in double and float,
// and compares with the CPU results.
//
//   cuda_kernel_check <robots dir>      exit 0: agree (or no device), 1: mismatch
#include <cuda_runtime.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "rbdkit/algorithms/aba.hpp"
#include "rbdkit/algorithms/aba_derivatives.hpp"
#include "rbdkit/algorithms/crba.hpp"
#include "rbdkit/algorithms/minv.hpp"
#include "rbdkit/algorithms/rnea.hpp"
#include "rbdkit/model/configuration.hpp"
#include "rbdkit/parsers/model.hpp"
#include "rbdkit/plant/integrators.hpp"

using namespace rbd;

// outputs per sample: tau (nv), M (nv²), Minv (nv²), qdd_aba (nv), qdd_fd (nv), q_next (nq), dq (nv),
// dtau_dq (nv²), dtau_dqd (nv²), dqdd_dq (nv²), dqdd_dqd (nv²), qdd of the gradient call (nv)
constexpr int kOutputs = 12;
template <typename S> struct Outputs {
  S *tau, *M, *Minv, *qdd_aba, *qdd_fd, *q_next, *dq, *dtau_dq, *dtau_dqd, *dqdd_dq, *dqdd_dqd, *qdd_grad;
};

template <typename S>
__global__ void all_algorithms(ModelView<S> m, int B, const S* q, const S* qd, const S* tau_in, S gravity,
                               unsigned char* scratch, unsigned long ws_bytes, Outputs<S> out) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= B) return;
  Workspace<S> w = carve_workspace<S>(scratch + s * ws_bytes, m.nb, m.nv);
  const S* qs = q + s * m.nq;
  const S* vs = qd + s * m.nv;
  const int nv = m.nv;
  rnea(m, w, qs, vs, vs, static_cast<const S*>(nullptr), gravity, out.tau + s * nv);
  crba(m, w, qs, out.M + s * nv * nv);
  minv(m, w, qs, true, out.Minv + s * nv * nv);
  aba(m, w, qs, vs, tau_in + s * nv, static_cast<const S*>(nullptr), gravity, out.qdd_aba + s * nv);
  forward_dynamics(m, w, qs, vs, tau_in + s * nv, static_cast<const S*>(nullptr), gravity, out.qdd_fd + s * nv);
  integrate(m, qs, vs, out.q_next + s * m.nq);
  difference(m, qs, out.q_next + s * m.nq, out.dq + s * nv);
  // first-order derivatives
  rnea_derivatives(m, w, qs, vs, vs, static_cast<const S*>(nullptr), gravity, out.dtau_dq + s * nv * nv,
                   out.dtau_dqd + s * nv * nv);
  aba_derivatives(m, w, qs, vs, tau_in + s * nv, static_cast<const S*>(nullptr), gravity, out.qdd_grad + s * nv,
                  out.dqdd_dq + s * nv * nv, out.dqdd_dqd + s * nv * nv);
}

// one integrator step with its Jacobian per thread; compiled here so that the
// integrator family stays device code (the CPU results are checked in
// tests/python/test_integrators.py)
template <typename S>
__global__ void integrator_steps(ModelView<S> m, int B, int type, const S* q, const S* v, const S* u, S dt,
                                 unsigned char* scratch, unsigned long ws_bytes, S* values, long n_values,
                                 S* x_next, S* AB) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= B) return;
  Workspace<S> w = carve_workspace<S>(scratch + s * ws_bytes, m.nb, m.nv);
  const int nq = m.nq, nv = m.nv;
  integrator_gradient(m, w, type, q + s * nq, v + s * nv, u + s * nv, static_cast<const S*>(nullptr), dt, S(-9.81),
                      x_next + s * (nq + nv), x_next + s * (nq + nv) + nq, AB + s * 6L * nv * nv,
                      values + s * n_values);
}
template __global__ void integrator_steps<double>(ModelView<double>, int, int, const double*, const double*,
                                                  const double*, double, unsigned char*, unsigned long, double*,
                                                  long, double*, double*);
template __global__ void integrator_steps<float>(ModelView<float>, int, int, const float*, const float*, const float*,
                                                 float, unsigned char*, unsigned long, float*, long, float*, float*);

#define CHECK_CUDA(x)                                                           \
  do {                                                                          \
    cudaError_t e = (x);                                                        \
    if (e != cudaSuccess) {                                                     \
      std::printf("CUDA error %s at %s:%d\n", cudaGetErrorString(e), __FILE__, __LINE__); \
      return -1.0;                                                              \
    }                                                                           \
  } while (0)

template <typename T> T* to_device(const std::vector<T>& h) {
  T* d = nullptr;
  cudaMalloc(&d, h.size() * sizeof(T));
  cudaMemcpy(d, h.data(), h.size() * sizeof(T), cudaMemcpyHostToDevice);
  return d;
}

// run the kernel in scalar S on B random samples and return the largest
// relative difference to the CPU double results
template <typename S> double run(const Model& model, int B) {
  const int nq = model.nq, nv = model.nv, nb = model.nb();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::vector<double> q(B * nq), qd(B * nv), tau(B * nv);
  for (int s = 0; s < B; ++s) {
    std::vector<double> q0 = model.neutral(), dq(nv);
    for (auto& x : dq) x = U(rng);
    integrate(model.view(), q0.data(), dq.data(), q.data() + s * nq);
    for (int k = 0; k < nv; ++k) qd[s * nv + k] = U(rng), tau[s * nv + k] = 10 * U(rng);
  }
  // the model and inputs in S
  const std::vector<BodyDesc<S>> bodies = model.bodies_as<S>();
  std::vector<S> qs(q.begin(), q.end()), qds(qd.begin(), qd.end()), taus(tau.begin(), tau.end());
  BodyDesc<S>* d_bodies = to_device(bodies);
  S *d_q = to_device(qs), *d_qd = to_device(qds), *d_tau = to_device(taus);
  const unsigned long ws_bytes = (workspace_bytes<S>(nb, nv) + 255ul) & ~255ul;
  unsigned char* d_scratch = nullptr;
  CHECK_CUDA(cudaMalloc(&d_scratch, ws_bytes * B));
  const size_t n1 = nv, n2 = size_t(nv) * nv;
  const size_t sizes[kOutputs] = {n1, n2, n2, n1, n1, size_t(nq), n1, n2, n2, n2, n2, n1};
  S* d_out[kOutputs];
  for (int k = 0; k < kOutputs; ++k) CHECK_CUDA(cudaMalloc(&d_out[k], sizes[k] * B * sizeof(S)));
  Outputs<S> out{d_out[0], d_out[1], d_out[2], d_out[3], d_out[4], d_out[5],
                 d_out[6], d_out[7], d_out[8], d_out[9], d_out[10], d_out[11]};
  ModelView<S> mv{nb, nq, nv, model.general_path() ? 1 : 0, d_bodies};
  all_algorithms<S><<<(B + 63) / 64, 64>>>(mv, B, d_q, d_qd, d_tau, S(-9.81), d_scratch, ws_bytes, out);
  CHECK_CUDA(cudaGetLastError());
  CHECK_CUDA(cudaDeviceSynchronize());

  // the same on the CPU in double
  std::vector<double> buf(workspace_bytes<double>(nb, nv) / sizeof(double) + 2);
  Workspace<double> w = carve_workspace<double>(buf.data(), nb, nv);
  const ModelView<double> hv = model.view();
  double worst = 0;
  std::vector<double> scratch(2 * n2 + n1);
  for (int k = 0; k < kOutputs; ++k) {
    std::vector<S> dev(sizes[k] * B);
    CHECK_CUDA(cudaMemcpy(dev.data(), d_out[k], dev.size() * sizeof(S), cudaMemcpyDeviceToHost));
    std::vector<double> ref(sizes[k]);
    for (int s = 0; s < B; ++s) {
      const double* qh = q.data() + s * nq;
      const double* vh = qd.data() + s * nv;
      std::vector<double> qn(nq);
      switch (k) {
        case 0: rnea(hv, w, qh, vh, vh, static_cast<const double*>(nullptr), -9.81, ref.data()); break;
        case 1: crba(hv, w, qh, ref.data()); break;
        case 2: minv(hv, w, qh, true, ref.data()); break;
        case 3: aba(hv, w, qh, vh, tau.data() + s * nv, static_cast<const double*>(nullptr), -9.81, ref.data()); break;
        case 4: forward_dynamics(hv, w, qh, vh, tau.data() + s * nv, static_cast<const double*>(nullptr), -9.81, ref.data()); break;
        case 5: integrate(hv, qh, vh, ref.data()); break;
        case 6: integrate(hv, qh, vh, qn.data()); difference(hv, qh, qn.data(), ref.data()); break;
        case 7: rnea_derivatives(hv, w, qh, vh, vh, static_cast<const double*>(nullptr), -9.81, ref.data(), scratch.data()); break;
        case 8: rnea_derivatives(hv, w, qh, vh, vh, static_cast<const double*>(nullptr), -9.81, scratch.data(), ref.data()); break;
        case 9: aba_derivatives(hv, w, qh, vh, tau.data() + s * nv, static_cast<const double*>(nullptr), -9.81,
                                scratch.data() + 2 * n2, ref.data(), scratch.data()); break;
        case 10: aba_derivatives(hv, w, qh, vh, tau.data() + s * nv, static_cast<const double*>(nullptr), -9.81,
                                 scratch.data() + 2 * n2, scratch.data(), ref.data()); break;
        default: aba_derivatives(hv, w, qh, vh, tau.data() + s * nv, static_cast<const double*>(nullptr), -9.81,
                                 ref.data(), scratch.data(), scratch.data() + n2); break;
      }
      double scale = 1;
      for (double x : ref) scale = std::fmax(scale, std::fabs(x));
      for (size_t i = 0; i < sizes[k]; ++i)
        worst = std::fmax(worst, std::fabs(double(dev[s * sizes[k] + i]) - ref[i]) / scale);
    }
  }
  cudaFree(d_bodies); cudaFree(d_q); cudaFree(d_qd); cudaFree(d_tau); cudaFree(d_scratch);
  for (auto p : d_out) cudaFree(p);
  return worst;
}

int main(int argc, char** argv) {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess || count == 0) {
    std::printf("no CUDA device: the kernels compiled; nothing to run here\n");
    return 0;
  }
  const std::string dir = argc > 1 ? argv[1] : "robots";
  int bad = 0;
  for (auto [name, floating] : {std::pair<const char*, bool>{"iiwa", false}, {"hyq", true}, {"atlas", true}}) {
    const Model m = Model::from_urdf_file(dir + "/" + name + ".urdf", floating);
    const double e64 = run<double>(m, 1000), e32 = run<float>(m, 1000);
    // float: the CPU engine's float32 bound for M⁻¹ and the ABA derivatives (tests/cpp/registry_helpers.hpp),
    // which amplify rounding by cond(M) (floating Atlas on an H200: 1.4e-3)
    const bool ok = e64 >= 0 && e64 < 1e-11 && e32 >= 0 && e32 < 2e-3;
    std::printf("%-6s %s  double: max rel err %.2e   float: %.2e   %s\n", name, floating ? "floating" : "fixed   ",
                e64, e32, ok ? "ok" : "MISMATCH");
    bad += ok ? 0 : 1;
  }
  return bad ? 1 : 0;
}
