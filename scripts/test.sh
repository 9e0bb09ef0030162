#!/usr/bin/env bash
# Install what the tests need (idempotent) and run them: the README's test command.
#   bash scripts/test.sh [pytest args]
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null || PY=python3
[ -x .venv/bin/python ] || "$PY" -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
# torch: pinned (an unpinned torch pulls the newest multi-GB CUDA build). The 'detect' extra
# (Ultralytics) needs torchvision, and torch 2.14.1 + torchvision 0.29.1 is the pair this
# machine kind serves from its disk; where it cannot be had, the CPU build 2.13.0 serves the
# ILA extra and the detector-training tests skip.
if .venv/bin/python -m pip install -q "torch==2.14.1" "torchvision==0.29.1" \
   && .venv/bin/python -m pip install -q -e ".[dev,blender,waymo,ila,detect]"; then
  # Ultralytics pulls opencv-python, which shares the cv2 folder with the contrib build:
  # put the contrib build back when its modules are gone (DESIGN.md §5)
  if ! .venv/bin/python -c "import cv2, sys; sys.exit(not hasattr(cv2, 'ximgproc'))"; then
    CV=$(.venv/bin/python -m pip show opencv-contrib-python-headless | sed -n 's/^Version: //p')
    .venv/bin/python -m pip install -q --force-reinstall --no-deps "opencv-contrib-python-headless==$CV"
  fi
else
  echo "note: the 'detect' extra could not be installed: detector-training tests will skip" >&2
  .venv/bin/python -m pip uninstall -q -y ultralytics torchvision 2>/dev/null || true
  .venv/bin/python -m pip install -q "torch==2.13.0"
  .venv/bin/python -m pip install -q -e ".[dev,blender,waymo,ila]"
fi
.venv/bin/python -c "import cv2; cv2.ximgproc" \
  || { echo "error: cv2 lacks ximgproc: opencv-contrib-python-headless is not the cv2 in place" >&2; exit 1; }
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
