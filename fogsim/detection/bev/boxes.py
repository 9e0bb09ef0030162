"""Rotated boxes on the bird's-eye-view grid: a 3D label's footprint, its oriented-box (OBB) label line,
and the rotated IoU that scores a detection.

A footprint is the box's four ground corners (LiDAR frame, metres, 4×2), in order around the rectangle:
centre ± l/2 along the length axis ± w/2 along the width axis, the axes' x–y components (a KITTI box's
axes come through R0_rect and Tr_velo_to_cam, so they may tilt by a fraction of a degree: the footprint is
the box seen from above). Ultralytics' OBB label is ``class x1 y1 x2 y2 x3 y3 x4 y4`` with the corners in
image coordinates normalised to 0–1 (:meth:`~fogsim.detection.bev.grid.BevGrid.to_pixels` / width,
height); Ultralytics refuses coordinates outside 0–1, so a box over the grid's edge is written with its
corners clipped to it (training labels only: scores use the whole footprint).

The rotated IoU is the overlap of two convex quadrilaterals — one clipped by the other's edges
(Sutherland–Hodgman, float64) — over the union of their areas. Not OpenCV's ``intersectConvexConvex``: in
float32 it returns 0 or a fraction for boxes that (nearly) coincide — about 1 pair in 20 of boxes a
micrometre apart, 1 in 250 of boxes 0.05° apart — which would score the best detections as misses.
"""
from __future__ import annotations

import numpy as np

from fogsim.detection.bev.grid import BevGrid
from fogsim.lidar.boxes import Box3D


def footprint(box: Box3D) -> np.ndarray:
    """The 4×2 ground corners (x, y) of a LiDAR-frame box (the module docstring)."""
    c = np.asarray(box.centre, np.float64)[:2]
    a_len, a_wid = np.asarray(box.axes, np.float64)[:2, 0], np.asarray(box.axes, np.float64)[:2, 1]
    hl, hw = float(box.half[0]), float(box.half[1])
    return np.array([c + hl * a_len + hw * a_wid, c - hl * a_len + hw * a_wid,
                     c - hl * a_len - hw * a_wid, c + hl * a_len - hw * a_wid])


def yaw_box(x: float, y: float, length: float, width: float, yaw: float) -> np.ndarray:
    """The footprint of a box centred at (x, y) with its length along (cos yaw, sin yaw)."""
    return footprint(Box3D.from_yaw((x, y, 0.0), length, width, 1.0, yaw))


def obb_line(class_id: int, corners_xy: np.ndarray, grid: BevGrid) -> str:
    """Ultralytics' OBB label line of a footprint (clipped to the grid, normalised to 0–1)."""
    uv = grid.to_pixels(corners_xy)
    norm = np.clip(uv / [grid.width, grid.height], 0.0, 1.0)
    return f"{int(class_id)} " + " ".join(f"{v:.6f}" for v in norm.ravel())


def area(corners: np.ndarray) -> float:
    """The area of a polygon (shoelace)."""
    return abs(_signed_area(np.asarray(corners, np.float64).reshape(-1, 2)))


def _signed_area(corners: np.ndarray) -> float:
    x, y = corners.T
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _ccw(corners: np.ndarray) -> np.ndarray:
    """The corners (float64) in counter-clockwise order."""
    corners = np.asarray(corners, np.float64).reshape(-1, 2)
    return corners if _signed_area(corners) >= 0 else corners[::-1]


def intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The polygon where two convex polygons overlap (k×2, k = 0 when they do not): ``a`` clipped by each
    of ``b``'s edges in turn, points on an edge kept (so coinciding boxes give the box itself)."""
    poly, clipper = _ccw(a), _ccw(b)
    for p, q in zip(clipper, np.roll(clipper, -1, axis=0)):
        if len(poly) == 0:
            break
        edge = q - p
        side = edge[0] * (poly[:, 1] - p[1]) - edge[1] * (poly[:, 0] - p[0])  # ≥ 0: left of the edge, inside
        out = []
        for i in range(len(poly)):
            j = (i + 1) % len(poly)
            if side[i] >= 0:
                out.append(poly[i])
            if (side[i] >= 0) != (side[j] >= 0):
                out.append(poly[i] + side[i] / (side[i] - side[j]) * (poly[j] - poly[i]))
        poly = np.array(out).reshape(-1, 2)
    return poly


def rotated_iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two footprints (4×2 each, any units)."""
    inter = intersection(a, b)
    overlap = area(inter) if len(inter) >= 3 else 0.0
    union = area(a) + area(b) - overlap
    return min(1.0, overlap / union) if union > 0 else 0.0


def iou_matrix(dets: list[np.ndarray], gts: list[np.ndarray]) -> np.ndarray:
    """Rotated IoU of every detection footprint with every ground-truth footprint (n × m). Pairs whose
    bounding circles do not touch are 0 without a polygon test."""
    out = np.zeros((len(dets), len(gts)))
    if not dets or not gts:
        return out
    dc = np.array([d.mean(0) for d in dets])
    gc = np.array([g.mean(0) for g in gts])
    dr = np.array([np.linalg.norm(d - d.mean(0), axis=1).max() for d in dets])
    gr = np.array([np.linalg.norm(g - g.mean(0), axis=1).max() for g in gts])
    near = np.linalg.norm(dc[:, None] - gc[None], axis=2) <= dr[:, None] + gr[None]
    for i, j in zip(*np.nonzero(near)):
        out[i, j] = rotated_iou(dets[i], gts[j])
    return out
