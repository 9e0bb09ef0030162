"""Waymo LiDAR range images (v1 TFRecord, v2 parquet) → sparse per-camera ray distance.

No TensorFlow, no waymo package: v1 ``Frame`` records are parsed with :mod:`.protobuf_wire`
(field numbers of WOD ``dataset.proto``), their "compressed" matrices opened with ``zlib``;
v2 tables are read with pyarrow (imported lazily). The geometry is that of WOD
``utils/range_image_utils.py`` / ``frame_utils.py`` (see ``shared/notes/real-datasets.md`` §2):

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

Public API: :func:`decode_matrix`, :func:`encode_matrix`, :func:`beam_inclinations`,
:func:`range_image_to_points`, :func:`read_v1_lidar`, :func:`read_v2_lidar`,
:func:`camera_points`, :class:`LidarPoints` (the picklable points provider),
:func:`lidar_points_for_sample`, :func:`sparse_ray_depth`, :func:`filter_bleed_through`,
:func:`camera_ray_depth`.
"""
from __future__ import annotations

import os
import struct
import zlib
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Iterable, NamedTuple

import cv2
import numpy as np

from fogsim.camera import sparse_image
from fogsim.errors import FogsimError, InputError
from fogsim.readers import protobuf_wire as pw
from fogsim.readers.tfrecord import read_record
from fogsim.readers.waymo import CAMERA_NAMES, camera_ids


class NoLidar(InputError):
    """The frame has no LiDAR range images (a test-split or camera-only frame): a per-frame
    problem, which the label reader treats as "no points" and ``--depth-from lidar`` reports."""

#: LaserName.Name enum of dataset.proto
LASER_NAMES = {"TOP": 1, "FRONT": 2, "SIDE_LEFT": 3, "SIDE_RIGHT": 4, "REAR": 5}
_LASER_LABEL = {v: k for k, v in LASER_NAMES.items()}
_CAMERA_LABEL = {v: k for k, v in CAMERA_NAMES.items()}

# v1 field numbers (dataset.proto)
FRAME_CONTEXT, FRAME_POSE, FRAME_LASERS = 1, 3, 5
CONTEXT_CAMERA_CALIBRATIONS, CONTEXT_LASER_CALIBRATIONS = 2, 3
CCAL_NAME, CCAL_EXTRINSIC, CCAL_WIDTH, CCAL_HEIGHT = 1, 3, 4, 5
LCAL_NAME, LCAL_INCLINATIONS, LCAL_MIN, LCAL_MAX, LCAL_EXTRINSIC = 1, 2, 3, 4, 5
LASER_NAME, LASER_RETURNS = 1, {1: 2, 2: 3}  # return number → field of Laser
RI_DEPRECATED, RI_RANGE, RI_PROJECTION, RI_POSE = 1, 2, 3, 4
TRANSFORM = 1
MATRIX_DATA, MATRIX_SHAPE, SHAPE_DIMS = 1, 2, 1

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


def laser_name(laser: int) -> str:
    return _LASER_LABEL.get(laser, f"laser {laser}")


# ----------------------------------------------------------------------------- matrices
def _varint_spans(buf: np.ndarray, source: str) -> tuple[np.ndarray, np.ndarray]:
    """Start offset and byte length of every varint in a packed run (a byte < 0x80 ends one)."""
    ends = np.flatnonzero(buf < 0x80)
    if ends.size == 0 or ends[-1] != buf.size - 1:
        raise InputError(source, "malformed matrix (truncated varint)")
    starts = np.empty_like(ends)
    starts[0], starts[1:] = 0, ends[:-1] + 1
    return starts, ends - starts + 1


def _varints(buf: np.ndarray, source: str) -> np.ndarray:
    """Decode a packed run of base-128 varints (uint8 array) into int64 (two's complement)."""
    if buf.size == 0:
        return np.zeros(0, np.int64)
    if not (buf & 0x80).any():
        return buf.astype(np.int64)
    starts, lengths = _varint_spans(buf, source)
    if lengths.max() > 10:
        raise InputError(source, "malformed matrix (overlong varint)")
    values = (buf[starts] & 0x7F).astype(np.uint64)
    longer = np.flatnonzero(lengths > 1)  # byte k of the values longer than k, k = 1 … 9
    for k in range(1, int(lengths.max())):
        values[longer] |= (buf[starts[longer] + k] & 0x7F).astype(np.uint64) << np.uint64(7 * k)
        longer = longer[lengths[longer] > k + 1]
    return values.view(np.int64)


def _varints_int32(buf: np.ndarray, source: str) -> np.ndarray:
    """Packed int32 varints → int32, faster than :func:`_varints`: a valid int32 is 1–5 bytes
    (0 … 2³¹−1) or exactly 10 (negative, sign-extended to 64 bits), and its 32 bits are the low
    bits of its first 5 bytes; anything else (6–9 bytes, a 5-byte value ≥ 2³¹, a 10-byte one
    that is not a sign-extended int32) is refused as out of the int32 range."""
    if buf.size == 0 or not (buf & 0x80).any():
        return buf.astype(np.int32)
    starts, lengths = _varint_spans(buf, source)
    values = (buf[starts] & 0x7F).astype(np.uint32)
    longer = np.flatnonzero(lengths > 1)
    for k in range(1, 5):
        if not longer.size:
            break
        values[longer] |= (buf[starts[longer] + k] & 0x7F).astype(np.uint32) << np.uint32(7 * k)
        longer = longer[lengths[longer] > k + 1]
    five, ten = np.flatnonzero(lengths == 5), np.flatnonzero(lengths == 10)
    ok = ((lengths <= 5) | (lengths == 10)).all() and not (buf[starts[five] + 4] & 0x78).any()
    if ok and ten.size:
        tail = buf[starts[ten, None] + np.arange(4, 10)]
        # byte 4: continuation + bits 31–34 set (0xF8); bytes 5–8: 0xFF; byte 9: 0x01
        ok = bool(((tail[:, 0] & 0xF8) == 0xF8).all() and (tail[:, 1:5] == 0xFF).all() and (tail[:, 5] == 1).all())
    if not ok:
        raise InputError(source, "malformed MatrixInt32 (value out of the int32 range)")
    return values.view(np.int32)


def _ints(values: list, source: str) -> np.ndarray:
    """A repeated int field's entries (packed blobs and/or unpacked varints) as int64."""
    out = []
    for v in values:
        if isinstance(v, memoryview):
            out.append(_varints(np.frombuffer(v, np.uint8), source))
        elif isinstance(v, int):
            out.append(np.array([v], np.uint64).view(np.int64))
        else:
            raise InputError(source, "malformed matrix (integer field with a fixed-size wire type)")
    return np.concatenate(out) if out else np.zeros(0, np.int64)


def decode_matrix(data: bytes, kind: str, source: str, compressed: bool = True) -> np.ndarray:
    """A serialized ``MatrixFloat`` (``kind="float"``) or ``MatrixInt32`` (``"int32"``) as an array.

    ``data`` is zlib-compressed unless ``compressed`` is false. MatrixFloat data is packed
    little-endian float32 (unpacked fixed32 entries are accepted too); MatrixInt32 data is
    varints, packed or not, negative values as 10-byte sign-extended varints. ``shape.dims``
    may be packed or unpacked. Returns float32 or int32 of that shape (read-only for floats).
    Corrupt zlib, malformed protobuf or a size/shape mismatch → :class:`InputError` (``source``).
    """
    if compressed:
        try:
            data = zlib.decompress(data)
        except zlib.error as exc:
            raise InputError(source, f"corrupt zlib data ({exc})") from None
    fields = pw.decode_fields(data, source)
    shape = pw.submessage(fields, MATRIX_SHAPE, source)
    dims = tuple(int(d) for d in _ints(shape.get(SHAPE_DIMS, []), source))
    entries = fields.get(MATRIX_DATA, [])
    if kind == "float":
        chunks = []
        for v in entries:
            if isinstance(v, int) or (isinstance(v, bytes) and len(v) != 4) or len(v) % 4:
                raise InputError(source, "malformed MatrixFloat (data is not float32)")
            chunks.append(np.frombuffer(v, "<f4"))
        values = np.concatenate(chunks).astype(np.float32, copy=False) if chunks else np.zeros(0, np.float32)
    elif kind == "int32":
        if len(entries) == 1 and isinstance(entries[0], memoryview):  # packed: the usual case
            values = _varints_int32(np.frombuffer(entries[0], np.uint8), source)
        else:
            wide = _ints(entries, source)
            if wide.size and (wide.min() < -(1 << 31) or wide.max() >= 1 << 31):
                raise InputError(source, "malformed MatrixInt32 (value out of the int32 range)")
            values = wide.astype(np.int32)
    else:
        raise ValueError(f"matrix kind must be 'float' or 'int32', not {kind!r}")
    if not dims or any(d < 0 for d in dims) or int(np.prod(dims)) != values.size:
        raise InputError(source, f"malformed matrix: shape {list(dims)} does not hold its "
                                 f"{values.size} values")
    return values.reshape(dims)


def _encode_varints(values: np.ndarray) -> bytes:
    """Packed varints of int64 ``values`` (negative → 10-byte two's complement), vectorised."""
    v = np.asarray(values, np.int64).ravel().view(np.uint64)
    nbytes = np.ones(v.size, np.int64)
    for k in range(1, 10):
        nbytes += v >= np.uint64(1) << np.uint64(7 * k)
    k = np.arange(10, dtype=np.uint64)
    out = ((v[:, None] >> (k * np.uint64(7))) & np.uint64(0x7F)).astype(np.uint8)
    out[np.arange(10)[None, :] < (nbytes[:, None] - 1)] |= 0x80
    return out[np.arange(10)[None, :] < nbytes[:, None]].tobytes()


def encode_matrix(array: np.ndarray, *, packed_shape: bool = True, packed_data: bool = True,
                  compress: bool = True) -> bytes:
    """Serialize ``array`` as MatrixFloat (float dtypes, as float32) or MatrixInt32 (integer
    dtypes), optionally zlib-compressed: the inverse of :func:`decode_matrix`, for fixtures and
    the benchmark. ``packed_shape`` / ``packed_data`` choose the two legal encodings of the
    repeated fields (unpacked float data = one fixed32 entry per value)."""
    a = np.asarray(array)
    dims = np.array(a.shape, np.int64)
    if packed_shape:
        shape = pw.bytes_field(SHAPE_DIMS, _encode_varints(dims))
    else:
        shape = b"".join(pw.varint_field(SHAPE_DIMS, int(d)) for d in dims)
    if np.issubdtype(a.dtype, np.floating):
        flat = a.astype("<f4").ravel()
        data = (pw.bytes_field(MATRIX_DATA, flat.tobytes()) if packed_data else
                b"".join(b"\x0d" + struct.pack("<f", x) for x in flat))  # tag 1, wire type 5
    else:
        flat = a.astype(np.int64).ravel()
        data = (pw.bytes_field(MATRIX_DATA, _encode_varints(flat)) if packed_data else
                b"".join(pw.varint_field(MATRIX_DATA, int(x)) for x in flat))
    message = data + pw.bytes_field(MATRIX_SHAPE, shape)
    return zlib.compress(message, 6) if compress else message


# ----------------------------------------------------------------------------- decoded frame
@dataclass(frozen=True)
class LaserCalibration:
    """One lidar's calibration: ``extrinsic`` 4×4 lidar→vehicle; inclinations in radians
    (``beam_inclinations`` ascending as stored, or None for uniform spacing in [min, max])."""

    laser: int
    extrinsic: np.ndarray
    inclination_min: float | None = None
    inclination_max: float | None = None
    beam_inclinations: np.ndarray | None = None


@dataclass(frozen=True)
class LaserReturn:
    """One return of one lidar: range image H×W×4 float32 (0 range, 1 intensity, 2 elongation,
    3 no-label zone) and camera projection H×W×6 int32 (or None)."""

    range_image: np.ndarray
    camera_projection: np.ndarray | None


@dataclass
class LidarFrame:
    """The LiDAR data of one frame. ``returns[laser][n]`` is return n (1 or 2); ``pixel_poses``
    holds the per-cell pose range images (H×W×6, TOP only); ``cameras`` the camera→vehicle
    extrinsics (4×4) by camera id; ``pose`` the frame's vehicle→world pose (None if unknown)."""

    source: str
    returns: dict[int, dict[int, LaserReturn]]
    calibrations: dict[int, LaserCalibration]
    cameras: dict[int, np.ndarray] = field(default_factory=dict)
    pose: np.ndarray | None = None
    pixel_poses: dict[int, np.ndarray] = field(default_factory=dict)


def _matrix4(values, source: str, what: str) -> np.ndarray:
    m = np.asarray(values, np.float64)
    if m.size != 16 or not np.isfinite(m).all():
        raise InputError(source, f"malformed {what}: expected 16 finite values, got {m.size}")
    return m.reshape(4, 4)


def _require_frame_lidar(frame: LidarFrame, what: str) -> LidarFrame:
    if not frame.returns:
        raise NoLidar(frame.source, f"frame has no LiDAR range images ({what})")
    missing = [laser_name(k) for k in frame.returns if k not in frame.calibrations]
    if missing:
        raise InputError(frame.source, f"no laser calibration for {', '.join(missing)}")
    return frame


# ----------------------------------------------------------------------------- geometry
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
    camera centre (metres), ``lidar`` N int8 laser ids (:data:`LASER_NAMES`)."""

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
    cam_label = _CAMERA_LABEL.get(cam, f"camera {cam}")
    _require_frame_lidar(frame, "no laser data")
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


# ----------------------------------------------------------------------------- v1 (TFRecord)
def _transform(message: pw.Fields, number: int, source: str, what: str) -> np.ndarray | None:
    sub = pw.submessage(message, number, source)
    values = pw.doubles(sub, TRANSFORM, source)
    return _matrix4(values, source, what) if values else None


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
            _check_shapes(image, proj, poses.get(laser), where)
            out.setdefault(laser, {})[n] = LaserReturn(image, proj)
    pose = _transform(frame, FRAME_POSE, source, "frame pose")
    return LidarFrame(source, out, calibrations, cameras, pose, {k: v for k, v in poses.items() if k in out})


def _check_shapes(image: np.ndarray, proj: np.ndarray | None, pose: np.ndarray | None, where: str) -> None:
    if image.ndim != 3 or image.shape[2] < 1:
        raise InputError(where, f"range image has shape {list(image.shape)}, expected [H, W, 4]")
    for what, m in (("camera projection", proj), ("range image pose", pose)):
        if m is not None and (m.ndim != 3 or m.shape[:2] != image.shape[:2] or m.shape[2] < 6):
            raise InputError(where, f"{what} has shape {list(m.shape)}, expected "
                                    f"[{image.shape[0]}, {image.shape[1]}, 6]")


def read_v1_lidar(path: str | os.PathLike, offset: int, length: int, source: str | None = None,
                  verify: bool = True, returns: Iterable[int] = (1,)) -> LidarFrame:
    """:func:`parse_v1_lidar` of the record at ``offset`` of a .tfrecord file; a frame without
    range images is an InputError ("frame has no LiDAR range images …")."""
    source = source or f"{path}@byte {offset}"
    frame = parse_v1_lidar(read_record(path, offset, length, source, verify), source, returns)
    return _require_frame_lidar(frame, "its Frame has no lasers with a range image of return "
                                       f"{'/'.join(map(str, returns))}")


# ----------------------------------------------------------------------------- v2 (parquet)
def _parquet():
    try:
        import pyarrow.parquet as pq
    except ImportError as exc:
        raise FogsimError(f"Waymo v2 needs pyarrow: pip install -e '.[waymo]' ({exc})") from None
    return pq


def _sensor_key(value, source: str, names: dict[str, int] = LASER_NAMES) -> int:
    """A key.laser_name / key.camera_name value as its enum: ints, numeric strings, or names
    of ``names`` (:data:`LASER_NAMES` or ``CAMERA_NAMES``; "FRONT" is 2 as a laser, 1 as a camera)."""
    if isinstance(value, str):
        v = value.strip().upper()
        if v.lstrip("-").isdigit():
            return int(v)
        if v in names:
            return names[v]
        raise InputError(source, f"unknown sensor name {value!r}")
    if value is None:
        raise InputError(source, "null sensor key")
    return int(value)


def _v2_rows(file: Path, keys: dict[str, object], columns: list[str], source: str) -> list[dict]:
    """The rows of ``file`` whose key columns equal ``keys`` (compared after casting), with
    ``columns``; only the row groups holding them are read."""
    pq = _parquet()
    try:
        pf = pq.ParquetFile(file)
    except (OSError, ValueError) as exc:
        raise InputError(file, f"not a readable parquet file ({exc})") from None
    names = pf.schema_arrow.names
    missing = [c for c in list(keys) + columns if c not in names]
    if missing:
        raise InputError(file, f"missing column(s) {', '.join(missing)} (not a Waymo v2 table?)")
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
                data = pf.read_row_group(group, columns=key_cols + columns).take(hits)
                rows.extend(data.to_pylist())
    except (OSError, ValueError) as exc:
        raise InputError(file, f"cannot read ({exc})") from None
    return rows


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


def _v2_file(root: Path, tag: str, context: str) -> Path:
    return root / tag / f"{context}.parquet"


def read_v2_lidar(root: str | os.PathLike, context: str, timestamp: int, source: str | None = None,
                  returns: Iterable[int] = (1,)) -> LidarFrame:
    """The LiDAR data of frame (``context``, ``timestamp`` µs) of a v2 split folder: tables
    ``lidar``, ``lidar_camera_projection``, ``lidar_calibration`` and optionally
    ``lidar_pose`` + ``vehicle_pose`` (per-cell compensation, both or neither) and
    ``camera_calibration`` (camera extrinsics), each ``<root>/<tag>/<context>.parquet``.
    Key and value types are cast (int8 or string sensor names, float32 projections → int)."""
    root = Path(root)
    source = source or f"{root} {context}@{timestamp}"
    returns = sorted(set(returns))
    if any(n not in LASER_RETURNS for n in returns):
        raise ValueError(f"lidar returns are 1 or 2, not {returns}")
    lidar_file = _v2_file(root, "lidar", context)
    if not lidar_file.is_file():
        raise NoLidar(source, f"frame has no LiDAR range images ({lidar_file} not found)")
    frame_keys = {V2_CONTEXT: context, V2_TIME: int(timestamp)}

    def ret_cols(tag: str, ns) -> list[str]:
        return [f"{V2_TABLES[tag]}.range_image_return{n}.{p}" for n in ns for p in ("values", "shape")]

    rows = _v2_rows(lidar_file, frame_keys, [V2_LASER] + ret_cols("lidar", returns), source)
    if not rows:
        raise NoLidar(source, f"frame has no LiDAR range images (no rows in {lidar_file})")
    images: dict[int, dict[int, np.ndarray]] = {}
    for row in rows:
        laser = _sensor_key(row[V2_LASER], f"{lidar_file} {source}")
        for n in returns:
            m = _v2_matrix(row, f"{V2_TABLES['lidar']}.range_image_return{n}", np.float32, f"{lidar_file} {source}")
            if m is not None:
                images.setdefault(laser, {})[n] = m
    projections: dict[int, dict[int, np.ndarray]] = {}
    proj_file = _v2_file(root, "lidar_camera_projection", context)
    if proj_file.is_file():
        for row in _v2_rows(proj_file, frame_keys, [V2_LASER] + ret_cols("lidar_camera_projection", returns),
                            source):
            laser = _sensor_key(row[V2_LASER], f"{proj_file} {source}")
            for n in returns:
                m = _v2_matrix(row, f"{V2_TABLES['lidar_camera_projection']}.range_image_return{n}", np.int32,
                               f"{proj_file} {source}")
                if m is not None:
                    projections.setdefault(laser, {})[n] = m
    poses = {}
    pose_file = _v2_file(root, "lidar_pose", context)
    if pose_file.is_file():
        for row in _v2_rows(pose_file, frame_keys, [V2_LASER] + ret_cols("lidar_pose", [1]), source):
            laser = _sensor_key(row[V2_LASER], f"{pose_file} {source}")
            m = _v2_matrix(row, f"{V2_TABLES['lidar_pose']}.range_image_return1", np.float32, f"{pose_file} {source}")
            if m is not None:
                poses[laser] = m
    frame_pose = None
    vp_file = _v2_file(root, "vehicle_pose", context)
    if vp_file.is_file():
        vp = _v2_rows(vp_file, frame_keys, [V2_VEHICLE_POSE], source)
        if vp:
            frame_pose = _matrix4(vp[0][V2_VEHICLE_POSE] or [], f"{vp_file} {source}", "vehicle pose")
    if poses and frame_pose is None:
        raise InputError(source, f"{pose_file} has per-cell lidar poses but {vp_file} has no pose "
                                 "for this frame (needed to compensate them)")
    calibrations = {}
    cal_file = _v2_file(root, "lidar_calibration", context)
    if not cal_file.is_file():
        raise InputError(source, f"no laser calibrations ({cal_file} not found)")
    for row in _v2_rows(cal_file, {V2_CONTEXT: context}, [V2_LASER] + list(V2_LCAL.values()), source):
        where = f"{cal_file} {source}"
        laser = _sensor_key(row[V2_LASER], where)
        values = row[V2_LCAL["values"]]
        calibrations[laser] = LaserCalibration(
            laser, _matrix4(row[V2_LCAL["extrinsic"]] or [], where, f"extrinsic of {laser_name(laser)}"),
            None if row[V2_LCAL["min"]] is None else float(row[V2_LCAL["min"]]),
            None if row[V2_LCAL["max"]] is None else float(row[V2_LCAL["max"]]),
            np.asarray(values, np.float64) if values else None)
    cameras = {}
    cam_file = _v2_file(root, "camera_calibration", context)
    if cam_file.is_file():
        for row in _v2_rows(cam_file, {V2_CONTEXT: context}, [V2_CAMERA, V2_CAMERA_EXTRINSIC], source):
            where = f"{cam_file} {source}"
            cam = _sensor_key(row[V2_CAMERA], where, CAMERA_NAMES)
            cameras[cam] = _matrix4(row[V2_CAMERA_EXTRINSIC] or [], where, f"extrinsic of camera {cam}")
    out = {}
    for laser, by_return in images.items():
        for n, image in by_return.items():
            proj = projections.get(laser, {}).get(n)
            _check_shapes(image, proj, poses.get(laser), f"{source} {laser_name(laser)} return {n}")
            out.setdefault(laser, {})[n] = LaserReturn(image, proj)
    frame = LidarFrame(source, out, calibrations, cameras, frame_pose,
                       {k: v for k, v in poses.items() if k in out})
    return _require_frame_lidar(frame, f"no range image of return {'/'.join(map(str, returns))} in {lidar_file}")


# ----------------------------------------------------------------------------- points provider
@lru_cache(maxsize=2)
def _cached_frame(kind: str, path: str, offset: int, length: int, context: str, timestamp: int,
                  source: str, verify: bool, returns: tuple[int, ...], stamp) -> LidarFrame:
    if kind == "v1":
        return read_v1_lidar(path, offset, length, source, verify, returns)
    return read_v2_lidar(path, context, timestamp, source, returns)


@dataclass(frozen=True)
class LidarPoints:
    """Picklable points provider for one frame: ``LidarPoints(...)(camera) → (uv, ray)``.

    It holds only where the frame is: v1 (``kind="v1"``) the .tfrecord ``path`` and the
    record's data ``offset``/``length`` (from :func:`fogsim.readers.tfrecord.index_tfrecord`);
    v2 (``kind="v2"``) the split folder ``path``, ``context`` and ``timestamp`` (µs).
    ``source`` names the frame in messages. Calling it with a camera (name or id) returns
    :func:`camera_points`' ``uv`` (N×2 float32, Waymo pixel coordinates) and ``ray`` (N
    float32 metres from the camera centre); :meth:`points` also gives the lidar ids. The
    decoded frame is cached (the last two), so asking for several cameras decodes it once.
    """

    kind: str
    path: str
    source: str
    offset: int = 0
    length: int = 0
    context: str = ""
    timestamp: int = -1
    verify: bool = True
    returns: tuple[int, ...] = (1,)

    @classmethod
    def v1(cls, path, offset: int, length: int, source: str | None = None, verify: bool = True,
           returns: Iterable[int] = (1,)) -> "LidarPoints":
        return cls("v1", str(path), source or f"{path}@byte {offset}", int(offset), int(length),
                   verify=verify, returns=tuple(returns))

    @classmethod
    def v2(cls, root, context: str, timestamp: int, source: str | None = None,
           returns: Iterable[int] = (1,)) -> "LidarPoints":
        return cls("v2", str(root), source or f"{root} {context}@{timestamp}", context=context,
                   timestamp=int(timestamp), returns=tuple(returns))

    def frame(self) -> LidarFrame:
        """The decoded :class:`LidarFrame` (cached by location and the file's mtime and size)."""
        if self.kind not in ("v1", "v2"):
            raise ValueError(f"LidarPoints kind must be 'v1' or 'v2', not {self.kind!r}")
        probe = self.path if self.kind == "v1" else _v2_file(Path(self.path), "lidar", self.context)
        try:
            st = os.stat(probe)
            stamp = (st.st_mtime_ns, st.st_size)
        except OSError:
            stamp = None
        return _cached_frame(self.kind, self.path, self.offset, self.length, self.context, self.timestamp,
                             self.source, self.verify, tuple(self.returns), stamp)

    def points(self, camera: int | str) -> CameraPoints:
        return camera_points(self.frame(), camera, self.returns)

    def __call__(self, camera: int | str) -> tuple[np.ndarray, np.ndarray]:
        pts = self.points(camera)
        return pts.uv, pts.ray


@dataclass(frozen=True)
class OptionalPoints:
    """A :class:`LidarPoints` for the label reader's near-cluster fallback
    (:data:`fogsim.readers.waymo_labels.PointsProvider`): ``None`` for a frame without LiDAR
    instead of an error; a damaged range image still raises."""

    lidar: LidarPoints

    def __call__(self, camera: int | str):
        try:
            return self.lidar(camera)
        except NoLidar:
            return None


def lidar_points_for_sample(sample) -> LidarPoints:
    """The :class:`LidarPoints` of the frame of a Waymo sample made by
    :func:`fogsim.readers.waymo.waymo_samples` (v1: its record; v2: its split folder and key)."""
    from fogsim.readers.waymo import ParquetImage, TFRecordImage

    reader, meta = sample.read_image, sample.meta
    if isinstance(reader, TFRecordImage):
        return LidarPoints.v1(reader.path, reader.offset, reader.length, reader.source.rsplit(" ", 1)[0],
                              reader.verify)
    if isinstance(reader, ParquetImage):
        root = Path(reader.path).parent.parent
        return LidarPoints.v2(root, meta["context"], meta["timestamp_micros"],
                              f"{root} {meta['context']}@{meta['timestamp_micros']}")
    raise ValueError(f"{sample.source}: not a Waymo sample (no TFRecord or parquet image reader)")
