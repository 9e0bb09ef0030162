"""EXR files in and out: every channel of a file read through the OpenEXR package under the pixel bound
(damage as one line naming the file), and float32 depth maps and scene-linear RGB images written as ZIP EXR.

Writing goes through OpenCV when its build has an EXR encoder (the 4.x wheels), because this also runs
inside Debian's Blender 3.4, where the OpenEXR package crashes the process; OpenCV builds without one (the
5.x wheels) write through the OpenEXR package instead.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import cv2  # fogsim.io turned OpenCV's EXR codec on before this import
import numpy as np

from fogsim.errors import InputError
from fogsim.io.atomic import atomic_path, atomic_write_bytes
from fogsim.io.headers import HEADER_BYTES, exr_header, read_head
from fogsim.io.integrity import first_line, native_output
from fogsim.io.pixel_bound import check_declared

__all__ = ["read_exr_channels", "read_rgb_exr", "write_depth_exr", "write_rgb_exr"]


def read_exr_channels(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """All channels of an EXR file (single- or multi-layer), name → H×W array."""
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    check_declared(exr_header(read_head(path, HEADER_BYTES)), path)
    error = None
    with native_output() as said:  # OpenEXR prints its own lines on damaged files: keep them off the terminal
        try:
            with OpenEXR.File(str(path), separate_channels=True) as f:
                channels = {name: np.array(ch.pixels) for name, ch in f.channels().items()}
        except Exception as exc:  # OpenEXR raises plain RuntimeError/ValueError on corrupt files
            error = exc
    said = said[0] if said else ""
    damage = first_line(said, str(path))
    if error is not None or _EXR_DAMAGE.search(said):
        detail = damage or str(error)
        raise InputError(path, f"not a readable EXR file (truncated or corrupt: {detail})" if damage
                         else f"not a readable EXR file ({detail})")
    return channels


#: what OpenEXR prints when it skips damaged data
_EXR_DAMAGE = re.compile(r"EXR_ERR_|Exception raised reading|corrupt", re.IGNORECASE)


def write_depth_exr(path: str | os.PathLike, depth: np.ndarray) -> None:
    """Write H×W float32 metres as EXR (one float channel ``Y``, ZIP), atomically."""
    _write_exr(Path(path), np.ascontiguousarray(depth, dtype=np.float32), False, "depth map")


def write_rgb_exr(path: str | os.PathLike, rgb: np.ndarray) -> None:
    """Write an H×W×3 float32 scene-linear RGB image as EXR (channels R, G, B, ZIP), atomically."""
    rgb = np.ascontiguousarray(rgb, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"an RGB EXR needs an H×W×3 array, got shape {rgb.shape}")
    _write_exr(Path(path), rgb, True, "image")


def _write_exr(path: Path, image: np.ndarray, rgb: bool, what: str) -> None:
    """``image`` (float32) as a ZIP EXR at ``path``: channels R, G, B when ``rgb``, else one channel ``Y`` —
    through OpenCV when it has an EXR encoder, else the OpenEXR package (the module docstring)."""
    if not cv2.haveImageWriter(".exr"):
        import OpenEXR

        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        channels = {c: np.ascontiguousarray(image[:, :, i]) for i, c in enumerate("RGB")} if rgb else {"Y": image}
        with atomic_path(path) as tmp:
            with OpenEXR.File(header, channels) as f:
                f.write(str(tmp))
        return
    ok, data = cv2.imencode(".exr", np.ascontiguousarray(image[:, :, ::-1]) if rgb else image,
                            [cv2.IMWRITE_EXR_TYPE, cv2.IMWRITE_EXR_TYPE_FLOAT,
                             cv2.IMWRITE_EXR_COMPRESSION, cv2.IMWRITE_EXR_COMPRESSION_ZIP])
    if not ok:
        raise ValueError(f"OpenCV could not encode a {image.shape} {what} as EXR")
    atomic_write_bytes(path, data.tobytes())


def read_rgb_exr(path: str | os.PathLike) -> np.ndarray:
    """An EXR's R, G, B channels as H×W×3 float32 (what :func:`write_rgb_exr` writes)."""
    ch = read_exr_channels(path)
    if not all(c in ch for c in "RGB"):
        raise InputError(path, f"not an RGB EXR (channels {sorted(ch)})")
    return np.stack([ch[c] for c in "RGB"], axis=-1).astype(np.float32)
