#!/usr/bin/env bash
# The main job: install what is needed, build rbdkit, and run its demo: the
# bundled KUKA iiwa14 reaches an end-effector target from rest within its
# joint limits, optimised by iLQR on the plant layer; the figure and the JSON
# record go to ./rbdkit_demo/. Arguments go to the rbdkit command instead
# (e.g. ./run.sh demo --task atlas_reach, ./run.sh report --robot atlas --floating-base).
set -euo pipefail
cd "$(dirname "$0")"
bash scripts/setup.sh
PY=${PYTHON:-python3}
echo "building rbdkit (pip install .) ..."
PIP_BREAK_SYSTEM_PACKAGES=1 PIP_ROOT_USER_ACTION=ignore "$PY" -m pip install -q --no-build-isolation .
ROOT=$(pwd)
if [ $# -eq 0 ]; then set -- demo --out "$ROOT/rbdkit_demo"; fi
cd /tmp && exec "$PY" -m rbdkit "$@"
