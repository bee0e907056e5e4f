#!/usr/bin/env bash
# Builds (build/pinocchio_so) and runs the comparison of rbdkit's second-order
# derivatives with Pinocchio's C++ ComputeRNEASecondOrderDerivatives.
# Needs the `pin` wheel (scripts/pinocchio_prefix.sh). Exit status: the test's.
# Environment: PYTHON (python3), JOBS (build jobs, 2).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
BUILD="$ROOT/build/pinocchio_so"
JOBS=${JOBS:-2}
mkdir -p "$BUILD"
PREFIXES=$(PYTHON="${PYTHON:-python3}" "$ROOT/scripts/pinocchio_prefix.sh")
PIN_PREFIX="${PREFIXES##*;}"
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DRBDKIT_BUILD_PINOCCHIO_TESTS=ON \
  -DRBDKIT_BUILD_TESTS=OFF -DRBDKIT_CUDA_CHECK=OFF -DRBDKIT_BUILD_PYTHON=OFF \
  -DRBDKIT_PINOCCHIO_PREFIX="$PIN_PREFIX" -DRBDKIT_PINOCCHIO_EXTRA_PREFIX="${PREFIXES%;*}" \
  >"$BUILD/configure.log" || { cat "$BUILD/configure.log"; exit 1; }
t0=$(date +%s)
cmake --build "$BUILD" --target rbdkit_test_pinocchio_so -j "$JOBS"
echo "pinocchio_so: build took $(( $(date +%s) - t0 )) s"
"$BUILD/tests/pinocchio_so/rbdkit_test_pinocchio_so" "$ROOT/robots" "$ROOT/tests/urdf"
