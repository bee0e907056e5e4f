#!/usr/bin/env bash
# On a machine with an NVIDIA GPU: build with the real CUDA kernels, run the
# CUDA-vs-CPU tests on the device (C++ and, where NumPy is installed, Python
# with device arrays through PyTorch or CuPy when one is there), run
# compute-sanitizer (memcheck, racecheck) on a small batch, and
# bench/gpu.py. Prints one summary table at the end; record it, with the
# GPU's name, in docs/gpu.md.
#   scripts/gpu-check.sh [--quick]      --quick: the benchmark's short form
# Exit status: non-zero when a test or a sanitizer check fails.
set -uo pipefail
cd "$(dirname "$0")/.."
quick=()
[[ "${1:-}" == "--quick" ]] && quick=(--quick)
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
gpu=$(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1)

# ---- build: the library with the real kernels, the C++ tests
step "build (CMAKE_CUDA_ARCHITECTURES=$ARCH)" bash -c "
  cmake -S . -B build/gpu -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES=$ARCH -DRBDKIT_CUDA_CHECK=ON >/dev/null &&
  cmake --build build/gpu -j $JOBS"

# ---- the CUDA-vs-CPU tests on the device (the interpret-mode tests, with a real device instead)
step "C++ CUDA tests on the device" env RBDKIT_TEST_CUDA_DEVICE=1 build/gpu/tests/cpp/rbdkit_tests \
  --gtest_filter='*Cuda*'
step "C++ kernel check (cuda/kernel_check.cu)" build/gpu/cuda_kernel_check robots

# ---- compute-sanitizer on a small batch (one model, every operation): memcheck (global memory,
# launch errors); racecheck (shared-memory races: none possible in the one-sample-per-thread
# kernels, there for the cooperative kernels that will share memory within a block)
if command -v compute-sanitizer >/dev/null; then
  for tool in memcheck racecheck; do
    step "compute-sanitizer --tool $tool" env RBDKIT_TEST_CUDA_DEVICE=1 compute-sanitizer --tool "$tool" \
      --error-exitcode 1 build/gpu/tests/cpp/rbdkit_tests --gtest_filter='Models/CudaModels.*/iiwa_fixed'
  done
else
  summary+=("| compute-sanitizer | not found |")
fi

# ---- Python: the package on the same library, its CUDA tests on the device, the benchmark
PY=${PYTHON:-python3}
if "$PY" -c "import numpy, nanobind, scikit_build_core" 2>/dev/null; then
  step "Python package" env PIP_BREAK_SYSTEM_PACKAGES=1 PIP_ROOT_USER_ACTION=ignore "$PY" -m pip install -q \
    --no-build-isolation --no-deps . -Ccmake.define.RBDKIT_PREBUILT_LIBRARY="$PWD/build/gpu/librbdkit.a" \
    -Ccmake.define.CMAKE_CUDA_ARCHITECTURES="$ARCH"
  step "Python CUDA tests on the device" env RBDKIT_TEST_CUDA_DEVICE=1 "$PY" -m pytest -q -p no:cacheprovider \
    tests/python/test_cuda.py
  step "bench/gpu.py" "$PY" bench/gpu.py "${quick[@]}" --out build/gpu/gpu_bench.md
else
  summary+=("| Python tests and bench/gpu.py | skipped: numpy, nanobind or scikit-build-core missing |")
fi

echo
echo "## gpu-check on ${gpu:-an unknown GPU} ($(date -u +%Y-%m-%d))"
echo
echo "| step | result |"
echo "|---|---|"
printf '%s\n' "${summary[@]}"
[[ -f build/gpu/gpu_bench.md ]] && { echo; cat build/gpu/gpu_bench.md; }
exit $status
