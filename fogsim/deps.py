"""Versions of fogsim and the libraries that shape its outputs (for manifests), and the checks
that turn a missing or clobbered dependency into one clear line saying how to fix it.

Nothing heavy is imported here at module level: optional extras (bpy, torch, Ultralytics,
pyarrow) are imported only when :func:`require` is called, and OpenCV only when
:func:`require_contrib` is.
"""
from __future__ import annotations

import importlib
import platform
from functools import lru_cache
from importlib.metadata import PackageNotFoundError, version

from fogsim._version import __version__
from fogsim.errors import MissingDependency

PACKAGES = ("numpy", "opencv-contrib-python-headless", "trimesh", "OpenEXR", "bpy")

#: OpenCV distributions that install a ``cv2`` without the contrib modules (``ximgproc``);
#: any of them installed next to ``opencv-contrib-python-headless`` can replace its files.
NON_CONTRIB_OPENCV = ("opencv-python", "opencv-python-headless", "opencv-contrib-python")


def package_versions() -> dict:
    out = {"fogsim": __version__, "python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            continue
    return out


def require(module: str, extra: str):
    """Import ``module`` (e.g. ``"torch"``, ``"pyarrow.parquet"``) or say which extra to install.

    Returns the imported module. Raises :class:`~fogsim.errors.MissingDependency` (a
    :class:`~fogsim.errors.FogsimError`) naming the extra when the import fails.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingDependency(
            f"{module} is not available ({exc}): this needs the '{extra}' extra: "
            f"pip install 'fogsim[{extra}]' (from a checkout: pip install -e '.[{extra}]')") from None


def _contrib_version() -> str:
    """The version to reinstall: the installed contrib wheel's, else the cv2 in place's."""
    try:
        return version("opencv-contrib-python-headless")
    except PackageNotFoundError:
        pass
    try:
        import cv2
        return f"{cv2.__version__}.*"
    except Exception:  # noqa: BLE001 - no usable cv2 at all: any 4.x contrib build will do
        return "4.*"


@lru_cache(maxsize=None)
def require_contrib(*names: str) -> None:
    """Check that ``cv2.ximgproc.<name>`` exists for every name (the opencv-contrib build).

    ``hasattr(cv2, "ximgproc")`` is not enough: when ``opencv-python`` (pulled in by
    Ultralytics) is installed over ``opencv-contrib-python-headless`` they share the ``cv2``
    folder, and what remains can be an empty ``ximgproc`` namespace. Raises
    :class:`~fogsim.errors.MissingDependency` with the commands that put the contrib build
    back. Only a successful check is cached.
    """
    import cv2

    ximgproc = getattr(cv2, "ximgproc", None)
    missing = [n for n in names if not hasattr(ximgproc, n)]
    if not missing:
        return
    present = []
    for dist in NON_CONTRIB_OPENCV:
        try:
            present.append(f"{dist} {version(dist)}")
        except PackageNotFoundError:
            continue
    who = (f"{' and '.join(present)} has replaced the contrib build's cv2" if present
           else "the cv2 in place is not the opencv-contrib build")
    raise MissingDependency(
        f"cv2.ximgproc lacks {', '.join(missing)}: {who} (cv2 {cv2.__version__} at "
        f"{getattr(cv2, '__file__', '?')}). Fix: pip uninstall -y {' '.join(NON_CONTRIB_OPENCV)} "
        f"&& pip install --force-reinstall --no-deps opencv-contrib-python-headless=={_contrib_version()}")
