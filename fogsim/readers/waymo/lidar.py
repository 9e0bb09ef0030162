"""The LiDAR points of a Waymo frame as seen by one camera, for the label distances and
``--depth-from lidar``: :class:`LidarPoints`, the picklable points provider.

A provider holds only where the frame is (a :class:`~.address.V1Record` or a
:class:`~.address.V2Frame`); called with a camera it decodes the frame (:mod:`.lidar_v1`,
:mod:`.lidar_v2`: range images, calibrations, poses as in :mod:`.lidar_frame`) and returns
:func:`~.lidar_geometry.camera_points`' ``uv`` (N×2 float32 Waymo pixel coordinates) and ``ray``
(N float32 metres from the camera centre).

The LiDAR modules, bottom up: :mod:`.matrix` (MatrixFloat / MatrixInt32 protos),
:mod:`.lidar_frame` (the decoded frame and its checks), :mod:`.lidar_v1` / :mod:`.lidar_v2` (the
readers), :mod:`.lidar_geometry` (range image → points → per-camera ray distance, conventions
stated there), this module.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Iterable

import numpy as np

from fogsim.readers.waymo.address import V1Record, V2Frame
from fogsim.readers.waymo.images import ParquetImage, TFRecordImage
from fogsim.readers.waymo.lidar_frame import LidarFrame, NoLidar
from fogsim.readers.waymo.lidar_geometry import CameraPoints, camera_points
from fogsim.readers.waymo.lidar_v1 import has_range_images, read_v1_lidar
from fogsim.readers.waymo.lidar_v2 import read_v2_lidar


@lru_cache(maxsize=2)
def _cached_frame(where: V1Record | V2Frame, source: str, returns: tuple[int, ...], stamp) -> LidarFrame:
    if isinstance(where, V1Record):
        return read_v1_lidar(where.path, where.offset, where.length, source, where.verify, returns)
    return read_v2_lidar(where.root, where.context, where.timestamp, source, returns)


@dataclass(frozen=True)
class LidarPoints:
    """Picklable points provider for one frame: ``LidarPoints(...)(camera) → (uv, ray)``.

    ``where``: the frame, a :class:`~.address.V1Record` (v1 .tfrecord) or a
    :class:`~.address.V2Frame` (v2 split folder); ``source`` names it in messages; ``returns``:
    the lidar returns used (1, 2). Calling it with a camera (name or id) returns
    :func:`~.lidar_geometry.camera_points`' ``uv`` (N×2 float32, Waymo pixel coordinates) and
    ``ray`` (N float32 metres from the camera centre); :meth:`points` also gives the lidar ids.
    The decoded frame is cached (the last two), so asking for several cameras decodes it once.
    """

    where: V1Record | V2Frame
    source: str
    returns: tuple[int, ...] = (1,)

    @classmethod
    def v1(cls, path, offset: int, length: int, source: str | None = None, verify: bool = True,
           returns: Iterable[int] = (1,)) -> "LidarPoints":
        return cls(V1Record(str(path), int(offset), int(length), verify), source or f"{path}@byte {offset}",
                   tuple(returns))

    @classmethod
    def v2(cls, root, context: str, timestamp: int, source: str | None = None,
           returns: Iterable[int] = (1,)) -> "LidarPoints":
        return cls(V2Frame(str(root), context, int(timestamp)), source or f"{root} {context}@{timestamp}",
                   tuple(returns))

    def frame(self) -> LidarFrame:
        """The decoded :class:`~.lidar_frame.LidarFrame` (cached by location and the file's mtime and size)."""
        if not isinstance(self.where, (V1Record, V2Frame)):
            raise ValueError(f"LidarPoints needs a V1Record or V2Frame, not {self.where!r}")
        probe = self.where.path if isinstance(self.where, V1Record) else self.where.table("lidar")
        try:
            st = os.stat(probe)
            stamp = (st.st_mtime_ns, st.st_size)
        except OSError:
            stamp = None
        return _cached_frame(self.where, self.source, tuple(self.returns), stamp)

    def points(self, camera: int | str) -> CameraPoints:
        return camera_points(self.frame(), camera, self.returns)

    def __call__(self, camera: int | str) -> tuple[np.ndarray, np.ndarray]:
        pts = self.points(camera)
        return pts.uv, pts.ray


@dataclass(frozen=True)
class OptionalPoints:
    """A :class:`LidarPoints` for the label reader's near-cluster fallback
    (:data:`fogsim.readers.waymo.labels.PointsProvider`): ``None`` for a frame without LiDAR
    instead of an error; a damaged range image still raises."""

    lidar: LidarPoints

    def __call__(self, camera: int | str):
        try:
            return self.lidar(camera)
        except NoLidar:
            return None


def frame_has_lidar(points: LidarPoints) -> bool:
    """Whether the frame of ``points`` has LiDAR data at all, without decoding it: a v1 Frame
    with a range image in one of its ``lasers`` (a laser entry without one, as real camera-only
    frames have, is none), a v2 segment with a ``lidar`` table (a run-wide check: data without any
    is refused before ``--depth-from lidar`` starts)."""
    where = points.where
    if isinstance(where, V1Record):
        return has_range_images(where.read(points.source), points.source)
    return where.table("lidar").is_file()


def lidar_points_for_sample(sample) -> LidarPoints:
    """The :class:`LidarPoints` of the frame of a Waymo sample made by
    :func:`fogsim.readers.waymo.samples.waymo_samples` (v1: its record; v2: its split folder and key)."""
    reader, meta = sample.read_image, sample.meta
    if isinstance(reader, TFRecordImage):
        return LidarPoints(reader.record, reader.source.rsplit(" ", 1)[0])
    if isinstance(reader, ParquetImage):
        root = Path(reader.path).parent.parent
        return LidarPoints.v2(root, meta["context"], meta["timestamp_micros"],
                              f"{root} {meta['context']}@{meta['timestamp_micros']}")
    raise ValueError(f"{sample.source}: not a Waymo sample (no TFRecord or parquet image reader)")
