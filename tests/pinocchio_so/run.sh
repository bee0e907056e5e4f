#!/usr/bin/env bash
# Builds (build/pinocchio_so) and runs the comparison of rbdkit's second-order
# derivatives with Pinocchio's C++ ComputeRNEASecondOrderDerivatives.
# Needs the `pin` wheel (scripts/pinocchio_prefix.sh). Exit status: the test's.
# Environment: PYTHON (python3), JOBS (build jobs, 2), RBDKIT_PINOCCHIO_BUILD
# (a configured build folder of this tree to build in, reusing its library;
# default: a build of its own, build/pinocchio_so).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
JOBS=${JOBS:-2}
PREFIXES=$(PYTHON="${PYTHON:-python3}" "$ROOT/scripts/pinocchio_prefix.sh")
PIN_PREFIX="${PREFIXES##*;}"
pin=(-DRBDKIT_BUILD_PINOCCHIO_TESTS=ON -DRBDKIT_PINOCCHIO_PREFIX="$PIN_PREFIX"
     -DRBDKIT_PINOCCHIO_EXTRA_PREFIX="${PREFIXES%;*}")
if [[ -n "${RBDKIT_PINOCCHIO_BUILD:-}" ]]; then
  # a configured build of this tree (./test.sh: build/cpp): its library is
  # reused, and the option is switched off again once the test is built
  BUILD="$(cd "$RBDKIT_PINOCCHIO_BUILD" && pwd)"
  opts=()
else
  BUILD="$ROOT/build/pinocchio_so"
  opts=(-DCMAKE_BUILD_TYPE=Release -DRBDKIT_BUILD_TESTS=OFF -DRBDKIT_CUDA_CHECK=OFF -DRBDKIT_BUILD_PYTHON=OFF)
fi
mkdir -p "$BUILD"
cmake -S "$ROOT" -B "$BUILD" "${opts[@]}" "${pin[@]}" >"$BUILD/configure_pinocchio.log" \
  || { cat "$BUILD/configure_pinocchio.log"; exit 1; }
t0=$(date +%s)
cmake --build "$BUILD" --target rbdkit_test_pinocchio_so -j "$JOBS"
echo "pinocchio_so: build took $(( $(date +%s) - t0 )) s"
if [[ -n "${RBDKIT_PINOCCHIO_BUILD:-}" ]]; then
  cmake -S "$ROOT" -B "$BUILD" -DRBDKIT_BUILD_PINOCCHIO_TESTS=OFF >/dev/null
fi
"$BUILD/tests/pinocchio_so/rbdkit_test_pinocchio_so" "$ROOT/robots" "$ROOT/tests/urdf"
