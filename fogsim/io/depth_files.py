"""Depth maps in and out, in metres as H×W float32: EXR (its depth channel), ``.npy`` (read in bounded
memory, never unpickled) and 16-bit PNG/TIFF times a scale; and 16-bit single-channel maps read exactly.
"""
from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from fogsim.errors import InputError
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.exr import read_exr_channels, write_depth_exr
from fogsim.io.headers import ImageHeader, read_npy
from fogsim.io.images import read_stored
from fogsim.io.pixel_bound import check_declared

__all__ = ["DEPTH_SUFFIXES", "EXR_DEPTH_CHANNELS", "read_depth_file", "read_uint16_map", "write_depth"]

DEPTH_SUFFIXES = (".exr", ".npy", ".png", ".tif", ".tiff")


#: channel names tried, in order, when an EXR holds depth
EXR_DEPTH_CHANNELS = ("Z", "depth", "Depth", "ViewLayer.Depth.Z", "Depth.Z", "Y", "R", "V")


def write_depth(path: str | os.PathLike, depth: np.ndarray) -> None:
    """Write H×W float32 metres as EXR (one float channel ``Y``, ZIP: :func:`~fogsim.io.exr.write_depth_exr`)
    or ``.npy``, by suffix, atomically."""
    path = Path(path)
    depth = np.ascontiguousarray(depth, dtype=np.float32)
    if path.suffix == ".npy":
        buf = io.BytesIO()
        np.save(buf, depth)
        atomic_write_bytes(path, buf.getvalue())
        return
    write_depth_exr(path, depth)


def read_depth_file(path: str | os.PathLike, png_scale: float | None = None) -> np.ndarray:
    """Read a depth map in metres as H×W float32.

    ``.exr``: the first channel of ``EXR_DEPTH_CHANNELS`` present. ``.npy``: a 2-D array.
    ``.png``/``.tif``: 16-bit integers times ``png_scale`` metres per unit (required; an
    8-bit file is refused because it cannot hold metric depth). Values are returned as
    stored: 0 means a hole, +inf no hit; the caller validates.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "depth file not found")
    suffix = path.suffix.lower()
    if suffix == ".exr":
        channels = read_exr_channels(path)
        name = next((c for c in EXR_DEPTH_CHANNELS if c in channels), None)
        if name is None:
            raise InputError(path, f"no depth channel (looked for {', '.join(EXR_DEPTH_CHANNELS)}; "
                                   f"found {', '.join(channels) or 'none'})")
        depth = channels[name]
    elif suffix == ".npy":
        depth = read_npy(path, lambda dtype, shape: _check_depth_npy(path, dtype, shape))
        if depth.ndim == 3 and depth.shape[2] == 1:
            depth = depth[:, :, 0]
    elif suffix in (".png", ".tif", ".tiff"):
        raw = read_uint16_map(path)
        if png_scale is None:
            raise InputError(path, "a 16-bit depth image needs a scale in metres per unit "
                                   "(--depth-scale)")
        depth = raw.astype(np.float32) * np.float32(png_scale)
    else:
        raise InputError(path, f"unsupported depth format {suffix!r} (use .exr, .npy or 16-bit .png)")
    if depth.ndim != 2:
        raise InputError(path, f"depth must be a single-channel map, got shape {depth.shape}")
    return depth.astype(np.float32, copy=False)


def _check_depth_npy(path: Path, dtype: np.dtype, shape: tuple[int, ...]) -> None:
    """A depth ``.npy``'s header: real numbers, H×W (or H×W×1), within the pixel bound."""
    if dtype.kind not in "fiu" or dtype.names:
        raise InputError(path, f"depth must hold real numbers (a float or integer array), got {dtype}")
    if len(shape) not in (2, 3) or (len(shape) == 3 and shape[2] != 1):
        raise InputError(path, f"depth must be a single-channel map, got shape {shape}")
    check_declared(ImageHeader("npy", shape[1], shape[0], 1), path)


def read_uint16_map(path: str | os.PathLike) -> np.ndarray:
    """Read a single-channel 16-bit PNG/TIFF exactly (never through OpenCV's 8-bit default)."""
    path = Path(path)
    raw = read_stored(path)
    if raw.ndim == 3:
        raise InputError(path, f"expected a single-channel 16-bit map, got {raw.shape[2]} channels")
    if raw.dtype != np.uint16:
        raise InputError(path, f"expected 16-bit integers, got {raw.dtype} (an 8-bit image cannot "
                               "hold this map; was an RGB or preview image passed?)")
    return raw
