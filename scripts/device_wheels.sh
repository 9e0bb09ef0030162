#!/usr/bin/env bash
# The wheels scripts/device_check.sh needs on the GPU machine (Python 3.12, torch + CUDA already
# there, no registry), downloaded here into .whl/ for manylinux x86-64:
#   bash scripts/device_wheels.sh            # → .whl/ (about 38 MB; the carry limit is 64 MiB)
#   bash scripts/device_wheels.sh --names    # the requirement list only (device_check.sh uses it)
# Then carry .whl in the device call: device_check.sh installs .whl/*.whl with --no-deps into a
# private folder. Ultralytics and the pieces of it the image lacks (polars 1.9: one 33 MB wheel;
# 2.x splits into a 54 MB runtime), trimesh and OpenEXR (fogsim's core), pycocotools (COCO AP).
# bpy cannot be carried: bpy 5.0 needs Python 3.11 and is ~300 MB.
set -euo pipefail
cd "$(dirname "$0")/.."
NAMES=(ultralytics==8.4.190 ultralytics-thop==2.2.3 ultralytics-platform==0.1.99 polars==1.9.0
       trimesh==5.2.0 OpenEXR==3.5.3 pycocotools==2.0.11)
if [ "${1:-}" = "--names" ]; then
  echo "${NAMES[@]}"
  exit 0
fi
PY=${PYTHON:-python3}
[ -x .venv/bin/python ] && PY=.venv/bin/python
"$PY" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
  -d .whl "${NAMES[@]}"
du -sh .whl
