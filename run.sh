#!/usr/bin/env bash
# The main job: install what is needed, build rbdkit, and print its report
# on the bundled KUKA iiwa14. Arguments go to the rbdkit command
# (e.g. ./run.sh report --robot atlas --floating-base).
set -euo pipefail
cd "$(dirname "$0")"
bash scripts/setup.sh
PY=${PYTHON:-python3}
echo "building rbdkit (pip install .) ..."
PIP_BREAK_SYSTEM_PACKAGES=1 PIP_ROOT_USER_ACTION=ignore "$PY" -m pip install -q --no-build-isolation .
cd /tmp && exec "$PY" -m rbdkit "$@"
