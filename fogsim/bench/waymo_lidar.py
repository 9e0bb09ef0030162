"""Speed of Waymo LiDAR decode + projection for one FRONT frame (1920×1280), synthetic data of
real sizes: TOP 64×2650 (range image, camera projection, per-cell pose) and four short-range
lidars 200×600, with the calibration of a real frame (TOP at (1.43, 0, 2.18) m, FRONT camera
at (1.54, −0.02, 2.12) m, f = 2044 px). The record is built once; each repeat times

  decode    :func:`fogsim.readers.waymo.lidar_v1.parse_v1_lidar` of the serialized Frame
            (protobuf split, zlib, MatrixFloat / MatrixInt32 with vectorised varints)
  project   :func:`camera_points` (all lidars, FRONT) + :func:`sparse_ray_depth` +
            :func:`filter_bleed_through` (7 px, 10 %)

against two baselines measured in the same run: ``zlib`` (inflating the five range images,
projections and the pose alone: the floor of any decoder) and ``python varints`` (decoding the
TOP camera projection with protobuf_wire's varint reader one value at a time, what a
straightforward decoder does; timed on fewer repeats, it takes about a second).

    python -m fogsim.bench.waymo_lidar [repeat]     (``bench_decode(repeat) -> dict``)
"""
from __future__ import annotations

import math
import statistics
import sys
import zlib

import numpy as np

from fogsim.bench.timing import elapsed_ms
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo.lidar_frame import LaserCalibration
from fogsim.readers.waymo.lidar_geometry import (
    beam_inclinations,
    camera_points,
    filter_bleed_through,
    range_image_to_points,
    sparse_ray_depth,
)
from fogsim.readers.waymo.lidar_v1 import FRAME_LASERS, RI_POSE, RI_PROJECTION, RI_RANGE, parse_v1_lidar
from fogsim.readers.waymo.matrix import MATRIX_DATA, decode_matrix, encode_matrix

WIDTH, HEIGHT, FOCAL = 1920, 1280, 2044.0
TOP_SHAPE, SHORT_SHAPE = (64, 2650), (200, 600)


def _rz(yaw: float) -> np.ndarray:
    m = np.eye(4)
    m[:2, :2] = [[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]
    return m


def _transform_msg(m: np.ndarray) -> bytes:
    return b"".join(pw.double_field(1, float(v)) for v in m.ravel())


def _scene_ranges(cal: LaserCalibration, shape, rng, max_range: float) -> np.ndarray:
    """Ranges of a plausible street: ground below the lidar, walls at 8–60 m, 8 % dropouts."""
    h, w = shape
    incl = beam_inclinations(cal, h)[:, None]
    mount = cal.extrinsic[2, 3]
    with np.errstate(divide="ignore"):
        ground = np.where(incl < 0, mount / np.maximum(-np.sin(incl), 1e-6), np.inf)
    walls = np.repeat(rng.uniform(8, 60, (1, w // 10 + 1)), 10, axis=1)[:, :w]
    r = np.minimum(ground, walls / np.maximum(np.cos(incl), 1e-3))
    r = np.where((r < max_range) & (rng.random((h, w)) > 0.08), r, -1.0)
    return r.astype(np.float32)


def _projection(points: np.ndarray, valid: np.ndarray, camera: np.ndarray, rng) -> np.ndarray:
    """Camera projection channels: FRONT where the pinhole sees the point, else side cameras."""
    h, w = valid.shape
    p = (points.reshape(-1, 3) - camera[:3, 3]) @ camera[:3, :3]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = FOCAL * (-p[:, 1] / p[:, 0]) + WIDTH / 2
        v = FOCAL * (-p[:, 2] / p[:, 0]) + HEIGHT / 2
    front = ((p[:, 0] > 0) & (u >= 0) & (u < WIDTH) & (v >= 0) & (v < HEIGHT)).reshape(h, w) & valid
    proj = np.zeros((h, w, 6), np.int32)
    proj[..., 0] = np.where(front, 1, np.where(valid & (rng.random((h, w)) < 0.4), rng.integers(2, 6, (h, w)), 0))
    proj[..., 1] = np.where(front, np.nan_to_num(u).reshape(h, w), rng.integers(0, WIDTH, (h, w))).astype(np.int32)
    proj[..., 2] = np.where(front, np.nan_to_num(v).reshape(h, w), rng.integers(0, 886, (h, w))).astype(np.int32)
    proj[proj[..., 0] == 0, 1:3] = -1  # "no projection" cells: −1, i.e. 10-byte varints
    proj[..., 3:] = np.where(rng.random((h, w, 1)) < 0.1, proj[..., :3], [0, -1, -1])
    return proj


def build_frame(seed: int = 0) -> bytes:
    """The serialized synthetic Frame (lasers, laser and FRONT calibrations, pose)."""
    rng = np.random.default_rng(seed)
    camera = _rz(math.radians(-0.5))
    camera[:3, 3] = [1.54, -0.02, 2.12]
    pose = _rz(0.8)
    pose[:3, 3] = [1523.4, -802.1, 12.3]
    top = np.eye(4)
    top[:3, 3] = [1.43, 0.0, 2.18]
    top = top @ _rz(math.radians(-0.8))
    beams = np.linspace(math.radians(-17.55), math.radians(2.5), 64)
    lasers = [(1, LaserCalibration(1, top, beams[0], beams[-1], beams), TOP_SHAPE, 75.0)]
    for name, (x, y, yaw) in zip((2, 3, 4, 5), ((4.07, 0, 0), (3.24, 1.02, 1.57), (3.24, -1.02, -1.57),
                                              (-1.15, 0, 3.14))):
        ext = _rz(yaw)
        ext[:3, 3] = [x, y, 0.9]
        lasers.append((name, LaserCalibration(name, ext, -math.pi / 2, math.radians(30)), SHORT_SHAPE, 20.0))
    ctx = pw.bytes_field(1, "bench_context") + pw.bytes_field(2, pw.varint_field(1, 1) + pw.bytes_field(
        3, _transform_msg(camera)) + pw.varint_field(4, WIDTH) + pw.varint_field(5, HEIGHT))
    body = b""
    for name, cal, shape, max_range in lasers:
        calib = pw.varint_field(1, name)
        if cal.beam_inclinations is not None:
            calib += b"".join(pw.double_field(2, b) for b in cal.beam_inclinations)
        calib += pw.double_field(3, cal.inclination_min) + pw.double_field(4, cal.inclination_max)
        ctx += pw.bytes_field(3, calib + pw.bytes_field(5, _transform_msg(cal.extrinsic)))
        r = _scene_ranges(cal, shape, rng, max_range)
        ri = np.stack([r, rng.random(shape), rng.random(shape) * 0.1, np.zeros(shape)], -1).astype(np.float32)
        points = range_image_to_points(ri, cal)
        msg = (pw.bytes_field(2, encode_matrix(ri))
               + pw.bytes_field(3, encode_matrix(_projection(points, r > 0, camera, rng))))
        if name == 1:
            cell = np.zeros(shape + (6,), np.float32)
            cell[..., 0:2] = rng.normal(0, 1e-3, shape + (2,))
            cell[..., 2] = 0.8 + np.linspace(-0.004, 0.004, shape[1])
            cell[..., 3:] = pose[:3, 3] + rng.normal(0, 0.05, shape + (3,))
            msg += pw.bytes_field(4, encode_matrix(cell))
        body += pw.bytes_field(5, pw.varint_field(1, name) + pw.bytes_field(2, msg))
    return pw.bytes_field(1, ctx) + pw.varint_field(2, 1) + pw.bytes_field(3, _transform_msg(pose)) + body


def _compressed_blobs(frame: bytes) -> list[bytes]:
    out = []
    for laser in pw.submessages(pw.decode_fields(frame), FRAME_LASERS):
        ri = pw.submessage(laser, 2)
        out += [pw.blob(ri, n) for n in (RI_RANGE, RI_PROJECTION, RI_POSE) if n in ri]
    return out


def _python_varints(blob: bytes) -> list[int]:
    """MatrixInt32 data decoded value by value with protobuf_wire (the straightforward way)."""
    fields = pw.decode_fields(zlib.decompress(blob))
    data = memoryview(bytes(fields[MATRIX_DATA][0]))
    out, pos = [], 0
    while pos < len(data):
        value, pos = pw._read_varint(data, pos, "bench")
        out.append(value - (1 << 64) if value >= 1 << 63 else value)
    return out


def bench_decode(repeat: int = 5) -> dict:
    """Median milliseconds (interleaved repeats) of decode, project and the baselines, plus
    the sizes: ``{"decode_ms", "project_ms", "total_ms", "zlib_ms", "python_varints_ms",
    "vector_varints_ms", "varint_speedup", "frame_mb", "points", "pixels", "dropped"}``."""
    if repeat < 1:
        raise ValueError("repeat must be ≥ 1")
    frame_bytes = build_frame()
    blobs = _compressed_blobs(frame_bytes)
    top_projection = blobs[1]
    times = {k: [] for k in ("decode", "project", "zlib", "python_varints", "vector_varints")}
    result = {}
    for i in range(repeat):
        box = {}
        times["zlib"].append(elapsed_ms(lambda: [zlib.decompress(b) for b in blobs]))
        times["decode"].append(elapsed_ms(lambda: box.setdefault("frame", parse_v1_lidar(frame_bytes, "bench"))))

        def project():
            pts = camera_points(box["frame"], "FRONT")
            depth = sparse_ray_depth(pts.uv, pts.ray, WIDTH, HEIGHT)
            result.update(points=len(pts.ray), pixels=int((depth > 0).sum()),
                          dropped=filter_bleed_through(depth)[1])
        times["project"].append(elapsed_ms(project))
        times["vector_varints"].append(elapsed_ms(lambda: decode_matrix(top_projection, "int32", "bench")))
        if i < min(repeat, 3):
            times["python_varints"].append(elapsed_ms(lambda: _python_varints(top_projection)))
    med = {f"{k}_ms": statistics.median(v) for k, v in times.items()}
    med["total_ms"] = med["decode_ms"] + med["project_ms"]
    med["varint_speedup"] = med["python_varints_ms"] / med["vector_varints_ms"]
    return med | result | {"frame_mb": len(frame_bytes) / 1e6, "repeat": repeat}


def run(repeat: int = 5) -> int:
    """Print :func:`bench_decode`'s figures (``python -m fogsim.bench.waymo_lidar``); returns 0."""
    r = bench_decode(repeat)
    print(f"Waymo LiDAR decode + FRONT projection, synthetic frame of real sizes ({r['frame_mb']:.1f} MB: "
          f"TOP 64×2650 + 4 × 200×600), medians of {repeat}:")
    print(f"  decode    {r['decode_ms']:8.1f} ms   (zlib alone {r['zlib_ms']:.1f} ms: "
          f"{r['decode_ms'] / r['zlib_ms']:.2f}× the floor)")
    print(f"  project   {r['project_ms']:8.1f} ms   ({r['points']} points → {r['pixels']} px of "
          f"{WIDTH}×{HEIGHT}, bleed filter dropped {r['dropped']})")
    print(f"  total     {r['total_ms']:8.1f} ms")
    print(f"  TOP camera projection varints: {r['vector_varints_ms']:.1f} ms vectorised vs "
          f"{r['python_varints_ms']:.0f} ms one at a time ({r['varint_speedup']:.0f}×)")
    return 0


if __name__ == "__main__":
    sys.exit(run(int(sys.argv[1]) if len(sys.argv) > 1 else 5))
