"""Waymo LiDAR fixtures built from the spec (WOD dataset.proto, v2 component columns), with
geometry computed here by hand, independently of :mod:`fogsim.readers.waymo_lidar`.

The scene: a TOP lidar at a known extrinsic (yaw, translation), uniformly spaced beams, every
beam that points forward hits the wall plane x = WALL_X (vehicle frame); its range is solved
from the ray–plane intersection. A pinhole camera (Waymo axes: x forward, y left, z up; no
distortion) 1.5 m to the left of the lidar projects those points to pixels
``u = f·(−y/x) + cu``, ``v = f·(−z/x) + cv`` (Waymo's 0 = left edge of the first pixel), which
become the camera projection range image (channel 0 = camera id, 1, 2 = floor of u, v).
"""
from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass, field

import numpy as np

from fogsim.readers.waymo import protobuf_wire as pw

CONTEXT = "10017090168044687777_6380_000_6400_000"
TIMESTAMP = 1550083467346370
WALL_X = 20.0
FRONT, FRONT_LEFT = 1, 2
TOP, SIDE_LEFT = 1, 3
IMAGE_W, IMAGE_H, FOCAL = 320, 240, 200.0


def rz(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def ry(pitch: float) -> np.ndarray:
    c, s = math.cos(pitch), math.sin(pitch)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


def rx(roll: float) -> np.ndarray:
    c, s = math.cos(roll), math.sin(roll)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def transform(R: np.ndarray, t) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = R, t
    return m


@dataclass
class Laser:
    """One lidar of the fixture: calibration, range image (return 1), projection, pose."""

    name: int
    extrinsic: np.ndarray
    incl_min: float
    incl_max: float
    beams: list[float] | None
    range_image: np.ndarray  # H×W×4 float32
    projection: np.ndarray | None = None  # H×W×6 int32
    pose: np.ndarray | None = None  # H×W×6 float32 (roll, pitch, yaw, x, y, z)
    points: np.ndarray | None = None  # H×W×3 vehicle-frame truth (NaN where invalid)
    range_image2: np.ndarray | None = None
    projection2: np.ndarray | None = None


@dataclass
class Camera:
    name: int
    extrinsic: np.ndarray  # camera→vehicle
    f: float = FOCAL
    cu: float = IMAGE_W / 2
    cv: float = IMAGE_H / 2
    width: int = IMAGE_W
    height: int = IMAGE_H


@dataclass
class Scene:
    lasers: list[Laser]
    cameras: list[Camera]
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))


def beam_directions(extrinsic: np.ndarray, incl_min: float, incl_max: float, beams, h: int, w: int) -> np.ndarray:
    """H×W×3 unit beam directions in the vehicle frame, written out from the spec."""
    if beams:
        incl = list(reversed(beams))
    else:
        incl = [incl_min + (h - 1 - k + 0.5) / h * (incl_max - incl_min) for k in range(h)]  # row 0 highest
    yaw = math.atan2(extrinsic[1, 0], extrinsic[0, 0])
    d = np.zeros((h, w, 3))
    for i in range(h):
        for j in range(w):
            az = ((w - j - 0.5) / w * 2 - 1) * math.pi - yaw
            local = [math.cos(az) * math.cos(incl[i]), math.sin(az) * math.cos(incl[i]), math.sin(incl[i])]
            d[i, j] = extrinsic[:3, :3] @ local
    return d


def wall_laser(name: int = TOP, extrinsic: np.ndarray | None = None, h: int = 12, w: int = 96,
               incl_min: float = -0.25, incl_max: float = 0.15, beams=None, wall_x: float = WALL_X,
               max_range: float = 75.0) -> Laser:
    """A lidar whose forward beams all hit the plane x = wall_x (vehicle frame); others −1."""
    if extrinsic is None:
        extrinsic = transform(rz(math.radians(7.0)), [1.2, 0.1, 2.0])
    d = beam_directions(extrinsic, incl_min, incl_max, beams, h, w)
    t = extrinsic[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        r = (wall_x - t[0]) / d[..., 0]
    valid = (d[..., 0] > 0.05) & (r < max_range)
    r = np.where(valid, r, -1.0)
    ri = np.zeros((h, w, 4), np.float32)
    ri[..., 0] = r
    ri[..., 1] = 0.5
    points = np.where(valid[..., None], t + r[..., None] * d, np.nan)
    return Laser(name, extrinsic, incl_min, incl_max, beams, ri, points=points)


def front_camera(offset=(0.0, 1.5, 0.0), yaw: float = 0.0, name: int = FRONT,
                 lidar: np.ndarray | None = None) -> Camera:
    """A camera ``offset`` metres from the TOP lidar of :func:`wall_laser` (default 1.5 m left)."""
    base = (lidar if lidar is not None else transform(rz(math.radians(7.0)), [1.2, 0.1, 2.0]))[:3, 3]
    return Camera(name, transform(rz(yaw), base + np.asarray(offset, float)))


def project(points: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous pixel coordinates (u, v) and an in-image mask of vehicle-frame points."""
    E = camera.extrinsic
    p = (points.reshape(-1, 3) - E[:3, 3]) @ E[:3, :3]  # = R^T (p − c)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = camera.f * (-p[:, 1] / p[:, 0]) + camera.cu
        v = camera.f * (-p[:, 2] / p[:, 0]) + camera.cv
    ok = np.isfinite(u) & np.isfinite(v) & (p[:, 0] > 0)
    ok &= (u >= 0) & (u < camera.width) & (v >= 0) & (v < camera.height)
    shape = points.shape[:-1]
    return u.reshape(shape), v.reshape(shape), ok.reshape(shape)


def camera_projection(points: np.ndarray, cameras: list[Camera]) -> np.ndarray:
    """H×W×6 int32 camera projection: the first two cameras (in the given order) seeing a cell."""
    h, w = points.shape[:2]
    proj = np.zeros((h, w, 6), np.int32)
    slot = np.zeros((h, w), int)
    for cam in cameras:
        u, v, ok = project(points, cam)
        for i, j in zip(*np.nonzero(ok)):
            if slot[i, j] < 2:
                k = 3 * slot[i, j]
                proj[i, j, k:k + 3] = (cam.name, math.floor(u[i, j]), math.floor(v[i, j]))
                slot[i, j] += 1
    return proj


def wall_scene(cameras: list[Camera] | None = None, **laser_kw) -> Scene:
    laser = wall_laser(**laser_kw)
    cameras = cameras or [front_camera(lidar=laser.extrinsic)]
    laser.projection = camera_projection(laser.points, cameras)
    return Scene([laser], cameras)


# ----------------------------------------------------------------------------- v1 encoding
def matrix_message(array: np.ndarray, packed_shape: bool = True) -> bytes:
    """MatrixFloat / MatrixInt32 written with protobuf_wire's encoder, value by value."""
    a = np.asarray(array)
    if packed_shape:
        shape = pw.bytes_field(1, b"".join(pw.encode_varint(int(d)) for d in a.shape))
    else:
        shape = b"".join(pw.varint_field(1, int(d)) for d in a.shape)
    if np.issubdtype(a.dtype, np.floating):
        data = pw.bytes_field(1, a.astype("<f4").tobytes())
    else:
        data = pw.bytes_field(1, b"".join(pw.encode_varint(int(x)) for x in a.ravel()))
    return data + pw.bytes_field(2, shape)


def compressed(array: np.ndarray, packed_shape: bool = True) -> bytes:
    return zlib.compress(matrix_message(array, packed_shape))


def transform_msg(m: np.ndarray) -> bytes:
    return b"".join(pw.double_field(1, float(v)) for v in np.asarray(m).ravel())  # unpacked, as proto2


def range_image_msg(ri: np.ndarray, proj=None, pose=None, packed_shape: bool = True) -> bytes:
    out = pw.bytes_field(2, compressed(ri, packed_shape))
    if proj is not None:
        out += pw.bytes_field(3, compressed(proj, packed_shape))
    if pose is not None:
        out += pw.bytes_field(4, compressed(pose, packed_shape))
    return out


def laser_calibration_msg(laser: Laser) -> bytes:
    out = pw.varint_field(1, laser.name)
    if laser.beams:
        out += b"".join(pw.double_field(2, b) for b in laser.beams)
    out += pw.double_field(3, laser.incl_min) + pw.double_field(4, laser.incl_max)
    return out + pw.bytes_field(5, transform_msg(laser.extrinsic))


def camera_calibration_msg(cam: Camera) -> bytes:
    intrinsic = b"".join(pw.double_field(2, v) for v in (cam.f, cam.f, cam.cu, cam.cv, 0, 0, 0, 0, 0))
    return (pw.varint_field(1, cam.name) + intrinsic + pw.bytes_field(3, transform_msg(cam.extrinsic))
            + pw.varint_field(4, cam.width) + pw.varint_field(5, cam.height))


def frame_msg(scene: Scene, timestamp: int = TIMESTAMP, with_lasers: bool = True, packed_shape: bool = True,
              image: bytes | None = None) -> bytes:
    """A v1 Frame: context (name, camera and laser calibrations), timestamp, pose, lasers."""
    ctx = pw.bytes_field(1, CONTEXT)
    ctx += b"".join(pw.bytes_field(2, camera_calibration_msg(c)) for c in scene.cameras)
    ctx += b"".join(pw.bytes_field(3, laser_calibration_msg(la)) for la in scene.lasers)
    out = pw.bytes_field(1, ctx) + pw.varint_field(2, timestamp) + pw.bytes_field(3, transform_msg(scene.pose))
    if image is not None:
        for cam in scene.cameras:
            out += pw.bytes_field(4, pw.varint_field(1, cam.name) + pw.bytes_field(2, image))
    if with_lasers:
        for la in scene.lasers:
            body = pw.varint_field(1, la.name)
            body += pw.bytes_field(2, range_image_msg(la.range_image, la.projection, la.pose, packed_shape))
            if la.range_image2 is not None:
                body += pw.bytes_field(3, range_image_msg(la.range_image2, la.projection2, None, packed_shape))
            out += pw.bytes_field(5, body)
    return out


# ----------------------------------------------------------------------------- v2 tables
def write_v2(root, scene: Scene, timestamp: int = TIMESTAMP, camera_key_as_string: bool = False,
             pose_as_float32: bool = True) -> None:
    """The v2 tables of one frame (lidar, lidar_camera_projection, lidar_pose, lidar_calibration,
    vehicle_pose, camera_calibration) under ``root/<tag>/<CONTEXT>.parquet``, with the type
    deviations seen in real files (string camera keys, float32 vehicle pose) on request."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    def write(tag: str, columns: dict) -> None:
        (root / tag).mkdir(parents=True, exist_ok=True)
        pq.write_table(pa.table(columns), root / tag / f"{CONTEXT}.parquet")

    def ri_columns(comp: str, arrays: list, n: int = 1) -> dict:
        values = pa.array([None if a is None else np.asarray(a, np.float32).ravel() for a in arrays],
                          pa.list_(pa.float32()))
        shapes = pa.array([None if a is None else list(a.shape) for a in arrays], pa.list_(pa.int32(), 3))
        return {f"[{comp}].range_image_return{n}.values": values, f"[{comp}].range_image_return{n}.shape": shapes}

    n = len(scene.lasers)
    keys = {"key.segment_context_name": pa.array([CONTEXT] * n),
            "key.frame_timestamp_micros": pa.array([timestamp] * n, pa.int64()),
            "key.laser_name": pa.array([la.name for la in scene.lasers], pa.int8())}
    second = ([la.range_image2 for la in scene.lasers]  # pyarrow cannot read back null fixed-size lists
              if all(la.range_image2 is not None for la in scene.lasers) else None)
    write("lidar", keys | ri_columns("LiDARComponent", [la.range_image for la in scene.lasers])
          | (ri_columns("LiDARComponent", second, 2) if second else {}))
    write("lidar_camera_projection", keys | ri_columns("LiDARCameraProjectionComponent",
                                                       [la.projection for la in scene.lasers]))
    posed = [la for la in scene.lasers if la.pose is not None]
    if posed:
        m = len(posed)
        write("lidar_pose", {"key.segment_context_name": pa.array([CONTEXT] * m),
                             "key.frame_timestamp_micros": pa.array([timestamp] * m, pa.int64()),
                             "key.laser_name": pa.array([la.name for la in posed], pa.int8())}
              | ri_columns("LiDARPoseComponent", [la.pose for la in posed]))
    cal = "[LiDARCalibrationComponent]"
    write("lidar_calibration", {
        "key.segment_context_name": pa.array([CONTEXT] * n),
        "key.laser_name": pa.array([la.name for la in scene.lasers], pa.int8()),
        f"{cal}.extrinsic.transform": pa.array([la.extrinsic.ravel().tolist() for la in scene.lasers],
                                               pa.list_(pa.float64(), 16)),
        f"{cal}.beam_inclination.min": pa.array([la.incl_min for la in scene.lasers], pa.float64()),
        f"{cal}.beam_inclination.max": pa.array([la.incl_max for la in scene.lasers], pa.float64()),
        f"{cal}.beam_inclination.values": pa.array([la.beams or None for la in scene.lasers],
                                                   pa.list_(pa.float64()))})
    write("vehicle_pose", {
        "key.segment_context_name": pa.array([CONTEXT]),
        "key.frame_timestamp_micros": pa.array([timestamp], pa.int64()),
        "[VehiclePoseComponent].world_from_vehicle.transform": pa.array(
            [scene.pose.ravel().tolist()], pa.list_(pa.float32() if pose_as_float32 else pa.float64()))})
    names = {1: "FRONT", 2: "FRONT_LEFT", 3: "FRONT_RIGHT", 4: "SIDE_LEFT", 5: "SIDE_RIGHT"}
    cams = scene.cameras
    write("camera_calibration", {
        "key.segment_context_name": pa.array([CONTEXT] * len(cams)),
        "key.camera_name": (pa.array([names[c.name] for c in cams]) if camera_key_as_string
                            else pa.array([c.name for c in cams], pa.int8())),
        "[CameraCalibrationComponent].extrinsic.transform": pa.array(
            [c.extrinsic.ravel().tolist() for c in cams], pa.list_(pa.float64(), 16)),
        **{f"[CameraCalibrationComponent].intrinsic.{k}": pa.array([float(getattr(c, a)) for c in cams])
           for k, a in (("f_u", "f"), ("f_v", "f"), ("c_u", "cu"), ("c_v", "cv"))},
        "[CameraCalibrationComponent].width": pa.array([c.width for c in cams], pa.int32()),
        "[CameraCalibrationComponent].height": pa.array([c.height for c in cams], pa.int32())})


def float32_bits(x: float) -> bytes:
    return struct.pack("<f", x)
