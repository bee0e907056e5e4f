#!/usr/bin/env bash
# Builds here, on a machine without a GPU, what scripts/gpu-check.sh would build on the GPU machine,
# so that a short lease of one is spent on running, not compiling (the library's CUDA routes take
# about 5 minutes per dtype even on many cores). One compiler makes every part.
#   scripts/gpu-prebuild.sh [PYTHON]
#     PYTHON: an interpreter here of the GPU machine's Python version (default python3), for the
#             wheel; it needs numpy, nanobind and scikit-build-core
#     CUDA_ARCH (default 90: H100, H200), ENGINE_ARCH (default x86-64-v3: AVX2, which any recent
#     x86-64 host runs; the CPU column of bench/gpu.py is then the engine with AVX2 packs)
# Writes:
#   build/gpu/        the library with the real kernels, the C++ tests, the kernel check
#   .gpu/wheel/*.whl  the Python package on that library, for PYTHON
#   .gpu/lib/         the shared tinyxml2 that both link
#   .gpu/carry.tar.xz all that the GPU machine needs of the above, in one file (about 50 MB: the
#                     `device` tool carries at most 64 MB with the source tree, and the uncompressed
#                     paths had grown to 69 MB)
# On the GPU machine, with .gpu/carry.tar.xz copied beside the source tree (the `device` tool's carry):
#   GPU_CHECK_PREBUILT=1 scripts/gpu-check.sh [bench/gpu.py's options]
# which unpacks it first.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${1:-python3}
JOBS=${JOBS:-$(nproc)}
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_CUDA_COMPILER_LAUNCHER=ccache)
cmake -S . -B build/gpu -DCMAKE_BUILD_TYPE=Release -DCMAKE_CUDA_ARCHITECTURES="${CUDA_ARCH:-90}" \
  -DRBDKIT_ENGINE_ARCH="${ENGINE_ARCH:-x86-64-v3}" -DRBDKIT_CUDA_CHECK=ON "${launcher[@]}" >/dev/null
grep -q "RBDKIT_PREBUILT_HAS_CUDA ON" build/gpu/rbdkit_build_info.cmake || {
  echo "gpu-prebuild: nvcc was not found; the build has no CUDA kernels" >&2
  exit 1
}
cmake --build build/gpu -j "$JOBS"
rm -rf .gpu && mkdir -p .gpu/wheel .gpu/lib
PIP_BREAK_SYSTEM_PACKAGES=1 PIP_ROOT_USER_ACTION=ignore "$PY" -m pip wheel -q --no-build-isolation --no-deps \
  -w .gpu/wheel . -Cbuild-dir=build/gpu-py -Ccmake.define.RBDKIT_PREBUILT_LIBRARY="$PWD/build/gpu/librbdkit.a"
lib=$(ldd build/gpu/tests/cpp/rbdkit_tests | awk '/libtinyxml2/ {print $3}')
[[ -z "$lib" ]] || cp -L "$lib" .gpu/lib/  # (none to copy where tinyxml2 is linked statically)
# the binaries without their symbol tables, and everything in one compressed file
carried=(build/gpu/CMakeCache.txt build/gpu/cuda_kernel_check build/gpu/cuda_stage_latency
  build/gpu/tests/cpp/rbdkit_tests .gpu/lib .gpu/wheel)
strip build/gpu/cuda_kernel_check build/gpu/cuda_stage_latency build/gpu/tests/cpp/rbdkit_tests
tar cf - "${carried[@]}" | xz -T"$JOBS" -6 > .gpu/carry.tar.xz
du -sh "${carried[@]}" .gpu/carry.tar.xz
