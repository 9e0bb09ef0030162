"""Images in and out: encoded images (PNG, JPEG, BMP, TIFF, WebP, EXR) read as RGB under the pixel bound,
refused when damaged, and written atomically.

Conventions: RGB arrays are H×W×3 in RGB order (OpenCV's BGR never leaves this module); a 16-bit image stays
16-bit unless converted by :func:`to_8bit`, the one 16 → 8 bit rule.
"""
from __future__ import annotations

import os
from pathlib import Path

import cv2  # fogsim.io turned OpenCV's EXR codec on before this import
import numpy as np

from fogsim.errors import InputError
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.headers import HEADER_BYTES, image_header, read_head
from fogsim.io.integrity import DECODER_DAMAGE, encoded_image_damage, first_line, native_output
from fogsim.io.pixel_bound import MAX_FILE_BYTES_PER_PIXEL, check_declared, max_pixels_now

__all__ = ["IMAGE_SUFFIXES", "TO_8BIT", "decode_image", "encode_image", "read_image", "read_stored", "to_8bit",
           "write_image"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


def decode_image(data: bytes, source: str) -> np.ndarray:
    """Decode encoded image bytes (PNG, JPEG, ...) to an RGB array of the file's bit depth.

    The size its header declares is checked first (:func:`check_declared`); truncated or corrupt data
    is an :class:`InputError` naming ``source``, never an image with the decoder's grey fill: the
    structural check of :func:`encoded_image_damage` first, then any damage the decoder reports
    (libjpeg only warns about corrupt data).
    """
    return _to_rgb(_decode(data, source), source)


def _decode(data: bytes, source) -> np.ndarray:
    """The stored pixels (BGR, any bit depth) of encoded image bytes, or InputError."""
    check_declared(image_header(data[:HEADER_BYTES]), source)
    damage = encoded_image_damage(data)
    if damage:
        raise InputError(source, damage)
    with native_output() as said:
        arr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    said = said[0] if said else ""
    if arr is None:
        detail = first_line(said)
        raise InputError(source, "not a readable image (corrupt or unsupported format"
                                 + (f"; the decoder says: {detail})" if detail else ")"))
    damage = DECODER_DAMAGE.search(said)
    if damage:
        raise InputError(source, f"corrupt image data (the decoder says: {damage.group(0).strip()})")
    return arr


def read_stored(path: str | os.PathLike) -> np.ndarray:
    """The stored pixels of an image file, as OpenCV decodes them (BGR, any bit depth), read in bounded
    memory: a header declaring too many pixels or channels, and a file larger than the pixel bound can
    need (:data:`MAX_FILE_BYTES_PER_PIXEL` a pixel), are refused before the body is read."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    size = path.stat().st_size
    bound = max_pixels_now()
    check_declared(image_header(read_head(path, HEADER_BYTES)), path)
    if size > bound * MAX_FILE_BYTES_PER_PIXEL + HEADER_BYTES:
        raise InputError(path, f"{size:,} bytes is more than an image of at most {bound:,} pixels takes "
                               f"({MAX_FILE_BYTES_PER_PIXEL} bytes a pixel; --max-pixels {bound}): not an image "
                               "fogsim reads")
    return _decode(read_head(path, size + 1), path)


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as RGB (uint8 or uint16, as stored; float32 for EXR)."""
    return _to_rgb(read_stored(path), str(path))


def _to_rgb(arr: np.ndarray, source: str) -> np.ndarray:
    if arr.ndim == 2:
        return np.repeat(arr[:, :, None], 3, axis=2)
    if arr.shape[2] == 4:
        arr = arr[:, :, :3]
    if arr.shape[2] != 3:
        raise InputError(source, f"expected an RGB image, got {arr.shape[2]} channels")
    return np.ascontiguousarray(arr[:, :, ::-1])


#: the one 16 → 8 bit conversion (JPEG holds 8 bits): v8 = round(v16 · 255 / 65535)
TO_8BIT = "round(v * 255 / 65535)"


def to_8bit(rgb: np.ndarray) -> np.ndarray:
    """An 8-bit copy of a uint8/uint16 image, scaled by :data:`TO_8BIT` (uint8 is returned as is)."""
    if rgb.dtype == np.uint8:
        return rgb
    if rgb.dtype != np.uint16:
        raise ValueError(f"only uint8 and uint16 images convert to 8 bit, got {rgb.dtype}")
    return np.rint(rgb.astype(np.float32) * np.float32(255.0 / 65535.0)).astype(np.uint8)


def encode_image(rgb: np.ndarray, suffix: str = ".png") -> bytes:
    """Encode an RGB uint8/uint16 array (PNG keeps 16 bit). JPEG takes uint8 only: a 16-bit
    array is refused rather than saturated (convert it with :func:`to_8bit` first)."""
    if suffix.lower() in (".jpg", ".jpeg") and rgb.dtype != np.uint8:
        raise ValueError(f"JPEG holds 8-bit values, got a {rgb.dtype} image: convert it first "
                         "(fogsim.io.images.to_8bit)")
    if rgb.ndim == 3:
        rgb = np.ascontiguousarray(rgb[:, :, ::-1])
    ok, buf = cv2.imencode(suffix, rgb)
    if not ok:
        raise ValueError(f"OpenCV could not encode a {rgb.dtype} {rgb.shape} array as {suffix}")
    return buf.tobytes()


def write_image(path: str | os.PathLike, rgb: np.ndarray) -> None:
    """Write an RGB (or single-channel) array atomically; the format follows the suffix."""
    atomic_write_bytes(path, encode_image(rgb, Path(path).suffix or ".png"))
