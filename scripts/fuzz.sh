#!/usr/bin/env bash
# Fuzzes the URDF reader and ModelBuilder with libFuzzer under AddressSanitizer
# and UndefinedBehaviorSanitizer (clang++). Builds the targets in tests/fuzz/
# with the few library sources they need (build/fuzz), replays the saved
# regression inputs (tests/fuzz/regressions/<target>/), then fuzzes each
# target from a working copy of its seed corpus (build/fuzz/corpus/<target>:
# tests/fuzz/corpus/<target>/, for urdf also tests/urdf/ and robots/). New
# corpus entries stay in build/; nothing is written into the source tree.
# Exits non-zero on a crash, a leak or a broken invariant, printing the
# reproducer's path; replay one with  build/fuzz/fuzz_<target> <file>.
#   scripts/fuzz.sh [--runs N] [--time SECONDS] [--target urdf|builder] [-- libFuzzer flags]
# Default (./test.sh): per target 100000 runs or 20 seconds, whichever comes first.
set -euo pipefail
cd "$(dirname "$0")/.."

runs=""
secs=""
targets=(urdf builder)
extra=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --runs) runs=$2; shift 2 ;;
    --time) secs=$2; shift 2 ;;
    --target) targets=("$2"); shift 2 ;;
    --) shift; extra=("$@"); break ;;
    *) echo "fuzz: unknown argument '$1' (expected --runs N, --time SECONDS, --target urdf|builder, -- flags)" >&2; exit 2 ;;
  esac
done
# no option: both limits; one option: that limit alone (-runs=-1 and
# -max_total_time=0 mean none to libFuzzer)
# (and a fixed seed: ./test.sh's short run is the same every time)
seed=()
if [[ -z "$runs" && -z "$secs" ]]; then runs=100000 secs=20 seed=(-seed=1); fi
runs=${runs:--1}
secs=${secs:-0}
CXX=${FUZZ_CXX:-clang++}
JOBS=${JOBS:-$(nproc)}
out=build/fuzz

# ---- build: library objects with coverage (fuzzer-no-link), one program per target
launcher=()
if command -v ccache >/dev/null; then launcher=(ccache); fi
san="-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer"
eigen=$(pkg-config --cflags eigen3 2>/dev/null || echo "-I/usr/include/eigen3")
flags="-std=c++17 -O1 -g $san -fsanitize=fuzzer-no-link -Iinclude $eigen"
lib_sources=(src/parsers/builder.cpp src/parsers/urdf.cpp src/parsers/model.cpp src/batch/dynamics.cpp src/batch/kinematics.cpp)
mkdir -p "$out/obj"
if [[ "$(cat "$out/flags" 2>/dev/null)" != "$CXX $flags" ]]; then rm -f "$out"/obj/*.o; fi
echo "$CXX $flags" >"$out/flags"

# compile $1 to $2 unless $2 is newer than $1 and every header it read
compile() {
  local src=$1 obj=$2 dep=${2%.o}.d
  if [[ -f "$obj" && -f "$dep" ]]; then
    local stale=0 f
    for f in $(sed -e 's/^[^:]*://' -e 's/\\$//' "$dep"); do
      [[ "$f" -nt "$obj" ]] && { stale=1; break; }
    done
    [[ $stale == 0 ]] && return 0
  fi
  echo "fuzz: compiling $src"
  "${launcher[@]}" "$CXX" $flags -MMD -MF "$dep" -c "$src" -o "$obj"
}
pids=()
for src in "${lib_sources[@]}" "${targets[@]/#/tests/fuzz/fuzz_}"; do
  [[ "$src" == tests/fuzz/fuzz_* ]] && src=$src.cpp
  compile "$src" "$out/obj/$(basename "${src%.cpp}").o" &
  pids+=($!)
  if [[ ${#pids[@]} -ge $JOBS ]]; then wait "${pids[0]}"; pids=("${pids[@]:1}"); fi
done
for p in "${pids[@]}"; do wait "$p"; done
lib_objs=()
for src in "${lib_sources[@]}"; do lib_objs+=("$out/obj/$(basename "${src%.cpp}").o"); done
for t in "${targets[@]}"; do
  "$CXX" $san -fsanitize=fuzzer "$out/obj/fuzz_$t.o" "${lib_objs[@]}" -ltinyxml2 -o "$out/fuzz_$t"
done

# ---- run: regressions once, then the fuzzer on the working corpus
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1} UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1}
for t in "${targets[@]}"; do
  bin=$out/fuzz_$t
  crashes=$out/crashes/$t
  corpus=$out/corpus/$t
  mkdir -p "$crashes" "$corpus"
  if compgen -G "tests/fuzz/regressions/$t/*" >/dev/null; then
    echo "fuzz: $t: replaying tests/fuzz/regressions/$t/"
    "$bin" tests/fuzz/regressions/$t/* 2>"$out/replay_$t.log" ||
      { tail -n 40 "$out/replay_$t.log"
        echo "fuzz: $t: a regression input fails again: $(grep -a '^Running: ' "$out/replay_$t.log" | tail -n 1 |
          cut -d' ' -f2-) (log: $out/replay_$t.log)" >&2
        exit 1; }
  fi
  cp tests/fuzz/corpus/$t/* "$corpus"/ 2>/dev/null || true
  if [[ $t == urdf ]]; then cp tests/urdf/*.urdf robots/*.urdf "$corpus"/; fi
  dict=()
  [[ -f tests/fuzz/$t.dict ]] && dict=(-dict=tests/fuzz/$t.dict)
  echo "fuzz: $t: runs $( [[ $runs -ge 0 ]] && echo "$runs" || echo "unlimited" ), time $( [[ $secs -gt 0 ]] && echo "$secs s" || echo "unlimited" )"
  status=0
  nice "$bin" "$corpus" "${dict[@]}" -runs="$runs" -max_total_time="$secs" -max_len=16384 -timeout=20 \
    -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$crashes/" "${seed[@]}" "${extra[@]}" 2>"$out/fuzz_$t.log" ||
    status=$?
  grep -E '^(#[0-9]+[[:space:]]+DONE|Done [0-9]+ runs|stat::(number_of_executed_units|average_exec_per_sec|peak_rss_mb))' \
    "$out/fuzz_$t.log" || true
  if [[ $status != 0 ]]; then
    tail -n 60 "$out/fuzz_$t.log"
    echo "fuzz: $t: CRASH (exit $status); reproducer: $(ls -t "$crashes"/* 2>/dev/null | head -n 1)" >&2
    echo "fuzz: replay it with $bin <file>; the full log is $out/fuzz_$t.log" >&2
    exit 1
  fi
done
