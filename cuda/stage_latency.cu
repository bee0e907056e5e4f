// cuda/stage_latency.cu — how long one GPU thread takes for each pass of the
// per-sample maths (issue 17: where the time of a sample-per-thread kernel
// goes, before it is split across threads).
//
// One thread computes one sample, each stage `reps` times in a row, and
// times each repetition with clock64(); the table holds the fastest, in
// cycles and in µs at the SM clock. The workspace is in the block's shared
// memory where it fits (as the backend's launch puts it at small B), else in
// global memory. Built by the test command with nvcc beside the kernel check;
// run on a machine with a GPU (scripts/gpu-check.sh):
//
//   cuda_stage_latency <robots dir>
//
// The second table times the phases of the team kernels (include/rbdkit/cuda/team_kernels.cuh)
// the same way: one block of kTeam threads, one sample, its first thread reading
// the clock after each phase's last barrier. It says which serial phase decides a
// team's time (∇FD's first phase is M⁻¹'s team on a warp beside RNEA on one thread;
// before, ABA there).
#include <cuda_runtime.h>

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
#include "rbdkit/cuda/team_kernels.cuh"
#include "generated_iiwa.hpp"
#include "rbdkit/codegen/robot_model.hpp"

using namespace rbd;

#define CHECK_CUDA(x)                                                                   \
  do {                                                                                  \
    cudaError_t e_ = (x);                                                               \
    if (e_ != cudaSuccess) {                                                            \
      std::fprintf(stderr, "%s:%d: %s\n", __FILE__, __LINE__, cudaGetErrorString(e_)); \
      std::exit(2);                                                                     \
    }                                                                                   \
  } while (0)

// the stages, in the order ∇FD runs them (aba_derivatives.hpp), then the other families
constexpr int kStages = 10;
const char* const kStageNames[kStages] = {"world placements", "rnea", "crba", "minv (direct)", "aba",
                                          "∇ID forward pass", "∇ID backward pass", "-M⁻¹ D (one nv x nv)",
                                          "∇FD (whole)", "empty (clock cost)"};

// Known: 1, the workspace is in shared memory and the compiler sees it (shared loads and stores);
// 0, it is where ws_in_shared says, through a generic pointer, as in the backend's kernels
template <typename S, typename Src, int Known>
__global__ void stages(ModelView<S> call_model, const S* q, const S* qd, const S* tau, S gravity, unsigned char* global_ws,
                       int ws_in_shared, int reps, long long* cycles, S* sink) {
  extern __shared__ __align__(16) unsigned char shared_ws[];
  const ModelView<S> m = Src::view(call_model);
  Workspace<S> w = carve_workspace<S>(Known || ws_in_shared ? shared_ws : global_ws, m.nb, m.nv);
  const int nv = m.nv;
  S* out = sink;                  // (nv)
  S* D1 = sink + nv;              // (nv x nv)
  S* D2 = sink + nv + nv * nv;    // (nv x nv)
  S* qdd = sink + nv + 2 * nv * nv;
  for (int k = 0; k < kStages; ++k) cycles[k] = 1ll << 62;
  for (int r = 0; r < reps; ++r) {
    for (int k = 0; k < kStages; ++k) {
      const long long t0 = clock64();
      switch (k) {
        case 0: for (int i = 0; i < m.nb; ++i) world_placement(m, w, q, i); break;
        case 1: rnea(m, w, q, qd, qd, static_cast<const S*>(nullptr), gravity, out); break;
        case 2: crba(m, w, q, D1); break;
        case 3: minv_passes(m, w, q, true, w.dense); break;
        case 4: aba(m, w, q, qd, tau, static_cast<const S*>(nullptr), gravity, qdd); break;
        case 5: rnea_derivatives_forward_pass(m, w, q, qd, qdd, static_cast<const S*>(nullptr), gravity, false, true); break;
        case 6: rnea_derivatives_backward_pass(m, w, D1, D2, static_cast<S*>(nullptr)); break;
        // (w.dense: stage 3's M⁻¹, its first 2 nv entries overwritten where stage 4's aba factorised
        // M: the same work)
        case 7: apply_neg_minv(m, w, D1, nv); break;
        case 8: aba_derivatives(m, w, q, qd, tau, static_cast<const S*>(nullptr), gravity, qdd, D1, D2); break;
        default: break;
      }
      // the stage's results must be visible before the clock is read again
      __threadfence_block();
      const long long dt = clock64() - t0;
      if (dt < cycles[k]) cycles[k] = dt;
    }
  }
}

// the team kernels' phases, in the order ∇FD runs them, then ID's and FD's first phase
constexpr int kTeamStages = 11;
const char* const kTeamStageNames[kTeamStages] = {
    "M⁻¹ (minv_team on a warp)", "ABA (one thread)", "M⁻¹ on a warp beside ABA (∇FD's phase 1 before)",
    "∇FD and FD phase 1: M⁻¹ on a warp beside RNEA", "∇FD phase 2: ∇ID (rnea_derivatives_team)",
    "-M⁻¹ ∂ID, an entry per index (before)", "∇FD (aba_derivatives_team, whole)", "ID (rnea_team)",
    "M⁻¹ (minv_team on the block)", "∇FD phase 3: -M⁻¹ ∂ID in tiles (matmul_tiles)",
    "qdd = M⁻¹ (u - c), a row per index"};

template <typename S, typename Src, int Known>
__global__ void team_stages(ModelView<S> call_model, const S* q, const S* qd, const S* tau, S gravity, unsigned char* global_ws,
                            int ws_in_shared, unsigned long ws_bytes, int reps, long long* cycles, S* sink) {
  extern __shared__ __align__(16) unsigned char shared_ws[];
  const ModelView<S> m = Src::view(call_model);
  unsigned char* slice = Known || ws_in_shared ? shared_ws : global_ws;
  Workspace<S> w = carve_workspace<S>(slice, m.nb, m.nv);
  cuda::BlockTeam t;
  t.extra = slice + ws_bytes;  // aba_derivatives_team_bytes: FD's (RNEA's linear workspace, u - c, a flag), ∂ID, qdd
  const int nv = m.nv, n2 = nv * nv;
  Workspace<S> wa = carve_workspace<S>(t.extra, m.nb, nv, kLinearWorkspace);
  S* dq = reinterpret_cast<S*>(t.extra + forward_dynamics_team_bytes<S>(m.nb, nv));
  S* dv = dq + n2;
  S* qdd = dv + n2;
  int* ok = reinterpret_cast<int*>(t.extra + forward_dynamics_team_bytes<S>(m.nb, nv) - 16);  // (FD's flag and the next)
  S* out = sink;
  S* D1 = sink + nv;
  S* D2 = sink + nv + n2;
  if (threadIdx.x == 0)
    for (int k = 0; k < kTeamStages; ++k) cycles[k] = 1ll << 62;
  for (int r = 0; r < reps; ++r) {
    for (int k = 0; k < kTeamStages; ++k) {
      __syncthreads();
      const long long t0 = clock64();
      switch (k) {
        case 0: t.beside([&](const auto& sub) { minv_team(sub, m, w, q, true, w.dense, ok + 1); }, [] {}); break;
        case 1: t.beside([](const auto&) {}, [&] { ok[0] = aba(m, wa, q, qd, tau, static_cast<const S*>(nullptr), gravity, qdd); }); break;
        case 2:
          t.beside([&](const auto& sub) { minv_team(sub, m, w, q, true, w.dense, ok + 1); },
                   [&] { ok[0] = aba(m, wa, q, qd, tau, static_cast<const S*>(nullptr), gravity, qdd); });
          break;
        case 3:
          t.beside([&](const auto& sub) { minv_team(sub, m, w, q, true, w.dense, ok + 1); },
                   [&] {
                     rnea(m, wa, q, qd, static_cast<const S*>(nullptr), static_cast<const S*>(nullptr), gravity, out);
                     for (int j = 0; j < nv; ++j) out[j] = tau[j] - out[j];
                   });
          break;
        case 4: rnea_derivatives_team(t, m, w, q, qd, qdd, static_cast<const S*>(nullptr), gravity, dq, dv, true); break;
        case 5:
          t.each(2 * n2, [&](long e) {
            const S* D = e < n2 ? dq : dv;
            const int row = static_cast<int>(e % n2) / nv, c = static_cast<int>(e % nv);
            S acc = S(0);
            for (int l = 0; l < nv; ++l) acc += w.dense[row * nv + l] * D[l * nv + c];
            (e < n2 ? D1 : D2)[row * nv + c] = -acc;
          });
          break;
        case 6:
          aba_derivatives_team(t, m, w, t.extra, q, qd, tau, static_cast<const S*>(nullptr), gravity, qdd, D1, D2);
          break;
        case 7: rnea_team(t, m, w, q, qd, qd, static_cast<const S*>(nullptr), gravity, out); break;
        case 8: minv_team(t, m, w, q, true, w.dense, ok + 1); break;
        case 9: {
          const S* D[2] = {dq, dv};
          S* C[2] = {D1, D2};
          matmul_tiles(t, cuda::kTeam, w.dense, D, C, 2, nv, nv, nv, S(-1));
          break;
        }
        case 10:
          t.each(nv, [&](long row) {
            S acc = S(0);
            for (int c = 0; c < nv; ++c) acc += w.dense[row * nv + c] * out[c];
            qdd[row] = acc;
          });
          break;
        default: break;
      }
      __syncthreads();
      const long long dt = clock64() - t0;
      if (threadIdx.x == 0 && dt < cycles[k]) cycles[k] = dt;
    }
  }
}

// one table row: a stage's cycles and µs in each of `cols` columns (cycles[c * stride]; negative: not run)
void print_row(const char* name, const long long* cycles, int stride, int cols, int clock_khz) {
  std::printf("| %s |", name);
  for (int c = 0; c < cols; ++c) {
    const long long n = cycles[c * stride];
    if (n < 0) std::printf(" — | — |");
    else std::printf(" %lld | %.2f |", n, n / (clock_khz * 1e-3));
  }
  std::printf("\n");
}

// Src: the kernels' model, the view's (cuda::CallModel) or a generated robot's constants
// (instance::RobotModel, the per-robot instances' kernels)
template <typename S, typename Src = cuda::CallModel> void run(const Model& model, const char* label, int reps) {
  const int nq = model.nq, nv = model.nv, nb = model.nb();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::vector<double> q0 = model.neutral(), dq(nv), q(nq);
  for (auto& x : dq) x = U(rng);
  integrate(model.view(), q0.data(), dq.data(), q.data());
  std::vector<S> qs(q.begin(), q.end()), qd(nv), tau(nv);
  for (int k = 0; k < nv; ++k) qd[k] = S(U(rng)), tau[k] = S(10 * U(rng));
  const std::vector<BodyDesc<S>> bodies = model.bodies_as<S>();
  BodyDesc<S>* d_bodies;
  S *d_q, *d_qd, *d_tau, *d_sink;
  long long* d_cycles;
  unsigned char* d_ws;
  const unsigned long ws_bytes = (workspace_bytes<S>(nb, nv) + 255ul) & ~255ul;
  CHECK_CUDA(cudaMalloc(&d_bodies, bodies.size() * sizeof(BodyDesc<S>)));
  CHECK_CUDA(cudaMemcpy(d_bodies, bodies.data(), bodies.size() * sizeof(BodyDesc<S>), cudaMemcpyHostToDevice));
  CHECK_CUDA(cudaMalloc(&d_q, nq * sizeof(S)));
  CHECK_CUDA(cudaMalloc(&d_qd, nv * sizeof(S)));
  CHECK_CUDA(cudaMalloc(&d_tau, nv * sizeof(S)));
  CHECK_CUDA(cudaMalloc(&d_sink, (2 * nv + 2 * nv * nv) * sizeof(S)));
  CHECK_CUDA(cudaMalloc(&d_cycles, kStages * sizeof(long long)));
  CHECK_CUDA(cudaMalloc(&d_ws, ws_bytes));
  CHECK_CUDA(cudaMemcpy(d_q, qs.data(), nq * sizeof(S), cudaMemcpyHostToDevice));
  CHECK_CUDA(cudaMemcpy(d_qd, qd.data(), nv * sizeof(S), cudaMemcpyHostToDevice));
  CHECK_CUDA(cudaMemcpy(d_tau, tau.data(), nv * sizeof(S), cudaMemcpyHostToDevice));
  int shared_max = 0, clock_khz = 0;
  CHECK_CUDA(cudaDeviceGetAttribute(&shared_max, cudaDevAttrMaxSharedMemoryPerBlockOptin, 0));
  CHECK_CUDA(cudaDeviceGetAttribute(&clock_khz, cudaDevAttrClockRate, 0));
  CHECK_CUDA(cudaFuncSetAttribute(stages<S, Src, 0>, cudaFuncAttributeMaxDynamicSharedMemorySize, shared_max));
  CHECK_CUDA(cudaFuncSetAttribute(stages<S, Src, 1>, cudaFuncAttributeMaxDynamicSharedMemorySize, shared_max));
  const ModelView<S> mv{nb, nq, nv, model.general_path() ? 1 : 0, d_bodies};
  std::printf("\n%s, %s, workspace %lu bytes (one thread)\n", label, sizeof(S) == 8 ? "float64" : "float32", ws_bytes);
  std::printf("| stage | shared: cycles | µs | global: cycles | µs | shared, known to the compiler: cycles | µs |\n"
              "|---|---:|---:|---:|---:|---:|---:|\n");
  // columns: the workspace in shared memory through a generic pointer (as the backend's kernels), in
  // global memory, in shared memory with the compiler knowing it
  const bool fits = ws_bytes <= static_cast<unsigned long>(shared_max);
  long long cyc[3][kStages];
  for (int col = 0; col < 3; ++col) {
    for (int k = 0; k < kStages; ++k) cyc[col][k] = -1;
    if (col != 1 && !fits) continue;
    if (col == 2)
      stages<S, Src, 1><<<1, 1, ws_bytes>>>(mv, d_q, d_qd, d_tau, S(-9.81), d_ws, 1, reps, d_cycles, d_sink);
    else
      stages<S, Src, 0><<<1, 1, col == 0 ? ws_bytes : 0>>>(mv, d_q, d_qd, d_tau, S(-9.81), d_ws, col == 0, reps,
                                                           d_cycles, d_sink);
    CHECK_CUDA(cudaGetLastError());
    CHECK_CUDA(cudaDeviceSynchronize());
    CHECK_CUDA(cudaMemcpy(cyc[col], d_cycles, sizeof(cyc[col]), cudaMemcpyDeviceToHost));
  }
  for (int k = 0; k < kStages; ++k) print_row(kStageNames[k], &cyc[0][k], kStages, 3, clock_khz);
  // the team kernels' phases: a block of kTeam threads, the slice (workspace, then the team's extra)
  // in shared memory where it fits (through a generic pointer, and known to the compiler)
  const unsigned long team_bytes = ws_bytes + ((aba_derivatives_team_bytes<S>(nb, nv) + 255ul) & ~255ul);
  unsigned char* d_team_ws;
  long long* d_team_cycles;
  CHECK_CUDA(cudaMalloc(&d_team_ws, team_bytes));
  CHECK_CUDA(cudaMalloc(&d_team_cycles, kTeamStages * sizeof(long long)));
  CHECK_CUDA(cudaFuncSetAttribute(team_stages<S, Src, 0>, cudaFuncAttributeMaxDynamicSharedMemorySize, shared_max));
  CHECK_CUDA(cudaFuncSetAttribute(team_stages<S, Src, 1>, cudaFuncAttributeMaxDynamicSharedMemorySize, shared_max));
  const bool team_shared = team_bytes <= static_cast<unsigned long>(shared_max);
  long long tc[2][kTeamStages];
  for (int known = 0; known < 2; ++known) {
    for (int k = 0; k < kTeamStages; ++k) tc[known][k] = -1;
    if (known && !team_shared) continue;
    if (known)
      team_stages<S, Src, 1><<<1, cuda::kTeam, team_bytes>>>(mv, d_q, d_qd, d_tau, S(-9.81), d_team_ws, 1, ws_bytes,
                                                               20, d_team_cycles, d_sink);
    else
      team_stages<S, Src, 0><<<1, cuda::kTeam, team_shared ? team_bytes : 0>>>(
          mv, d_q, d_qd, d_tau, S(-9.81), d_team_ws, team_shared, ws_bytes, 20, d_team_cycles, d_sink);
    CHECK_CUDA(cudaGetLastError());
    CHECK_CUDA(cudaDeviceSynchronize());
    CHECK_CUDA(cudaMemcpy(tc[known], d_team_cycles, sizeof(tc[known]), cudaMemcpyDeviceToHost));
  }
  std::printf("\n%s, %s, a team of %d threads, slice %lu bytes in %s memory\n"
              "| team phase | cycles | µs | shared, known to the compiler: cycles | µs |\n|---|---:|---:|---:|---:|\n",
              label, sizeof(S) == 8 ? "float64" : "float32", cuda::kTeam, team_bytes, team_shared ? "shared" : "global");
  for (int k = 0; k < kTeamStages; ++k) print_row(kTeamStageNames[k], &tc[0][k], kTeamStages, 2, clock_khz);
  cudaFree(d_bodies), cudaFree(d_q), cudaFree(d_qd), cudaFree(d_tau), cudaFree(d_sink), cudaFree(d_cycles),
      cudaFree(d_ws), cudaFree(d_team_ws), cudaFree(d_team_cycles);
}

int main(int argc, char** argv) {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess || count == 0) {
    std::printf("no CUDA device: the probe compiled; nothing to run here\n");
    return 0;
  }
  cudaDeviceProp p;
  CHECK_CUDA(cudaGetDeviceProperties(&p, 0));
  int clock_khz = 0;
  CHECK_CUDA(cudaDeviceGetAttribute(&clock_khz, cudaDevAttrClockRate, 0));
  std::printf("%s, SM clock %.0f MHz; fastest of 20 repetitions per stage\n", p.name, clock_khz * 1e-3);
  const std::string dir = argc > 1 ? argv[1] : "robots";
  for (auto [name, floating] : {std::pair<const char*, bool>{"iiwa", false}, {"atlas", true}}) {
    const Model m = Model::from_urdf_file(dir + "/" + name + ".urdf", floating);
    const std::string label = std::string(name) + (floating ? " floating" : "");
    run<float>(m, label.c_str(), 20);
    run<double>(m, label.c_str(), 20);
    if (std::string(name) == "iiwa") {  // the same kernels on the generated header's constants
      using Iiwa = instance::RobotModel<rbdkit_generated::Iiwa>;
      run<float, Iiwa>(m, "iiwa as compile-time constants (cuda/generated_iiwa.hpp)", 20);
      run<double, Iiwa>(m, "iiwa as compile-time constants (cuda/generated_iiwa.hpp)", 20);
    }
  }
  return 0;
}
