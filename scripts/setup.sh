#!/usr/bin/env bash
# Installs what rbdkit needs on a Debian machine: compilers and C++ libraries
# from apt, Python packages from PyPI. Idempotent: installs only what is
# missing. Sourced by run.sh and test.sh.
#   scripts/setup.sh [--test]     --test adds the test dependencies
set -euo pipefail

with_test=0
[[ "${1:-}" == "--test" ]] && with_test=1

SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi

# ---- Debian packages
pkgs=(cmake g++ make libeigen3-dev libtinyxml2-dev)
# clang and libFuzzer (libclang-rt-dev) for scripts/fuzz.sh
if [[ $with_test == 1 ]]; then pkgs+=(libgtest-dev googletest libbenchmark-dev clang libclang-rt-dev); fi
missing=()
for p in "${pkgs[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [[ ${#missing[@]} -gt 0 ]]; then
  echo "setup: apt-get install ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

# ---- Python itself: pip and the headers the extension compiles against
PY=${PYTHON:-python3}
if ! command -v "$PY" >/dev/null || ! "$PY" -m pip --version >/dev/null 2>&1 ||
   ! "$PY" -c 'import os, sysconfig; raise SystemExit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))'; then
  echo "setup: apt-get install python3 python3-pip python3-dev"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq python3 python3-pip python3-dev python3-venv >/dev/null
fi

# ---- Python packages
export PIP_BREAK_SYSTEM_PACKAGES=1 PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_ROOT_USER_ACTION=ignore
if [[ $with_test == 1 ]]; then
  "$PY" -m pip install -q -r "$(dirname "$0")/../requirements-dev.txt"
else
  "$PY" -m pip install -q "numpy>=1.22" "scikit-build-core>=0.10" "nanobind>=2.0" "matplotlib>=3.5"
fi
