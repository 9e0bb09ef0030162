#!/usr/bin/env bash
# Install what the tests need (idempotent) and run them: the README's test command.
#   bash scripts/test.sh [pytest args]
# Fast tier only: bash scripts/test.sh -m "not blender and not torch and not detect and not slow"
#
# What it installs (README "Two commands"; measured on Debian 12, x86-64):
#   .venv/   the project with its extras dev, blender (the bpy module), waymo, ila + detect (torch,
#            torchvision, Ultralytics, pycocotools), docs, and albumentations: about 8.6 GB, 5.3 GB of it
#            torch's CUDA build with its NVIDIA libraries (the only torch + torchvision pair pip gets from
#            PyPI on x86-64; PyTorch's CPU wheels, installed into .venv first, are kept: README)
#   Debian   blender (3.4), slurm-wlm + munge, xvfb, with their dependencies: about 1.1 GB (as root)
# A fresh install took 15 min on a shared 2-core machine (torch's wheels from a local disk); the suite ~30 min.
# Expected repairs are printed as "note:" lines; "error:" means the tests cannot run as intended.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null || PY=python3
[ -x .venv/bin/python ] || "$PY" -m venv .venv
PIP=(.venv/bin/python -m pip)
"${PIP[@]}" install -q --upgrade pip

# pip_or_note NOTE ARGS…: pip install ARGS; when it fails, its messages are repeated as notes (an expected
# step of this script, not the end of it) and the status is returned.
pip_or_note() {
  local note=$1 out
  shift
  if out=$("${PIP[@]}" install -q "$@" 2>&1); then
    [ -z "$out" ] || printf '%s\n' "$out" >&2
    return 0
  fi
  printf '%s\n' "$out" | sed -e 's/^ERROR: /note: pip: /' >&2
  echo "note: $note" >&2
  return 1
}

# torch: pinned (an unpinned torch pulls the newest multi-GB CUDA build). The 'detect' extra
# (Ultralytics) needs torchvision, and torch 2.14.1 + torchvision 0.29.1 is the pair this
# machine kind serves from its disk; where it cannot be had, the CPU build 2.13.0 serves the
# ILA extra and the detector-training tests skip.
if pip_or_note "torch 2.14.1 + torchvision 0.29.1 are not available here: installing without the 'detect' extra" \
     "torch==2.14.1" "torchvision==0.29.1" \
   && pip_or_note "the 'detect' extra could not be installed: installing without it" \
     -e ".[dev,blender,waymo,ila,detect,docs]"; then
  :
else
  echo "note: the detector-training tests will skip" >&2
  "${PIP[@]}" uninstall -q -y ultralytics torchvision 2>/dev/null || true
  "${PIP[@]}" install -q "torch==2.13.0"
  "${PIP[@]}" install -q -e ".[dev,blender,waymo,ila,docs]"
fi

# albumentations (the 'augment' extra's library) without its declared dependencies: those pull
# opencv-python-headless over the contrib build and, through its newest wheels, numpy 2 over bpy's
# numpy<2. Its pure-Python needs first, then it with --no-deps (last, so no later pip run reports its
# undeclared opencv-python-headless as a conflict).
"${PIP[@]}" install -q "scipy>=1.10" "pydantic>=2.9.2" pyyaml "stringzilla>=3.10.4" "simsimd>=5.9.2"
"${PIP[@]}" install -q --no-deps "albumentations==2.0.8" "albucore==0.0.24"

# --- OpenCV: the contrib build must be the cv2 in place, whatever was installed in what order.
# opencv-python (pulled by Ultralytics), opencv-python-headless and opencv-contrib-python all
# write the same cv2/ folder as opencv-contrib-python-headless; whichever came last wins and
# can leave cv2.ximgproc an empty namespace (so hasattr(cv2, "ximgproc") proves nothing).
# Check the functions fogsim calls (fogsim.deps.require_contrib; docs/safety.md).
CV2_CHECK='import sys
try:
    import cv2
except Exception as exc:
    sys.exit(f"import cv2 failed: {exc}")
x = getattr(cv2, "ximgproc", None)
missing = [n for n in ("guidedFilter", "createRightMatcher", "createDisparityWLSFilter") if not hasattr(x, n)]
if missing:
    sys.exit("cv2 %s (%s) lacks cv2.ximgproc: %s" % (cv2.__version__, cv2.__file__, " ".join(missing)))'
OTHER_OPENCV=(opencv-python opencv-python-headless opencv-contrib-python)
ensure_opencv_contrib() {  # $1: the venv's python
  local py=$1 version spec d others=()
  for d in "${OTHER_OPENCV[@]}"; do
    if "$py" -m pip show -q "$d" >/dev/null 2>&1; then others+=("$d"); fi
  done
  # done only when the functions are there AND nothing else can overwrite cv2/ later
  # (a later upgrade or uninstall of opencv-python would break it again)
  local why
  if why=$("$py" -c "$CV2_CHECK" 2>&1); then
    [ ${#others[@]} -eq 0 ] && return 0
  else
    echo "note: $why" >&2   # what is wrong, and (below) the repair
  fi
  version=$("$py" -m pip show opencv-contrib-python-headless 2>/dev/null | sed -n 's/^Version: //p')
  # not installed at all: what the 'blender' extra requires (numpy < 2 holds it below 4.12)
  if [ -n "$version" ]; then spec="opencv-contrib-python-headless==$version"
  else spec="opencv-contrib-python-headless>=4.8,<4.12"; fi
  echo "note: putting the contrib build back: $spec" >&2
  for d in "${others[@]}"; do
    echo "note: uninstalling $d (it shares cv2/ with opencv-contrib-python-headless)" >&2
    "$py" -m pip uninstall -q -y "$d"
  done
  "$py" -m pip install -q --force-reinstall --no-deps "$spec"
  "$py" -c "$CV2_CHECK" || {
    echo "error: cv2 still lacks the opencv-contrib modules after reinstalling $spec" >&2; return 1; }
}
ensure_opencv_contrib .venv/bin/python

# Debian packages the tests need, installed as root (apt-get update once, only when one is missing):
#   blender          Blender 3.4 for the `blender -b -P` tests
#   slurm-wlm munge  a single-node Slurm for tests/test_cluster.py
#   xvfb             a virtual display for the add-on window test (xvfb-run)
# Where they cannot be installed (not root, no network) a note says which tests will skip.
declare -A NEEDS=([blender]="blender" [slurmctld]="slurm-wlm" [munged]="munge" [Xvfb]="xvfb")
declare -A SKIPS=([blender]="the blender-binary tests" [slurm-wlm]="the Slurm test" [munge]="the Slurm test"
                  [xvfb]="the add-on window test")
# Another apt (unattended-upgrades, a second session) may hold the locks: apt-get waits up to 10 min for
# dpkg's (DPkg::Lock::Timeout); the package lists' own lock, which apt-get update takes and does not wait
# for, is retried here for as long.
APT=(apt-get -o DPkg::Lock::Timeout=600)
apt_update() {
  local out end=$((SECONDS + 600))
  until out=$(timeout 600 "${APT[@]}" update -qq 2>&1); do
    if ! grep -qiE "could not get lock|unable to lock" <<<"$out" || [ $SECONDS -ge $end ]; then
      printf '%s\n' "$out" | sed -e 's/^/note: apt-get update: /' >&2
      return 1
    fi
    echo "note: another apt holds the package lists' lock: waiting for it (up to 10 min)" >&2
    sleep 10
  done
}
missing=()
for cmd in "${!NEEDS[@]}"; do
  command -v "$cmd" >/dev/null 2>&1 || missing+=("${NEEDS[$cmd]}")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "note: installing Debian's ${missing[*]} (apt-get, about 1.1 GB with their dependencies for all four)" >&2
  if [ "$(id -u)" = 0 ] && apt_update \
     && DEBIAN_FRONTEND=noninteractive timeout 2400 "${APT[@]}" install -y -qq --no-install-recommends \
        "${missing[@]}" >/dev/null; then
    :
  else
    for pkg in "${missing[@]}"; do
      why=$([ "$(id -u)" = 0 ] && echo "could not be installed" || echo "is not installed and this is not root")
      echo "note: $pkg $why: ${SKIPS[$pkg]} will skip" >&2
    done
  fi
fi
exec .venv/bin/python -m pytest "$@"
