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

__all__ = ["Box3D", "box_members", "points_in_box", "points_in_boxes"]


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
    """Points inside each box (M int64): the sizes of :func:`box_members`."""
    return np.array([len(m) for m in box_members(xyz, boxes)], np.int64)


def box_members(xyz: np.ndarray, boxes: list[Box3D]) -> list[np.ndarray]:
    """The rows of the points (N×3) inside each box (M int64 arrays). First the points in any box's
    bounding square are picked on a grid of :data:`GRID_CELL_M` (one lookup per point); those are bucketed by x
    (cells of :data:`SLAB_CELL_M`, int16 keys: numpy's stable sort is then a radix sort, O(N)); each box tests
    exactly only the points of the cells its bounding sphere spans in x, within its reach in y (O(N + Σ slab)
    instead of O(N·M))."""
    xyz = np.asarray(xyz)
    out = [np.zeros(0, np.int64) for _ in boxes]
    if not len(xyz) or not boxes:
        return out
    reach = np.sqrt((np.array([b.half for b in boxes], np.float64) ** 2).sum(-1))  # bounding spheres' radii
    cx = np.array([float(b.centre[0]) for b in boxes])
    cy = np.array([float(b.centre[1]) for b in boxes])
    rows = _in_squares(xyz, cx, cy, reach)
    if not len(rows):
        return out
    x = xyz[rows, 0]
    lo_m, hi_m = float((cx - reach).min()), float((cx + reach).max())
    cells = np.floor((np.clip(x, lo_m - SLAB_CELL_M, hi_m + SLAB_CELL_M) - lo_m) / SLAB_CELL_M)
    if cells.max(initial=0) < 32767:
        key = cells.astype(np.int16)
    else:  # boxes spread over more than ~8 km: plain keys
        key = cells.astype(np.int64)
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    order = rows[order]
    first = np.floor((cx - reach - lo_m) / SLAB_CELL_M)
    last = np.floor((cx + reach - lo_m) / SLAB_CELL_M)
    starts = np.searchsorted(sorted_key, first, side="left")
    ends = np.searchsorted(sorted_key, last, side="right")
    for k, box in enumerate(boxes):
        i, j = starts[k], ends[k]
        if j > i:
            got = order[i:j]
            got = got[np.abs(xyz[got, 1] - cy[k]) <= reach[k]]  # the slab's part of the sphere's band
            if len(got):
                out[k] = got[box.contains(xyz[got])].astype(np.int64)
    return out


#: the grid (metres) on which :func:`box_members` first picks the points near any box
GRID_CELL_M = 1.0
#: the most cells that grid may have (boxes spread wider: every point goes on to the x buckets)
GRID_MAX_CELLS = 1 << 22


def _in_squares(xyz: np.ndarray, cx: np.ndarray, cy: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """The rows of the points whose (x, y) lies in a grid cell that a box's bounding square (centre ± reach)
    touches: every point of every box, and few others."""
    x0, y0 = float((cx - reach).min()), float((cy - reach).min())
    nx = int((float((cx + reach).max()) - x0) // GRID_CELL_M) + 1
    ny = int((float((cy + reach).max()) - y0) // GRID_CELL_M) + 1
    if nx * ny > GRID_MAX_CELLS:
        return np.arange(len(xyz))
    occupied = np.zeros((nx, ny), bool)
    i0, i1 = ((cx - reach - x0) // GRID_CELL_M).astype(int), ((cx + reach - x0) // GRID_CELL_M).astype(int)
    j0, j1 = ((cy - reach - y0) // GRID_CELL_M).astype(int), ((cy + reach - y0) // GRID_CELL_M).astype(int)
    for a, b, c, d in zip(i0, i1, j0, j1):
        occupied[a:b + 1, c:d + 1] = True
    ix = np.floor((xyz[:, 0] - x0) / GRID_CELL_M)
    iy = np.floor((xyz[:, 1] - y0) / GRID_CELL_M)
    inside = np.flatnonzero((ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny))
    return inside[occupied[ix[inside].astype(np.intp), iy[inside].astype(np.intp)]]
