"""Waymo v2 (parquet) camera labels: the label tables and the :class:`WaymoV2Labels` reader.

Tables under a split root, ``<root>/<tag>/<file>.parquet`` with the camera_image file's name:
``camera_box`` (required for labels), ``camera_to_lidar_box_association``, ``lidar_box``,
``projected_lidar_box``, ``camera_calibration`` (each optional). Tables are read column-wise and
cached per file and process; pyarrow is imported lazily. Box conventions and distances are those of
:mod:`fogsim.readers.waymo.label_distance` (pixel-edge boxes, ray distance in metres).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Callable

import numpy as np

from fogsim.errors import InputError
from fogsim.readers.base import Labels
from fogsim.readers.waymo.address import V2Frame
from fogsim.readers.waymo.images import open_parquet
from fogsim.readers.waymo.label_distance import build_labels
from fogsim.readers.waymo.labels import (
    WAYMO_CLASSES,
    Box2D,
    CameraFrameLabels,
    LabelRead,
    LaserBox,
    PointsProvider,
    camera_extrinsic,
    camera_label_id,
    finite_floats,
)
from fogsim.readers.waymo.sensors import CAMERA_BY_ID, sensor_enum
from fogsim.schema.base import check
from fogsim.schema.waymo import V2BoxCodes

# v2 tables and columns (v2/perception/box.py, context.py; v2/component.py names them)
V2_CAMERA_BOX, V2_ASSOCIATION, V2_LIDAR_BOX = "camera_box", "camera_to_lidar_box_association", "lidar_box"
V2_PROJECTED, V2_CALIBRATION = "projected_lidar_box", "camera_calibration"
K_CONTEXT, K_TIME, K_CAMERA = "key.segment_context_name", "key.frame_timestamp_micros", "key.camera_name"
K_CAMERA_OBJECT, K_LASER_OBJECT = "key.camera_object_id", "key.laser_object_id"
_CB, _LB, _PB, _CAL = ("[CameraBoxComponent]", "[LiDARBoxComponent]", "[ProjectedLiDARBoxComponent]",
                       "[CameraCalibrationComponent]")
V2_BOX2D = ("box.center.x", "box.center.y", "box.size.x", "box.size.y")
V2_CAMERA_BOX_COLUMNS = (K_CONTEXT, K_TIME, K_CAMERA, K_CAMERA_OBJECT,
                         *(f"{_CB}.{c}" for c in V2_BOX2D), f"{_CB}.type")
V2_CAMERA_BOX_DIFFICULTY = f"{_CB}.difficulty_level.detection"
V2_ASSOCIATION_COLUMNS = (K_CONTEXT, K_TIME, K_CAMERA, K_CAMERA_OBJECT, K_LASER_OBJECT)
V2_LIDAR_BOX_COLUMNS = (K_CONTEXT, K_TIME, K_LASER_OBJECT,
                        *(f"{_LB}.box.center.{a}" for a in "xyz"), f"{_LB}.type")
V2_LIDAR_BOX_POINTS = f"{_LB}.num_lidar_points_in_box"
#: the 3D box's size (x = length along the heading, y = width, z = height) and heading, where present
V2_LIDAR_BOX_SHAPE = (*(f"{_LB}.box.size.{a}" for a in "xyz"), f"{_LB}.box.heading")
V2_PROJECTED_COLUMNS = (K_CONTEXT, K_TIME, K_CAMERA, K_LASER_OBJECT,
                        *(f"{_PB}.{c}" for c in V2_BOX2D), f"{_PB}.type")
V2_CAL_EXTRINSIC = f"{_CAL}.extrinsic.transform"
V2_CAL_SIZE = (f"{_CAL}.width", f"{_CAL}.height")


def camera_enum(value, source: str) -> int:
    """A v2 ``key.camera_name`` (int8, or a string "1" / "FRONT" as some files have) as the enum."""
    return sensor_enum(value, source)


def _timestamp(value, source: str) -> int:
    if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
        return int(value)
    raise InputError(source, f"malformed key.frame_timestamp_micros {value!r}")


@dataclass(frozen=True)
class _Table:
    """The named columns of one v2 file (lists, file order) and its rows grouped by key."""

    path: str
    columns: dict[str, list]
    groups: dict[tuple, list[int]]

    def rows(self, key: tuple) -> list[tuple[int, dict]]:
        """(row number, {column: value}) of the rows with this key."""
        return [(n, {c: v[n] for c, v in self.columns.items()}) for n in self.groups.get(key, ())]


def _column_values(column):
    """A parquet column as a sequence: numpy for floats (null → NaN) and null-free integers
    (converting tens of thousands of rows to Python objects is what costs), else a list."""
    import pyarrow as pa

    if pa.types.is_floating(column.type) or (pa.types.is_integer(column.type) and column.null_count == 0):
        return column.to_numpy()
    return column.to_pylist()


def _load_table(path: str, required: tuple[str, ...], optional: tuple[str, ...], key: tuple[str, ...]) -> _Table:
    """Read the columns of a v2 file column-wise (``optional`` ones where the file has them) and
    group the rows by the ``key`` columns (camera names as enum values, timestamps as int)."""
    pf = open_parquet(Path(path), required, optional)
    names = list(required) + [c for c in optional if c in pf.schema_arrow.names]
    try:
        table = pf.read(columns=names)
        columns = {c: _column_values(table.column(c)) for c in names}
    except (OSError, ValueError) as exc:
        raise InputError(path, f"cannot read the columns ({exc})") from None
    converted = []
    for c in key:
        convert = camera_enum if c == K_CAMERA else _timestamp if c == K_TIME else None
        if convert is None:
            converted.append(columns[c])
            continue
        values = columns[c]
        first = {}
        for n, v in enumerate(values):  # convert each distinct value once (errors name its first row)
            first.setdefault(v, n)
        mapping = {v: convert(v, f"{path}#row {n}") for v, n in first.items()}
        converted.append([mapping[v] for v in values])
    groups: dict[tuple, list[int]] = {}
    for n, k in enumerate(zip(*converted)):
        groups.setdefault(k, []).append(n)
    return _Table(path, columns, groups)


def _python(value):
    return value.item() if isinstance(value, np.generic) else value


def _v2_box2d(row: dict, prefix: str, label_id: str, laser_id: str | None, source: str) -> Box2D:
    cx, cy, length, width = finite_floats([row[f"{prefix}.{c}"] for c in V2_BOX2D], "2D box", source)
    codes = {"type": _python(row[f"{prefix}.type"])}
    if prefix == _CB and row.get(V2_CAMERA_BOX_DIFFICULTY) is not None:
        codes["difficulty_level.detection"] = _python(row[V2_CAMERA_BOX_DIFFICULTY])
    box = check(codes, V2BoxCodes, source, prefix)
    return Box2D(str(label_id), box.type, cx, cy, length, width, box.difficulty or 0, laser_id)


@lru_cache(maxsize=16)
def _v2_table(path: str, stamp, tag: str) -> _Table:
    """One v2 label table, cached (keyed by ``stamp`` = mtime, size too): one load per file and
    process, however many of its images are read."""
    if tag == V2_CAMERA_BOX:
        return _load_table(path, V2_CAMERA_BOX_COLUMNS, (V2_CAMERA_BOX_DIFFICULTY,), (K_CONTEXT, K_TIME, K_CAMERA))
    if tag == V2_ASSOCIATION:
        return _load_table(path, V2_ASSOCIATION_COLUMNS, (), (K_CONTEXT, K_TIME, K_CAMERA))
    if tag == V2_LIDAR_BOX:
        return _load_table(path, V2_LIDAR_BOX_COLUMNS, (V2_LIDAR_BOX_POINTS, *V2_LIDAR_BOX_SHAPE),
                           (K_CONTEXT, K_TIME))
    if tag == V2_PROJECTED:
        return _load_table(path, V2_PROJECTED_COLUMNS, (), (K_CONTEXT, K_TIME, K_CAMERA))
    return _load_table(path, (K_CONTEXT, K_CAMERA), (V2_CAL_EXTRINSIC, *V2_CAL_SIZE), (K_CONTEXT, K_CAMERA))


def _table(root: Path, tag: str, file_name: str) -> _Table | None:
    """The cached table ``root/tag/file_name``, or None when the file is absent."""
    path = root / tag / file_name
    try:
        stat = os.stat(path)
    except OSError:
        return None
    return _v2_table(str(path), (stat.st_mtime_ns, stat.st_size), tag)


def _v2_camera(table: _Table | None, context: str, camera: int) -> tuple:
    """(extrinsic 4×4 or None, width or None, height or None) of a camera_calibration table."""
    for n, row in (table.rows((context, camera)) if table else [])[-1:]:
        width, height = (row.get(c) for c in V2_CAL_SIZE)
        return (camera_extrinsic(row.get(V2_CAL_EXTRINSIC), f"{table.path}#row {n}"),
                int(width) if width else None, int(height) if height else None)
    return None, None, None


def v2_extrinsics(root: str | os.PathLike) -> dict[tuple[str, int], list[list[float]]]:
    """(context, camera) → camera→vehicle extrinsic (4×4 nested lists) of every
    ``camera_calibration/*.parquet`` under a v2 split root that has the column ({} otherwise;
    a file or row that cannot be read here is left out: the label reader refuses it when read)."""
    out = {}
    for path in sorted((Path(root) / V2_CALIBRATION).glob("*.parquet")):
        try:
            table = _table(Path(root), V2_CALIBRATION, path.name)
        except InputError:
            continue
        for context, camera in table.groups:
            try:
                extrinsic = _v2_camera(table, context, camera)[0]
            except InputError:
                continue
            if extrinsic is not None:
                out[(context, camera)] = extrinsic.tolist()
    return out


def parse_v2_labels(root: str | os.PathLike, file_name: str, context: str, timestamp: int, camera: int,
                    image_size: tuple[int, int] | None = None) -> CameraFrameLabels | None:
    """One camera image's labels from the v2 tables ``<root>/<tag>/<file_name>``, or None when
    ``camera_box/<file_name>`` is absent (no 2D labels for this context). A frame without
    camera_box rows is labelled with no objects (v2 stores only boxes). ``image_size`` (W, H) is
    used when ``camera_calibration`` does not give the size."""
    root = Path(root)
    boxes = _table(root, V2_CAMERA_BOX, file_name)
    if boxes is None:
        return None
    name = CAMERA_BY_ID.get(camera, str(camera))
    frame_key, image_key = (context, timestamp), (context, timestamp, camera)
    associations = _table(root, V2_ASSOCIATION, file_name)
    assoc = {row[K_CAMERA_OBJECT]: row[K_LASER_OBJECT] for _, row in
             (associations.rows(image_key) if associations else [])}
    laser = {}
    lidar = _table(root, V2_LIDAR_BOX, file_name)
    for n, row in lidar.rows(frame_key) if lidar else []:
        source = f"{lidar.path}#row {n}"
        center = finite_floats([row[f"{_LB}.box.center.{a}"] for a in "xyz"], "laser box centre", source)
        points = row.get(V2_LIDAR_BOX_POINTS)
        shape = [row.get(c) for c in V2_LIDAR_BOX_SHAPE]
        size = heading = None
        if None not in shape:
            *size, heading = finite_floats(shape, "laser box size and heading", source)
        laser[str(row[K_LASER_OBJECT])] = LaserBox(str(row[K_LASER_OBJECT]), int(row[f"{_LB}.type"] or 0),
                                                   tuple(center), None if points is None else int(points),
                                                   None if size is None else tuple(size), heading)
    projected_table = _table(root, V2_PROJECTED, file_name)
    projected = [_v2_box2d(row, _PB, camera_label_id(str(row[K_LASER_OBJECT]), name), None,
                           f"{projected_table.path}#row {n}")
                 for n, row in (projected_table.rows(image_key) if projected_table else [])]
    extrinsic, width, height = _v2_camera(_table(root, V2_CALIBRATION, file_name), context, camera)
    if (width is None or height is None) and image_size is not None:
        width, height = image_size
    camera_boxes = [_v2_box2d(row, _CB, row[K_CAMERA_OBJECT], assoc.get(row[K_CAMERA_OBJECT]),
                              f"{boxes.path}#row {n}") for n, row in boxes.rows(image_key)]
    return CameraFrameLabels(name, width, height, extrinsic, camera_boxes, projected, laser)


@dataclass(frozen=True)
class WaymoV2Labels:
    """Picklable :data:`~fogsim.readers.base.LabelReader`: one camera image's labels of ``frame``
    from the v2 tables under its split root (files named ``file_name``, the camera_image file's name).

    ``camera``: the CameraName enum value; ``source`` names it in messages; ``image``: optional
    picklable image reader, called only to learn the image size when ``camera_calibration`` does
    not give it; ``points``: optional :data:`PointsProvider`."""

    classes = WAYMO_CLASSES  # the class list, known without reading (not a field)

    frame: V2Frame
    file_name: str
    camera: int
    source: str
    image: Callable[[], np.ndarray] | None = None
    points: PointsProvider | None = None

    def read(self) -> LabelRead:
        """The labels and the drop counts (:class:`LabelRead`)."""
        where = self.frame
        frame = parse_v2_labels(where.root, self.file_name, where.context, where.timestamp, self.camera)
        if frame is None:
            raise InputError(Path(where.root) / V2_CAMERA_BOX / self.file_name,
                             f"not found: no 2D camera labels for {self.source} (this split has no "
                             f"{V2_CAMERA_BOX} table for it)")
        if (frame.width is None or frame.height is None) and self.image is not None:
            h, w = self.image().shape[:2]
            frame.width, frame.height = w, h
        return build_labels(frame, self.points)

    def __call__(self) -> Labels:
        return self.read().labels
