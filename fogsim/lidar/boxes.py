"""Oriented 3D boxes in the LiDAR frame and the points inside them (pure geometry, numpy).

A :class:`Box3D` is a centre (m), three unit axes (the columns of ``axes``: the box's length, width and
height directions in the LiDAR frame) and the half extents along them. A point p is inside when
|(p − centre)·axisₖ| ≤ halfₖ for k = 1, 2, 3 (the faces count as inside). :meth:`Box3D.from_yaw`
builds the usual ground-aligned box (yaw about z, z up); KITTI's camera-frame label boxes are
converted by :func:`fogsim.readers.kitti.boxes.label_box` through the frame's calibration.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Box3D", "points_in_box", "points_in_boxes"]


@dataclass(frozen=True, eq=False)
class Box3D:
    """``centre`` (3,), ``axes`` 3×3 (columns: unit length, width, height directions), ``half`` (3,) metres."""

    centre: np.ndarray
    axes: np.ndarray
    half: np.ndarray

    @classmethod
    def from_yaw(cls, centre, length: float, width: float, height: float, yaw: float) -> "Box3D":
        """A box on the ground plane: length along (cos yaw, sin yaw, 0), height along z."""
        c, s = math.cos(yaw), math.sin(yaw)
        axes = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return cls(np.asarray(centre, np.float64), axes, 0.5 * np.array([length, width, height], np.float64))

    def contains(self, xyz: np.ndarray) -> np.ndarray:
        """Boolean mask of the points (N×3) inside the box."""
        local = (np.asarray(xyz, np.float64) - self.centre) @ self.axes
        return (np.abs(local) <= self.half).all(axis=1)

    def corners(self) -> np.ndarray:
        """8×3 corner points (for pictures)."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], np.float64)
        return self.centre + (signs * self.half) @ self.axes.T


def points_in_box(xyz: np.ndarray, box: Box3D) -> int:
    """How many of the points (N×3) lie in ``box``."""
    return int(box.contains(xyz).sum())


#: the x cells (metres) points are bucketed into before each box scans its slab (int16 keys: a radix sort)
SLAB_CELL_M = 0.25


def points_in_boxes(xyz: np.ndarray, boxes: list[Box3D]) -> np.ndarray:
    """Points inside each box (M int64). The points are bucketed by x once (cells of :data:`SLAB_CELL_M`,
    int16 keys: numpy's stable sort is then a radix sort, O(N)); each box tests exactly only the points of the
    cells its bounding sphere spans in x, within its reach in y (O(N + Σ slab) instead of O(N·M))."""
    xyz = np.asarray(xyz)
    out = np.zeros(len(boxes), np.int64)
    if not len(xyz) or not boxes:
        return out
    x = xyz[:, 0]
    reach = np.array([float(np.linalg.norm(b.half)) for b in boxes])
    cx = np.array([float(b.centre[0]) for b in boxes])
    lo_m, hi_m = float((cx - reach).min()), float((cx + reach).max())
    cells = np.floor((np.clip(x, lo_m - SLAB_CELL_M, hi_m + SLAB_CELL_M) - lo_m) / SLAB_CELL_M)
    if cells.max(initial=0) < 32767:
        key = cells.astype(np.int16)
    else:  # boxes spread over more than ~8 km: plain keys
        key = cells.astype(np.int64)
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    for k, box in enumerate(boxes):
        a = np.floor((cx[k] - reach[k] - lo_m) / SLAB_CELL_M)
        b = np.floor((cx[k] + reach[k] - lo_m) / SLAB_CELL_M)
        i, j = np.searchsorted(sorted_key, [a, b], side="left")[0], np.searchsorted(sorted_key, b, side="right")
        if j > i:
            slab = xyz[order[i:j]]
            near = slab[np.abs(slab[:, 1] - box.centre[1]) <= reach[k]]  # the slab's part of the sphere's band
            out[k] = int(box.contains(near).sum()) if len(near) else 0
    return out
