#!/usr/bin/env python3
"""Package the Blender add-on.

    python scripts/build_addon.py [--out dist] [--kind extension|legacy|both]

* ``fogsim-<v>-extension.zip`` — a Blender 4.2+ extension: the add-on, ``lib/fogsim`` (the
  library and its presets) and ``wheels/`` for OpenCV, trimesh and tqdm, listed in
  ``blender_manifest.toml`` so Blender installs them (Blender ships numpy).
* ``fogsim-<v>-legacy.zip`` — a Blender 3.x add-on (``bl_info``): the same, with the wheels
  unpacked into ``lib/`` and numpy included (Debian's Blender has none). Wheels are
  platform-specific: ``--platform`` (default manylinux2014_x86_64) and Python 3.11.

Install: Edit ▸ Preferences ▸ Add-ons ▸ Install… (3.x) or Get Extensions ▸ Install from Disk (4.2+).
"""
from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from importlib.metadata import version
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
PACKAGE = "fogsim_blender"
DEPS = ("opencv-contrib-python-headless", "trimesh", "tqdm",
        # fogsim.schema (every document fogsim reads); pydantic-core is platform-specific like OpenCV
        "pydantic", "pydantic-core", "annotated-types", "typing-extensions", "typing-inspection")


def download_wheels(dest: Path, platform: str, with_numpy: bool) -> list[Path]:
    """The pinned (installed) versions of the add-on's dependencies as wheels for ``platform``."""
    pins = [f"{d}=={version(d)}" for d in DEPS] + ([f"numpy=={version('numpy')}"] if with_numpy else [])
    subprocess.run([sys.executable, "-m", "pip", "download", "--quiet", "--only-binary=:all:", "--no-deps",
                    "--python-version", "3.11", "--platform", platform, "-d", str(dest), *pins], check=True)
    return sorted(dest.glob("*.whl"))


def stage(dest: Path) -> None:
    """Add-on modules at ``dest``, the fogsim library and presets in ``dest/lib``."""
    from fogsim import __version__

    init = (ROOT / "blender_addon" / "__init__.py").read_text()
    stamped = re.sub(r'"version": \(\d+, \d+, \d+\)', f'"version": {_version_tuple(__version__)}', init, count=1)
    if stamped == init and "(0, 0, 0)" in init:
        raise SystemExit("build_addon: could not stamp bl_info['version'] in blender_addon/__init__.py")
    (dest / "__init__.py").write_text(stamped)
    shutil.copytree(ROOT / "fogsim", dest / "lib" / "fogsim", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))


def _version_tuple(version: str) -> tuple[int, int, int]:
    """``"0.2.0"`` → ``(0, 2, 0)`` for bl_info (pre-release tags dropped)."""
    nums = [int(re.match(r"\d+", part).group()) for part in version.split(".")[:3]]
    return tuple(nums + [0] * (3 - len(nums)))


def stamp_manifest(text: str, version: str) -> str:
    """The manifest with its ``version = "…"`` line set to ``version``."""
    out, n = re.subn(r'(?m)^version = "[^"]*".*$', f'version = "{version}"', text, count=1)
    if n != 1:
        raise SystemExit("build_addon: blender_manifest.toml has no version line")
    return out


def zip_tree(src: Path, out: Path, prefix: str = "") -> None:
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for p in sorted(src.rglob("*")):
            if p.is_file():
                z.write(p, prefix + str(p.relative_to(src)))


def build_extension(out_dir: Path, platform: str, tmp: Path) -> Path:
    from fogsim import __version__

    stage_dir = tmp / "extension"
    stage_dir.mkdir()
    stage(stage_dir)
    wheels = download_wheels(stage_dir / "wheels", platform, with_numpy=False)
    manifest = (ROOT / "blender_addon" / "blender_manifest.toml").read_text()
    listed = ", ".join(f'"./wheels/{w.name}"' for w in wheels)
    manifest = manifest.replace("wheels = []", f'wheels = [{listed}]\nplatforms = ["{_blender_platform(platform)}"]')
    manifest = stamp_manifest(manifest, __version__)
    (stage_dir / "blender_manifest.toml").write_text(manifest)
    out = out_dir / f"fogsim-{__version__}-extension.zip"
    zip_tree(stage_dir, out)
    return out


def build_legacy(out_dir: Path, platform: str, tmp: Path) -> Path:
    from fogsim import __version__

    stage_dir = tmp / "legacy" / PACKAGE
    stage_dir.mkdir(parents=True)
    stage(stage_dir)
    for wheel in download_wheels(tmp / "legacy_wheels", platform, with_numpy=True):
        with zipfile.ZipFile(wheel) as z:
            z.extractall(stage_dir / "lib")
    out = out_dir / f"fogsim-{__version__}-legacy.zip"
    zip_tree(stage_dir, out, prefix=f"{PACKAGE}/")
    return out


def _blender_platform(platform: str) -> str:
    return "linux-x64" if "x86_64" in platform else "linux-arm64" if "aarch64" in platform else platform


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(ROOT / "dist"))
    ap.add_argument("--kind", choices=("extension", "legacy", "both"), default="both")
    ap.add_argument("--platform", default="manylinux2014_x86_64")
    args = ap.parse_args()
    out_dir = Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        if args.kind in ("extension", "both"):
            print(f"wrote {build_extension(out_dir, args.platform, Path(tmp))}")
        if args.kind in ("legacy", "both"):
            print(f"wrote {build_legacy(out_dir, args.platform, Path(tmp))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
