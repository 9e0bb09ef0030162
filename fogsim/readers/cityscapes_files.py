"""Cityscapes' stereo files: the camera JSON and the 16-bit disparity PNG → planar depth.

The one reader of this format. ``DepthSpec`` (encoding ``disparity``), ``fogsim ila fill``,
ILA's training loader and the depth benchmark all go through :func:`read_cityscapes_disparity`
/ :func:`read_cityscapes_depth`, so every caller validates the camera file the same way and
every problem names the file it is in. fogsim's ``--stereo`` renders write the same files.

Camera: ``extrinsic.baseline`` in metres, ``intrinsic.fx``, ``fy``, ``u0``, ``v0`` in pixels
(the image size is the disparity map's). Disparity: p = 256·d + 1 (uint16), p = 0 a hole;
depth Z = baseline·fx/d (see :mod:`fogsim.camera` for the pure conversions).

This module holds the file format only; the dataset tree (``leftImg8bit/``, ``disparity/``,
``camera/``) is walked by :mod:`fogsim.readers.cityscapes`, which re-exports these readers.
They live apart because :mod:`fogsim.readers.base` needs them and ``cityscapes`` needs ``base``.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fogsim.camera import Intrinsics, StereoCamera, decode_disparity_png, disparity_to_depth
from fogsim.errors import InputError
from fogsim.io.depth_files import read_uint16_map
from fogsim.io.documents import read_json

_FIELDS = "extrinsic.baseline and intrinsic.fx, fy, u0, v0"


def load_cityscapes_camera(path: str | Path, width: int, height: int) -> StereoCamera:
    """Read a Cityscapes camera JSON (``extrinsic.baseline``, ``intrinsic.fx/fy/u0/v0``) for a
    ``width``×``height`` image. Raises :class:`InputError` naming ``path`` on any problem."""
    d = read_json(path)
    try:
        intr = d["intrinsic"]
        values = (d["extrinsic"]["baseline"], intr["fx"], intr["fy"], intr["u0"], intr["v0"])
    except KeyError as exc:
        raise InputError(path, f"not a Cityscapes camera file (missing {exc})") from None
    except TypeError:
        raise InputError(path, f"not a Cityscapes camera file (need {_FIELDS})") from None
    try:
        baseline, fx, fy, u0, v0 = (float(v) for v in values)
    except (TypeError, ValueError):
        raise InputError(path, f"not a Cityscapes camera file ({_FIELDS} must be numbers)") from None
    if not all(math.isfinite(v) for v in (baseline, fx, fy, u0, v0)):
        raise InputError(path, f"not a Cityscapes camera file ({_FIELDS} must be finite)")
    if baseline <= 0 or fx <= 0 or fy <= 0:
        raise InputError(path, f"baseline ({baseline}), fx ({fx}) and fy ({fy}) must be positive")
    return StereoCamera(baseline, Intrinsics(fx, fy, u0, v0, width, height))


def read_cityscapes_disparity(disparity_path: str | Path,
                              camera_path: str | Path | None) -> tuple[np.ndarray, StereoCamera]:
    """Disparity in pixels (H×W float32, 0 = hole) and the stereo camera of a disparity PNG.

    The camera's image size is the disparity map's. Raises :class:`InputError` naming the
    disparity file when its camera JSON is missing, and the camera file when that is malformed.
    """
    if camera_path is None or not Path(camera_path).is_file():
        raise InputError(disparity_path, f"disparity needs its camera JSON "
                                         f"({camera_path or 'none given'} not found)")
    raw = read_uint16_map(disparity_path)
    camera = load_cityscapes_camera(camera_path, raw.shape[1], raw.shape[0])
    return decode_disparity_png(raw), camera


def read_cityscapes_depth(disparity_path: str | Path,
                          camera_path: str | Path | None) -> tuple[np.ndarray, StereoCamera]:
    """Planar depth Z = baseline·fx/d in metres (H×W float32, 0 = hole) and the stereo camera."""
    disparity, camera = read_cityscapes_disparity(disparity_path, camera_path)
    return disparity_to_depth(disparity, camera.baseline, camera.intrinsics.fx), camera
