"""Pixel value scales and the sRGB transfer function — the one place for both.

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


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] → linear light in [0, 1] (IEC 61966-2-1)."""
    x = np.asarray(x, dtype=np.float32)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """Linear light in [0, 1] → sRGB-encoded values in [0, 1]."""
    x = np.clip(np.asarray(x, dtype=np.float32), 0.0, None)
    return np.where(x <= 0.0031308, x * 12.92, 1.055 * x ** (1 / 2.4) - 0.055).astype(np.float32)


def from_float(x: np.ndarray, dtype) -> np.ndarray:
    """Float values already in the dtype's scale → that dtype, rounded half up and clipped."""
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        return x.astype(dtype, copy=False)
    top = full_scale(dtype)
    np.add(x, 0.5, out=x)
    np.clip(x, 0.0, top, out=x)
    return x.astype(dtype)
