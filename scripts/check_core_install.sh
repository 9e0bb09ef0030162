#!/usr/bin/env bash
# Prove the fog-only install works on the NEWEST releases the registry serves: build a wheel
# of this checkout, install it (no extras, no Blender) into a fresh venv, which pulls the
# newest numpy 2.x and opencv-contrib-python-headless, run the fog commands from another
# folder, and run the fast test tier against the INSTALLED package (not the checkout).
#   bash scripts/check_core_install.sh          (KEEP=1 keeps the temp folder and says where)
# Needs python3.11+ with venv and pip access to the registry. Takes a few minutes.
set -euo pipefail
REPO=$(cd "$(dirname "$0")/.." && pwd)
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null || PY=python3
WORK=$(mktemp -d "${TMPDIR:-/tmp}/fogsim-core.XXXXXX")
if [ "${KEEP:-0}" = 1 ]; then trap 'echo "kept $WORK"' EXIT; else trap 'rm -rf "$WORK"' EXIT; fi
step() { printf '\n== %s\n' "$*"; }
fail() { echo "check_core_install: FAIL: $*" >&2; exit 1; }

step "wheel of $REPO"
# Built from a clean copy of the checkout (tracked + untracked-but-not-ignored files): an
# in-tree build would leave build/ in the checkout, and a stale build/lib there can smuggle
# modules that no longer exist into the wheel.
"$PY" - "$REPO" "$WORK/src" <<'EOF'
import shutil, subprocess, sys
from pathlib import Path
src, dst = Path(sys.argv[1]), Path(sys.argv[2])
try:
    out = subprocess.run(["git", "-C", str(src), "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                         check=True, capture_output=True).stdout.decode()
    files = [f for f in out.split("\0") if f and (src / f).is_file()]
except (OSError, subprocess.CalledProcessError):  # not a git checkout: copy all but the usual junk
    junk = shutil.ignore_patterns(".git", ".venv", "build", "dist", "*.egg-info", "__pycache__", ".pytest_cache")
    shutil.copytree(src, dst, ignore=junk)
    files = []
for f in files:
    (dst / f).parent.mkdir(parents=True, exist_ok=True)
    shutil.copy2(src / f, dst / f)
EOF
"$PY" -m venv "$WORK/venv"
V=$WORK/venv/bin
"$V/python" -m pip install -q --upgrade pip
(cd "$WORK/src" && "$V/python" -m pip wheel -q --no-deps -w "$WORK/wheel" .)
WHEEL=$(ls "$WORK"/wheel/fogsim-*.whl)
echo "$WHEEL"
"$V/python" - "$WHEEL" "$REPO" <<'EOF'
import sys, zipfile
from pathlib import Path
names = set(zipfile.ZipFile(sys.argv[1]).namelist())
want = {p.relative_to(sys.argv[2]).as_posix() for p in Path(sys.argv[2], "fogsim", "presets").rglob("*.json")}
missing = sorted(want - names)
assert want and not missing, f"presets missing from the wheel: {missing}"
print(f"wheel holds all {len(want)} preset JSON files")
EOF

step "install the wheel alone (core dependencies, newest releases, no Blender)"
"$V/python" -m pip install -q "$WHEEL"
"$V/python" -m pip check
"$V/python" - <<'EOF'
from importlib.metadata import version
import numpy, cv2
for d in ("fogsim", "numpy", "opencv-contrib-python-headless", "OpenEXR", "trimesh", "tqdm"):
    print(f"  {d} {version(d)}")
assert int(numpy.__version__.split(".")[0]) >= 2, f"expected numpy 2.x from a core install, got {numpy.__version__}"
import cv2
print(f"  cv2 {cv2.__version__}: EXR encoder {'yes' if cv2.haveImageWriter('.exr') else 'no (OpenEXR writes depth)'}")
from fogsim.deps import require_contrib
require_contrib("guidedFilter", "createRightMatcher", "createDisparityWLSFilter")
print("  cv2.ximgproc: guidedFilter, createRightMatcher, createDisparityWLSFilter present")
EOF
# "newest" is what pip chose; say so if the registry lists something newer for these two
OUTDATED=$("$V/python" -m pip list --outdated 2>/dev/null | grep -iE '^(numpy|opencv-contrib-python-headless) ' || true)
[ -z "$OUTDATED" ] || printf 'note: newer releases listed but not installed (a pin in pyproject.toml?):\n%s\n' "$OUTDATED" >&2

step "the fog commands, run from another folder"
RUN=$WORK/run
mkdir -p "$RUN"
cd "$RUN"
F=$V/fogsim
"$F" levels
"$F" demo --out D --frames 1 --quiet
"$F" fog --input D/input/images --depth D/input/depth --hfov 50 --out F --quiet
N=$(find F -name '*.png' | wc -l)
[ "$N" -gt 0 ] || fail "fogsim fog wrote no PNG under $RUN/F"
echo "fogsim fog wrote $N PNGs"
"$F" fog --input D/input/images --depth D/input/depth --hfov 50 --extended --kernel guided --out G --quiet
[ "$(find G -name '*.png' | wc -l)" -gt 0 ] || fail "fogsim fog --kernel guided wrote no PNG"
for cmd in render study bench; do
  "$F" "$cmd" --help >/dev/null || fail "fogsim $cmd --help failed"
  echo "fogsim $cmd --help: ok"
done
"$V/python" -c "
import sys, fogsim
loaded = [m for m in ('bpy', 'mathutils', 'torch', 'ultralytics') if m in sys.modules]
assert not loaded, f'import fogsim imported {loaded}'
print('import fogsim: none of bpy, torch, ultralytics imported; fogsim from', fogsim.__file__)
assert '$WORK/venv/' in fogsim.__file__, 'fogsim did not come from the installed wheel'
"

step "fast test tier against the installed package"
"$V/python" -m pip install -q "pytest>=8"
# A plugin that says where fogsim came from and fails the run unless it is the installed
# wheel (and the checkout root is not on sys.path). tests/ has no __init__.py, so pytest's
# rootdir insertion adds tests/ only; run from $RUN so the cwd adds nothing either.
mkdir -p "$WORK/plugin"
cat > "$WORK/plugin/fogsim_installed_check.py" <<EOF
import os, sys
import pytest

def pytest_collection_finish(session):
    import fogsim
    repo = os.path.realpath("$REPO")
    print(f"\nfogsim under test: {fogsim.__file__}")
    if not os.path.realpath(fogsim.__file__).startswith(os.path.realpath("$WORK/venv") + os.sep):
        raise pytest.UsageError(f"fogsim was imported from {fogsim.__file__}, not the installed wheel")
    if any(os.path.realpath(p or os.getcwd()) == repo for p in sys.path):
        raise pytest.UsageError(f"the checkout root {repo} is on sys.path")
EOF
set +e
export PYTHONDONTWRITEBYTECODE=1  # no __pycache__ written into the checkout's tests/
PYTHONPATH="$WORK/plugin" "$V/pytest" -q -p fogsim_installed_check -p no:cacheprovider \
  --rootdir "$REPO" -c "$REPO/pyproject.toml" \
  -m "not blender and not torch and not detect and not slow" "$REPO/tests"
RC=$?
set -e
# 5 = no test collected: the fast tier always has tests, so that means something is wrong
[ "$RC" -ne 5 ] || fail "pytest collected no test in the fast tier (exit 5)"
[ "$RC" -eq 0 ] || fail "fast test tier against the installed wheel failed (pytest exit $RC)"

# With the dev venv (which has bpy, torch and Ultralytics installed) the import check means more
if [ -x "$REPO/.venv/bin/python" ]; then
  step "import fogsim in the dev venv imports none of bpy, torch, ultralytics"
  "$REPO/.venv/bin/python" -c "
import sys, fogsim
loaded = [m for m in ('bpy', 'mathutils', 'torch', 'ultralytics') if m in sys.modules]
assert not loaded, f'import fogsim imported {loaded}'
print('ok')"
fi
step "core install: ok"
