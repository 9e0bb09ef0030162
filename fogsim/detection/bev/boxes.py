"""Rotated boxes on the bird's-eye-view grid: a 3D label's footprint, its oriented-box (OBB) label line,
and the rotated IoU that scores a detection.

A footprint is the box's four ground corners (LiDAR frame, metres, 4×2), in order around the rectangle:
centre ± l/2 along the length axis ± w/2 along the width axis, the axes' x–y components (a KITTI box's
axes come through R0_rect and Tr_velo_to_cam, so they may tilt by a fraction of a degree: the footprint is
the box seen from above). Ultralytics' OBB label is ``class x1 y1 x2 y2 x3 y3 x4 y4`` with the corners in
image coordinates normalised to 0–1 (:meth:`~fogsim.detection.bev.grid.BevGrid.to_pixels` / width,
height); Ultralytics refuses coordinates outside 0–1, so a box over the grid's edge is written with its
corners clipped to it (training labels only: scores use the whole footprint).

The rotated IoU is the overlap of two convex quadrilaterals by OpenCV's ``intersectConvexConvex``
(float32), over the union of their areas.
"""
from __future__ import annotations

import cv2
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
    """The area of a quadrilateral (shoelace)."""
    x, y = np.asarray(corners, np.float64).T
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _convex(corners: np.ndarray) -> np.ndarray:
    """The corners as a float32 convex polygon in counter-clockwise order (what OpenCV wants)."""
    return cv2.convexHull(np.asarray(corners, np.float32).reshape(-1, 1, 2), clockwise=False)


def rotated_iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two footprints (4×2 each, any units)."""
    pa, pb = _convex(a), _convex(b)
    inter, _ = cv2.intersectConvexConvex(pa, pb)
    inter = max(0.0, float(inter))
    union = area(a) + area(b) - inter
    return inter / union if union > 0 else 0.0


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
