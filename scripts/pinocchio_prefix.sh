#!/usr/bin/env bash
# Prints the CMAKE_PREFIX_PATH (';'-separated) under which CMake finds
# Pinocchio's C++ package from the `pin` wheel: its cmeel.prefix, preceded by
# the urdfdom_headers that package requires and no installed wheel ships
# (cmeel-urdfdom-headers of the version Pinocchio was built with, header only,
# fetched once into build/bench/_deps, where bench/run.sh puts it too;
# nothing is installed system-wide). Messages go to stderr.
#   scripts/pinocchio_prefix.sh          PYTHON: the interpreter with `pin` (python3)
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
PY=${PYTHON:-python3}
PREFIX=$("$PY" -c "
import os, pinocchio
p = os.path.dirname(os.path.abspath(pinocchio.__file__))
while os.path.dirname(p) != p and not os.path.isfile(os.path.join(p, 'lib', 'cmake', 'pinocchio', 'pinocchioConfig.cmake')):
    p = os.path.dirname(p)
print(p if os.path.dirname(p) != p else '')")
if [[ -z "$PREFIX" ]]; then
  echo "pinocchio_prefix: Pinocchio's CMake package not found next to $PY's pinocchio (pip install pin)" >&2
  exit 1
fi
if [[ -d "$PREFIX/lib/urdfdom_headers/cmake" ]]; then
  echo "$PREFIX"
  exit 0
fi
DEPS="$ROOT/build/bench/_deps"
if [[ ! -d "$DEPS/cmeel.prefix/lib/urdfdom_headers/cmake" ]]; then
  targets="$PREFIX/lib/cmake/pinocchio/pinocchioTargets.cmake"
  ver() { sed -n "s/.*PINOCCHIO_URDFDOM_HEADERS_$1_VERSION=\([0-9]*\).*/\1/p" "$targets" | head -1; }
  V="$(ver MAJOR).$(ver MINOR).$(ver PATCH)"
  echo "pinocchio_prefix: fetching cmeel-urdfdom-headers==$V into $DEPS" >&2
  PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_ROOT_USER_ACTION=ignore \
    "$PY" -m pip install -q --no-deps --target "$DEPS" "cmeel-urdfdom-headers==$V" >&2
fi
echo "$DEPS/cmeel.prefix;$PREFIX"
