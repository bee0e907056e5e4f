#!/usr/bin/env bash
# Builds the rbdkit-vs-Pinocchio benchmark in build/bench and prints the ratio
# table (bench/README.md). Needs libbenchmark-dev and the `pin` wheel.
#   bench/run.sh [extra Google Benchmark flags, e.g. --benchmark_filter=aba]
# Environment: PYTHON (python3), JOBS (build jobs, 2), REPS (repetitions, 5),
#   BENCH_JSON (where the JSON goes, build/bench/results.json), BENCH_REPORT=0
#   (no table: `rbdkit bench` reports itself),
#   MIN_TIME (seconds per repetition, 0.2), PINOCCHIO_INLINE=1 (compile
#   Pinocchio's algorithms here instead of calling its shared library; builds
#   in build/bench-inline), COUNT_CALLS=N (no timing: instructions per call
#   under callgrind, N calls per benchmark; combine with --benchmark_filter).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
# what the benchmark needs (Google Benchmark, the `pin` wheel): installed if missing
bash "$ROOT/scripts/setup.sh" --test
INLINE=OFF
BUILD="$ROOT/build/bench"
if [[ "${PINOCCHIO_INLINE:-0}" == 1 ]]; then INLINE=ON; BUILD="$ROOT/build/bench-inline"; fi
PY=${PYTHON:-python3}
JOBS=${JOBS:-2}
REPS=${REPS:-5}
MIN_TIME=${MIN_TIME:-0.2}
mkdir -p "$BUILD"

# ---- Pinocchio's prefix (cmeel.prefix of the `pin` wheel)
PREFIX=$("$PY" -c "
import os, pinocchio
p = os.path.dirname(os.path.abspath(pinocchio.__file__))
while os.path.dirname(p) != p and not os.path.isfile(os.path.join(p, 'lib', 'cmake', 'pinocchio', 'pinocchioConfig.cmake')):
    p = os.path.dirname(p)
print(p if os.path.dirname(p) != p else '')")
if [[ -z "$PREFIX" ]]; then
  echo "bench: Pinocchio's CMake package not found next to $PY's pinocchio (pip install pin)" >&2
  exit 1
fi

# ---- urdfdom_headers: Pinocchio's URDF parser headers include them and the
# wheels do not ship them; fetch the version Pinocchio was built with into
# build/bench/_deps (header only; nothing is installed system-wide)
PREFIXES="$PREFIX"
if [[ ! -d "$PREFIX/lib/urdfdom_headers/cmake" ]]; then
  DEPS="$ROOT/build/bench/_deps"
  if [[ ! -d "$DEPS/cmeel.prefix/lib/urdfdom_headers/cmake" ]]; then
    targets="$PREFIX/lib/cmake/pinocchio/pinocchioTargets.cmake"
    ver() { sed -n "s/.*PINOCCHIO_URDFDOM_HEADERS_$1_VERSION=\([0-9]*\).*/\1/p" "$targets" | head -1; }
    V="$(ver MAJOR).$(ver MINOR).$(ver PATCH)"
    echo "bench: fetching cmeel-urdfdom-headers==$V into $DEPS"
    PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_ROOT_USER_ACTION=ignore \
      "$PY" -m pip install -q --no-deps --target "$DEPS" "cmeel-urdfdom-headers==$V"
  fi
  PREFIXES="$DEPS/cmeel.prefix;$PREFIX"
fi

# ---- configure and build (the prefix in CMAKE_PREFIX_PATH: rbdkit then
# links the prefix's tinyxml2, the one Pinocchio's URDF parser uses)
echo "bench: configuring $BUILD"
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$PREFIXES" \
  -DRBDKIT_BUILD_BENCH=ON -DRBDKIT_BUILD_TESTS=OFF -DRBDKIT_CUDA_CHECK=OFF -DRBDKIT_CUDA=OFF -DRBDKIT_BUILD_PYTHON=OFF \
  -DRBDKIT_BENCH_PINOCCHIO_PREFIX="$PREFIX" -DRBDKIT_BENCH_PINOCCHIO_INLINE=$INLINE >"$BUILD/configure.log" ||
  { cat "$BUILD/configure.log"; exit 1; }
t0=$(date +%s)
cmake --build "$BUILD" --target rbdkit_bench -j "$JOBS"
echo "bench: build took $(( $(date +%s) - t0 )) s (-j $JOBS)"

# ---- or count instructions: one callgrind dump per selected benchmark
if [[ -n "${COUNT_CALLS:-}" ]]; then
  CG="$BUILD/callgrind"
  rm -rf "$CG" && mkdir -p "$CG"
  echo "bench: counting instructions under callgrind ($COUNT_CALLS calls per benchmark) into $CG"
  valgrind --tool=callgrind --collect-atstart=no --callgrind-out-file="$CG/callgrind.out" \
    "$BUILD/bench/rbdkit_bench" --count_calls="$COUNT_CALLS" "$@" 2>"$CG/valgrind.log" ||
    { tail -20 "$CG/valgrind.log"; exit 1; }
  "$PY" "$ROOT/bench/callgrind_report.py" "$CG" "$COUNT_CALLS" ${CALLGRIND_MARKDOWN:+--markdown}
  exit 0
fi

# ---- run: interleaved repetitions, all of them kept in the JSON, the
# minimum reported (the machine is shared: the minimum is the least disturbed)
JSON="${BENCH_JSON:-$BUILD/results.json}"
echo "bench: running ($REPS repetitions x ${MIN_TIME}s per benchmark, interleaved)"
"$BUILD/bench/rbdkit_bench" \
  --benchmark_repetitions="$REPS" --benchmark_min_time="$MIN_TIME" \
  --benchmark_enable_random_interleaving=true --benchmark_display_aggregates_only=true \
  --benchmark_out="$JSON" --benchmark_out_format=json "$@" >"$BUILD/console.txt"
if [[ "${BENCH_REPORT:-1}" != 0 ]]; then
  "$PY" "$ROOT/bench/report.py" "$JSON" --csv "$BUILD/results/latest.csv"
fi
