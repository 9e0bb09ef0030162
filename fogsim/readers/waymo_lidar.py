"""Waymo LiDAR range images (v1 TFRecord, v2 parquet) → sparse per-camera ray distance: the front door.

No TensorFlow, no waymo package. The work is split by topic; this module re-exports their
public names (``from fogsim.readers import waymo_lidar as wl; wl.camera_points(...)``):

* :mod:`.waymo_matrix` — MatrixFloat / MatrixInt32 protos: :func:`decode_matrix`, :func:`encode_matrix`;
* :mod:`.waymo_lidar_frame` — the decoded frame: :class:`LaserCalibration`, :class:`LaserReturn`,
  :class:`LidarFrame`, :data:`LASER_NAMES`, :class:`NoLidar`;
* :mod:`.waymo_lidar_geometry` — the geometry (conventions stated there): :func:`beam_inclinations`,
  :func:`range_image_to_points`, :func:`camera_points`, :func:`sparse_ray_depth`,
  :func:`filter_bleed_through`, :func:`camera_ray_depth`;
* :mod:`.waymo_lidar_v1` / :mod:`.waymo_lidar_v2` — the readers: :func:`parse_v1_lidar`,
  :func:`read_v1_lidar`, :func:`read_v2_lidar`.

Defined here: :class:`LidarPoints` (the picklable points provider: ``uv`` N×2 float32 Waymo
pixel coordinates, ``ray`` N float32 metres from the camera centre), :class:`OptionalPoints`
and :func:`lidar_points_for_sample`.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Iterable

import numpy as np

from fogsim.readers.waymo_lidar_frame import (LASER_NAMES, LaserCalibration, LaserReturn, LidarFrame, NoLidar,
                                              laser_name)
from fogsim.readers.waymo_lidar_geometry import (CameraPoints, beam_inclinations, camera_points, camera_ray_depth,
                                                 column_azimuths, filter_bleed_through, range_image_to_points,
                                                 rotation_rpy, sparse_ray_depth)
from fogsim.readers.waymo_lidar_v1 import (CCAL_EXTRINSIC, CCAL_HEIGHT, CCAL_NAME, CCAL_WIDTH,
                                           CONTEXT_CAMERA_CALIBRATIONS, CONTEXT_LASER_CALIBRATIONS, FRAME_CONTEXT,
                                           FRAME_LASERS, FRAME_POSE, LASER_NAME, LASER_RETURNS, LCAL_EXTRINSIC,
                                           LCAL_INCLINATIONS, LCAL_MAX, LCAL_MIN, LCAL_NAME, RI_DEPRECATED,
                                           RI_POSE, RI_PROJECTION, RI_RANGE, TRANSFORM, parse_v1_lidar,
                                           read_v1_lidar)
from fogsim.readers.waymo_lidar_v2 import (V2_CAMERA, V2_CAMERA_EXTRINSIC, V2_CONTEXT, V2_LASER, V2_LCAL,
                                           V2_TABLES, V2_TIME, V2_VEHICLE_POSE, _v2_file, read_v2_lidar)
from fogsim.readers.waymo_matrix import (MATRIX_DATA, MATRIX_SHAPE, SHAPE_DIMS, _encode_varints, _varints,
                                         _varints_int32, decode_matrix, encode_matrix)

__all__ = [
    # defined here
    "LidarPoints", "OptionalPoints", "lidar_points_for_sample",
    # waymo_matrix (the private varint codecs are re-exported for their tests)
    "decode_matrix", "encode_matrix", "MATRIX_DATA", "MATRIX_SHAPE", "SHAPE_DIMS",
    "_varints", "_varints_int32", "_encode_varints",
    # waymo_lidar_frame
    "LASER_NAMES", "LaserCalibration", "LaserReturn", "LidarFrame", "NoLidar", "laser_name",
    # waymo_lidar_geometry
    "CameraPoints", "beam_inclinations", "column_azimuths", "rotation_rpy", "range_image_to_points",
    "camera_points", "sparse_ray_depth", "filter_bleed_through", "camera_ray_depth",
    # waymo_lidar_v1
    "parse_v1_lidar", "read_v1_lidar", "FRAME_CONTEXT", "FRAME_POSE", "FRAME_LASERS",
    "CONTEXT_CAMERA_CALIBRATIONS", "CONTEXT_LASER_CALIBRATIONS", "CCAL_NAME", "CCAL_EXTRINSIC", "CCAL_WIDTH",
    "CCAL_HEIGHT", "LCAL_NAME", "LCAL_INCLINATIONS", "LCAL_MIN", "LCAL_MAX", "LCAL_EXTRINSIC", "LASER_NAME",
    "LASER_RETURNS", "RI_DEPRECATED", "RI_RANGE", "RI_PROJECTION", "RI_POSE", "TRANSFORM",
    # waymo_lidar_v2
    "read_v2_lidar", "V2_CONTEXT", "V2_TIME", "V2_LASER", "V2_CAMERA", "V2_TABLES", "V2_LCAL",
    "V2_CAMERA_EXTRINSIC", "V2_VEHICLE_POSE",
]


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
