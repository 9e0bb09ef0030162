"""Waymo LiDAR geometry: range image → vehicle-frame points → per-camera ray distances.

The geometry is that of WOD ``utils/range_image_utils.py`` / ``frame_utils.py``:

* **Rows → inclination.** ``beam_inclinations`` when given, else uniform
  ``incl_k = min + (k + 0.5)/H · (max − min)``; then reversed, so row 0 is the highest beam.
* **Columns → azimuth.** ``az_j = ((W − j − 0.5)/W · 2 − 1)·π − atan2(E[1,0], E[0,0])`` with E
  the lidar→vehicle extrinsic: column 0 looks backwards (≈ +π), the middle column along
  vehicle +x, whatever the lidar's mounting yaw.
* **Point.** ``r`` = range image channel 0 (metres from the lidar origin along the beam);
  ``p_lidar = r·(cos az cos incl, sin az cos incl, sin incl)``; ``p_vehicle = E·p_lidar``.
* **Rolling-sweep compensation** (TOP only: the one lidar with a per-cell pose range image,
  channels roll, pitch, yaw, x, y, z vehicle→world, ``R = Rz(yaw)·Ry(pitch)·Rx(roll)``):
  ``p = inv(frame pose) · cell pose · p_vehicle``, i.e. into the vehicle frame of the frame's
  pose. The second return uses the first return's pose.
* **Valid cells** for a camera: ``range > 0`` and a camera projection naming that camera
  (channel 0, pixel ``(ch1, ch2)``; else channel 3, pixel ``(ch4, ch5)``).
* **Ray distance** = ``‖inv(E_cam)·p_vehicle‖`` = ``‖p_vehicle − t_cam‖``: the Euclidean distance
  from the *camera centre* (E_cam camera→vehicle), which is fogsim's ray distance
  (``DepthSpec.kind = "ray"``), not the distance from the vehicle origin.

Pixel coordinates are Waymo's: the integer projection ``(x, y)`` with 0 at the *left/top edge*
of the first pixel, so the point lies in pixel ``[row = int(y), col = int(x)]``.

Not modelled: the camera's own pose/rolling shutter (``inv(image.pose)·frame.pose``, ≈ v·50 ms
of ego motion) — the points are in the frame's vehicle frame, as WOD's
``build_camera_depth_image`` uses them.
"""
from __future__ import annotations

from typing import Iterable, NamedTuple

import cv2
import numpy as np

from fogsim.camera import sparse_image
from fogsim.errors import InputError
from fogsim.readers.waymo.lidar_frame import LaserCalibration, LidarFrame, require_lidar
from fogsim.readers.waymo.sensors import CAMERA_BY_ID, camera_ids, laser_name


def beam_inclinations(calibration: LaserCalibration, height: int) -> np.ndarray:
    """Inclination (radians) of each range-image row, row 0 the highest beam (float64, H)."""
    if calibration.beam_inclinations is not None and len(calibration.beam_inclinations):
        incl = np.asarray(calibration.beam_inclinations, np.float64)
        if incl.size != height:
            raise ValueError(f"{laser_name(calibration.laser)} has {incl.size} beam inclinations "
                             f"but its range image has {height} rows")
    else:
        lo, hi = calibration.inclination_min, calibration.inclination_max
        if lo is None or hi is None:
            raise ValueError(f"{laser_name(calibration.laser)} calibration has neither beam "
                             "inclinations nor their min/max")
        incl = lo + (np.arange(height) + 0.5) / height * (hi - lo)
    return incl[::-1].copy()


def column_azimuths(extrinsic: np.ndarray, width: int) -> np.ndarray:
    """Azimuth (radians, lidar frame) of each range-image column (float64, W)."""
    j = np.arange(width, dtype=np.float64)
    return ((width - j - 0.5) / width * 2.0 - 1.0) * np.pi - np.arctan2(extrinsic[1, 0], extrinsic[0, 0])


def rotation_rpy(roll, pitch, yaw) -> np.ndarray:
    """``Rz(yaw)·Ry(pitch)·Rx(roll)`` (WOD ``transform_utils.get_rotation_matrix``), shape (..., 3, 3)."""
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    return np.stack([np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
                     np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
                     np.stack([-sp, cp * sr, cp * cr], -1)], -2)


def _cell_points(rows, cols, r, calibration: LaserCalibration, shape: tuple[int, int],
                 pixel_pose: np.ndarray | None, frame_pose: np.ndarray | None) -> np.ndarray:
    """Vehicle-frame points (N×3 float64) of the cells ``(rows, cols)`` with ranges ``r``."""
    height, width = shape
    E = calibration.extrinsic
    incl = beam_inclinations(calibration, height)[rows]
    az = column_azimuths(E, width)[cols]
    r = np.asarray(r, np.float64)
    p = np.stack([np.cos(az) * np.cos(incl) * r, np.sin(az) * np.cos(incl) * r, np.sin(incl) * r], -1)
    p = p @ E[:3, :3].T + E[:3, 3]
    if pixel_pose is not None:
        if frame_pose is None:
            raise ValueError(f"{laser_name(calibration.laser)} has a per-cell pose but the frame has no pose")
        cell = np.asarray(pixel_pose)[rows, cols].astype(np.float64)
        R = rotation_rpy(cell[:, 0], cell[:, 1], cell[:, 2])
        world = np.einsum("nij,nj->ni", R, p) + cell[:, 3:6]
        inv = np.linalg.inv(frame_pose)
        p = world @ inv[:3, :3].T + inv[:3, 3]
    return p


def range_image_to_points(range_image: np.ndarray, calibration: LaserCalibration,
                          pixel_pose: np.ndarray | None = None,
                          frame_pose: np.ndarray | None = None) -> np.ndarray:
    """H×W×3 float64 points in the vehicle frame (metres) of every cell of a range image
    (H×W or H×W×C, channel 0 the range); with ``pixel_pose`` (H×W×6) compensated into the
    vehicle frame of ``frame_pose`` (4×4 vehicle→world, then required). Invalid cells
    (range ≤ 0) are computed too: mask them with ``range_image[..., 0] > 0``."""
    ri = np.asarray(range_image)
    r = ri[..., 0] if ri.ndim == 3 else ri
    h, w = r.shape
    rows, cols = np.indices((h, w)).reshape(2, -1)
    return _cell_points(rows, cols, r.ravel(), calibration, (h, w), pixel_pose, frame_pose).reshape(h, w, 3)


class CameraPoints(NamedTuple):
    """The lidar points seen by one camera: ``uv`` N×2 float32 pixel coordinates (Waymo's
    convention, 0 = left/top edge of the first pixel), ``ray`` N float32 ray distance from the
    camera centre (metres), ``lidar`` N int8 laser ids (:data:`~.sensors.LASER_NAMES`)."""

    uv: np.ndarray
    ray: np.ndarray
    lidar: np.ndarray


def _camera_id(camera: int | str) -> int:
    if isinstance(camera, (int, np.integer)) and not isinstance(camera, bool):
        return int(camera)
    return next(iter(camera_ids(camera)))


def camera_points(frame: LidarFrame, camera: int | str, returns: Iterable[int] = (1,)) -> CameraPoints:
    """All lidars' points that the camera projection puts in ``camera`` (name or id), for the
    chosen returns (default: the first). A cell counts when its range is > 0 and its first
    projection (channel 0, pixel ch1, ch2) or else its second (channel 3, pixel ch4, ch5)
    names the camera. ``ray`` = ‖p_vehicle − t_cam‖ with t_cam the camera's position in the
    vehicle frame (= ‖inv(E_cam)·p_vehicle‖). Raises InputError when the frame has no range
    images, no camera projections, or no calibration for the camera."""
    cam, returns = _camera_id(camera), tuple(returns)
    cam_label = CAMERA_BY_ID.get(cam, f"camera {cam}")
    require_lidar(frame, "no laser data")
    if cam not in frame.cameras:
        raise InputError(frame.source, f"no calibration (extrinsic) for camera {cam_label}: the "
                                       "ray distance needs its position")
    centre = frame.cameras[cam][:3, 3]
    uvs, rays, ids, projected = [], [], [], False
    for laser in sorted(frame.returns):
        for n in returns:
            ret = frame.returns[laser].get(n)
            if ret is None or ret.camera_projection is None:
                continue
            projected = True
            proj = ret.camera_projection
            r = ret.range_image[..., 0]
            if proj.shape[:2] != r.shape or proj.shape[2] < 6:
                raise InputError(frame.source, f"{laser_name(laser)} return {n}: camera projection "
                                               f"{list(proj.shape)} does not match range image {list(r.shape)}")
            first, second = proj[..., 0] == cam, proj[..., 3] == cam
            take = (r > 0) & (first | second)
            rows, cols = np.nonzero(take)
            if not rows.size:
                continue
            use_first = first[rows, cols]
            u = np.where(use_first, proj[rows, cols, 1], proj[rows, cols, 4])
            v = np.where(use_first, proj[rows, cols, 2], proj[rows, cols, 5])
            try:
                p = _cell_points(rows, cols, r[rows, cols], frame.calibrations[laser], r.shape,
                                 frame.pixel_poses.get(laser), frame.pose)
            except ValueError as exc:
                raise InputError(frame.source, str(exc)) from None
            uvs.append(np.stack([u, v], -1).astype(np.float32))
            rays.append(np.linalg.norm(p - centre, axis=1).astype(np.float32))
            ids.append(np.full(rows.size, laser, np.int8))
    if not projected:
        raise InputError(frame.source, f"frame has no LiDAR camera projections (returns "
                                       f"{', '.join(map(str, returns))}) to place points in {cam_label}")
    if not uvs:
        return CameraPoints(np.zeros((0, 2), np.float32), np.zeros(0, np.float32), np.zeros(0, np.int8))
    return CameraPoints(np.concatenate(uvs), np.concatenate(rays), np.concatenate(ids))


# ----------------------------------------------------------------------------- sparse maps
def sparse_ray_depth(uv: np.ndarray, ray: np.ndarray, width: int, height: int) -> np.ndarray:
    """H×W float32 ray-distance map from points: pixel ``[floor(v), floor(u)]`` gets the nearest
    (min) ray distance of the points landing on it; 0 = no point
    (:func:`fogsim.camera.sparse_image`, the one rasteriser)."""
    return sparse_image(uv, ray, width, height)


def filter_bleed_through(depth: np.ndarray, window: int = 7, margin: float = 0.10) -> tuple[np.ndarray, int]:
    """Drop far points seen "through" the edge of a nearer object (lidar–camera parallax).

    A point (non-zero pixel) is kept only if ``d ≤ (1 + margin)·m``, where m is the smallest
    point distance in the ``window``×``window`` pixel neighbourhood centred on it (itself
    included): an isolated point, or one on a smooth surface, is kept; a far point among near
    ones is dropped (set to 0). Returns (the filtered copy, the number of points dropped).

    Choosing ``window``: on Waymo FRONT (f ≈ 2044 px) TOP points are ≈ 5 px apart along a row
    and ≈ 11 px between rows, so the default 7 px compares a point with neighbours of its own
    column cluster and overlapping lidars only; ≥ 11 px also catches lateral bleed (≈ 9 px wide
    at 5 m), ≥ 25 px vertical bleed, at the cost of dropping slanted surfaces whose distance
    changes by more than ``margin`` across the window (e.g. far ground near the horizon).
    """
    if window < 1 or window % 2 == 0:
        raise ValueError(f"bleed window must be an odd number of pixels ≥ 1, not {window}")
    if not margin >= 0:
        raise ValueError(f"bleed margin must be ≥ 0, not {margin}")
    d = np.asarray(depth, np.float32)
    points = d > 0
    work = np.where(points, d, np.float32(np.inf))
    local = cv2.erode(work, np.ones((window, window), np.uint8), borderType=cv2.BORDER_REPLICATE)
    drop = points & (d > np.float32(1.0 + margin) * local)
    out = d.copy()
    out[drop] = 0.0
    return out, int(drop.sum())


def camera_ray_depth(frame: LidarFrame, camera: int | str, width: int, height: int,
                     returns: Iterable[int] = (1,), window: int = 7,
                     margin: float | None = 0.10) -> tuple[np.ndarray, int]:
    """Sparse H×W float32 ray-distance map of ``camera`` (0 = no point) from all lidars, with
    the bleed-through filter (``margin=None``: none); returns (map, points dropped)."""
    pts = camera_points(frame, camera, returns)
    depth = sparse_ray_depth(pts.uv, pts.ray, width, height)
    if margin is None:
        return depth, 0
    return filter_bleed_through(depth, window, margin)
