#!/usr/bin/env bash
# On a machine with an NVIDIA GPU: build with the real CUDA kernels, run the
# CUDA-vs-CPU tests on the device (C++ and, where NumPy is installed, Python
# with device arrays through PyTorch or CuPy when one is there, and rbdkit.jax
# on XLA's GPU buffers when JAX has its CUDA platform), run
# compute-sanitizer (memcheck, racecheck) on a small batch, and
# bench/gpu.py. Prints one summary table at the end; record it, with the
# GPU's name, in docs/gpu.md.
#   scripts/gpu-check.sh [--quick] [bench/gpu.py's options...]   --quick: the benchmark's short form
# GPU_CHECK_PREBUILT=1: the build was made elsewhere by scripts/gpu-prebuild.sh (whose outputs come
# here as .gpu/carry.tar.xz, unpacked first): the build step is skipped, and the Python step
# installs its wheel instead of compiling (a Python extension compiled here against a library
# compiled there mixes two compilers in one shared object: docs/gpu.md, 2026-11-26).
# SANITIZER_TIMEOUT: seconds per compute-sanitizer run (default 300).
# Exit status: non-zero when a test or a sanitizer check fails.
set -uo pipefail
cd "$(dirname "$0")/.."
bench_args=("$@")  # --quick, --budget S, --max-gb G: bench/gpu.py's
export PATH="$PATH:/usr/local/cuda/bin"
JOBS=${JOBS:-$(nproc)}
ARCH=${CUDA_ARCH:-native}  # the machine's GPU only: a quicker build than 80;90
declare -a summary
status=0
step() {  # step <name> <command...>: runs it, records pass/fail
  local name=$1
  shift
  echo "==== $name"
  if "$@"; then summary+=("| $name | pass |"); else summary+=("| $name | FAIL |"); status=1; fi
}

nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
rm -f build/gpu/stage_latency.md build/gpu/call_cost.md build/gpu/gpu_bench.md  # (no table of an earlier run)
gpu=$(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1)

# ---- build: the library with the real kernels, the C++ tests
prebuilt=${GPU_CHECK_PREBUILT:-0}
if [[ "$prebuilt" == 1 ]]; then
  # scripts/gpu-prebuild.sh's outputs, carried here as one file: unpacked on every run (a warm
  # machine keeps the last run's build/gpu, which a newer carry must replace)
  [[ -f .gpu/carry.tar.xz ]] && tar xJf .gpu/carry.tar.xz
  [[ -f build/gpu/CMakeCache.txt ]] || {
    echo "gpu-check: GPU_CHECK_PREBUILT=1 but build/gpu/CMakeCache.txt is missing: copy scripts/gpu-prebuild.sh's outputs here" >&2
    exit 2
  }
  ARCH=$(sed -n 's/^CMAKE_CUDA_ARCHITECTURES:[A-Z]*=//p' build/gpu/CMakeCache.txt)
  summary+=("| build (CMAKE_CUDA_ARCHITECTURES=$ARCH) | built elsewhere (scripts/gpu-prebuild.sh), copied |")
  export LD_LIBRARY_PATH="$PWD/.gpu/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"  # its tinyxml2
  # the tests read the robots from the source tree's path there
  src=$(sed -n 's/^CMAKE_HOME_DIRECTORY:INTERNAL=//p' build/gpu/CMakeCache.txt)
  if [[ "$src" != "$PWD" && ! -e "$src" ]]; then mkdir -p "$(dirname "$src")" && ln -s "$PWD" "$src"; fi
else
  step "build (CMAKE_CUDA_ARCHITECTURES=$ARCH)" bash -c "
    cmake -S . -B build/gpu -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES=$ARCH -DRBDKIT_CUDA_CHECK=ON >/dev/null &&
    cmake --build build/gpu -j $JOBS"
fi

# ---- the CUDA-vs-CPU tests on the device (the interpret-mode tests, with a real device instead)
step "C++ CUDA tests on the device" env RBDKIT_TEST_CUDA_DEVICE=1 build/gpu/tests/cpp/rbdkit_tests \
  --gtest_filter='*Cuda*'
step "C++ kernel check (cuda/kernel_check.cu)" build/gpu/cuda_kernel_check robots
# one thread's cycles per pass of the per-sample maths (issue 17's profile); its table is printed at the end
if [[ -x build/gpu/cuda_stage_latency ]]; then
  step "one thread's cycles per pass (cuda/stage_latency.cu)" bash -c \
    "build/gpu/cuda_stage_latency robots > build/gpu/stage_latency.md"
fi

# ---- compute-sanitizer on a small batch (a chain and a branched floating robot, every operation, the
# team kernels among them; about 40 s more per tool for the branched one): memcheck (global and shared
# memory, launch errors); racecheck (shared-memory races: each thread's work slice must not overlap
# another's, and a team kernel's threads share their sample's); synccheck (a team kernel's barriers
# reached by every thread of its block)
if command -v compute-sanitizer >/dev/null; then
  for tool in memcheck racecheck synccheck; do
    step "compute-sanitizer --tool $tool" env RBDKIT_TEST_CUDA_DEVICE=1 timeout "${SANITIZER_TIMEOUT:-300}" \
      compute-sanitizer --tool "$tool" \
      --error-exitcode 1 build/gpu/tests/cpp/rbdkit_tests \
      --gtest_filter='Models/CudaModels.*/iiwa_fixed:Models/CudaModels.*/hyq_floating:Cuda.SharedBlocksOfManySamples'
  done
else
  summary+=("| compute-sanitizer | not found |")
fi

# ---- Python: the package on the same library, its CUDA tests on the device, the benchmark
PY=${PYTHON:-python3}
if [[ "$prebuilt" == 1 ]]; then
  step "Python package (.gpu/wheel)" env PIP_BREAK_SYSTEM_PACKAGES=1 PIP_ROOT_USER_ACTION=ignore "$PY" -m pip install \
    -q --no-index --no-deps --force-reinstall .gpu/wheel/*.whl
fi
if [[ "$prebuilt" == 1 ]] || "$PY" -c "import numpy, nanobind, scikit_build_core" 2>/dev/null; then
  [[ "$prebuilt" == 1 ]] || step "Python package" env PIP_BREAK_SYSTEM_PACKAGES=1 PIP_ROOT_USER_ACTION=ignore "$PY" -m pip install -q \
    --no-build-isolation --no-deps . -Ccmake.define.RBDKIT_PREBUILT_LIBRARY="$PWD/build/gpu/librbdkit.a" \
    -Ccmake.define.CMAKE_CUDA_ARCHITECTURES="$ARCH"
  step "Python CUDA tests on the device" env RBDKIT_TEST_CUDA_DEVICE=1 "$PY" -m pytest -q -p no:cacheprovider \
    tests/python/test_cuda.py
  if "$PY" -c "import torch; assert torch.cuda.is_available()" 2>/dev/null; then
    step "rbdkit.torch on CUDA tensors" env RBDKIT_TEST_CUDA_DEVICE=1 "$PY" -m pytest -q -p no:cacheprovider \
      tests/python/test_torch.py -k cuda
    # where a B = 1 call's time goes (issue 17's single-call target); its table is printed at the end
    step "bench/gpu_call_cost.py" bash -c "'$PY' bench/gpu_call_cost.py > build/gpu/call_cost.md"
  fi
  if "$PY" -c "import jax; assert jax.default_backend() == 'gpu'" 2>/dev/null; then
    step "rbdkit.jax on GPU arrays (XLA's CUDA platform)" env RBDKIT_TEST_CUDA_DEVICE=1 "$PY" -m pytest -q \
      -p no:cacheprovider tests/python/test_jax.py -k cuda
  fi
  step "bench/gpu.py" "$PY" bench/gpu.py "${bench_args[@]}" --out build/gpu/gpu_bench.md
else
  summary+=("| Python tests and bench/gpu.py | skipped: numpy, nanobind or scikit-build-core missing |")
fi

echo
echo "## gpu-check on ${gpu:-an unknown GPU} ($(date -u +%Y-%m-%d))"
echo
echo "| step | result |"
echo "|---|---|"
printf '%s\n' "${summary[@]}"
[[ -f build/gpu/stage_latency.md ]] && { echo; cat build/gpu/stage_latency.md; }
[[ -f build/gpu/call_cost.md ]] && { echo; cat build/gpu/call_cost.md; }
[[ -f build/gpu/gpu_bench.md ]] && { echo; cat build/gpu/gpu_bench.md; }
exit $status
