"""Waymo range images → :class:`fogsim.lidar.points.PointCloud`: one lidar's points in its own (sensor)
frame, both returns, with the sensor record its calibration implies (``waymo-top`` with the frame's beam
inclinations and mount), ready for :class:`fogsim.lidar.fog.LidarFogger`.

Geometry as :mod:`.lidar_geometry` (rows → inclination, row 0 the highest beam; columns → azimuth in
the lidar frame), without the extrinsic: p = r·(cos az cos incl, sin az cos incl, sin incl), r the range
image's channel 0 (> 0: a return). ``cloud.transformed(sensor.mount_pose)`` (= the extrinsic) gives the
vehicle frame; the per-cell rolling-shutter compensation of :mod:`.lidar_geometry` (TOP, into the frame
pose's vehicle frame) is not applied here — fog acts along each beam, in the frame the pulse travelled.

Columns: ``raw_intensity`` = channel 1 as stored (float ≥ 0, scale ``tanh``), ``ring`` = the range-image
row, ``return_index`` = 1 or 2, ``index`` = the row of the concatenation (return 1's cells row-major, then
return 2's). :func:`laser_camera_uv` gives the same rows' pixels in one camera (the range image's camera
projection), :class:`WaymoScan` is a sample's scan source for ``fogsim fog --waymo … --lidar``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Iterable

import numpy as np

from fogsim.errors import InputError
from fogsim.lidar.boxes import Box3D
from fogsim.lidar.points import PointCloud
from fogsim.lidar.sensors import LidarSensor, load_sensor
from fogsim.readers.waymo.lidar import LidarPoints
from fogsim.readers.waymo.lidar_frame import LidarFrame, NoLidar, require_lidar
from fogsim.readers.waymo.lidar_geometry import beam_inclinations, column_azimuths
from fogsim.readers.waymo.sensors import LASER_NAMES, camera_ids, laser_name

__all__ = ["WaymoScan", "laser_camera_uv", "laser_point_cloud", "laser_sensor"]


def _laser_id(laser: int | str) -> int:
    if isinstance(laser, str):
        try:
            return LASER_NAMES[laser.upper()]
        except KeyError:
            raise ValueError(f"unknown Waymo lidar {laser!r} (known: {', '.join(LASER_NAMES)})") from None
    return int(laser)


def laser_point_cloud(frame: LidarFrame, laser: int | str = "TOP", returns: Iterable[int] = (1, 2)) -> PointCloud:
    """The points of ``laser`` (name or id) for the ``returns`` the frame holds, in the lidar frame.
    A frame without that lidar is :class:`~.lidar_frame.NoLidar`; one without any return cell an
    :class:`InputError` (an empty scan), both naming the frame."""
    lid = _laser_id(laser)
    require_lidar(frame, f"no {laser_name(lid)} range images")
    if lid not in frame.returns:
        raise NoLidar(frame.source, f"frame has no {laser_name(lid)} range images")
    cal = frame.calibrations[lid]
    xyz, raw, ring, ret = [], [], [], []
    for n in sorted(set(returns)):
        got = frame.returns[lid].get(n)
        if got is None:
            continue
        image = got.range_image
        h, w = image.shape[:2]
        try:
            incl = beam_inclinations(cal, h)
        except ValueError as exc:
            raise InputError(frame.source, str(exc)) from None
        az = column_azimuths(cal.extrinsic, w)
        rows, cols = np.nonzero(image[..., 0] > 0)
        r = image[rows, cols, 0].astype(np.float64)
        ci = np.cos(incl[rows])
        xyz.append(np.stack([r * ci * np.cos(az[cols]), r * ci * np.sin(az[cols]), r * np.sin(incl[rows])], 1))
        raw.append(image[rows, cols, 1] if image.shape[2] > 1 else np.zeros(len(rows), np.float32))
        ring.append(rows)
        ret.append(np.full(len(rows), n))
    if not xyz:
        raise NoLidar(frame.source, f"{laser_name(lid)} has none of returns {', '.join(map(str, returns))}")
    where = f"{frame.source} {laser_name(lid)}"
    return PointCloud.from_raw(np.concatenate(xyz).astype(np.float32), np.concatenate(raw), "tanh", where,
                               ring=np.concatenate(ring), return_index=np.concatenate(ret))


def laser_sensor(frame: LidarFrame, laser: int | str = "TOP", base: LidarSensor | str = "waymo-top") -> LidarSensor:
    """``base`` (default the ``waymo-top`` preset) with the frame's beam inclinations (row order: row 0
    the highest) and its extrinsic as the mount."""
    lid = _laser_id(laser)
    require_lidar(frame, f"no {laser_name(lid)} range images")
    if lid not in frame.returns:
        raise NoLidar(frame.source, f"frame has no {laser_name(lid)} range images")
    cal = frame.calibrations[lid]
    h = next(iter(frame.returns[lid].values())).range_image.shape[0]
    sensor = base if isinstance(base, LidarSensor) else LidarSensor.preset(base)
    if sensor.beams != h:
        sensor = replace(sensor, beams=h, inclinations_deg=None)
    try:
        sensor = sensor.with_inclinations(beam_inclinations(cal, h))
    except ValueError as exc:
        raise InputError(frame.source, str(exc)) from None
    R = cal.extrinsic[:3, :3]
    rpy = (math.atan2(R[2, 1], R[2, 2]), math.asin(max(-1.0, min(1.0, -R[2, 0]))), math.atan2(R[1, 0], R[0, 0]))
    return replace(sensor, mount_xyz_m=tuple(float(v) for v in cal.extrinsic[:3, 3]),
                   mount_rpy_deg=tuple(math.degrees(v) for v in rpy))


def laser_camera_uv(frame: LidarFrame, camera: int | str, laser: int | str = "TOP",
                    returns: Iterable[int] = (1, 2)) -> np.ndarray:
    """The pixel of each point of :func:`laser_point_cloud` (same rows, same order) in ``camera``: N×2
    float64 Waymo pixel coordinates (0 = the left/top edge of the first pixel, fogsim's pixel-edge
    convention) from the range image's camera projection — its first projection when that names the
    camera, else its second — NaN for the points that camera does not see (or a return without a
    projection)."""
    lid = _laser_id(laser)
    cam = camera if isinstance(camera, int) else next(iter(camera_ids(camera)))
    require_lidar(frame, f"no {laser_name(lid)} range images")
    out = []
    for n in sorted(set(returns)):
        got = frame.returns.get(lid, {}).get(n)
        if got is None:
            continue
        rows, cols = np.nonzero(got.range_image[..., 0] > 0)
        uv = np.full((len(rows), 2), np.nan)
        proj = got.camera_projection
        if proj is not None and proj.shape[:2] == got.range_image.shape[:2] and proj.shape[2] >= 6:
            p = proj[rows, cols].astype(np.float64)
            first, second = p[:, 0] == cam, (p[:, 0] != cam) & (p[:, 3] == cam)
            uv[first] = p[first][:, 1:3]
            uv[second] = p[second][:, 4:6]
        out.append(uv)
    return np.concatenate(out) if out else np.zeros((0, 2))


def _yaw_box(box: dict, to_lidar: np.ndarray) -> Box3D:
    """A vehicle-frame laser box (``{"center_m", "size_m": [l, w, h], "heading_rad"}``) in the lidar frame."""
    length, width, height = box["size_m"]
    b = Box3D.from_yaw(box["center_m"], length, width, height, box["heading_rad"])
    R, t = to_lidar[:3, :3], to_lidar[:3, 3]
    return Box3D(R @ b.centre + t, R @ b.axes, b.half)


@dataclass(frozen=True)
class WaymoScan:
    """The scan source (:class:`fogsim.readers.base.ScanSource`) of one Waymo frame seen from one camera:
    ``points`` the frame's :class:`~fogsim.readers.waymo.lidar.LidarPoints` (both returns are read),
    ``camera`` the sample's camera, ``key`` the frame's name (``<segment>/<timestamp>``, without the
    camera: one scan per frame), ``laser`` the lidar fogged (TOP). Levels are written as PLY (Waymo has no
    point file of its own; PLY keeps the raw intensity with its scale, the ring = range-image row and the
    return index). Boxes: the records' ``laser_box`` (the matched 3D laser label, vehicle frame)."""

    points: LidarPoints
    camera: str
    key: str
    laser: str = "TOP"
    fmt: str = "ply"
    return_mode: str | None = None

    def frame(self) -> LidarFrame:
        return replace(self.points, returns=(1, 2)).frame()

    def cloud(self) -> PointCloud:
        return laser_point_cloud(self.frame(), self.laser)

    def sensor(self, base: LidarSensor | str | None = None) -> LidarSensor:
        return laser_sensor(self.frame(), self.laser, load_sensor(base) if base else "waymo-top")

    def image_uv(self, cloud: PointCloud) -> np.ndarray:
        return laser_camera_uv(self.frame(), self.camera, self.laser)

    def boxes(self, records: list[dict]) -> list[Box3D | None]:
        frame = self.frame()
        to_lidar = np.linalg.inv(frame.calibrations[_laser_id(self.laser)].extrinsic)
        return [_yaw_box(r["laser_box"], to_lidar) if r.get("kept", True) and r.get("laser_box") else None
                for r in records]

    def kitti_calib(self):
        return None

    def camera_view(self):
        return None  # the TOP laser's range image is a full sweep

    def describe(self) -> dict:
        return {"file": None, "frame": self.points.source, "laser": self.laser, "returns": [1, 2],
                "format": "waymo range images"}
