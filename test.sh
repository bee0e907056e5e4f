#!/usr/bin/env bash
# Every test: installs what is needed, builds the C++ library (the CUDA
# backend's kernels with nvcc) and its tests, runs ctest (also under ASan/UBSan), fuzzes
# the URDF reader and ModelBuilder briefly (scripts/fuzz.sh), builds the
# Python package and runs pytest (Pinocchio equivalence included; nothing is skipped), then the
# comparison with Pinocchio's C++ second-order derivatives (tests/pinocchio_so).
set -euo pipefail
cd "$(dirname "$0")"
bash scripts/setup.sh --test
PY=${PYTHON:-python3}
JOBS=${JOBS:-$(nproc)}

# JAX and PyTorch (rbdkit.jax, rbdkit.torch): downloaded and installed in the
# background while the C++ builds (a few GB, mostly network time); waited for
# before the Python package is built (its XLA FFI handler needs jaxlib's headers)
mkdir -p build
PIP_BREAK_SYSTEM_PACKAGES=1 PIP_ROOT_USER_ACTION=ignore PIP_DISABLE_PIP_VERSION_CHECK=1 \
  "$PY" -m pip install -q -r requirements-frameworks.txt >build/frameworks-install.log 2>&1 &
frameworks_pid=$!
# (a failure before the wait below must not leave it writing to site-packages)
trap 'kill "$frameworks_pid" 2>/dev/null || true' EXIT

# ---- C++: library with the CUDA backend's real kernels (nvcc), GoogleTest
# suite (the CUDA backend in interpret mode included), find_package consumer.
# The kernels as PTX for one architecture here (RBDKIT_TEST_CUDA_ARCH, default
# 90-virtual: the driver compiles it to machine code when it loads it; a plain
# cmake build compiles CMake's default, 80;90, machine code and PTX). Without a
# GPU (CI) they are compiled and never run, so nvcc's device optimiser is off
# (-Xcicc -O0): every kernel still goes through the front end and PTX
# generation, in about 25 core-seconds instead of 320. The optimised kernels
# are what scripts/gpu-check.sh builds and runs, and the ctest
# cuda_model_read_only compiles its kernel optimised. RBDKIT_TEST_CUDA_FLAGS overrides.
export PATH="$PATH:/usr/local/cuda/bin"
if ! command -v nvcc >/dev/null; then
  if [[ "${CI:-}" == "true" ]]; then echo "test: nvcc not found; CI must compile the CUDA kernels" >&2; exit 1; fi
  echo "test: nvcc not found: the CUDA kernels are NOT compiled (interpret mode is still tested)" >&2
fi
if nvidia-smi -L >/dev/null 2>&1; then cuda_flags=""; else cuda_flags="-Xcicc -O0"; fi
cmake -S . -B build/cpp -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES="${RBDKIT_TEST_CUDA_ARCH:-90-virtual}" \
  -DCMAKE_CUDA_FLAGS="${RBDKIT_TEST_CUDA_FLAGS-$cuda_flags}" -DRBDKIT_CUDA_CHECK=OFF >/dev/null
cmake --build build/cpp -j "$JOBS"
# the compiled per-robot instances the tests make (Handle::specialize), one cache for every suite below
export RBDKIT_CACHE_DIR="$PWD/build/instances"
(cd build/cpp && ctest --output-on-failure -j "$JOBS")

# ---- the same C++ tests under AddressSanitizer and UndefinedBehaviorSanitizer
# (-O1 -g1 and no flattening of the engine kernels keep its compile time down;
# the engine at the compiler's baseline vector width, 16-byte packs: with
# 32-byte AVX packs, GCC 12's -fsanitize=null reports references to them as
# null at -O1, a false report on references to locals)
san="-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer"
cmake -S . -B build/sanitize -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRBDKIT_CUDA_CHECK=OFF -DRBDKIT_CUDA=OFF \
  -DRBDKIT_ENGINE_ARCH= \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DCMAKE_CXX_FLAGS="$san -DRBDKIT_NO_FLATTEN" -DCMAKE_EXE_LINKER_FLAGS="$san" >/dev/null
cmake --build build/sanitize -j "$JOBS"
# (Atlas's cases are left to the plain build's ctest above: under the sanitizers they took 150 s of the
# 360 core-seconds, for the code paths floating HyQ already covers)
(cd build/sanitize && ctest --output-on-failure -j "$JOBS" -E "find_package_consumer|atlas")

# ---- fuzzing (libFuzzer, clang, ASan/UBSan): the URDF reader and ModelBuilder,
# saved regression inputs first, then up to 20 s per target (scripts/fuzz.sh)
JOBS="$JOBS" scripts/fuzz.sh

# ---- second-order derivatives against Pinocchio's C++ library (not in its
# Python module): one program built against the `pin` wheel
# (built in build/cpp: the library compiled above is reused)
RBDKIT_PINOCCHIO_BUILD=build/cpp JOBS="$JOBS" PYTHON="$PY" tests/pinocchio_so/run.sh

# ---- Python: build and install the package, then pytest (last: its summary closes the run)
if ! wait "$frameworks_pid"; then
  cat build/frameworks-install.log
  echo "test: installing JAX and PyTorch (requirements-frameworks.txt) failed" >&2
  exit 1
fi
trap - EXIT
echo "building the Python package (pip install .) ..."
# (linked to build/cpp's librbdkit.a: the library is not compiled a second time)
PIP_BREAK_SYSTEM_PACKAGES=1 PIP_ROOT_USER_ACTION=ignore "$PY" -m pip install -q --no-build-isolation . \
  -Ccmake.define.RBDKIT_PREBUILT_LIBRARY="$PWD/build/cpp/librbdkit.a"
# (-n: one pytest worker per core, pytest-xdist)
"$PY" -m pytest -q -p no:cacheprovider -n "$JOBS" tests/python
