#!/usr/bin/env bash
# Install what the tests need (idempotent) and run them: the README's test command.
#   bash scripts/test.sh [pytest args]
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null || PY=python3
[ -x .venv/bin/python ] || "$PY" -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
# torch: pinned to the CPU build (an unpinned torch pulls a multi-GB CUDA build)
.venv/bin/python -m pip install -q "torch==2.13.0"
.venv/bin/python -m pip install -q -e ".[dev,blender,waymo,ila]"
# Debian's Blender 3.4 for the `blender -b -P` tests
if ! command -v blender >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ]; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends blender >/dev/null
  else
    echo "note: blender is not installed and this is not root: the blender-binary tests will skip" >&2
  fi
fi
exec .venv/bin/python -m pytest "$@"
