"""Versions of fogsim and the libraries that shape its outputs, for manifests."""
from __future__ import annotations

import platform
from importlib.metadata import PackageNotFoundError, version

from . import __version__

PACKAGES = ("numpy", "opencv-contrib-python-headless", "trimesh", "OpenEXR", "bpy")


def package_versions() -> dict:
    out = {"fogsim": __version__, "python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            continue
    return out
