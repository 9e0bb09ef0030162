"""Pixel value scales, float → integer rounding and the sRGB transfer function — the one place
for each (images, asset colours, previews and the renderer's 8-bit output all call these).

Images keep their dtype end to end: uint8 (0–255), uint16 (0–65535) or float (0–1).
Airlight is always given in 8-bit units (255 = white), as in the paper, and scaled here.
"""
from __future__ import annotations

import numpy as np


def full_scale(dtype) -> float:
    """The value of white for an image dtype: 255, 65535 or 1.0."""
    dtype = np.dtype(dtype)
    if dtype == np.uint8:
        return 255.0
    if dtype == np.uint16:
        return 65535.0
    if dtype.kind == "f":
        return 1.0
    raise TypeError(f"unsupported image dtype {dtype} (use uint8, uint16 or float)")


def srgb_to_linear(x: np.ndarray, dtype=np.float32) -> np.ndarray:
    """sRGB-encoded values in [0, 1] → linear light in [0, 1] (IEC 61966-2-1), computed in and
    returned as ``dtype`` (float32 for images; float64 for colour constants)."""
    x = np.asarray(x, dtype=dtype)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(dtype)


def linear_to_srgb(x: np.ndarray, dtype=np.float32) -> np.ndarray:
    """Linear light in [0, 1] → sRGB-encoded values in [0, 1] (negatives clip to 0), computed in
    and returned as ``dtype``."""
    x = np.clip(np.asarray(x, dtype=dtype), 0.0, None)
    return np.where(x <= 0.0031308, x * 12.92, 1.055 * x ** (1 / 2.4) - 0.055).astype(dtype)


def from_float(x: np.ndarray, dtype) -> np.ndarray:
    """Float values already in the dtype's scale → that dtype, rounded half up and clipped."""
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        return x.astype(dtype, copy=False)
    top = full_scale(dtype)
    np.add(x, 0.5, out=x)
    np.clip(x, 0.0, top, out=x)
    return x.astype(dtype)


def to_uint8(image: np.ndarray) -> np.ndarray:
    """An image of any supported dtype → uint8 (0–255): rescaled, rounded half up, clipped.
    uint8 input comes back as is (not copied)."""
    if image.dtype == np.uint8:
        return image
    return from_float(image.astype(np.float32) * (255.0 / full_scale(image.dtype)), np.uint8)


def linear_to_srgb8(rgb_linear: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Scene-linear light → 8-bit sRGB: exposure scale, clip at white, sRGB transfer, rounded
    half up."""
    x = linear_to_srgb(np.clip(rgb_linear * np.float32(exposure), 0.0, 1.0))
    return from_float(np.multiply(x, 255.0, out=x), np.uint8)


#: Relative-luminance weights of linear sRGB / Rec. 709 primaries (IEC 61966-2-1, ITU-R BT.709).
LUMINANCE_WEIGHTS = (0.2126, 0.7152, 0.0722)


def luminance(rgb_linear: np.ndarray) -> np.ndarray:
    """Linear-light RGB (H×W×3, any scale) → relative luminance Y (H×W float32, same scale)."""
    x = np.asarray(rgb_linear, np.float32)
    r, g, b = LUMINANCE_WEIGHTS
    return (x[..., 0] * np.float32(r) + x[..., 1] * np.float32(g) + x[..., 2] * np.float32(b)).astype(np.float32)


def _decode_table(dtype) -> np.ndarray:
    """srgb_to_linear of every code value of an integer dtype (float32 lookup table)."""
    top = int(full_scale(dtype))
    if top not in _DECODE:
        _DECODE[top] = srgb_to_linear(np.arange(top + 1, dtype=np.float64) / top)
    return _DECODE[top]


_DECODE: dict[int, np.ndarray] = {}


def decode_codes(values: np.ndarray) -> np.ndarray:
    """uint8 / uint16 sRGB code values → linear light (float32, 0–1) through a lookup table of
    :func:`srgb_to_linear` (the same numbers, faster)."""
    return _decode_table(values.dtype)[values]


def srgb_luminance(image: np.ndarray) -> np.ndarray:
    """A stored (sRGB-encoded) image of any supported dtype → relative luminance Y in linear light,
    H×W float32, 0–1 (white = 1): decode the transfer function per channel, then weight (8- and
    16-bit images through a lookup table of :func:`srgb_to_linear`, the same numbers)."""
    image = np.asarray(image)
    if image.dtype in (np.uint8, np.uint16):
        return luminance(_decode_table(image.dtype)[image])
    return luminance(srgb_to_linear(image.astype(np.float32) / np.float32(full_scale(image.dtype))))
