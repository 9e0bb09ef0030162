"""Real-format Waymo fixtures with labels: v1 ``Frame`` protos and v2 parquet tables of one content.

Field numbers and columns as in WOD (``dataset.proto``,
``label.proto``, ``v2/perception/*.py``). A :class:`LabelFrame` describes one frame (calibrations,
camera labels, projected laser labels, laser labels, images); :func:`frame_message` encodes it as
a v1 Frame, :func:`write_v1` writes .tfrecord files and :func:`write_v2` the same content as a v2
split folder, so a test can check that both readers give the same result.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fogsim.io.images import encode_image
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo.tfrecord import write_tfrecord

CAMERA_NAMES = {1: "FRONT", 2: "FRONT_LEFT", 3: "FRONT_RIGHT", 4: "SIDE_LEFT", 5: "SIDE_RIGHT"}
TYPE_VEHICLE, TYPE_PEDESTRIAN, TYPE_SIGN, TYPE_CYCLIST = 1, 2, 3, 4


def extrinsic(position, yaw: float = 0.0) -> np.ndarray:
    """Camera→vehicle 4×4: the camera at ``position`` (vehicle frame, metres), turned by ``yaw``
    (rad, about +z) from looking along vehicle +x (Waymo camera frame: x forward, y left, z up)."""
    c, s = math.cos(yaw), math.sin(yaw)
    m = np.eye(4)
    m[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    m[:3, 3] = position
    return m


@dataclass
class Box2D:
    """A 2D label: centre, ``length`` along image x, ``width`` along image y (pixels)."""

    id: str
    type: int
    cx: float
    cy: float
    length: float
    width: float
    difficulty: int = 0
    laser_id: str | None = None  # association.laser_object_id


@dataclass
class Box3D:
    """A laser label: box centre in the vehicle frame, size (metres) and heading (rad)."""

    id: str
    type: int
    center: tuple[float, float, float]
    length: float = 4.0
    width: float = 2.0
    height: float = 1.5
    heading: float = 0.0
    num_points: int = 100


@dataclass
class Camera:
    intrinsic: tuple = (200.0, 200.0, 160.0, 120.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    extrinsic: np.ndarray = field(default_factory=lambda: np.eye(4))
    width: int = 320
    height: int = 240


@dataclass
class LabelFrame:
    """One frame's content. ``camera_labels``: camera → labels (a camera key with [] is
    "labelled, nothing there"; a missing key means no entry). ``projected``: camera → projected
    laser boxes whose ``id`` is the laser id (v1 writes ``<id>_<CAMERA>``)."""

    context: str
    timestamp: int
    cameras: dict[int, Camera]
    camera_labels: dict[int, list[Box2D]] = field(default_factory=dict)
    projected: dict[int, list[Box2D]] = field(default_factory=dict)
    laser: list[Box3D] = field(default_factory=list)

    def image(self, camera: int) -> np.ndarray:
        cam = self.cameras[camera]
        return np.full((cam.height, cam.width, 3), 10 * camera, np.uint8)


# ----------------------------------------------------------------------------- v1 messages
def transform_message(matrix, packed: bool = False) -> bytes:
    """Transform{1: repeated double transform} (16 values row-major; proto2: unpacked by default)."""
    values = np.asarray(matrix, dtype=np.float64).ravel()
    if packed:
        return pw.packed_doubles(1, values)
    return b"".join(pw.double_field(1, v) for v in values)


def calibration_message(camera: int, cam: Camera) -> bytes:
    """CameraCalibration: 1 name, 2 intrinsic, 3 extrinsic (camera→vehicle), 4 width, 5 height."""
    return (pw.varint_field(1, camera) + b"".join(pw.double_field(2, v) for v in cam.intrinsic)
            + pw.bytes_field(3, transform_message(cam.extrinsic)) + pw.varint_field(4, cam.width)
            + pw.varint_field(5, cam.height) + pw.varint_field(6, 2))


def box2d_message(cx: float, cy: float, length: float, width: float) -> bytes:
    """Label.Box of a 2D label: 1 center_x, 2 center_y, 5 length (along x), 4 width (along y)."""
    return (pw.double_field(1, cx) + pw.double_field(2, cy) + pw.double_field(4, width)
            + pw.double_field(5, length))


def box3d_message(b: Box3D) -> bytes:
    """Label.Box of a 3D label: 1–3 centre, 4 width, 5 length, 6 height, 7 heading."""
    return b"".join(pw.double_field(n, v) for n, v in zip(
        (1, 2, 3, 4, 5, 6, 7), (*b.center, b.width, b.length, b.height, b.heading)))


def label_message(box: bytes, type_: int, id_: str, difficulty: int = 0, laser_id: str | None = None,
                  num_points: int | None = None) -> bytes:
    """Label: 1 box, 3 type, 4 id, 5 detection_difficulty_level, 7 num_lidar_points_in_box,
    10 association{1 laser_object_id}."""
    out = pw.bytes_field(1, box) + pw.varint_field(3, type_) + pw.bytes_field(4, id_)
    if difficulty:
        out += pw.varint_field(5, difficulty)
    if num_points is not None:
        out += pw.varint_field(7, num_points)
    if laser_id is not None:
        out += pw.bytes_field(10, pw.bytes_field(1, laser_id))
    return out


def camera_labels_message(camera: int, labels: list[bytes]) -> bytes:
    """CameraLabels: 1 name, 2 repeated labels."""
    return pw.varint_field(1, camera) + b"".join(pw.bytes_field(2, lab) for lab in labels)


def camera_label(b: Box2D) -> bytes:
    return label_message(box2d_message(b.cx, b.cy, b.length, b.width), b.type, b.id, b.difficulty, b.laser_id)


def frame_message(f: LabelFrame, images: bool = True) -> bytes:
    """A Frame: 1 context (name, calibrations), 2 timestamp, 3 pose, 4 images, 6 laser_labels,
    8 camera_labels, 9 projected_lidar_labels."""
    ctx = pw.bytes_field(1, f.context) + b"".join(
        pw.bytes_field(2, calibration_message(c, cam)) for c, cam in f.cameras.items())
    out = (pw.bytes_field(1, ctx) + pw.varint_field(2, f.timestamp)
           + pw.bytes_field(3, transform_message(np.eye(4))))
    if images:
        for c in f.cameras:
            image = pw.varint_field(1, c) + pw.bytes_field(2, encode_image(f.image(c), ".png"))
            out += pw.bytes_field(4, image)
    for b in f.laser:
        out += pw.bytes_field(6, label_message(box3d_message(b), b.type, b.id, num_points=b.num_points))
    for c, labels in f.camera_labels.items():
        out += pw.bytes_field(8, camera_labels_message(c, [camera_label(b) for b in labels]))
    for c, boxes in f.projected.items():
        projected = [label_message(box2d_message(b.cx, b.cy, b.length, b.width), b.type,
                                   f"{b.id}_{CAMERA_NAMES[c]}") for b in boxes]
        out += pw.bytes_field(9, camera_labels_message(c, projected))
    return out


def write_v1(path: Path, frames: list[LabelFrame]) -> Path:
    write_tfrecord(path, [frame_message(f) for f in frames])
    return path


# ----------------------------------------------------------------------------- v2 tables
V2_TABLES = ("camera_image", "camera_box", "camera_to_lidar_box_association", "lidar_box",
             "projected_lidar_box", "camera_calibration")


def write_v2(root: Path, frames: list[LabelFrame], file_name: str | None = None,
             tables: tuple[str, ...] = V2_TABLES, camera_name: str = "int8") -> Path:
    """The same content as v2 tables ``root/<tag>/<file_name>`` (default: the first context's
    name + .parquet). ``camera_name``: the key type of the label tables, ``"int8"`` (the dataclass
    type) or ``"string"`` (as some real files have; written as the enum number, e.g. "1")."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    file_name = file_name or f"{frames[0].context}.parquet"

    def cam_array(values):
        if camera_name == "string":
            return pa.array([str(v) for v in values], pa.string())
        return pa.array(values, pa.int8())

    def keys(rows, with_camera=True):
        out = {"key.segment_context_name": pa.array([r[0].context for r in rows], pa.string()),
               "key.frame_timestamp_micros": pa.array([r[0].timestamp for r in rows], pa.int64())}
        if with_camera:
            out["key.camera_name"] = cam_array([r[1] for r in rows])
        return out

    def box2d(prefix, boxes):
        return {f"{prefix}.box.center.x": pa.array([b.cx for b in boxes], pa.float64()),
                f"{prefix}.box.center.y": pa.array([b.cy for b in boxes], pa.float64()),
                f"{prefix}.box.size.x": pa.array([b.length for b in boxes], pa.float64()),
                f"{prefix}.box.size.y": pa.array([b.width for b in boxes], pa.float64()),
                f"{prefix}.type": pa.array([b.type for b in boxes], pa.int8())}

    columns: dict[str, dict] = {}
    rows = [(f, c) for f in frames for c in f.cameras]
    columns["camera_image"] = keys(rows) | {"key.camera_name": pa.array([c for _, c in rows], pa.int8()),
                                            "[CameraImageComponent].image": pa.array(
                                                [encode_image(f.image(c), ".png") for f, c in rows], pa.binary())}
    cb = [(f, c, b) for f in frames for c, labels in f.camera_labels.items() for b in labels]
    p = "[CameraBoxComponent]"
    columns["camera_box"] = keys(cb) | {
        "key.camera_object_id": pa.array([b.id for *_, b in cb], pa.string())} | box2d(p, [b for *_, b in cb]) | {
        f"{p}.difficulty_level.detection": pa.array([b.difficulty for *_, b in cb], pa.int8()),
        f"{p}.difficulty_level.tracking": pa.array([b.difficulty for *_, b in cb], pa.int8())}
    assoc = [r for r in cb if r[2].laser_id is not None]
    columns["camera_to_lidar_box_association"] = keys(assoc) | {
        "key.camera_object_id": pa.array([b.id for *_, b in assoc], pa.string()),
        "key.laser_object_id": pa.array([b.laser_id for *_, b in assoc], pa.string())}
    lb = [(f, None, b) for f in frames for b in f.laser]
    p = "[LiDARBoxComponent]"
    columns["lidar_box"] = keys(lb, with_camera=False) | {
        "key.laser_object_id": pa.array([b.id for *_, b in lb], pa.string())} | {
        f"{p}.box.center.{a}": pa.array([b.center[i] for *_, b in lb], pa.float64()) for i, a in enumerate("xyz")} | {
        f"{p}.box.size.x": pa.array([b.length for *_, b in lb], pa.float64()),
        f"{p}.box.size.y": pa.array([b.width for *_, b in lb], pa.float64()),
        f"{p}.box.size.z": pa.array([b.height for *_, b in lb], pa.float64()),
        f"{p}.box.heading": pa.array([b.heading for *_, b in lb], pa.float64()),
        f"{p}.type": pa.array([b.type for *_, b in lb], pa.int8()),
        f"{p}.num_lidar_points_in_box": pa.array([b.num_points for *_, b in lb], pa.int64())}
    pb = [(f, c, b) for f in frames for c, boxes in f.projected.items() for b in boxes]
    columns["projected_lidar_box"] = keys(pb) | {
        "key.laser_object_id": pa.array([b.id for *_, b in pb], pa.string())} | box2d(
        "[ProjectedLiDARBoxComponent]", [b for *_, b in pb])
    p = "[CameraCalibrationComponent]"
    cal = [(frames[0], c, cam) for c, cam in frames[0].cameras.items()]
    names = ("f_u", "f_v", "c_u", "c_v", "k1", "k2", "p1", "p2", "k3")
    columns["camera_calibration"] = {
        "key.segment_context_name": pa.array([f.context for f, *_ in cal], pa.string()),
        "key.camera_name": cam_array([c for _, c, _ in cal])} | {
        f"{p}.intrinsic.{n}": pa.array([cam.intrinsic[i] for *_, cam in cal], pa.float64())
        for i, n in enumerate(names)} | {
        f"{p}.extrinsic.transform": pa.array([np.asarray(cam.extrinsic).ravel().tolist() for *_, cam in cal],
                                             pa.list_(pa.float64(), 16)),
        f"{p}.width": pa.array([cam.width for *_, cam in cal], pa.int32()),
        f"{p}.height": pa.array([cam.height for *_, cam in cal], pa.int32()),
        f"{p}.rolling_shutter_direction": pa.array([2 for _ in cal], pa.int8())}
    for tag in tables:
        (root / tag).mkdir(parents=True, exist_ok=True)
        pq.write_table(pa.table(columns[tag]), root / tag / file_name)
    return root


# ----------------------------------------------------------------------------- LiDAR points
@dataclass(frozen=True)
class StaticPoints:
    """A picklable points provider: camera name → (uv N×2, ray N) given as nested tuples."""

    by_camera: tuple  # ((camera name, uv rows, ray values), ...)

    def __call__(self, camera: str):
        for name, uv, ray in self.by_camera:
            if name == camera:
                return np.asarray(uv, dtype=np.float64).reshape(-1, 2), np.asarray(ray, dtype=np.float64)
        return None
