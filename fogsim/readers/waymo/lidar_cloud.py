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
return 2's).
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Iterable

import numpy as np

from fogsim.errors import InputError
from fogsim.lidar.points import PointCloud
from fogsim.lidar.sensors import LidarSensor
from fogsim.readers.waymo.lidar_frame import LidarFrame, NoLidar, require_lidar
from fogsim.readers.waymo.lidar_geometry import beam_inclinations, column_azimuths
from fogsim.readers.waymo.sensors import LASER_NAMES, laser_name

__all__ = ["laser_point_cloud", "laser_sensor"]


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
