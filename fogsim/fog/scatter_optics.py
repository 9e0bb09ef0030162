"""The scatter fog model's image-space optics (:mod:`fogsim.fog.scatter`): each pixel's viewing
elevation, and the atmospheric point-spread function — a Gaussian in angle whose width is each source
pixel's own, splatted by layers of box filters (energy conserving), plus the reduction of a sparse
image to the PSF's grid. Pixel coordinates as in docs/conventions.md (integers are pixel centres)."""
from __future__ import annotations

import math

import cv2
import numpy as np

from fogsim.camera import Intrinsics

#: field of view assumed when no intrinsics are given (degrees, horizontal, level camera)
DEFAULT_HFOV_DEG = 60.0
#: the PSF's widths: layers from SIGMA_MIN px (reduced copy) up, a factor LAYER_STEP apart
SIGMA_MIN = 0.7
LAYER_STEP = 2.0
#: widest PSF (rad); wider light is spread no further (it is nearly uniform by then)
SIGMA_MAX_RAD = 0.6
#: a PSF layer wider than 2× this (px) is blurred on a copy reduced by a power of two, at least
#: REDUCE_MIN_SIDE px a side (speed; the PSF term moves by ≤ 0.005 of A, ``docs/speed.md``)
REDUCE_ABOVE = 3.0
REDUCE_MIN_SIDE = 8
#: the airlight's elevation gain is computed on a grid this many times coarser (it is smooth)
GAIN_STEP = 8


# ----------------------------------------------------------------------------- geometry
#: world up in OpenCV camera coordinates (x right, y down, z forward) for a level camera
LEVEL_UP = (0.0, -1.0, 0.0)


def up_from_world_to_camera(world_to_camera) -> tuple[float, float, float]:
    """World up (+z) in camera coordinates, from a 4×4 (or 3×3) world→camera matrix."""
    r = np.asarray(world_to_camera, np.float64)[:3, :3]
    return tuple(float(v) for v in r[:, 2])


def _camera(shape: tuple[int, int], intrinsics: Intrinsics | None) -> Intrinsics:
    """``intrinsics`` at the image's size (None: :data:`DEFAULT_HFOV_DEG`, centred)."""
    h, w = shape
    if intrinsics is None:
        return Intrinsics.from_hfov(DEFAULT_HFOV_DEG, w, h)
    return intrinsics if (intrinsics.width, intrinsics.height) == (w, h) else intrinsics.scaled(w, h)


def _sine_at(u: np.ndarray, v: np.ndarray, K: Intrinsics, up) -> np.ndarray:
    """sin of the viewing elevation at pixel columns ``u`` × rows ``v`` (pixel coordinates, centres
    at integers as in docs/conventions.md), len(v)×len(u) float32."""
    y = ((np.asarray(v, np.float64) - K.cy) / K.fy).astype(np.float32)   # image y down
    x = ((np.asarray(u, np.float64) - K.cx) / K.fx).astype(np.float32)
    ux, uy, uz = (np.float32(c) for c in (LEVEL_UP if up is None else up))
    dot = (ux * x)[None, :] + (uy * y + uz)[:, None]              # camera ray (x, y, 1) · up
    norm = np.sqrt((x * x)[None, :] + (y * y + np.float32(1.0))[:, None])
    return np.divide(dot, norm, out=dot)


def elevation_sine(shape: tuple[int, int], intrinsics: Intrinsics | None, up=None) -> np.ndarray:
    """sin of each pixel's viewing elevation above the horizon (H×W float32) for a camera with
    ``intrinsics`` (None: :data:`DEFAULT_HFOV_DEG`, centred) and world ``up`` in its coordinates
    (None: :data:`LEVEL_UP`, a level camera)."""
    h, w = shape
    return _sine_at(np.arange(w), np.arange(h), _camera(shape, intrinsics), up)


def smooth_elevation_sine(shape: tuple[int, int], intrinsics: Intrinsics | None, up=None) -> np.ndarray:
    """:func:`elevation_sine`, exact on a grid :data:`GAIN_STEP` px apart that reaches one step beyond
    every border and bilinear in between (the map is smooth: ≤ 1e-5 off the exact one at 1920×1280,
    ``tests/test_scatter.py``); exact on images under 256 px a side, where 8 px is a wide angle."""
    h, w = shape
    if min(h, w) < 32 * GAIN_STEP:
        return elevation_sine(shape, intrinsics, up)
    s = GAIN_STEP
    nu, nv = -(-w // s) + 2, -(-h // s) + 2                     # coarse samples, one beyond each side
    centre = (s - 1) / 2.0                                      # coarse sample k sits at s·(k − 1) + centre
    coarse = _sine_at(s * (np.arange(nu) - 1) + centre, s * (np.arange(nv) - 1) + centre,
                      _camera(shape, intrinsics), up)
    full = cv2.resize(coarse, (s * nu, s * nv), interpolation=cv2.INTER_LINEAR)  # integer ratio: same centres
    return np.ascontiguousarray(full[s:s + h, s:s + w])


def focal_px(shape: tuple[int, int], intrinsics: Intrinsics | None) -> float:
    h, w = shape
    K = intrinsics or Intrinsics.from_hfov(DEFAULT_HFOV_DEG, w, h)
    return float(K.fx) * w / K.width


# ----------------------------------------------------------------------------- the PSF
def gaussian_by_boxes(x: np.ndarray, sigma: float) -> np.ndarray:
    """x blurred by ≈ a Gaussian of std ``sigma`` px: three normalised box filters (running sums,
    cost independent of σ), mirrored at the border so no light is lost or gained there."""
    if sigma < 0.5:
        return x
    ideal = math.sqrt(12.0 * sigma * sigma / 3.0 + 1.0)
    k = max(1, int(round((ideal - 1) / 2)) * 2 + 1)
    lim = 2 * min(x.shape[:2]) - 1
    k = min(k, lim if lim % 2 else lim - 1)
    out = x
    for _ in range(3):
        out = cv2.boxFilter(out, cv2.CV_32F, (k, k), normalize=True, borderType=cv2.BORDER_REFLECT)
    return out


def _blur_reduced(layer: np.ndarray, sigma: float) -> np.ndarray:
    """``layer`` blurred by ≈ a Gaussian of std ``sigma`` px; a wide blur on a copy reduced by a
    power of two (area average, then bilinear back up, rescaled to keep each channel's sum) so the reduced
    σ stays ≥ :data:`REDUCE_ABOVE` px and the copy ≥ :data:`REDUCE_MIN_SIDE` px a side."""
    h, w = layer.shape[:2]
    r = 1
    while sigma / (2 * r) >= REDUCE_ABOVE and min(h, w) // (2 * r) >= REDUCE_MIN_SIDE:
        r *= 2
    if r == 1:
        return gaussian_by_boxes(layer, sigma)
    size = (max(1, round(w / r)), max(1, round(h / r)))
    small = gaussian_by_boxes(cv2.resize(layer, size, interpolation=cv2.INTER_AREA), sigma * size[0] / w)
    up = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
    have, want = cv2.sumElems(up)[:3], cv2.sumElems(layer)[:3]   # resampling keeps the sum only nearly
    return cv2.multiply(up, tuple(float(a / b) if b > 0 else 0.0 for a, b in zip(want, have)) + (0.0,))


def splat(source: np.ndarray, sigma_px: np.ndarray) -> np.ndarray:
    """Spread each pixel of ``source`` (h×w×3) by a Gaussian of its own std ``sigma_px`` (h×w, px):
    the widths are split between layers a factor :data:`LAYER_STEP` apart (weights linear in log σ,
    summing to 1), each layer blurred once (wide ones on a reduced copy, :func:`_blur_reduced`;
    layers no pixel reaches are skipped). Energy conserving: the sum over the image is kept."""
    top = max(SIGMA_MIN, float(sigma_px.max()))
    n = max(1, int(math.ceil(math.log(top / SIGMA_MIN, LAYER_STEP))) + 1)
    u = np.log(np.maximum(sigma_px, SIGMA_MIN) / SIGMA_MIN).astype(np.float32) * np.float32(1 / math.log(LAYER_STEP))
    lo, hi = float(u.min()), float(u.max())
    out = np.zeros_like(source)
    for j in range(n):
        if j <= lo - 1 or (j >= hi + 1 and j != n - 1):  # no pixel has weight in this layer
            continue
        wj = cv2.max(cv2.subtract(1.0, cv2.absdiff(u, float(j))), 0.0)   # max(0, 1 − |u − j|)
        if j == n - 1:
            wj[u >= j] = 1.0
        if not cv2.countNonZero(wj):
            continue
        out += _blur_reduced(cv2.multiply(source, cv2.merge([wj, wj, wj])), SIGMA_MIN * LAYER_STEP ** j)
    return out


def psf_sigma_rad(optical_depth: np.ndarray, spread: float) -> np.ndarray:
    """The PSF's angular std σ_θ = √(ρ·T) in radians, capped at :data:`SIGMA_MAX_RAD`."""
    return np.minimum(np.sqrt(np.float32(spread) * optical_depth), np.float32(SIGMA_MAX_RAD))


def reduce_points(values: np.ndarray, ys: np.ndarray, xs: np.ndarray, shape: tuple[int, int],
                  small: tuple[int, int]) -> np.ndarray:
    """A sparse image (``values`` n×3 at rows ``ys``, columns ``xs`` of an H×W image, zero elsewhere)
    area-averaged to ``small`` (w, h), as ``cv2.resize(…, INTER_AREA)`` of the full image would:
    accumulated per block when the sizes divide, else through the full image."""
    h, w = shape
    sw, sh = small
    if w % sw or h % sh:
        full = np.zeros((h, w, 3), np.float32)
        np.add.at(full, (ys, xs), values)
        return cv2.resize(full, small, interpolation=cv2.INTER_AREA)
    fx, fy = w // sw, h // sh
    out = np.zeros((sh * sw, 3), np.float64)
    np.add.at(out, (ys // fy) * sw + xs // fx, values)
    return (out / (fx * fy)).astype(np.float32).reshape(sh, sw, 3)


__all__ = ["DEFAULT_HFOV_DEG", "LEVEL_UP", "elevation_sine", "focal_px", "gaussian_by_boxes", "psf_sigma_rad",
           "reduce_points", "smooth_elevation_sine", "splat", "up_from_world_to_camera"]
