#!/usr/bin/env bash
# Builds and runs the batched benchmark (bench_batch.cpp: rbdkit's engine
# against a per-sample Pinocchio loop, time per knot point) in build/bench,
# the folder bench/run.sh configures (run that once first, or this script
# configures it the same way through run.sh's --check_only path).
#   bench/run_batch.sh [Google Benchmark flags, e.g. --benchmark_filter=/iiwa/]
# Environment: JOBS (2), REPS (3), MIN_TIME (0.1). Output: build/bench/batch.json
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
# what the benchmark needs (Google Benchmark, the `pin` wheel): installed if missing
bash "$ROOT/scripts/setup.sh" --test
BUILD="$ROOT/build/bench"
JOBS=${JOBS:-2}
REPS=${REPS:-3}
MIN_TIME=${MIN_TIME:-0.1}
if [[ ! -f "$BUILD/CMakeCache.txt" ]]; then
  BENCH_REPORT=0 "$ROOT/bench/run.sh" --check_only >/dev/null
fi
cmake --build "$BUILD" --target rbdkit_bench_batch -j "$JOBS"
"$BUILD/bench/rbdkit_bench_batch" \
  --benchmark_repetitions="$REPS" --benchmark_min_time="$MIN_TIME" \
  --benchmark_display_aggregates_only=true --benchmark_report_aggregates_only=false \
  --benchmark_out="$BUILD/batch.json" --benchmark_out_format=json "$@"
