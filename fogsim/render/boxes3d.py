"""Oriented 3D boxes of a frame's labelled objects, from the meshes the renderer drew.

An object's box is the tight box of all its triangles (a labelled parent: the union of its meshes) in
its own upright frame: its origin and heading from the object's transform, the vertical world z. The
heading is the object's forward axis — procedural assets face their local +y (:mod:`fogsim.scene`);
a user's object (scene mode, ``forward="auto"``) faces along its longer horizontal local axis, −y when
that is y (Blender's front view looks along +y at an object's −y face), +x when it is x. The box is a
:class:`fogsim.lidar.boxes.Box3D` (centre, unit axes length/width/height, half extents) in the world,
then in the LiDAR frame (yaw about z) and in the camera frame as KITTI writes it (OpenCV axes x right, y
down, z forward): bottom centre ``location_m``, ``dimensions_hwl_m`` (height, width, length),
``rotation_y`` about the camera's y (the length axis is (cos ry, 0, −sin ry)) and the observation angle
``alpha`` = ry − atan2(x, z), both in (−π, π]. A camera that is pitched or rolled tilts the box out of
KITTI's yaw-only form: ``rotation_y`` is then the heading's projection on the camera's x–z plane.
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.lidar.boxes import Box3D


def _wrap(a: float) -> float:
    return float(math.atan2(math.sin(a), math.cos(a)))


def object_box(parts, transform, forward: str = "+y") -> Box3D | None:
    """The world box of an object's ``parts`` ((vertices N×3, faces, slot) world metres) in the upright
    frame of ``transform`` (4×4 object → world; its scale is ignored). None without vertices."""
    verts = [np.asarray(v, np.float64) for v, *_ in parts if len(v)]
    if not verts:
        return None
    v = np.concatenate(verts)
    m = np.asarray(transform, np.float64)
    x_axis, y_axis = m[:3, 0], m[:3, 1]
    if forward == "auto":
        extent_x, extent_y = (np.ptp((v - m[:3, 3]) @ (a / np.linalg.norm(a))) for a in (x_axis, y_axis))
        head = -y_axis if extent_y >= extent_x else x_axis
    else:
        head = {"+y": y_axis, "-y": -y_axis, "+x": x_axis, "-x": -x_axis}[forward]
    length = np.array([head[0], head[1], 0.0])
    if np.linalg.norm(length) < 1e-9:  # an object lying on its front: keep the world x as its heading
        length = np.array([1.0, 0.0, 0.0])
    length /= np.linalg.norm(length)
    up = np.array([0.0, 0.0, 1.0])
    axes = np.stack([length, np.cross(up, length), up], axis=1)
    local = (v - m[:3, 3]) @ axes
    lo, hi = local.min(axis=0), local.max(axis=0)
    return Box3D(m[:3, 3] + axes @ ((lo + hi) / 2), axes, (hi - lo) / 2)


def transformed(box: Box3D, world_to_frame) -> Box3D:
    """The box in another frame (``world_to_frame``: 4×4 rigid)."""
    m = np.asarray(world_to_frame, np.float64)
    return Box3D(m[:3, :3] @ box.centre + m[:3, 3], m[:3, :3] @ box.axes, box.half)


def box_record(box: Box3D, world_to_camera, world_to_lidar=None) -> dict:
    """The object record's ``box3d``: the box in the world, the camera frame as KITTI writes it, and the
    LiDAR frame (when there is one) — see the module docstring."""
    cam = transformed(box, world_to_camera)
    size = (2 * box.half).tolist()  # length, width, height
    bottom = cam.centre - cam.axes[:, 2] * box.half[2]  # half a height below the centre, along the box's up
    a = cam.axes[:, 0]
    ry = _wrap(math.atan2(-a[2], a[0]))
    out = {"world": {"centre_m": box.centre.tolist(), "size_lwh_m": size,
                     "yaw": _wrap(math.atan2(box.axes[1, 0], box.axes[0, 0]))},
           "camera": {"location_m": bottom.tolist(), "dimensions_hwl_m": [size[2], size[1], size[0]],
                      "rotation_y": ry, "alpha": _wrap(ry - math.atan2(bottom[0], bottom[2]))},
           "convention": "world and lidar: centre, size (length, width, height), yaw about z; camera: KITTI "
                         "(bottom centre, h w l, rotation_y about the camera's y, alpha)"}
    if world_to_lidar is not None:
        lid = transformed(box, world_to_lidar)
        out["lidar"] = {"centre_m": lid.centre.tolist(), "size_lwh_m": size,
                        "yaw": _wrap(math.atan2(lid.axes[1, 0], lid.axes[0, 0]))}
    return out
