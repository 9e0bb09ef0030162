"""Waymo 2D camera labels as fogsim :class:`~fogsim.readers.base.Labels`, with a distance per box.

Sources (field numbers and columns: ``shared/notes/real-datasets.md`` §1, §3):

* v1 ``Frame`` (TFRecord): ``camera_labels`` (8), ``laser_labels`` (6), ``projected_lidar_labels``
  (9) and the camera calibration (``Context.camera_calibrations``: extrinsic, width, height).
* v2 parquet under the split root, ``<root>/<tag>/<file>.parquet`` with the camera_image file's
  name: ``camera_box`` (required for labels), ``camera_to_lidar_box_association``,
  ``lidar_box``, ``projected_lidar_box``, ``camera_calibration`` (each optional: a missing one
  only removes the distance sources that need it).

Classes: :data:`WAYMO_CLASSES` from ``Label.Type`` VEHICLE 1, PEDESTRIAN 2, CYCLIST 4. Signs (3)
and unknown (0) never become 2D objects (Waymo has no 2D sign labels; their projected boxes are
loose amodal projections).

Boxes: a camera label's centre ``cx, cy`` and ``length`` (extent along image x) and ``width``
(extent along image y), in pixels, become the pixel-edge box ``[cx − L/2, cy − W/2, cx + L/2,
cy + W/2)``, each edge rounded half up (``floor(v + 0.5)``) and clamped to ``[0, W] × [0, H]``.
A box empty after clamping is dropped and counted (:attr:`LabelRead.dropped`). Every other
annotation is kept as annotated (``kept = True``; no pixel filter); ``pixels`` is the box area.
``difficulty`` is ``detection_difficulty_level`` as stored (0 = unset, which Waymo's metrics
treat as LEVEL_1; 1; 2) and ``id`` the camera label's id.

Distance (``distance_m``, metres, the Euclidean range from the camera centre; ``distance_source``
says which rule gave it), first that applies:

1. ``"laser box centre (association)"``: the label's ``association.laser_object_id`` (v2:
   ``camera_to_lidar_box_association``; Waymo fills it for pedestrians only) names a laser label.
2. ``"laser box centre (projected-box match)"``: the camera box is matched one-to-one to a
   same-type projected laser box of the same camera, greedily by IoU (pairs with IoU ≥
   :data:`MATCH_IOU` and intersection / camera-box area ≥ :data:`MATCH_IOA`; boxes compared as
   floats clamped to the image); the projected id minus its ``_<CAMERA>`` suffix is the laser id.
   Laser labels already claimed by an association are not matched again.

   For 1 and 2: ``p_cam = inv(E_cam)·[c, 1]`` with ``c`` the 3D box centre (vehicle frame) and
   ``E_cam`` the camera→vehicle extrinsic; ``distance_m = ‖p_cam‖`` and ``planar_depth_m =
   p_cam.x`` (Waymo's camera frame: x forward, y left, z up). ``laser_id`` names the laser label
   and ``laser_points_in_box`` is its ``num_lidar_points_in_box`` (None when unknown).
3. ``"lidar points in box (near cluster)"``: :func:`distance_from_points` on the projected
   LiDAR points of this camera, from the reader's optional points provider.
4. ``"unknown"``: ``distance_m = None``.

The readers (:class:`WaymoV1Labels`, :class:`WaymoV2Labels`) are picklable and hold where the
labels are (path and record offset, or parquet root and file name), never the labels.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Callable

import numpy as np

from fogsim.errors import InputError
from fogsim.readers import protobuf_wire as pw
from fogsim.readers.base import Labels
from fogsim.readers.tfrecord import read_record
from fogsim.readers.waymo import CAMERA_NAMES, _open_parquet

#: The Waymo study's class list (YOLO id = index); VEHICLE includes vans, trucks, buses, motorcycles.
WAYMO_CLASSES = ("vehicle", "pedestrian", "cyclist")
#: Label.Type → class name; other types (UNKNOWN 0, SIGN 3) are not 2D objects.
TYPE_CLASS = {1: "vehicle", 2: "pedestrian", 4: "cyclist"}
CAMERA_BY_ID = {v: k for k, v in CAMERA_NAMES.items()}

#: Projected-box matching thresholds (camera boxes are tight, projected ones amodal and loose).
MATCH_IOU, MATCH_IOA = 0.3, 0.7
#: Near-cluster split of :func:`distance_from_points`: a gap between consecutive sorted ray
#: distances larger than max(CLUSTER_GAP_M, CLUSTER_GAP_FRACTION · distance) starts a new cluster.
CLUSTER_GAP_M, CLUSTER_GAP_FRACTION = 1.0, 0.1

SOURCE_ASSOCIATION = "laser box centre (association)"
SOURCE_MATCH = "laser box centre (projected-box match)"
SOURCE_POINTS = "lidar points in box (near cluster)"
SOURCE_UNKNOWN = "unknown"

#: A picklable callable ``(camera name, e.g. "FRONT") → (uv, ray)`` giving the LiDAR points that
#: project into that camera: ``uv`` N×2 pixel-edge image coordinates (x along the width, y along
#: the height), ``ray`` N ray distances camera centre → point in metres; or None when it has none.
PointsProvider = Callable[[str], "tuple[np.ndarray, np.ndarray] | None"]

# v1 field numbers (dataset.proto, label.proto)
FRAME_CONTEXT, FRAME_LASER_LABELS, FRAME_CAMERA_LABELS, FRAME_PROJECTED_LABELS = 1, 6, 8, 9
CONTEXT_CALIBRATIONS = 2
CALIB_NAME, CALIB_EXTRINSIC, CALIB_WIDTH, CALIB_HEIGHT = 1, 3, 4, 5
TRANSFORM_VALUES = 1
CAMERA_LABELS_NAME, CAMERA_LABELS_LABELS = 1, 2
LABEL_BOX, LABEL_TYPE, LABEL_ID, LABEL_DIFFICULTY, LABEL_NUM_POINTS, LABEL_ASSOCIATION = 1, 3, 4, 5, 7, 10
ASSOCIATION_LASER_ID = 1
BOX_CENTER_X, BOX_CENTER_Y, BOX_CENTER_Z, BOX_WIDTH, BOX_LENGTH = 1, 2, 3, 4, 5

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
V2_PROJECTED_COLUMNS = (K_CONTEXT, K_TIME, K_CAMERA, K_LASER_OBJECT,
                        *(f"{_PB}.{c}" for c in V2_BOX2D), f"{_PB}.type")
V2_CAL_EXTRINSIC = f"{_CAL}.extrinsic.transform"
V2_CAL_SIZE = (f"{_CAL}.width", f"{_CAL}.height")


# ----------------------------------------------------------------------------- records
@dataclass(frozen=True)
class Box2D:
    """One 2D label as stored: centre and extents in pixels (``length`` along image x)."""

    id: str
    type: int
    cx: float
    cy: float
    length: float
    width: float
    difficulty: int = 0
    laser_id: str | None = None  # association.laser_object_id (v2: the association table)


@dataclass(frozen=True)
class LaserBox:
    """One 3D laser label: its id, type, box centre in the vehicle frame (metres)."""

    id: str
    type: int
    center: tuple[float, float, float]
    num_points: int | None = None


@dataclass
class CameraFrameLabels:
    """Everything one camera image's labels and distances are made from (v1 and v2 alike).

    ``extrinsic``: camera→vehicle 4×4, or None when unknown (no laser-box distances then).
    ``projected``: projected laser boxes of this camera, ``id`` = the laser id (suffix removed).
    """

    camera: str
    width: int | None
    height: int | None
    extrinsic: np.ndarray | None
    boxes: list[Box2D]
    projected: list[Box2D] = field(default_factory=list)
    laser: dict[str, LaserBox] = field(default_factory=dict)


@dataclass(frozen=True)
class LabelRead:
    """A read's :class:`Labels` and the annotations left out of it, by reason → count
    (``"not a 2D class"``: signs and unknown types; ``"empty after clamping"``)."""

    labels: Labels
    dropped: dict[str, int]


# ----------------------------------------------------------------------------- geometry
def pixel_box(cx: float, cy: float, length: float, width: float,
              image_width: int | None, image_height: int | None) -> list[int]:
    """Pixel-edge ``[x0, y0, x1, y1)`` of a Waymo 2D label, edges rounded half up and clamped to
    the image (an unknown size clamps at 0 only). May be empty (x1 ≤ x0 or y1 ≤ y0)."""
    edges = [cx - length / 2, cy - width / 2, cx + length / 2, cy + width / 2]
    x0, y0, x1, y1 = (math.floor(v + 0.5) for v in edges)
    hi_x = math.inf if image_width is None else image_width
    hi_y = math.inf if image_height is None else image_height
    return [int(min(max(x0, 0), hi_x)), int(min(max(y0, 0), hi_y)),
            int(min(max(x1, 0), hi_x)), int(min(max(y1, 0), hi_y))]


def _float_box(b: Box2D, width: int | None, height: int | None) -> tuple[float, float, float, float]:
    hi_x = math.inf if width is None else float(width)
    hi_y = math.inf if height is None else float(height)
    return (min(max(b.cx - b.length / 2, 0.0), hi_x), min(max(b.cy - b.width / 2, 0.0), hi_y),
            min(max(b.cx + b.length / 2, 0.0), hi_x), min(max(b.cy + b.width / 2, 0.0), hi_y))


def _area(b) -> float:
    return max(b[2] - b[0], 0.0) * max(b[3] - b[1], 0.0)


def _overlap(a, b) -> tuple[float, float]:
    """(IoU of a and b, intersection / area of a)."""
    inter = _area((max(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), min(a[3], b[3])))
    union = _area(a) + _area(b) - inter
    return (inter / union if union > 0 else 0.0), (inter / _area(a) if _area(a) > 0 else 0.0)


def match_projected(boxes: list[Box2D], projected: list[Box2D], width: int | None, height: int | None,
                    exclude: set[str] = frozenset()) -> dict[int, tuple[int, float]]:
    """One-to-one matches camera box index → (projected box index, IoU): same type only, IoU ≥
    :data:`MATCH_IOU` and IoA(camera box) ≥ :data:`MATCH_IOA`, greedy by decreasing IoU (ties by
    index); projected boxes whose laser id is in ``exclude`` are not matched."""
    cam = [_float_box(b, width, height) for b in boxes]
    proj = [_float_box(p, width, height) for p in projected]
    pairs = []
    for i, b in enumerate(boxes):
        for j, p in enumerate(projected):
            if p.type != b.type or p.id in exclude:
                continue
            iou, ioa = _overlap(cam[i], proj[j])
            if iou >= MATCH_IOU and ioa >= MATCH_IOA:
                pairs.append((-iou, i, j))
    matches, used = {}, set()
    for neg_iou, i, j in sorted(pairs):
        if i not in matches and j not in used:
            matches[i] = (j, -neg_iou)
            used.add(j)
    return matches


def camera_range(center, extrinsic: np.ndarray) -> tuple[float, float]:
    """(Euclidean range camera centre → ``center``, planar depth p_cam.x), metres, for a point
    in the vehicle frame and the camera→vehicle 4×4 ``extrinsic``."""
    p = np.linalg.solve(extrinsic, np.array([*center, 1.0]))
    return float(np.linalg.norm(p[:3])), float(p[0])


def distance_from_points(bbox, uv: np.ndarray, ray: np.ndarray, min_points: int = 5) -> float | None:
    """Distance (metres) of the object in a 2D box from the LiDAR points projected into it.

    ``bbox``: pixel-edge ``[x0, y0, x1, y1)``; ``uv``: N×2 pixel-edge point coordinates (x, y);
    ``ray``: N ray distances camera centre → point (non-finite or ≤ 0 are ignored). The points
    inside the box are sorted by distance and split into 1-D clusters wherever the gap to the
    next one exceeds max(:data:`CLUSTER_GAP_M`, :data:`CLUSTER_GAP_FRACTION` · distance); the
    result is the **median of the nearest cluster with at least ``min_points`` points** (the
    background seen past the object's edges falls into farther clusters). None when there is
    no such cluster (fewer than ``min_points`` points in the box, or all clusters smaller).
    """
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    ray = np.asarray(ray, dtype=np.float64).ravel()
    if uv.shape[0] != ray.size:
        raise ValueError(f"{uv.shape[0]} point coordinates but {ray.size} distances")
    x0, y0, x1, y1 = bbox
    with np.errstate(invalid="ignore"):
        inside = ((uv[:, 0] >= x0) & (uv[:, 0] < x1) & (uv[:, 1] >= y0) & (uv[:, 1] < y1)
                  & np.isfinite(ray) & (ray > 0))
    d = np.sort(ray[inside])
    if d.size < min_points:
        return None
    gaps = np.flatnonzero(np.diff(d) > np.maximum(CLUSTER_GAP_M, CLUSTER_GAP_FRACTION * d[:-1])) + 1
    bounds = np.concatenate([[0], gaps, [d.size]])
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a >= min_points:
            return float(np.median(d[a:b]))
    return None


# ----------------------------------------------------------------------------- labels
def build_labels(frame: CameraFrameLabels, points: PointsProvider | None = None,
                 min_points: int = 5) -> LabelRead:
    """The :class:`Labels` of one camera image (records in annotation order) and the drop counts.

    ``points`` is called (once, with the camera name) only when some box has no laser-box distance.
    """
    dropped = {"not a 2D class": 0, "empty after clamping": 0}
    kept: list[tuple[Box2D, list[int]]] = []
    for b in frame.boxes:
        if b.type not in TYPE_CLASS:
            dropped["not a 2D class"] += 1
            continue
        box = pixel_box(b.cx, b.cy, b.length, b.width, frame.width, frame.height)
        if box[2] <= box[0] or box[3] <= box[1]:
            dropped["empty after clamping"] += 1
            continue
        kept.append((b, box))
    laser_of: dict[int, tuple[str, str]] = {}  # kept index → (laser id, source)
    if frame.extrinsic is not None:
        for i, (b, _) in enumerate(kept):
            if b.laser_id and b.laser_id in frame.laser:
                laser_of[i] = (b.laser_id, SOURCE_ASSOCIATION)
        rest = [i for i in range(len(kept)) if i not in laser_of]
        claimed = {lid for lid, _ in laser_of.values()}
        matches = match_projected([kept[i][0] for i in rest], frame.projected, frame.width, frame.height,
                                  exclude=claimed)
        for k, (j, _) in matches.items():
            if frame.projected[j].id in frame.laser:
                laser_of[rest[k]] = (frame.projected[j].id, SOURCE_MATCH)
    cloud: list = []  # the points, fetched on first need: [] not yet, [None] none
    objects = []
    for i, (b, box) in enumerate(kept):
        distance = planar = laser_id = laser_points = None
        source = SOURCE_UNKNOWN
        if i in laser_of:
            laser_id, source = laser_of[i]
            distance, planar = camera_range(frame.laser[laser_id].center, frame.extrinsic)
            laser_points = frame.laser[laser_id].num_points
        elif points is not None:
            if not cloud:
                cloud.append(points(frame.camera))
            if cloud[0] is not None:
                distance = distance_from_points(box, *cloud[0], min_points=min_points)
                source = SOURCE_POINTS if distance is not None else SOURCE_UNKNOWN
        name = TYPE_CLASS[b.type]
        x0, y0, x1, y1 = box
        objects.append({
            "object_id": b.id, "class": name, "class_id": WAYMO_CLASSES.index(name), "bbox": box,
            "pixels": (x1 - x0) * (y1 - y0), "kept": True, "reason": None,
            "truncated": x0 == 0 or y0 == 0 or x1 == frame.width or y1 == frame.height,
            "difficulty": b.difficulty,
            "distance_m": None if distance is None else round(distance, 3), "distance_source": source,
            "planar_depth_m": None if planar is None else round(planar, 3), "laser_id": laser_id,
            "laser_points_in_box": laser_points})
    return LabelRead(Labels(WAYMO_CLASSES, objects), {k: v for k, v in dropped.items() if v})


def _extrinsic(values, source: str) -> np.ndarray | None:
    """A camera→vehicle 4×4 from 16 row-major values (None when absent); refused when unusable."""
    if values is None or len(values) == 0:
        return None
    m = np.asarray(values, dtype=np.float64)
    if m.size != 16 or not np.all(np.isfinite(m)):
        raise InputError(source, f"unusable camera extrinsic ({m.size} values, need 16 finite)")
    m = m.reshape(4, 4)
    if abs(np.linalg.det(m[:3, :3])) < 1e-9:
        raise InputError(source, "unusable camera extrinsic (its rotation is singular)")
    return m


def _finite(values, what: str, source: str) -> list[float]:
    try:
        out = [float(v) for v in values]
    except (TypeError, ValueError):
        out = [math.nan]
    if not all(math.isfinite(v) for v in out):
        raise InputError(source, f"malformed {what}: {list(values)!r}")
    return out


def camera_label_id(projected_id: str, camera: str) -> str:
    """The laser label id of a projected laser label id ``"<laser id>_<CAMERA>"`` (unchanged when
    it has no such suffix, as v2's ``key.laser_object_id``)."""
    suffix = f"_{camera}"
    return projected_id[:-len(suffix)] if projected_id.endswith(suffix) else projected_id


# ----------------------------------------------------------------------------- v1
def _v1_double(fields: pw.Fields, number: int, source: str) -> float | None:
    values = pw.doubles(fields, number, source)
    return values[-1] if values else None


def _v1_box2d(label: pw.Fields, camera: str, projected: bool, source: str) -> Box2D:
    box = pw.submessage(label, LABEL_BOX, source)
    values = [_v1_double(box, n, source) for n in (BOX_CENTER_X, BOX_CENTER_Y, BOX_LENGTH, BOX_WIDTH)]
    label_id = pw.string(label, LABEL_ID, source)
    cx, cy, length, width = _finite([0.0 if v is None else v for v in values], "2D box", source)
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
    return LaserBox(pw.string(label, LABEL_ID, source), pw.integer(label, LABEL_TYPE, 0, source),
                    tuple(_finite(center, "laser box centre", source)), None if points < 0 else points)


def v1_label_index(data: bytes, source: str, labels: bool = True) -> tuple[set[int], dict[int, list[list[float]]]]:
    """For indexing: the cameras with a ``camera_labels`` entry in this Frame (an entry with no
    labels counts: "labelled, nothing there"; none looked for unless ``labels``) and each
    calibrated camera's extrinsic (camera→vehicle, 4×4 row-major nested lists; an unusable one is
    left out)."""
    frame = pw.decode_fields(data, source)
    labelled = {pw.integer(pw.decode_fields(v, source), CAMERA_LABELS_NAME, 0, source)
                for v in frame.get(FRAME_CAMERA_LABELS, [])} if labels else set()
    extrinsics = {}
    for cal in pw.submessages(pw.submessage(frame, FRAME_CONTEXT, source), CONTEXT_CALIBRATIONS, source):
        camera = pw.integer(cal, CALIB_NAME, 0, source)
        try:
            e = _extrinsic(pw.doubles(pw.submessage(cal, CALIB_EXTRINSIC, source), TRANSFORM_VALUES, source),
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
            extrinsic = _extrinsic(pw.doubles(pw.submessage(cal, CALIB_EXTRINSIC, source), TRANSFORM_VALUES,
                                              source), f"{source} calibration of camera {name}")
    return CameraFrameLabels(name, width, height, extrinsic, boxes, projected, laser)


@dataclass(frozen=True)
class WaymoV1Labels:
    """Picklable :data:`~fogsim.readers.base.LabelReader`: one camera's labels of the Frame record
    at ``offset`` of a v1 .tfrecord (its data CRC checked unless ``verify`` is false).

    ``camera``: the CameraName enum value; ``points``: optional :data:`PointsProvider` for the
    LiDAR-points fallback distance."""

    classes = WAYMO_CLASSES  # the class list, known without reading (not a field)

    path: str
    offset: int
    length: int
    camera: int
    source: str
    verify: bool = True
    points: PointsProvider | None = None

    def read(self) -> LabelRead:
        """The labels and the drop counts (:class:`LabelRead`)."""
        data = read_record(self.path, self.offset, self.length, self.source, self.verify)
        frame = parse_v1_labels(data, self.camera, self.source)
        if frame is None:
            raise InputError(self.source, f"no camera_labels entry for {CAMERA_BY_ID.get(self.camera, self.camera)}"
                                          " in this frame: it has no 2D labels (an unlabelled frame?)")
        return build_labels(frame, self.points)

    def __call__(self) -> Labels:
        return self.read().labels


# ----------------------------------------------------------------------------- v2
def camera_enum(value, source: str) -> int:
    """A v2 ``key.camera_name`` (int8, or a string "1" / "FRONT" as some files have) as the enum."""
    if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
        return int(value)
    if isinstance(value, str):
        if value.strip().isdigit():
            return int(value)
        if value.strip().upper() in CAMERA_NAMES:
            return CAMERA_NAMES[value.strip().upper()]
    raise InputError(source, f"malformed key.camera_name {value!r}")


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
    pf = _open_parquet(Path(path), required)
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


def _v2_box2d(row: dict, prefix: str, label_id: str, laser_id: str | None, source: str) -> Box2D:
    cx, cy, length, width = _finite([row[f"{prefix}.{c}"] for c in V2_BOX2D], "2D box", source)
    kind = row[f"{prefix}.type"]
    if kind is None:
        raise InputError(source, "malformed box (type is null)")
    difficulty = row.get(V2_CAMERA_BOX_DIFFICULTY) if prefix == _CB else None
    return Box2D(str(label_id), int(kind), cx, cy, length, width, int(difficulty or 0), laser_id)


@lru_cache(maxsize=16)
def _v2_table(path: str, stamp, tag: str) -> _Table:
    """One v2 label table, cached (keyed by ``stamp`` = mtime, size too): one load per file and
    process, however many of its images are read."""
    if tag == V2_CAMERA_BOX:
        return _load_table(path, V2_CAMERA_BOX_COLUMNS, (V2_CAMERA_BOX_DIFFICULTY,), (K_CONTEXT, K_TIME, K_CAMERA))
    if tag == V2_ASSOCIATION:
        return _load_table(path, V2_ASSOCIATION_COLUMNS, (), (K_CONTEXT, K_TIME, K_CAMERA))
    if tag == V2_LIDAR_BOX:
        return _load_table(path, V2_LIDAR_BOX_COLUMNS, (V2_LIDAR_BOX_POINTS,), (K_CONTEXT, K_TIME))
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
        return (_extrinsic(row.get(V2_CAL_EXTRINSIC), f"{table.path}#row {n}"),
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
        center = _finite([row[f"{_LB}.box.center.{a}"] for a in "xyz"], "laser box centre", source)
        points = row.get(V2_LIDAR_BOX_POINTS)
        laser[str(row[K_LASER_OBJECT])] = LaserBox(str(row[K_LASER_OBJECT]), int(row[f"{_LB}.type"] or 0),
                                                   tuple(center), None if points is None else int(points))
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
    """Picklable :data:`~fogsim.readers.base.LabelReader`: one camera image's labels from the v2
    tables under split root ``root`` (files named ``file_name``, the camera_image file's name).

    ``image``: optional picklable image reader, called only to learn the image size when
    ``camera_calibration`` does not give it; ``points``: optional :data:`PointsProvider`."""

    classes = WAYMO_CLASSES  # the class list, known without reading (not a field)

    root: str
    file_name: str
    context: str
    timestamp: int
    camera: int
    source: str
    image: Callable[[], np.ndarray] | None = None
    points: PointsProvider | None = None

    def read(self) -> LabelRead:
        """The labels and the drop counts (:class:`LabelRead`)."""
        frame = parse_v2_labels(self.root, self.file_name, self.context, self.timestamp, self.camera)
        if frame is None:
            raise InputError(Path(self.root) / V2_CAMERA_BOX / self.file_name,
                             f"not found: no 2D camera labels for {self.source} (this split has no "
                             f"{V2_CAMERA_BOX} table for it)")
        if (frame.width is None or frame.height is None) and self.image is not None:
            h, w = self.image().shape[:2]
            frame.width, frame.height = w, h
        return build_labels(frame, self.points)

    def __call__(self) -> Labels:
        return self.read().labels
