"""Filling holes in real depth maps before fogging.

Holes (depth = 0: stereo occlusions, sky without disparity, missing predictions) would
otherwise get t = 1 and stay unfogged — bright, clear blotches in a foggy image. Every
method here works on *inverse* depth (1/Z, proportional to disparity), which is linear in
image coordinates on planar surfaces, so interpolating it bends nothing; +inf (no hit) is
inverse depth 0 and is a valid value, not a hole.

Methods (``--fill``):
  * ``none``     — refuse maps with holes (the safe default for exact, rendered depth).
  * ``inpaint``  — OpenCV's Navier–Stokes inpainting of inverse depth (smooth). Telea is not
                   used: on float32 input OpenCV 4.11's Telea returns garbage (checked).
  * ``ipbasic``  — IP-Basic-style morphological fill: growing erosions of inverse depth copy
                   the *farthest* neighbouring valid value into the hole (stereo holes are
                   mostly occlusions, where the background is right), then a median blur of
                   the filled pixels only.
Learned fills (the ILA model) plug in with :func:`register_fill`.
"""
from __future__ import annotations

from typing import Callable

import cv2
import numpy as np

FillFn = Callable[[np.ndarray, np.ndarray, "np.ndarray | None"], np.ndarray]
_FILLS: dict[str, FillFn] = {}


class HolesError(ValueError):
    """Raised by ``--fill none`` when the depth has holes."""


def register_fill(name: str, fn: FillFn) -> None:
    """Register ``fn(inverse_depth, hole_mask, image) -> filled inverse depth``."""
    _FILLS[name] = fn


def fill_methods() -> list[str]:
    return sorted(_FILLS)


def hole_mask(depth: np.ndarray) -> np.ndarray:
    """True where the depth is a hole (0); +inf (no hit) is not a hole."""
    return depth == 0


def fill_holes(depth: np.ndarray, method: str, image: np.ndarray | None = None) -> np.ndarray:
    """Depth in metres with its holes (0) filled by ``method``; other pixels are unchanged."""
    if method not in _FILLS:
        raise ValueError(f"unknown fill method {method!r} (known: {', '.join(fill_methods())})")
    holes = hole_mask(depth)
    if not holes.any():
        return depth
    inv = np.zeros(depth.shape, np.float32)
    valid = ~holes & np.isfinite(depth)
    inv[valid] = 1.0 / depth[valid]
    if not (~holes).any():
        raise HolesError("the depth map has no valid pixel to fill from")
    filled = _FILLS[method](inv, holes, image)
    out = depth.astype(np.float32, copy=True)
    with np.errstate(divide="ignore"):
        out[holes] = np.where(filled[holes] > 0, 1.0 / np.maximum(filled[holes], 1e-30), np.inf)
    return out


def _fill_none(inv, holes, image):
    n = int(holes.sum())
    raise HolesError(f"depth has {n} hole pixels ({100.0 * n / holes.size:.1f} %); "
                     f"choose a fill: --fill {'|'.join(m for m in fill_methods() if m != 'none')}")


def _fill_inpaint(inv, holes, image):
    scale = float(inv.max()) or 1.0  # keep values O(1)
    out = cv2.inpaint(inv / scale, holes.astype(np.uint8), 5, cv2.INPAINT_NS)
    return out * scale


def _fill_ipbasic(inv, holes, image):
    big = np.float32(np.finfo(np.float32).max)
    work = np.where(holes, big, inv).astype(np.float32)
    todo = holes.copy()
    size = 5
    while todo.any():
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
        eroded = cv2.erode(work, kernel, borderType=cv2.BORDER_REPLICATE)
        take = todo & (eroded < big)
        work[take] = eroded[take]
        todo &= ~take
        if size > 2 * max(inv.shape):
            break
        size = size * 2 + 1
    blurred = cv2.medianBlur(work, 5)
    work[holes] = blurred[holes]
    return work


register_fill("none", _fill_none)
register_fill("inpaint", _fill_inpaint)
register_fill("ipbasic", _fill_ipbasic)
