"""The argument checks of every ``fogsim.augment`` front end (NumPy, albumentations, torch,
torchvision), in one place: an image, depth, β or airlight the fog does not support is a
``TypeError`` (wrong type or dtype) or ``ValueError`` (wrong shape or range) naming the argument
— never a result computed from it (an int32 or 0–255 float image read as 0–1, a NaN airlight
making a black image) and never a library's own error from deep inside (OpenCV's assertion on an
empty image, a torch broadcast error).

What is supported (docs/augment.md): images uint8, uint16, or floating point in [0, 1] (NaN
refused), at least 1×1; depth real numbers, metres, the image's height and width; β finite
≥ 0 (1/m); airlight finite in [0, 255] (8-bit units). The functions take NumPy arrays or the
numbers the torch front end reads off its tensors, so both share the rules and the words.
"""
from __future__ import annotations

import math
from numbers import Real

import numpy as np

#: image dtypes by name (NumPy and torch spell them alike); floats must hold values in [0, 1]
INTEGER_DTYPES = ("uint8", "uint16")
FLOAT_DTYPES = ("float16", "float32", "float64", "bfloat16")
IMAGE_KINDS = "uint8, uint16, or floating point in [0, 1]"
#: how far a float image may stray outside [0, 1] (rounding of a resample), and still count as 0–1
UNIT_SLACK = 1e-3


def dtype_name(dtype) -> str:
    """``uint8`` for ``np.uint8`` / ``np.dtype("uint8")`` / ``torch.uint8``."""
    return str(dtype).rsplit(".", 1)[-1]


def check_image_dtype(dtype, name: str = "image") -> str:
    """The dtype's name if an image may have it; else a TypeError naming ``name``."""
    kind = dtype_name(dtype)
    if kind not in INTEGER_DTYPES + FLOAT_DTYPES:
        hint = " (a mask? fog takes images)" if kind == "bool" else \
            " (convert: uint8 for 0–255 values, or float / 255)" if kind.startswith("int") or kind == "uint32" else ""
        raise TypeError(f"{name} must be {IMAGE_KINDS}, got dtype {kind}{hint}")
    return kind


def check_size(height: int, width: int, name: str = "image") -> None:
    if height < 1 or width < 1:
        raise ValueError(f"{name} is {width}×{height}: there is nothing to fog (at least 1×1 pixel)")


def check_unit_range(low: float, high: float, name: str = "image") -> None:
    """A float image's smallest and largest value (NaN: either is NaN) must lie in [0, 1]."""
    if math.isnan(low) or math.isnan(high):
        raise ValueError(f"{name} holds NaN values")
    if low < -UNIT_SLACK or high > 1 + UNIT_SLACK:
        hint = " — a 0–255 image? divide it by 255 or pass it as uint8" if high > 1.5 else ""
        raise ValueError(f"{name} is floating point with values in [{low:g}, {high:g}]: float images hold "
                         f"[0, 1]{hint}")


def check_numpy_image(image, name: str = "image") -> np.ndarray:
    """``image`` as the NumPy front ends take it: an H×W×3 array (see the module doc)."""
    if not isinstance(image, np.ndarray):
        raise TypeError(f"{name} must be a NumPy array H×W×3 ({IMAGE_KINDS}), got {type(image).__name__}")
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"{name} must be H×W×3 (RGB), got shape {image.shape}")
    kind = check_image_dtype(image.dtype, name)
    check_size(image.shape[0], image.shape[1], name)
    if kind in FLOAT_DTYPES:
        check_unit_range(float(np.min(image)), float(np.max(image)), name)
    return image


def check_numpy_depth(depth, shape: tuple[int, int], name: str = "depth") -> np.ndarray:
    """``depth`` as an array of real numbers, H×W or H×W×1 with the image's ``shape`` (H, W)."""
    if isinstance(depth, (str, bytes)) or depth is None:
        raise TypeError(f"{name} must be an H×W array of distances in metres, got {type(depth).__name__}")
    depth = np.asarray(depth)
    if depth.dtype.kind not in "fiu":
        raise TypeError(f"{name} must hold real numbers (metres), got dtype {depth.dtype}")
    plane = depth[:, :, 0] if depth.ndim == 3 and depth.shape[2] == 1 else depth
    if plane.ndim != 2 or plane.shape != tuple(shape):
        raise ValueError(f"{name} must be H×W (or H×W×1) = {shape[0]}×{shape[1]} like the image, got shape "
                         f"{depth.shape}")
    return depth


def is_number(v) -> bool:
    """A real number that is not a bool (``True`` is not a β) nor a string."""
    return isinstance(v, (Real, np.number)) and not isinstance(v, (bool, np.bool_))


def check_beta(value, name: str = "beta") -> float:
    """One β: a finite number ≥ 0 in 1/m."""
    if not is_number(value):
        raise TypeError(f"{name} must be a number in 1/m, got {type(value).__name__} {value!r}")
    if not (math.isfinite(float(value)) and value >= 0):
        raise ValueError(f"{name} must be a finite number ≥ 0 (1/m), got {value}")
    return float(value)


def check_airlight(values, name: str = "airlight") -> None:
    """Airlight values (a number, R, G, B, or per-sample rows) finite in [0, 255] (8-bit units)."""
    a = np.asarray(values, dtype=object).ravel()
    if not all(is_number(v) for v in a):
        raise TypeError(f"{name} must be numbers in [0, 255] (8-bit units), got {values!r}")
    f = np.asarray(a, np.float64)
    if not (np.isfinite(f).all() and (f >= 0).all() and (f <= 255).all()):
        raise ValueError(f"{name} must be finite and in [0, 255] (8-bit units), got {values!r}"[:200])
