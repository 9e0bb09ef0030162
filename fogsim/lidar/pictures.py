"""Pictures of LiDAR fog (RGB uint8 arrays, :mod:`fogsim.viz` style; :func:`write_png` saves one atomically).

* :func:`bev_image` — a bird's-eye view of one level: the sensor at the centre, x (forward) up, y (left)
  to the left, rings every 10 m with their distances written on them; each input point drawn where the
  sensor reports it, coloured by outcome (:data:`OUTCOME_COLOURS`: kept green, attenuated blue, clutter
  orange — at its new range near the sensor), a lost point faint grey where it was (a no-return row too, at
  the sensor); optional 3D boxes as their footprints.
* :func:`bev_levels` — one bird's-eye view per level side by side, captioned with β and the outcome shares,
  over the legend (:data:`BEV_LEGEND`), so the picture reads alone.
* :func:`projected_image` — a level's reported points drawn on the camera image, coloured by outcome.
* :func:`points_vs_distance` — points per object (log scale) against the object's distance, one colour
  per level, the ``min_points`` line drawn.
"""
from __future__ import annotations

import math
import os

import cv2
import numpy as np

from fogsim.io.images import write_image
from fogsim.lidar.boxes import Box3D
from fogsim.lidar.fogged_scan import FoggedScan
from fogsim.lidar.objects import MIN_POINTS, distances_and_points
from fogsim.lidar.outcomes import ATTENUATED, CLUTTER, KEPT, LOST, NO_RETURN
from fogsim.lidar.points import PointCloud
from fogsim.viz import legend_row, ring_labels, strip

__all__ = ["BEV_LEGEND", "OUTCOME_COLOURS", "bev_image", "bev_levels", "points_vs_distance", "projected_image",
           "write_png"]

OUTCOME_COLOURS = {KEPT: (44, 160, 44), ATTENUATED: (31, 119, 180), LOST: (205, 205, 205), CLUTTER: (255, 127, 14),
                   NO_RETURN: (205, 205, 205)}
LEVEL_COLOURS = ((40, 40, 40), (31, 119, 180), (44, 160, 44), (255, 127, 14), (214, 39, 40), (148, 103, 189))
#: drawing order: lost (and no-return rows, which sit at the sensor) underneath, clutter on top
ORDER = (NO_RETURN, LOST, KEPT, ATTENUATED, CLUTTER)
BOX_COLOUR = (60, 60, 60)
#: what the colours of a bird's-eye view (and of the points drawn on an image) mean: :func:`fogsim.viz.legend_row`
BEV_LEGEND = [("dot", OUTCOME_COLOURS[KEPT], "kept"), ("dot", OUTCOME_COLOURS[ATTENUATED], "attenuated (weaker echo)"),
              ("dot", OUTCOME_COLOURS[CLUTTER], "fog clutter (the fog's own echo)"),
              ("dot", OUTCOME_COLOURS[LOST], "lost (where it was)"), ("box", BOX_COLOUR, "object's 3D box"),
              ("sensor", (0, 0, 0), "LiDAR; x forward up, y left, rings every 10 m")]


def _to_pixels(xyz: np.ndarray, extent_m: float, px_per_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    size = int(round(2 * extent_m * px_per_m))
    col = np.floor((extent_m - xyz[:, 1]) * px_per_m).astype(np.int64)
    row = np.floor((extent_m - xyz[:, 0]) * px_per_m).astype(np.int64)
    inside = (col >= 0) & (col < size) & (row >= 0) & (row < size)
    return row, col, inside


def bev_image(scan: PointCloud, fogged: FoggedScan | None = None, extent_m: float = 50.0, px_per_m: float = 8.0,
              boxes: list[Box3D | None] | None = None) -> np.ndarray:
    """The bird's-eye view of ``scan`` (clear: every point kept) or of its fogged level ``fogged``."""
    size = int(round(2 * extent_m * px_per_m))
    img = np.full((size, size, 3), 255, np.uint8)
    centre = (size // 2, size // 2)
    rings = list(range(10, int(extent_m) + 1, 10))
    for r in rings:
        cv2.circle(img, centre, int(r * px_per_m), (228, 228, 228), 1, cv2.LINE_AA)
    n = len(scan)
    outcome = np.full(n, KEPT, np.int8) if fogged is None else fogged.outcome
    xyz = scan.xyz.astype(np.float64)
    if fogged is not None:
        shown = fogged.output_index >= 0
        xyz = xyz.copy()
        xyz[shown] = fogged.cloud.xyz[fogged.output_index[shown]]
        extra = fogged.cloud.xyz[int(shown.sum()):].astype(np.float64)  # the empty rays' fog clutter
        if len(extra):
            xyz = np.concatenate([xyz, extra])
            outcome = np.concatenate([outcome, np.full(len(extra), CLUTTER, np.int8)])
    row, col, inside = _to_pixels(xyz, extent_m, px_per_m)
    for kind in ORDER:
        pick = inside & (outcome == kind)
        img[row[pick], col[pick]] = OUTCOME_COLOURS[kind]
    for box in boxes or []:
        if box is None:
            continue
        c = box.corners()[[0, 2, 6, 4]]  # the bottom face, in order around it
        r, k, _ = _to_pixels(c, extent_m, px_per_m)
        cv2.polylines(img, [np.stack([k, r], 1).astype(np.int32)], True, BOX_COLOUR, 1, cv2.LINE_AA)
    cv2.drawMarker(img, centre, (0, 0, 0), cv2.MARKER_TRIANGLE_UP, 10, 2)
    step = 1 if 10 * px_per_m >= 40 else 2  # every ring's distance where there is room, else every other one
    return ring_labels(img, centre, rings[step - 1::step], px_per_m)


def projected_image(image: np.ndarray, fogged: FoggedScan, intrinsics, lidar_to_camera: np.ndarray,
                    max_range_m: float = 80.0) -> np.ndarray:
    """The camera ``image`` (RGB uint8) with a level's reported points drawn where they project (one pixel
    each, coloured by outcome; OpenCV pinhole ``intrinsics``: fx, fy, cx, cy, integer = pixel centre;
    ``lidar_to_camera`` 4×4 LiDAR → camera). Points behind the camera or beyond ``max_range_m`` are left out."""
    img = image.copy()
    h, w = img.shape[:2]
    xyz = fogged.cloud.xyz.astype(np.float64)
    m = np.asarray(lidar_to_camera, np.float64)
    cam = xyz @ m[:3, :3].T + m[:3, 3]
    rows = np.flatnonzero(fogged.output_index >= 0)
    kinds = fogged.outcome[rows]
    cam = cam[fogged.output_index[rows]]
    front = (cam[:, 2] > 0.1) & (np.linalg.norm(cam, axis=1) <= max_range_m)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.round(intrinsics.fx * cam[:, 0] / cam[:, 2] + intrinsics.cx).astype(np.int64)
        v = np.round(intrinsics.fy * cam[:, 1] / cam[:, 2] + intrinsics.cy).astype(np.int64)
    ok = front & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    for kind in ORDER:
        pick = ok & (kinds == kind)
        img[v[pick], u[pick]] = OUTCOME_COLOURS[kind]
    return img


def _caption(key: str, fogged: FoggedScan | None) -> str:
    if fogged is None:
        return f"{key}"
    c, n = fogged.counts(), max(1, len(fogged.outcome))
    return f"{key}: lost {100 * c['lost'] / n:.0f}%, clutter {100 * c['clutter'] / n:.0f}%"


def bev_levels(scan: PointCloud, levels: dict[str, FoggedScan | None], width: int = 480, **kw) -> np.ndarray:
    """One :func:`bev_image` per level (None: the clear scan), side by side, captioned with the level's key
    (ASCII: OpenCV's fonts have no β) and its lost and clutter shares, over the legend."""
    if "px_per_m" not in kw:  # drawn at the size shown (its labels readable), not shrunk
        kw["px_per_m"] = width / (2 * kw.get("extent_m", 50.0))
    images = [bev_image(scan, f, **kw) for f in levels.values()]
    row = strip(images, [_caption(k, f) for k, f in levels.items()], width=width)
    return np.vstack([row, legend_row(BEV_LEGEND, row.shape[1])])


def points_vs_distance(records: list[dict], levels: list[str], min_points: int = MIN_POINTS,
                       size: tuple[int, int] = (640, 400), max_distance_m: float | None = None) -> np.ndarray:
    """Points per object (log₁₀(1 + n)) against distance, one colour per level, with a legend."""
    w, h = size
    left, right, top, bottom = 56, 16, 16, 40
    img = np.full((h, w, 3), 255, np.uint8)
    data = {lv: distances_and_points(records, lv) for lv in levels}
    dmax = max_distance_m or max([float(d.max()) for d, _ in data.values() if len(d)] + [10.0])
    nmax = max([int(n.max()) for _, n in data.values() if len(n)] + [min_points * 10])
    ymax = math.log10(1 + nmax)

    def xy(d, n):
        x = left + (np.asarray(d) / dmax) * (w - left - right)
        y = h - bottom - (np.log10(1 + np.asarray(n, np.float64)) / ymax) * (h - top - bottom)
        return x.astype(np.int32), y.astype(np.int32)
    cv2.rectangle(img, (left, top), (w - right, h - bottom), (0, 0, 0), 1)
    for d in np.arange(0, dmax + 1e-9, 10 if dmax <= 100 else 20):
        x, _ = xy(d, 0)
        cv2.line(img, (int(x), h - bottom), (int(x), h - bottom + 4), (0, 0, 0), 1)
        cv2.putText(img, f"{d:g}", (int(x) - 8, h - bottom + 16), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (0, 0, 0), 1)
    for n in (0, 1, 10, 100, 1000, 10000):
        if n <= nmax:
            _, y = xy(0, n)
            cv2.putText(img, str(n), (8, int(y) + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (0, 0, 0), 1)
    _, yline = xy(0, min_points)
    cv2.line(img, (left, int(yline)), (w - right, int(yline)), (160, 160, 160), 1, cv2.LINE_AA)
    cv2.putText(img, "distance (m)", (w // 2 - 40, h - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
    cv2.putText(img, "points", (4, top + 10), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
    for k, lv in enumerate(levels):
        colour = LEVEL_COLOURS[k % len(LEVEL_COLOURS)]
        d, n = data[lv]
        xs, ys = xy(d, n)
        for x, y in zip(xs, ys):
            cv2.circle(img, (int(x) + k, int(y)), 3, colour, -1, cv2.LINE_AA)
        cv2.putText(img, lv, (w - right - 120, top + 16 + 14 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.4, colour, 1)
    return img


def write_png(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write a picture as PNG, atomically."""
    write_image(path, image)
