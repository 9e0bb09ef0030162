"""KITTI label boxes (rectified camera frame) as :class:`fogsim.lidar.boxes.Box3D` in the LiDAR frame.

A label's box: bottom centre ``location_m`` (x right, y down, z forward), ``dimensions_m`` h w l,
``rotation_y`` about the camera's y axis; in the object's own frame the length runs along x, the width
along z, the height from 0 up to −h along y (KITTI's devkit corners), rotated by R_y(ry): the length
axis is (cos ry, 0, −sin ry). The centre and the three axes go through the calibration's
rectified → LiDAR transform (:meth:`~.calib.KittiCalib.rect_to_velo`), exactly, tilt included.
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.lidar.boxes import Box3D
from fogsim.readers.kitti.calib import KittiCalib

__all__ = ["label_box", "label_boxes"]


def label_box(record: dict, calib: KittiCalib) -> Box3D:
    """The LiDAR-frame box of one label record (:func:`fogsim.readers.kitti.labels.label_records`)."""
    h, w, length = record["dimensions_m"]
    ry = record["rotation_y"]
    centre_rect = np.asarray(record["location_m"], np.float64) - [0.0, h / 2.0, 0.0]
    axes_rect = np.array([[math.cos(ry), 0.0, -math.sin(ry)],   # length
                          [math.sin(ry), 0.0, math.cos(ry)],    # width
                          [0.0, -1.0, 0.0]]).T                   # height (up)
    m = calib.rect_to_velo
    axes = m[:3, :3] @ axes_rect
    axes /= np.linalg.norm(axes, axis=0)
    return Box3D(calib.velo_from_rect(centre_rect)[0], axes, 0.5 * np.array([length, w, h], np.float64))


def label_boxes(records: list[dict], calib: KittiCalib) -> list[Box3D | None]:
    """A box per record; None for ignore regions (DontCare, unlabelled types) and records without 3D fields."""
    out = []
    for rec in records:
        ok = rec.get("kept", True) and "dimensions_m" in rec and min(rec["dimensions_m"]) > 0
        out.append(label_box(rec, calib) if ok else None)
    return out
