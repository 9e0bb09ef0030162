"""Where a rendered frame's LiDAR is: its pose from the camera's, the ego vehicle's frame between them.

The **ego frame** of a frame is level and follows the camera's heading: origin on the ground below the
camera's centre (world z = 0: the procedural streets' ground), x the camera's viewing direction projected
on the ground, y to its left, z up (metres). A sensor's ``mount`` (:class:`~fogsim.schema.lidar.Mount`,
e.g. KITTI's HDL-64E 1.73 m above the ground) places it in that frame: LiDAR → world =
ego → world · mount. In a user's scene, whose ground is not known, the LiDAR is an object marked with the
custom property ``fogsim_lidar`` (its own axes: x forward, y left, z up; scale ignored) or else the
camera's centre plus :data:`KITTI_CAMERA_OFFSET` in the level axes (KITTI's LiDAR sits 0.27 m behind and
0.08 m above its camera). Every matrix is 4×4, rigid, float64; ``world_to_camera`` is OpenCV's (x right,
y down, z forward).
"""
from __future__ import annotations

import numpy as np

#: KITTI's LiDAR relative to its left colour camera, in the level ego axes (x forward, y left, z up), metres
KITTI_CAMERA_OFFSET = (-0.27, 0.0, 0.08)
#: the custom property that marks a user's object as the LiDAR (scene mode)
LIDAR_PROPERTY = "fogsim_lidar"


def level_axes(world_to_camera) -> tuple[np.ndarray, np.ndarray]:
    """(the camera's centre in the world, 3×3 whose columns are the level axes forward, left, up)."""
    w2c = np.asarray(world_to_camera, np.float64)
    c2w = np.linalg.inv(w2c)
    forward = c2w[:3, 2].copy()
    forward[2] = 0.0
    if np.linalg.norm(forward) < 1e-6:  # looking straight down or up: the image's up direction leads
        forward = -c2w[:3, 1].copy()
        forward[2] = 0.0
    forward /= np.linalg.norm(forward)
    up = np.array([0.0, 0.0, 1.0])
    return c2w[:3, 3], np.stack([forward, np.cross(up, forward), up], axis=1)


def rigid(rotation: np.ndarray, origin) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rotation, origin
    return m


def ego_to_world(world_to_camera) -> np.ndarray:
    """The ego frame (the module docstring) → world."""
    centre, axes = level_axes(world_to_camera)
    return rigid(axes, [centre[0], centre[1], 0.0])


def mounted_pose(world_to_camera, mount_pose: np.ndarray) -> np.ndarray:
    """LiDAR → world of a sensor mounted on the ego vehicle (``mount_pose``: sensor → ego)."""
    return ego_to_world(world_to_camera) @ np.asarray(mount_pose, np.float64)


def camera_offset_pose(world_to_camera, offset=KITTI_CAMERA_OFFSET) -> np.ndarray:
    """LiDAR → world at the camera's centre plus ``offset`` (forward, left, up metres), level axes."""
    centre, axes = level_axes(world_to_camera)
    return rigid(axes, centre + axes @ np.asarray(offset, np.float64))


def object_pose(matrix_world) -> np.ndarray:
    """LiDAR → world of a marked object: its world matrix with the scale taken out (x forward, y left, z up)."""
    m = np.asarray(matrix_world, np.float64)
    u, _, vt = np.linalg.svd(m[:3, :3])
    r = u @ vt
    if np.linalg.det(r) < 0:  # a mirrored object: keep a right-handed frame
        r[:, 2] *= -1
    return rigid(r, m[:3, 3])


def lidar_to_camera(world_to_camera, lidar_to_world) -> np.ndarray:
    """LiDAR → OpenCV camera frame (KITTI's Tr_velo_to_cam with R0_rect = I)."""
    return np.asarray(world_to_camera, np.float64) @ np.asarray(lidar_to_world, np.float64)
