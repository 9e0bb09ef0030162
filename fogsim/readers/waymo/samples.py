"""Waymo Open Dataset camera images as fogsim samples, without TensorFlow or the waymo package.

* v1: TFRecord files of ``Frame`` protos (proto2, ``waymo_open_dataset/dataset.proto``),
  parsed with :mod:`.tfrecord` and :mod:`.protobuf_wire` using the field numbers below.
* v2: a split folder holding ``camera_image/*.parquet`` and optionally
  ``camera_calibration/*.parquet`` (read with pyarrow).

Sample keys are ``<context name>/<timestamp_micros>_<CAMERA>``. Intrinsics and distortion are
those of :mod:`.sensors` (the distortion is not removed, only recorded in ``meta["distortion"]``).
Waymo has no dense depth: depth maps come from ``depth_dir/<key><ext>`` (ext in
:data:`fogsim.io.depth_files.DEPTH_SUFFIXES`), else none. Each sample holds picklable readers of its image
(:mod:`.images`), labels (:mod:`.labels_v1`, :mod:`.labels_v2`) and, for the labels' distance
fallback, its LiDAR points (:mod:`.lidar`).
"""
from __future__ import annotations

import os
import re
from dataclasses import replace
from pathlib import Path
from typing import Iterable

from fogsim.errors import InputError
from fogsim.io.depth_files import DEPTH_SUFFIXES
from fogsim.readers.base import DepthSpec, Sample
from fogsim.readers.folder import find_depth
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo.address import V1Record, V2Frame
from fogsim.readers.waymo.images import FRAME_IMAGES, IMAGE_NAME, V2_IMAGE, ParquetImage, TFRecordImage, open_parquet
from fogsim.readers.waymo.labels_v1 import WaymoV1Labels, v1_label_index
from fogsim.readers.waymo.labels_v2 import V2_CAMERA_BOX, WaymoV2Labels, v2_extrinsics
from fogsim.readers.waymo.lidar import LidarPoints, OptionalPoints
from fogsim.readers.waymo.sensors import (
    CAMERA_BY_ID,
    DISTORTION,
    Calibration,
    calibration,
    camera_ids,
    sensor_enum,
)
from fogsim.readers.waymo.tfrecord import index_tfrecord

DEFAULT_DEPTH = DepthSpec(path="", encoding="metric", kind="planar")

# v1 field numbers (dataset.proto): Frame, Context, CameraCalibration (the image's are in .images)
FRAME_CONTEXT, FRAME_TIMESTAMP = 1, 2
CONTEXT_NAME, CONTEXT_CALIBRATIONS = 1, 2
CALIB_NAME, CALIB_INTRINSIC, CALIB_WIDTH, CALIB_HEIGHT = 1, 2, 4, 5

# v2 columns (v2/perception/base.py, camera_image.py, context.py; v2/component.py names them)
V2_KEYS = ("key.segment_context_name", "key.frame_timestamp_micros", "key.camera_name")
_CAL = "[CameraCalibrationComponent]"
V2_CAL_KEYS = ("key.segment_context_name", "key.camera_name")
V2_CAL_PINHOLE = tuple(f"{_CAL}.intrinsic.{n}" for n in ("f_u", "f_v", "c_u", "c_v"))
V2_CAL_SIZE = (f"{_CAL}.width", f"{_CAL}.height")
V2_CAL_DISTORTION = tuple(f"{_CAL}.intrinsic.{n}" for n in DISTORTION)

def _safe(name: str) -> str:
    """A context name made safe as one path component."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", name).lstrip(".") or "_"


def _sample(context: str, timestamp: int, camera: str, source: str, reader,
            calibration: Calibration | None, depth_dir: Path | None, depth: DepthSpec,
            listings: dict | None = None, labels=None, extra: dict | None = None) -> Sample:
    key = f"{_safe(context)}/{timestamp}_{camera}"
    spec = None
    if depth_dir is not None:
        found = find_depth(depth_dir, key, listings=listings)
        if found is None:
            raise InputError(depth_dir / f"{key}{DEPTH_SUFFIXES[0]}",
                             f"depth map for {source} not found (nor with "
                             f"{', '.join(DEPTH_SUFFIXES[1:])}); Waymo has no dense depth, so "
                             "the depth folder must hold one map per image, named by its key")
        spec = replace(depth, path=str(found))
    intrinsics, distortion = calibration or (None, {})
    meta = {"dataset": "waymo", "context": context, "timestamp_micros": timestamp,
            "camera": camera, "distortion": distortion} | (extra or {})
    return Sample(key, source, reader, spec, intrinsics, meta, labels)


def _depth_dir(depth_dir: str | os.PathLike | None) -> Path | None:
    if depth_dir is not None and not Path(depth_dir).is_dir():
        raise InputError(depth_dir, "depth folder not found")
    return None if depth_dir is None else Path(depth_dir)


def _unique(samples: list[Sample]) -> list[Sample]:
    """Refuse two samples with one key (their outputs would overwrite each other)."""
    seen: dict[str, str] = {}
    for s in samples:
        if s.key in seen:
            raise InputError(s.source, f"duplicate frame: key {s.key} is also {seen[s.key]}")
        seen[s.key] = s.source
    return samples


# ----------------------------------------------------------------------------- v1 (TFRecord)
def _tfrecord_files(path: Path) -> list[Path]:
    if path.is_file():
        return [path]
    if not path.is_dir():
        raise InputError(path, "not found")
    files = sorted(p for p in path.iterdir() if p.suffix == ".tfrecord" and p.is_file())
    if not files:
        raise InputError(path, "no .tfrecord files in this folder")
    return files


def _parse_frame(data: bytes, source: str) -> tuple[str, int, dict[int, Calibration], set[int]]:
    """Context name, timestamp (µs), calibrations by camera and the cameras with an image."""
    frame = pw.decode_fields(data, source)
    context = pw.submessage(frame, FRAME_CONTEXT, source)
    name = pw.string(context, CONTEXT_NAME, source)
    timestamp = pw.integer(frame, FRAME_TIMESTAMP, -1, source)
    if not name or timestamp < 0:
        raise InputError(source, "not a Waymo Frame (no context.name or timestamp_micros)")
    calibrations = {}
    for cal in pw.submessages(context, CONTEXT_CALIBRATIONS, source):
        values = pw.doubles(cal, CALIB_INTRINSIC, source)
        calibrations[pw.integer(cal, CALIB_NAME, 0, source)] = calibration(
            values[:4], pw.integer(cal, CALIB_WIDTH, 0, source),
            pw.integer(cal, CALIB_HEIGHT, 0, source), dict(zip(DISTORTION, values[4:9])),
            f"{source} calibration of camera {pw.integer(cal, CALIB_NAME, 0, source)}")
    cameras = {pw.integer(im, IMAGE_NAME, 0, source)
               for im in pw.submessages(frame, FRAME_IMAGES, source)}
    return name, timestamp, calibrations, cameras


def _nothing_to_do(path, count: int, what: str, selected: dict[int, str], present: set) -> InputError:
    """The error for a dataset without any image of the selected cameras (as an empty folder is)."""
    if not count:
        return InputError(path, f"no {what} in it (an empty dataset: nothing to fog)")
    found = ", ".join(CAMERA_BY_ID.get(c, str(c)) for c in sorted(present, key=str)) or "none"
    return InputError(path, f"none of its {count} {what} has an image from camera(s) "
                            f"{', '.join(selected.values())} (cameras present: {found}); choose "
                            "others with --cameras")


def _label_meta(extrinsic, missing: str | None) -> dict:
    """``meta["extrinsic"]`` (camera→vehicle 4×4, when known) and ``meta["labels_missing"]`` (why a
    sample has no labels although they were asked for)."""
    return ({} if extrinsic is None else {"extrinsic": extrinsic}) | ({} if missing is None else
                                                                      {"labels_missing": missing})


def waymo_v1_samples(path: str | os.PathLike, cameras: Iterable[str] = ("FRONT",),
                     depth_dir: str | os.PathLike | None = None,
                     depth: DepthSpec = DEFAULT_DEPTH, verify: bool = True,
                     labels: bool = True) -> list[Sample]:
    """Samples for the selected cameras of every Frame in a .tfrecord file or folder of them.

    Each record is read once here (image bytes are not kept); ``read_image`` re-reads it.
    ``depth`` is the template of every sample's :class:`DepthSpec` (its path is replaced).
    ``verify``: check every record's data CRC (on both reads). Raises :class:`InputError`
    when there is nothing to do: no frames, or no image of the selected cameras in any.
    ``labels``: give each sample whose frame has a ``camera_labels`` entry for its camera a
    :class:`~fogsim.readers.waymo.labels_v1.WaymoV1Labels` (others get ``labels = None`` and say why
    in ``meta["labels_missing"]``). ``meta["extrinsic"]`` is the camera→vehicle 4×4 (when known).
    """
    selected, depth_dir = camera_ids(cameras), _depth_dir(depth_dir)
    samples, frames, seen, listings = [], 0, set(), {}
    for file in _tfrecord_files(Path(path)):
        for i, (offset, length) in enumerate(index_tfrecord(file)):
            record, where = f"{file}#record {i}", V1Record(str(file), offset, length, verify)
            data = where.read(record)
            name, timestamp, calibrations, present = _parse_frame(data, record)
            labelled, extrinsics = v1_label_index(data, record, labels)
            frames, seen = frames + 1, seen | present
            for camera, cam_name in selected.items():
                if camera in present:
                    source = f"{record} {cam_name}"
                    reader = TFRecordImage(where, camera, source)
                    label_reader = missing = None
                    if labels and camera in labelled:
                        # the frame's LiDAR points for the near-cluster distance (None without LiDAR)
                        points = OptionalPoints(LidarPoints(where, record))
                        label_reader = WaymoV1Labels(where, camera, source, points)
                    elif labels:
                        missing = f"{record}: no camera_labels entry for {cam_name} (an unlabelled frame)"
                    samples.append(_sample(name, timestamp, cam_name, source, reader,
                                           calibrations.get(camera), depth_dir, depth, listings,
                                           label_reader, _label_meta(extrinsics.get(camera), missing)))
    if not samples:
        raise _nothing_to_do(path, frames, "frames", selected, seen)
    return _unique(samples)


# ----------------------------------------------------------------------------- v2 (parquet)
def _v2_calibrations(folder: Path) -> dict[tuple[str, int], Calibration]:
    """(context, camera) → calibration from ``camera_calibration/*.parquet`` ({} if absent)."""
    calibrations = {}
    for file in sorted(folder.glob("*.parquet")):
        pf = open_parquet(file, V2_CAL_KEYS + V2_CAL_PINHOLE + V2_CAL_SIZE, V2_CAL_DISTORTION)
        distortion = [c for c in V2_CAL_DISTORTION if c in pf.schema_arrow.names]
        cols = pf.read(columns=list(V2_CAL_KEYS + V2_CAL_PINHOLE + V2_CAL_SIZE) + distortion)
        for n, row in enumerate(cols.to_pylist()):
            camera = sensor_enum(row[V2_CAL_KEYS[1]], f"{file}#row {n}")
            calibrations[(row[V2_CAL_KEYS[0]], camera)] = calibration(
                [row[c] for c in V2_CAL_PINHOLE], *(row[c] for c in V2_CAL_SIZE),
                {c.rsplit(".", 1)[1]: row[c] for c in distortion}, f"{file}#row {n}")
    return calibrations


def _v2_key(source: str, name, timestamp) -> None:
    """Refuse a camera_image row whose key columns are null or of the wrong type."""
    problems = []
    if not isinstance(name, str) or not name:
        problems.append(f"{V2_KEYS[0]} is {name!r}, not a segment name")
    if not isinstance(timestamp, int) or isinstance(timestamp, bool) or timestamp < 0:
        problems.append(f"{V2_KEYS[1]} is {timestamp!r}, not a timestamp in µs")
    if problems:
        raise InputError(source, f"malformed Waymo v2 key: {'; '.join(problems)}")


def waymo_v2_samples(root: str | os.PathLike, cameras: Iterable[str] = ("FRONT",),
                     depth_dir: str | os.PathLike | None = None,
                     depth: DepthSpec = DEFAULT_DEPTH, labels: bool = True) -> list[Sample]:
    """Samples for the selected cameras of a Waymo v2 split folder (e.g. ``.../training``).

    Only the key columns are read here; ``read_image`` reads the image column of one row
    group when called. Without ``camera_calibration/`` the samples have no intrinsics.
    A row of a selected camera with a null or mistyped key is refused naming file and row;
    no image of the selected cameras at all is an :class:`InputError` too.
    ``labels``: give each sample of a camera_image file with a ``camera_box/`` file of the same
    name a :class:`~fogsim.readers.waymo.labels_v2.WaymoV2Labels` (others get ``labels = None`` and
    say why in ``meta["labels_missing"]``). ``meta["extrinsic"]`` is the camera→vehicle 4×4 (when known).
    """
    selected, depth_dir, root = camera_ids(cameras), _depth_dir(depth_dir), Path(root)
    files = sorted((root / "camera_image").glob("*.parquet"))
    if not files:
        raise InputError(root, "no camera_image/*.parquet here (expected a Waymo v2 split folder)")
    calibrations = _v2_calibrations(root / "camera_calibration")
    extrinsics = v2_extrinsics(root)
    samples, rows, seen, listings = [], 0, set(), {}
    for file in files:
        pf, start = open_parquet(file, V2_KEYS + (V2_IMAGE,)), 0
        boxes = root / V2_CAMERA_BOX / file.name
        labelled = labels and boxes.is_file()
        for group in range(pf.num_row_groups):
            keys = pf.read_row_group(group, columns=list(V2_KEYS)).to_pydict()
            for row, (name, timestamp, camera) in enumerate(zip(*(keys[k] for k in V2_KEYS))):
                camera = None if camera is None else sensor_enum(camera, f"{file}#row {start + row}")
                seen.add(camera)
                if camera in selected:
                    source = f"{file}#row {start + row} {selected[camera]}"
                    _v2_key(source, name, timestamp)
                    reader = ParquetImage(str(file), group, row, source)
                    label_reader = missing = None
                    if labelled:
                        frame = V2Frame(str(root), name, timestamp)
                        points = OptionalPoints(LidarPoints(frame, f"{file}#row {start + row}"))
                        label_reader = WaymoV2Labels(frame, file.name, camera, source, reader, points)
                    elif labels:
                        missing = f"{boxes}: not found (no 2D camera labels for this segment)"
                    samples.append(_sample(name, timestamp, selected[camera], source, reader,
                                           calibrations.get((name, camera)), depth_dir, depth, listings,
                                           label_reader, _label_meta(extrinsics.get((name, camera)), missing)))
            start += len(keys[V2_KEYS[0]])
        rows += start
    if not samples:
        raise _nothing_to_do(root, rows, "camera_image rows", selected, {c for c in seen if c is not None})
    return _unique(samples)


def waymo_samples(path: str | os.PathLike, cameras: Iterable[str] = ("FRONT",),
                  depth_dir: str | os.PathLike | None = None,
                  depth: DepthSpec = DEFAULT_DEPTH, verify: bool = True, labels: bool = True) -> list[Sample]:
    """v2 when ``path`` is a folder with ``camera_image/``, else v1 TFRecord file(s) (whose
    record CRCs are checked unless ``verify`` is false). ``labels``: attach the 2D camera labels
    where the dataset has them (:mod:`fogsim.readers.waymo.labels`)."""
    if (Path(path) / "camera_image").is_dir():
        return waymo_v2_samples(path, cameras, depth_dir, depth, labels)
    return waymo_v1_samples(path, cameras, depth_dir, depth, verify, labels)
