"""Waymo v1 (TFRecord ``Frame``) camera labels: protobuf parsing and the :class:`WaymoV1Labels` reader.

Reads ``camera_labels`` (8), ``laser_labels`` (6), ``projected_lidar_labels`` (9) and the camera
calibration (``Context.camera_calibrations``) of one Frame; box conventions and distances are those
of :mod:`fogsim.readers.waymo.label_distance` (pixel-edge boxes, ray distance in metres).
"""
from __future__ import annotations

from dataclasses import dataclass

from fogsim.errors import InputError
from fogsim.readers.base import Labels
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo.address import V1Record
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
from fogsim.readers.waymo.sensors import CAMERA_BY_ID

# v1 field numbers (dataset.proto, label.proto)
FRAME_CONTEXT, FRAME_LASER_LABELS, FRAME_CAMERA_LABELS, FRAME_PROJECTED_LABELS = 1, 6, 8, 9
CONTEXT_CALIBRATIONS = 2
CALIB_NAME, CALIB_EXTRINSIC, CALIB_WIDTH, CALIB_HEIGHT = 1, 3, 4, 5
TRANSFORM_VALUES = 1
CAMERA_LABELS_NAME, CAMERA_LABELS_LABELS = 1, 2
LABEL_BOX, LABEL_TYPE, LABEL_ID, LABEL_DIFFICULTY, LABEL_NUM_POINTS, LABEL_ASSOCIATION = 1, 3, 4, 5, 7, 10
ASSOCIATION_LASER_ID = 1
BOX_CENTER_X, BOX_CENTER_Y, BOX_CENTER_Z, BOX_WIDTH, BOX_LENGTH, BOX_HEIGHT, BOX_HEADING = 1, 2, 3, 4, 5, 6, 7


def _v1_double(fields: pw.Fields, number: int, source: str) -> float | None:
    values = pw.doubles(fields, number, source)
    return values[-1] if values else None


def _v1_box2d(label: pw.Fields, camera: str, projected: bool, source: str) -> Box2D:
    box = pw.submessage(label, LABEL_BOX, source)
    values = [_v1_double(box, n, source) for n in (BOX_CENTER_X, BOX_CENTER_Y, BOX_LENGTH, BOX_WIDTH)]
    label_id = pw.string(label, LABEL_ID, source)
    cx, cy, length, width = finite_floats([0.0 if v is None else v for v in values], "2D box", source)
    association = pw.submessage(label, LABEL_ASSOCIATION, source)
    laser_id = pw.string(association, ASSOCIATION_LASER_ID, source) or None
    return Box2D(camera_label_id(label_id, camera) if projected else label_id,
                 pw.integer(label, LABEL_TYPE, 0, source), cx, cy, length, width,
                 pw.integer(label, LABEL_DIFFICULTY, 0, source), None if projected else laser_id)


def _v1_laser(label: pw.Fields, source: str) -> LaserBox:
    box = pw.submessage(label, LABEL_BOX, source)
    center = [_v1_double(box, n, source) for n in (BOX_CENTER_X, BOX_CENTER_Y, BOX_CENTER_Z)]
    center = [0.0 if v is None else v for v in center]  # proto2 defaults
    points = pw.integer(label, LABEL_NUM_POINTS, -1, source)
    size = [_v1_double(box, n, source) for n in (BOX_LENGTH, BOX_WIDTH, BOX_HEIGHT)]
    size = None if None in size else tuple(finite_floats(size, "laser box size", source))
    heading = _v1_double(box, BOX_HEADING, source)
    heading = None if heading is None else finite_floats([heading], "laser box heading", source)[0]
    return LaserBox(pw.string(label, LABEL_ID, source), pw.integer(label, LABEL_TYPE, 0, source),
                    tuple(finite_floats(center, "laser box centre", source)), None if points < 0 else points,
                    size, heading)


def v1_label_index(data: bytes, source: str, labels: bool = True) -> tuple[set[int], dict[int, list[list[float]]]]:
    """For indexing: the cameras with a ``camera_labels`` entry in this Frame (an entry with no
    labels counts: "labelled, nothing there"; none looked for unless ``labels``) and each
    calibrated camera's extrinsic (camera→vehicle, 4×4 row-major nested lists; an unusable one is
    left out)."""
    frame = pw.decode_fields(data, source)
    labelled = {pw.integer(entry, CAMERA_LABELS_NAME, 0, source)
                for entry in pw.submessages(frame, FRAME_CAMERA_LABELS, source)} if labels else set()
    extrinsics = {}
    for cal in pw.submessages(pw.submessage(frame, FRAME_CONTEXT, source), CONTEXT_CALIBRATIONS, source):
        camera = pw.integer(cal, CALIB_NAME, 0, source)
        try:
            e = camera_extrinsic(pw.doubles(pw.submessage(cal, CALIB_EXTRINSIC, source), TRANSFORM_VALUES, source),
                           f"{source} calibration of camera {camera}")
        except InputError:  # left out of the index; the label reader refuses it when read
            e = None
        if e is not None:
            extrinsics[camera] = e.tolist()
    return labelled, extrinsics


def parse_v1_labels(data: bytes, camera: int, source: str) -> CameraFrameLabels | None:
    """One camera's labels of a serialized Frame, or None when it has no ``camera_labels`` entry
    for that camera (an unlabelled frame)."""
    frame = pw.decode_fields(data, source)
    name = CAMERA_BY_ID.get(camera, str(camera))
    entries = [e for e in pw.submessages(frame, FRAME_CAMERA_LABELS, source)
               if pw.integer(e, CAMERA_LABELS_NAME, 0, source) == camera]
    if not entries:
        return None
    boxes = [_v1_box2d(label, name, False, f"{source} camera label {n}")
             for n, label in enumerate(lab for e in entries for lab in pw.submessages(e, CAMERA_LABELS_LABELS, source))]
    projected = [_v1_box2d(label, name, True, f"{source} projected lidar label {n}")
                 for n, label in enumerate(lab for e in pw.submessages(frame, FRAME_PROJECTED_LABELS, source)
                                           if pw.integer(e, CAMERA_LABELS_NAME, 0, source) == camera
                                           for lab in pw.submessages(e, CAMERA_LABELS_LABELS, source))]
    laser = {}
    for n, label in enumerate(pw.submessages(frame, FRAME_LASER_LABELS, source)):
        box = _v1_laser(label, f"{source} laser label {n}")
        laser[box.id] = box
    width = height = extrinsic = None
    for cal in pw.submessages(pw.submessage(frame, FRAME_CONTEXT, source), CONTEXT_CALIBRATIONS, source):
        if pw.integer(cal, CALIB_NAME, 0, source) == camera:
            width = pw.integer(cal, CALIB_WIDTH, 0, source) or None
            height = pw.integer(cal, CALIB_HEIGHT, 0, source) or None
            extrinsic = camera_extrinsic(pw.doubles(pw.submessage(cal, CALIB_EXTRINSIC, source), TRANSFORM_VALUES,
                                              source), f"{source} calibration of camera {name}")
    return CameraFrameLabels(name, width, height, extrinsic, boxes, projected, laser)


@dataclass(frozen=True)
class WaymoV1Labels:
    """Picklable :data:`~fogsim.readers.base.LabelReader`: one camera's labels of the Frame at
    ``record`` of a v1 .tfrecord.

    ``camera``: the CameraName enum value; ``source`` names it in messages; ``points``: optional
    :data:`PointsProvider` for the LiDAR-points fallback distance."""

    classes = WAYMO_CLASSES  # the class list, known without reading (not a field)

    record: V1Record
    camera: int
    source: str
    points: PointsProvider | None = None

    def read(self) -> LabelRead:
        """The labels and the drop counts (:class:`LabelRead`)."""
        data = self.record.read(self.source)
        frame = parse_v1_labels(data, self.camera, self.source)
        if frame is None:
            raise InputError(self.source, f"no camera_labels entry for {CAMERA_BY_ID.get(self.camera, self.camera)}"
                                          " in this frame: it has no 2D labels (an unlabelled frame?)")
        return build_labels(frame, self.points)

    def __call__(self) -> Labels:
        return self.read().labels

