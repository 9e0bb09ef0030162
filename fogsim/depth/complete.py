"""Dense ray distance from sparse LiDAR points (Waymo TOP lidar projected into a camera).

Conventions: every map here is **ray distance** in metres from the camera centre (what
Waymo's ``camera_projection`` + ``‖p_cam‖`` gives, and what the fog model needs; no
planar→ray step), H×W float32; in a *sparse* map 0 = no point; in a *dense* map every pixel
is > 0, +inf = "sky / beyond the LiDAR". Points are ``uv`` N×2 float pixel coordinates
(integer = pixel centre, ``docs/conventions.md``) and ``ray`` N float metres.

Completion methods (:data:`METHODS`):

* ``ipbasic`` (default) — IP-Basic-style morphology on *inverse* distance (linear in the
  image on planes): growing dilations copy the **nearest** neighbouring return into each
  empty pixel (Ku et al. 2018: near wins, which also hides far points that bleed through
  near edges by parallax), a median blur of the filled pixels, then a Gaussian smoothing of
  the filled pixels only (σ ≈ the beam spacing) that turns the beam-row staircase into a ramp.
  The LiDAR returns themselves are kept exactly.
* ``linear`` — beam-aware: each return is spread along its row (near wins) to a line, then
  every pixel interpolates inverse distance linearly in its column between the lines above
  and below (exact on planes); across a depth edge (the two differ by > 25 %) it takes the
  one nearer in the image instead of mixing them. On the synthetic FRONT frame of
  ``fogsim bench lidar`` it has about half the AbsRel of ``ipbasic``.
* ``ila`` — an ILA prediction (``fogsim.depth.ila``, planar → ray with the camera) aligned to
  the points by a per-image least-squares scale and shift on inverse distance
  (1/ℓ_lidar ≈ a·1/ℓ_ila + b), then the points override it at their pixels. ILA supplies the
  upper image and the far range the LiDAR cannot see; no sky rule is applied.

Sky rule (``sky="above"``, the default for ``ipbasic``): the TOP lidar's highest beam
(+2.5°) lands near row 575 of the 1280-row FRONT image, so the upper ≈ 45 % has no return
(``docs/real-data.md``). A pixel becomes +inf when it lies **above the coverage envelope**
(above the highest point within ±``gap_px`` columns) **and** farther than ``gap_px`` pixels
from every point (default 24 px ≈ two beam rows at f ≈ 2044 px). Inside the envelope every
hole is filled (a dark car without returns must not become sky), and just above it the top
returns are extended by up to ``gap_px``. ``sky="extend"`` instead fills everything: each
column's topmost value is copied up to row 0 (IP-Basic's own choice; it keeps tall buildings
but leaves the sky at a finite distance, i.e. partly unfogged).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np

from fogsim.camera import pixel_index, sparse_image  # noqa: F401  (re-exported)

METHODS = ("ipbasic", "linear", "ila")
DEFAULT_METHOD = "ipbasic"
SKY_RULES = ("above", "extend")
DEFAULT_GAP_PX = 24


def holdout_split(n_points: int, fraction: float = 0.1, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Indices (used, held_out) of ``n_points`` points, both sorted int64, disjoint, covering all.

    Deterministic: ``round(fraction · n)`` points chosen by ``numpy.random.default_rng(seed)``
    (a permutation). ``fraction`` in [0, 1); 0 holds nothing out.
    """
    if not 0 <= fraction < 1:
        raise ValueError(f"the LiDAR hold-out fraction must be in [0, 1), got {fraction}")
    if n_points < 0:
        raise ValueError(f"n_points must be ≥ 0, got {n_points}")
    n_held = int(round(fraction * n_points))
    if n_held == 0:
        return np.arange(n_points, dtype=np.int64), np.zeros(0, np.int64)
    perm = np.random.default_rng(seed).permutation(n_points)
    return np.sort(perm[n_held:]).astype(np.int64), np.sort(perm[:n_held]).astype(np.int64)


@dataclass
class Completion:
    """A dense ray-distance map (H×W float32, > 0, +inf = sky / beyond LiDAR) and its record:
    ``method``, ``sky`` rule, ``points`` (pixels with a return), ``coverage`` (their fraction
    of the image), ``sky_fraction`` (pixels set to +inf), ``seconds``, and the method's own
    numbers (ILA: the fitted ``scale``/``shift`` on inverse distance and its residual)."""

    ray: np.ndarray
    record: dict


def complete(sparse_ray: np.ndarray, method: str = DEFAULT_METHOD, sky: str = "above", gap_px: int = DEFAULT_GAP_PX,
             image: np.ndarray | None = None, checkpoint: str | None = None, camera=None) -> Completion:
    """Complete a sparse ray-distance map (0 = no point) into a dense one (see the module doc).

    ``method="ila"`` needs ``image`` (RGB uint8), ``checkpoint`` and ``camera``
    (:class:`fogsim.camera.Intrinsics`, scaled to the image when its size differs).
    Raises ``ValueError`` for an unknown method/sky rule or a map without any point.
    """
    if method not in METHODS:
        raise ValueError(f"unknown LiDAR completion method {method!r} (known: {', '.join(METHODS)})")
    if sky not in SKY_RULES:
        raise ValueError(f"unknown sky rule {sky!r} (known: {', '.join(SKY_RULES)})")
    t0 = time.perf_counter()
    sparse = np.asarray(sparse_ray, np.float32)
    points = np.isfinite(sparse) & (sparse > 0)
    n = int(points.sum())
    if n == 0:
        raise ValueError("no LiDAR point falls in the image: nothing to complete from")
    if method == "ila":
        dense, extra = _complete_ila(sparse, points, image, checkpoint, camera)
        sky = "ila"
    elif method == "linear":
        dense, extra = _complete_linear(sparse, points, sky, gap_px)
    else:
        dense, extra = _complete_ipbasic(sparse, points, sky, gap_px)
    record = {"method": method, "sky": sky, "gap_px": gap_px if method != "ila" else None,
              "points": n, "coverage": round(n / points.size, 6),
              "sky_fraction": round(float(np.isinf(dense).mean()), 6), **extra,
              "seconds": round(time.perf_counter() - t0, 4)}
    return Completion(dense, record)


# ----------------------------------------------------------------------------- classical
def sky_mask(points: np.ndarray, gap_px: int = DEFAULT_GAP_PX) -> np.ndarray:
    """True where the sky rule sets +inf: above the coverage envelope (the highest point row
    within ±``gap_px`` columns; a column band without points is above it everywhere) and
    more than ``gap_px`` pixels from every point (Euclidean)."""
    h, w = points.shape
    has = points.any(axis=0)
    top = np.where(has, points.argmax(axis=0), h).astype(np.float32)  # first row with a point
    k = 2 * int(gap_px) + 1
    top = cv2.erode(top[None, :], np.ones((1, k), np.uint8), borderType=cv2.BORDER_REPLICATE)[0]
    above = np.arange(h, dtype=np.float32)[:, None] < top[None, :]
    dist = cv2.distanceTransform((~points).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return above & (dist > gap_px)


def _grow_nearest(inv: np.ndarray, todo: np.ndarray) -> np.ndarray:
    """Fill ``todo`` pixels of inverse distance ``inv`` (0 = empty) with the largest (nearest)
    value of growing neighbourhoods: ellipses 5 and 11 px, then (fast, separable) squares 23, 47, …"""
    work = inv.copy()
    todo = todo & (work == 0)
    size = 5
    while todo.any():
        shape = cv2.MORPH_ELLIPSE if size <= 11 else cv2.MORPH_RECT  # rectangles: separable, fast
        grown = cv2.dilate(work, cv2.getStructuringElement(shape, (size, size)), borderType=cv2.BORDER_REPLICATE)
        take = todo & (grown > 0)
        work[take] = grown[take]
        todo &= ~take
        if size > 2 * max(inv.shape):
            break
        size = size * 2 + 1
    return work


def _complete_ipbasic(sparse: np.ndarray, points: np.ndarray, sky: str, gap_px: int) -> tuple[np.ndarray, dict]:
    h, w = sparse.shape
    inv = np.zeros((h, w), np.float32)
    inv[points] = 1.0 / sparse[points]
    skym = sky_mask(points, gap_px) if sky == "above" else np.zeros((h, w), bool)
    empty = ~points & ~skym
    if sky == "extend":
        # only the rows down to each column's top point come from the growing fill; above,
        # the column's top value is copied upwards after it
        has = points.any(axis=0)
        top = np.where(has, points.argmax(axis=0), 0)
        above = np.arange(h)[:, None] < top[None, :]
        filled = _grow_nearest(inv, empty & ~above)
    else:
        filled = _grow_nearest(inv, empty)
    # median blur, then a normalised Gaussian over the non-sky pixels: filled pixels only
    med = cv2.medianBlur(filled, 5)
    filled = np.where(empty & (med > 0), med, filled)
    weight = (filled > 0).astype(np.float32)
    sigma = 5.0
    num = cv2.GaussianBlur(filled * weight, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
    den = cv2.GaussianBlur(weight, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
    smooth = np.divide(num, den, out=np.zeros_like(num), where=den > 1e-6)
    filled = np.where(empty & (filled > 0) & (smooth > 0), smooth, filled)
    if sky == "extend":
        top_val = filled[np.clip(top, 0, h - 1), np.arange(w)]
        filled = np.where(above, top_val[None, :], filled)
        rest = filled == 0  # columns without any point: the growing fill over the whole image
        if rest.any():
            filled = _grow_nearest(filled, rest)
    with np.errstate(divide="ignore"):
        dense = np.where(filled > 0, 1.0 / np.maximum(filled, 1e-30), np.inf).astype(np.float32)
    dense[points] = sparse[points]
    return dense, {}


def _complete_linear(sparse: np.ndarray, points: np.ndarray, sky: str, gap_px: int,
                     col_px: int = 5, edge_ratio: float = 1.25) -> tuple[np.ndarray, dict]:
    """Beam-aware interpolation of inverse distance: each return is first spread along its
    row to the nearest (near-wins) empty pixels within ``col_px`` (a beam becomes a line),
    then every pixel interpolates linearly in its column between the filled pixels above and
    below — exact on planes, where inverse distance is linear in the row. Where the two differ
    by more than ``edge_ratio`` (a depth edge) the pixel takes the one nearer in the image
    instead of mixing them. Above the top (below the bottom) value of a column it is copied."""
    h, w = sparse.shape
    inv = np.zeros((h, w), np.float32)
    inv[points] = 1.0 / sparse[points]
    line = cv2.dilate(inv, np.ones((1, 2 * col_px + 1), np.uint8), borderType=cv2.BORDER_REPLICATE)
    inv = np.where(points, inv, line)
    valid = inv > 0
    rows = np.arange(h, dtype=np.int32)[:, None]
    prev = np.maximum.accumulate(np.where(valid, rows, -1), axis=0)
    nxt = np.minimum.accumulate(np.where(valid, rows, h)[::-1], axis=0)[::-1]
    vp = np.take_along_axis(inv, np.clip(prev, 0, h - 1), axis=0)
    vn = np.take_along_axis(inv, np.clip(nxt, 0, h - 1), axis=0)
    vp = np.where(prev >= 0, vp, vn)  # above the top: copy the top value
    vn = np.where(nxt < h, vn, vp)    # below the bottom: copy the bottom value
    span = np.maximum(nxt - prev, 1).astype(np.float32)
    t = np.clip((rows - prev) / span, 0, 1).astype(np.float32)
    lin = vp + t * (vn - vp)
    edge = np.maximum(vp, vn) > edge_ratio * np.minimum(vp, vn)
    out = np.where(edge, np.where(t < 0.5, vp, vn), lin)
    out = np.where(valid, inv, out)
    if not valid.any(axis=0).all():  # columns without a return: their neighbours' values
        out = _grow_nearest(out, out == 0)
    if sky == "above":
        out[sky_mask(points, gap_px)] = 0
    with np.errstate(divide="ignore"):
        dense = np.where(out > 0, 1.0 / np.maximum(out, 1e-30), np.inf).astype(np.float32)
    dense[points] = sparse[points]
    return dense, {}


# ----------------------------------------------------------------------------- ILA, aligned
def align_inverse(pred_ray: np.ndarray, sparse: np.ndarray, points: np.ndarray) -> tuple[float, float, float]:
    """Least-squares (scale a, shift b) with 1/ℓ_lidar ≈ a·(1/ℓ_pred) + b over the LiDAR pixels,
    and the RMS residual in 1/m. Falls back to a pure scale (b = 0) when the fit is degenerate
    (a ≤ 0, e.g. every point at one distance)."""
    x = 1.0 / pred_ray[points].astype(np.float64)
    y = 1.0 / sparse[points].astype(np.float64)
    ok = np.isfinite(x) & (x > 0)
    x, y = x[ok], y[ok]
    if len(x) == 0:
        raise ValueError("the prediction has no finite distance at any LiDAR point")
    A = np.stack([x, np.ones_like(x)], 1)
    (a, b), *_ = np.linalg.lstsq(A, y, rcond=None)
    if not (np.isfinite(a) and a > 0):
        a, b = float(np.dot(x, y) / np.dot(x, x)), 0.0
    residual = float(np.sqrt(np.mean((a * x + b - y) ** 2)))
    return float(a), float(b), residual


def _complete_ila(sparse, points, image, checkpoint, camera) -> tuple[np.ndarray, dict]:
    if image is None or checkpoint is None or camera is None:
        raise ValueError("LiDAR completion with ILA needs the image, the checkpoint and the camera intrinsics")
    from fogsim.camera import planar_to_ray
    from fogsim.depth.ila import cached_model, predict_depth

    h, w = sparse.shape
    K = camera if (camera.width, camera.height) == (w, h) else camera.scaled(w, h)
    model, config, cam = cached_model(checkpoint)
    pred = planar_to_ray(predict_depth(model, config, cam, image), K)
    a, b, residual = align_inverse(pred, sparse, points)
    inv = a / pred.astype(np.float64) + b
    with np.errstate(divide="ignore"):
        dense = np.where(inv > 0, 1.0 / np.maximum(inv, 1e-30), np.inf).astype(np.float32)
    dense[points] = sparse[points]
    return dense, {"checkpoint": checkpoint, "scale": round(a, 6), "shift_per_m": round(b, 8),
                   "residual_per_m": round(residual, 8)}
