"""Waymo v1: the LiDAR part of a TFRecord ``Frame`` record, without TensorFlow or the waymo package.

The record is parsed with :mod:`.protobuf_wire` using the field numbers of WOD
``dataset.proto`` below; its "compressed" range images, camera projections and per-cell
poses are zlib'd matrices (:func:`fogsim.readers.waymo.matrix.decode_matrix`). Units and
conventions of the result: :mod:`fogsim.readers.waymo.lidar_frame`.
"""
from __future__ import annotations

import os
from typing import Iterable

import numpy as np

from fogsim.errors import InputError
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo.lidar_frame import (
    LaserCalibration,
    LaserReturn,
    LidarFrame,
    check_shapes,
    matrix4,
    require_lidar,
)
from fogsim.readers.waymo.matrix import decode_matrix
from fogsim.readers.waymo.sensors import laser_name
from fogsim.readers.waymo.tfrecord import read_record

# v1 field numbers (dataset.proto)
FRAME_CONTEXT, FRAME_POSE, FRAME_LASERS = 1, 3, 5
CONTEXT_CAMERA_CALIBRATIONS, CONTEXT_LASER_CALIBRATIONS = 2, 3
CCAL_NAME, CCAL_EXTRINSIC, CCAL_WIDTH, CCAL_HEIGHT = 1, 3, 4, 5
LCAL_NAME, LCAL_INCLINATIONS, LCAL_MIN, LCAL_MAX, LCAL_EXTRINSIC = 1, 2, 3, 4, 5
LASER_NAME, LASER_RETURNS = 1, {1: 2, 2: 3}  # return number → field of Laser
RI_DEPRECATED, RI_RANGE, RI_PROJECTION, RI_POSE = 1, 2, 3, 4
TRANSFORM = 1


def _transform(message: pw.Fields, number: int, source: str, what: str) -> np.ndarray | None:
    sub = pw.submessage(message, number, source)
    values = pw.doubles(sub, TRANSFORM, source)
    return matrix4(values, source, what) if values else None


def _single_double(fields: pw.Fields, number: int, source: str) -> float | None:
    values = pw.doubles(fields, number, source)
    return float(values[-1]) if values else None


def parse_v1_lidar(data: bytes, source: str, returns: Iterable[int] = (1,)) -> LidarFrame:
    """The LiDAR part of a serialized v1 ``Frame``: lasers (only the given returns decoded),
    laser and camera calibrations, the frame pose. ``source`` names the record in errors."""
    frame = pw.decode_fields(data, source)
    context = pw.submessage(frame, FRAME_CONTEXT, source)
    calibrations, cameras = {}, {}
    for cal in pw.submessages(context, CONTEXT_LASER_CALIBRATIONS, source):
        laser = pw.integer(cal, LCAL_NAME, 0, source)
        where = f"{source} laser calibration {laser_name(laser)}"
        extrinsic = _transform(cal, LCAL_EXTRINSIC, where, "extrinsic")
        if extrinsic is None:
            raise InputError(where, "no extrinsic")
        incl = pw.doubles(cal, LCAL_INCLINATIONS, where)
        calibrations[laser] = LaserCalibration(laser, extrinsic, _single_double(cal, LCAL_MIN, where),
                                               _single_double(cal, LCAL_MAX, where),
                                               np.asarray(incl, np.float64) if incl else None)
    for cal in pw.submessages(context, CONTEXT_CAMERA_CALIBRATIONS, source):
        cam = pw.integer(cal, CCAL_NAME, 0, source)
        extrinsic = _transform(cal, CCAL_EXTRINSIC, source, f"extrinsic of camera {cam}")
        if extrinsic is not None:
            cameras[cam] = extrinsic
    out: dict[int, dict[int, LaserReturn]] = {}
    poses = {}
    wanted = sorted(set(returns))
    if any(n not in LASER_RETURNS for n in wanted):
        raise ValueError(f"lidar returns are 1 or 2, not {wanted}")
    for laser_msg in pw.submessages(frame, FRAME_LASERS, source):
        laser = pw.integer(laser_msg, LASER_NAME, 0, source)
        for n in sorted(set(wanted) | {1}):
            if LASER_RETURNS[n] not in laser_msg:
                continue
            ri = pw.submessage(laser_msg, LASER_RETURNS[n], source)
            where = f"{source} {laser_name(laser)} return {n}"
            if n == 1 and (pose_blob := pw.blob(ri, RI_POSE, where)):
                poses[laser] = decode_matrix(pose_blob, "float", f"{where} range_image_pose_compressed")
            if n not in wanted:
                continue
            blob = pw.blob(ri, RI_RANGE, where)
            if blob:
                image = decode_matrix(blob, "float", f"{where} range_image_compressed")
            elif (raw := pw.blob(ri, RI_DEPRECATED, where)):
                image = decode_matrix(raw, "float", f"{where} range_image", compressed=False)
            else:
                continue
            proj_blob = pw.blob(ri, RI_PROJECTION, where)
            proj = (decode_matrix(proj_blob, "int32", f"{where} camera_projection_compressed")
                    if proj_blob else None)
            check_shapes(image, proj, poses.get(laser), where)
            out.setdefault(laser, {})[n] = LaserReturn(image, proj)
    pose = _transform(frame, FRAME_POSE, source, "frame pose")
    return LidarFrame(source, out, calibrations, cameras, pose, {k: v for k, v in poses.items() if k in out})


def has_range_images(frame: bytes, source: str) -> bool:
    """Whether a v1 Frame holds a range image in any laser (return 1 or 2, compressed or the
    deprecated raw field), without decoding one: real camera-only frames (the test split) carry
    ``lasers`` entries whose returns are empty."""
    for laser_msg in pw.submessages(pw.decode_fields(frame, source), FRAME_LASERS, source):
        for field in LASER_RETURNS.values():
            if field in laser_msg:
                ri = pw.submessage(laser_msg, field, source)
                if pw.blob(ri, RI_RANGE, source) or pw.blob(ri, RI_DEPRECATED, source):
                    return True
    return False


def read_v1_lidar(path: str | os.PathLike, offset: int, length: int, source: str | None = None,
                  verify: bool = True, returns: Iterable[int] = (1,)) -> LidarFrame:
    """:func:`parse_v1_lidar` of the record at ``offset`` of a .tfrecord file; a frame without
    range images is an InputError ("frame has no LiDAR range images …")."""
    source = source or f"{path}@byte {offset}"
    frame = parse_v1_lidar(read_record(path, offset, length, source, verify), source, returns)
    return require_lidar(frame, "its Frame has no lasers with a range image of return "
                                       f"{'/'.join(map(str, returns))}")
