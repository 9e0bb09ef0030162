"""Waymo v2: the LiDAR data of one frame from a split folder of parquet tables.

Each table is ``<root>/<tag>/<context>.parquet`` (v2 ``component.py`` names the columns
below); pyarrow is imported lazily, and only the row groups holding the frame are read.
Key and value types are cast (int8 or string sensor names, float32 projections → int).
Units and conventions of the result: :mod:`fogsim.readers.waymo.lidar_frame`.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

import numpy as np

from fogsim.errors import InputError
from fogsim.readers.waymo.address import V2Frame
from fogsim.readers.waymo.images import open_parquet
from fogsim.readers.waymo.lidar_frame import (
    LaserCalibration,
    LaserReturn,
    LidarFrame,
    NoLidar,
    check_shapes,
    matrix4,
    require_lidar,
)
from fogsim.readers.waymo.lidar_v1 import LASER_RETURNS
from fogsim.readers.waymo.matrix import MAX_BEAMS, MAX_CHANNELS, MAX_COLUMNS
from fogsim.readers.waymo.sensors import CAMERA_NAMES, LASER_NAMES, laser_name, sensor_enum

# v2 tables and columns (v2/perception/lidar.py, context.py, pose.py; v2/component.py names them)
V2_CONTEXT, V2_TIME, V2_LASER, V2_CAMERA = ("key.segment_context_name", "key.frame_timestamp_micros",
                                            "key.laser_name", "key.camera_name")
V2_TABLES = {"lidar": "[LiDARComponent]", "lidar_camera_projection": "[LiDARCameraProjectionComponent]",
             "lidar_pose": "[LiDARPoseComponent]"}
_LCAL = "[LiDARCalibrationComponent]"
V2_LCAL = {"extrinsic": f"{_LCAL}.extrinsic.transform", "min": f"{_LCAL}.beam_inclination.min",
           "max": f"{_LCAL}.beam_inclination.max", "values": f"{_LCAL}.beam_inclination.values"}
V2_CAMERA_EXTRINSIC = "[CameraCalibrationComponent].extrinsic.transform"
V2_VEHICLE_POSE = "[VehiclePoseComponent].world_from_vehicle.transform"


def _sensor_key(value, source: str, names: dict[str, int] = LASER_NAMES) -> int:
    """A key.laser_name / key.camera_name value as its enum (:func:`~.sensors.sensor_enum`)."""
    return sensor_enum(value, source, "key.laser_name" if names is LASER_NAMES else V2_CAMERA, names)


def _v2_rows(file: Path, keys: dict[str, object], columns: list[str], source: str) -> list[dict]:
    """The rows of ``file`` whose key columns equal ``keys`` (compared after casting), with
    ``columns``; only the row groups holding them are read."""
    pf = open_parquet(file, list(keys) + columns)
    key_cols = list(keys)
    rows = []
    try:
        for group in range(pf.num_row_groups):
            table = pf.read_row_group(group, columns=key_cols)
            match = np.ones(table.num_rows, bool)
            for name in key_cols:
                col = table.column(name).to_pylist()
                want = keys[name]
                if isinstance(want, int):
                    match &= np.array([_as_int(v) == want for v in col], bool)
                else:
                    match &= np.array([str(v) == want for v in col], bool)
            hits = np.flatnonzero(match)
            if hits.size:
                _check_value_counts(pf, group, columns, file)
                data = pf.read_row_group(group, columns=key_cols + columns).take(hits)
                rows.extend(data.to_pylist())
    except (OSError, ValueError) as exc:
        raise InputError(file, f"cannot read ({exc})") from None
    return rows


def _check_value_counts(pf, group: int, columns: list[str], file: Path) -> None:
    """Refuse a row group whose range-image ``values`` columns hold more values than its rows'
    range images can (≤ :data:`~.matrix.MAX_BEAMS` × :data:`~.matrix.MAX_COLUMNS` ×
    :data:`~.matrix.MAX_CHANNELS` each), from the parquet metadata, before anything is read (a
    run-length encoded column of zeros inflates like a zlib bomb)."""
    md = pf.metadata.row_group(group)
    limit = md.num_rows * MAX_BEAMS * MAX_COLUMNS * MAX_CHANNELS
    wanted = [c for c in columns if c.endswith(".values")]
    for i in range(md.num_columns):
        chunk = md.column(i)
        name = next((c for c in wanted if chunk.path_in_schema.startswith(c + ".")), None)
        if name and chunk.num_values > limit:
            raise InputError(file, f"row group {group}: {name} holds {chunk.num_values:,} values for {md.num_rows} "
                                   f"row(s), more than range images hold (≤ {MAX_BEAMS} beams × {MAX_COLUMNS} "
                                   f"columns × {MAX_CHANNELS} channels a row); not read")


def _as_int(v) -> int | None:
    try:
        return int(v)
    except (TypeError, ValueError):
        return None


def _v2_matrix(row: dict, prefix: str, dtype, source: str) -> np.ndarray | None:
    values, shape = row.get(f"{prefix}.values"), row.get(f"{prefix}.shape")
    if values is None or shape is None:
        return None
    a = np.asarray(values, np.float64 if dtype == np.int32 else np.float32)
    dims = [int(d) for d in shape]
    if len(dims) != 3 or int(np.prod(dims)) != a.size:
        raise InputError(source, f"malformed {prefix}: shape {dims} does not hold its {a.size} values")
    if dtype == np.int32:
        if not np.isfinite(a).all():
            raise InputError(source, f"malformed {prefix}: non-finite camera projection values")
        a = np.rint(a).astype(np.int32)
    return a.reshape(dims)


def _return_columns(tag: str, returns) -> list[str]:
    return [f"{V2_TABLES[tag]}.range_image_return{n}.{p}" for n in returns for p in ("values", "shape")]


def _by_laser(rows: list[dict], tag: str, returns, dtype, where: str) -> dict[int, dict[int, np.ndarray]]:
    """laser → return number → the H×W×C matrix of table ``tag`` in ``rows`` (a null one left out)."""
    out: dict[int, dict[int, np.ndarray]] = {}
    for row in rows:
        laser = _sensor_key(row[V2_LASER], where)
        for n in returns:
            m = _v2_matrix(row, f"{V2_TABLES[tag]}.range_image_return{n}", dtype, where)
            if m is not None:
                out.setdefault(laser, {})[n] = m
    return out


def _optional_by_laser(v2: V2Frame, tag: str, returns, dtype, source: str) -> dict[int, dict[int, np.ndarray]]:
    """:func:`_by_laser` of the frame's rows of table ``tag``; {} when the segment has no such table."""
    file = v2.table(tag)
    if not file.is_file():
        return {}
    rows = _v2_rows(file, _frame_keys(v2), [V2_LASER] + _return_columns(tag, returns), source)
    return _by_laser(rows, tag, returns, dtype, f"{file} {source}")


def _frame_keys(v2: V2Frame) -> dict[str, object]:
    return {V2_CONTEXT: v2.context, V2_TIME: v2.timestamp}


def _vehicle_pose(v2: V2Frame, source: str) -> np.ndarray | None:
    """The frame's vehicle→world pose (4×4) from ``vehicle_pose``, or None without one."""
    file = v2.table("vehicle_pose")
    rows = _v2_rows(file, _frame_keys(v2), [V2_VEHICLE_POSE], source) if file.is_file() else []
    return matrix4(rows[0][V2_VEHICLE_POSE] or [], f"{file} {source}", "vehicle pose") if rows else None


def _laser_calibrations(v2: V2Frame, source: str) -> dict[int, LaserCalibration]:
    """Every lidar's calibration of the segment (``lidar_calibration``, required)."""
    file = v2.table("lidar_calibration")
    if not file.is_file():
        raise InputError(source, f"no laser calibrations ({file} not found)")
    calibrations, where = {}, f"{file} {source}"
    for row in _v2_rows(file, {V2_CONTEXT: v2.context}, [V2_LASER] + list(V2_LCAL.values()), source):
        laser = _sensor_key(row[V2_LASER], where)
        values = row[V2_LCAL["values"]]
        calibrations[laser] = LaserCalibration(
            laser, matrix4(row[V2_LCAL["extrinsic"]] or [], where, f"extrinsic of {laser_name(laser)}"),
            None if row[V2_LCAL["min"]] is None else float(row[V2_LCAL["min"]]),
            None if row[V2_LCAL["max"]] is None else float(row[V2_LCAL["max"]]),
            np.asarray(values, np.float64) if values else None)
    return calibrations


def _camera_extrinsics(v2: V2Frame, source: str) -> dict[int, np.ndarray]:
    """Camera id → camera→vehicle 4×4 of the segment (``camera_calibration``; {} without it)."""
    file = v2.table("camera_calibration")
    if not file.is_file():
        return {}
    cameras, where = {}, f"{file} {source}"
    for row in _v2_rows(file, {V2_CONTEXT: v2.context}, [V2_CAMERA, V2_CAMERA_EXTRINSIC], source):
        cam = _sensor_key(row[V2_CAMERA], where, CAMERA_NAMES)
        cameras[cam] = matrix4(row[V2_CAMERA_EXTRINSIC] or [], where, f"extrinsic of camera {cam}")
    return cameras


def read_v2_lidar(root: str | os.PathLike, context: str, timestamp: int, source: str | None = None,
                  returns: Iterable[int] = (1,)) -> LidarFrame:
    """The LiDAR data of frame (``context``, ``timestamp`` µs) of a v2 split folder: tables
    ``lidar``, ``lidar_camera_projection``, ``lidar_calibration`` and optionally
    ``lidar_pose`` + ``vehicle_pose`` (per-cell compensation, both or neither) and
    ``camera_calibration`` (camera extrinsics), each ``<root>/<tag>/<context>.parquet``.
    Key and value types are cast (int8 or string sensor names, float32 projections → int)."""
    v2 = V2Frame(str(root), context, int(timestamp))
    source = source or f"{root} {context}@{timestamp}"
    returns = sorted(set(returns))
    if any(n not in LASER_RETURNS for n in returns):
        raise ValueError(f"lidar returns are 1 or 2, not {returns}")
    lidar_file = v2.table("lidar")
    if not lidar_file.is_file():
        raise NoLidar(source, f"frame has no LiDAR range images ({lidar_file} not found)")
    rows = _v2_rows(lidar_file, _frame_keys(v2), [V2_LASER] + _return_columns("lidar", returns), source)
    if not rows:
        raise NoLidar(source, f"frame has no LiDAR range images (no rows in {lidar_file})")
    images = _by_laser(rows, "lidar", returns, np.float32, f"{lidar_file} {source}")
    projections = _optional_by_laser(v2, "lidar_camera_projection", returns, np.int32, source)
    poses = {laser: r[1] for laser, r in _optional_by_laser(v2, "lidar_pose", [1], np.float32, source).items()}
    frame_pose = _vehicle_pose(v2, source)
    if poses and frame_pose is None:
        raise InputError(source, f"{v2.table('lidar_pose')} has per-cell lidar poses but {v2.table('vehicle_pose')} "
                                 "has no pose for this frame (needed to compensate them)")
    calibrations, cameras = _laser_calibrations(v2, source), _camera_extrinsics(v2, source)
    out = {}
    for laser, by_return in images.items():
        for n, image in by_return.items():
            proj = projections.get(laser, {}).get(n)
            check_shapes(image, proj, poses.get(laser), f"{source} {laser_name(laser)} return {n}")
            out.setdefault(laser, {})[n] = LaserReturn(image, proj)
    frame = LidarFrame(source, out, calibrations, cameras, frame_pose,
                       {k: v for k, v in poses.items() if k in out})
    return require_lidar(frame, f"no range image of return {'/'.join(map(str, returns))} in {lidar_file}")
