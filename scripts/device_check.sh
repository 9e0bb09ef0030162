#!/usr/bin/env bash
# The GPU path, checked in one run on the first GPU machine (under 8 minutes on one GPU):
#   bash scripts/device_check.sh            # on a GPU machine; exits 0 at once where there is none
#   bash scripts/device_check.sh --dry-run  # every row on the CPU at toy sizes: tests this script
#
# Rows (each in a process of its own, with a time limit; one table at the end):
#   render koschmieder --gpu   fogsim render, 640x426 draft, OptiX else CUDA; meta must name the GPU
#   render hybrid --gpu        fogsim render --fog volumetric --fog-medium hybrid, one fog level
#   ILA train                  fogsim.depth.ila.train_rounds on CUDA (a few steps, synthetic stereo)
#   YOLO 1 epoch               fogsim.detection.yolo.train on CUDA (synthetic boxes, yolov8n from scratch)
#   torch fog batch            a batched torch fog function in fogsim.augment, if there is one
# each beside the same work on the CPU where that is cheap (speed-up column).
#
# Installs: wheels carried in .whl/ (scripts/device_wheels.sh downloads them for Python 3.12 /
# manylinux x86-64) into a private folder, else from the registry when it answers, else none
# (the rows that need a missing package say so). Rendering needs the bpy module (Python 3.11
# only: bpy 5.0) or a blender binary; where there is neither, those rows say why and the rest run.
# Exit: 0 all rows ok or skipped (and when there is no GPU), 1 a row failed.
set -uo pipefail
cd "$(dirname "$0")/.."

DRY_RUN=0
[ "${1:-}" = "--dry-run" ] && DRY_RUN=1

if [ "$DRY_RUN" = 0 ]; then
  # no Python here: the answer on a machine without a GPU must take well under a second
  if ! command -v nvidia-smi >/dev/null 2>&1; then
    echo "device_check: no NVIDIA GPU on this machine (nvidia-smi not found): nothing to check."
    echo "device_check: run it on a GPU machine; 'bash scripts/device_check.sh --dry-run' checks this script on the CPU."
    exit 0
  fi
  if ! gpus=$(timeout 30 nvidia-smi -L 2>&1) || [ -z "$gpus" ]; then
    echo "device_check: nvidia-smi finds no usable GPU (${gpus:-no output}): nothing to check."
    exit 0
  fi
  echo "device_check: $gpus"
fi

PY=${PYTHON:-}
if [ -z "$PY" ]; then
  if [ -x .venv/bin/python ]; then PY=.venv/bin/python; else PY=python3; fi
fi

SITE=${TMPDIR:-/tmp}/fogsim_device_site
if [ "$DRY_RUN" = 0 ]; then
  if compgen -G ".whl/*.whl" >/dev/null; then
    echo "device_check: installing the carried wheels: $(ls .whl | tr '\n' ' ')"
    "$PY" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$SITE" .whl/*.whl \
      || echo "device_check: note: installing .whl/ failed; rows that need those packages will say so"
  elif timeout 20 "$PY" -m pip download -q --no-deps -d "$SITE.probe" ultralytics-thop >/dev/null 2>&1; then
    echo "device_check: the registry answers: installing what the rows need"
    # shellcheck disable=SC2046
    timeout 300 "$PY" -m pip install -q --no-deps --target "$SITE" $(scripts/device_wheels.sh --names) \
      || echo "device_check: note: installing from the registry failed; rows that need it will say so"
  else
    echo "device_check: no .whl/ folder and no registry: using what is installed"
  fi
  export PYTHONPATH="$SITE${PYTHONPATH:+:$PYTHONPATH}"
fi
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
export PYTHONUNBUFFERED=1

if [ "$DRY_RUN" = 1 ]; then
  exec "$PY" scripts/device_check.py --dry-run
fi
exec "$PY" scripts/device_check.py
