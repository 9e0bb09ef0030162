"""A small KITTI object tree (and an STF tree) written from the formats' specs, with geometry known here.

The LiDAR looks along +x; its frame maps to the rectified camera by the usual axis swap (camera x =
−y_velo, y = −z_velo, z = x_velo) plus a small offset, R0_rect a small rotation. Each frame's scan holds a
wall 30 m ahead and a car: a box of points (its surface sampled on a grid) whose centre, size and yaw are
chosen in the LiDAR frame and written as the KITTI label (camera frame, bottom centre, rotation_y).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

WIDTH, HEIGHT = 160, 48
FX = 100.0
# velo → camera: camera x = −y, y = −z, z = x, then a 5 cm offset
TR = np.array([[0.0, -1.0, 0.0, 0.02], [0.0, 0.0, -1.0, -0.08], [1.0, 0.0, 0.0, -0.27]])
R0 = np.array([[0.9999, -0.0099, 0.0074], [0.0099, 0.9999, -0.0043], [-0.0074, 0.0044, 0.9999]])
R0 = np.linalg.qr(R0)[0] * np.sign(np.diag(np.linalg.qr(R0)[1]))  # an exact rotation near R0
P2 = np.array([[FX, 0.0, 79.5, FX * 0.06], [0.0, FX, 23.5, 0.0], [0.0, 0.0, 1.0, 0.0]])
P_OTHER = np.array([[FX, 0.0, 79.5, 0.0], [0.0, FX, 23.5, 0.0], [0.0, 0.0, 1.0, 0.0]])
IMU = np.array([[1.0, 0, 0, -0.8], [0, 1.0, 0, 0.3], [0, 0, 1.0, -0.9]])


@dataclass(frozen=True)
class Car:
    """A car in the LiDAR frame: bottom-centre (x, y, z), size l w h, yaw about z."""

    x: float
    y: float
    z: float
    length: float = 4.0
    width: float = 1.8
    height: float = 1.5
    yaw: float = 0.3
    reflectance: float | None = None  # the car's points' KITTI reflectance (None: random, as the wall's)

    def surface(self, step: float = 0.25) -> np.ndarray:
        """Points on the box's faces (LiDAR frame), strictly inside it by a millimetre."""
        half = np.array([self.length, self.width, self.height]) / 2 - 1e-3
        g = [np.arange(-h, h + 1e-9, step) for h in half]
        pts = []
        for axis in range(3):
            others = [k for k in range(3) if k != axis]
            a, b = np.meshgrid(g[others[0]], g[others[1]], indexing="ij")
            for sign in (-1, 1):
                p = np.zeros((a.size, 3))
                p[:, others[0]], p[:, others[1]], p[:, axis] = a.ravel(), b.ravel(), sign * half[axis]
                pts.append(p)
        local = np.concatenate(pts)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
        return local @ rot.T + [self.x, self.y, self.z + self.height / 2]


def velo_to_rect(p: np.ndarray) -> np.ndarray:
    tr = np.vstack([TR, [0, 0, 0, 1]])
    r0 = np.eye(4)
    r0[:3, :3] = R0
    h = np.hstack([np.atleast_2d(p), np.ones((len(np.atleast_2d(p)), 1))])
    return (h @ (r0 @ tr).T)[:, :3]


def label_line(car: Car, kind: str = "Car", truncated: float = 0.0, occluded: int = 0, extra: list[str] = ()) -> str:
    """The KITTI line of ``car``: location = its bottom centre in the rectified frame; rotation_y such that
    the length axis (cos ry, 0, −sin ry) is the car's heading seen in the camera."""
    loc = velo_to_rect(np.array([[car.x, car.y, car.z]]))[0]
    head = velo_to_rect(np.array([[car.x + math.cos(car.yaw), car.y + math.sin(car.yaw), car.z]]))[0] - loc
    ry = math.atan2(-head[2], head[0])
    left, top, right, bottom = image_box(car)
    alpha = ry - math.atan2(loc[0], loc[2])
    fields = [kind, f"{truncated:.2f}", str(occluded), f"{alpha:.2f}", f"{left:.2f}", f"{top:.2f}", f"{right:.2f}",
              f"{bottom:.2f}", f"{car.height:.2f}", f"{car.width:.2f}", f"{car.length:.2f}", f"{loc[0]:.2f}",
              f"{loc[1]:.2f}", f"{loc[2]:.2f}", f"{ry:.2f}", *extra]
    return " ".join(fields)


def image_box(car: Car) -> tuple[float, float, float, float]:
    """The car's 2D box in image 2 (left, top, right, bottom; KITTI's pixel-centre coordinates)."""
    pts = velo_to_rect(car.surface())
    proj = pts @ P2[:, :3].T + P2[:, 3]
    uv = proj[:, :2] / proj[:, 2:]
    (left, top), (right, bottom) = uv.min(0), uv.max(0)
    return float(left), float(top), float(right), float(bottom)


def image(cars, background: int = 150, car: int = 40) -> np.ndarray:
    """A grey image (RGB uint8) with each car's 2D box painted dark."""
    img = np.full((HEIGHT, WIDTH, 3), background, np.uint8)
    for c in cars:
        left, top, right, bottom = image_box(c)
        x0, y0 = max(0, int(np.floor(left + 0.5))), max(0, int(np.floor(top + 0.5)))
        x1, y1 = min(WIDTH, int(np.floor(right + 0.5)) + 1), min(HEIGHT, int(np.floor(bottom + 0.5)) + 1)
        img[y0:y1, x0:x1] = car
    return img


def calib_text(tr16: bool = False, imu: bool = True, drop: str | None = None) -> str:
    rows = {"P0": P_OTHER, "P1": P_OTHER, "P2": P2, "P3": P_OTHER, "R0_rect": R0,
            "Tr_velo_to_cam": np.vstack([TR, [0, 0, 0, 1]]) if tr16 else TR}
    if imu:
        rows["Tr_imu_to_velo"] = IMU
    return "".join(f"{k}: {' '.join(f'{v:.12e}' for v in m.ravel())}\n" for k, m in rows.items() if k != drop)


def scan(car: Car, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(xyz N×3 float32, reflectance 0–1) of a wall 30 m ahead and the car's surface."""
    y, z = np.meshgrid(np.linspace(-10, 10, 40), np.linspace(-1.7, 3, 12))
    wall = np.stack([np.full(y.size, 30.0), y.ravel(), z.ravel()], 1)
    pts = np.concatenate([wall, car.surface()])
    refl = np.round(rng.uniform(0.05, 0.6, len(pts)), 2)
    if car.reflectance is not None:
        refl[len(wall):] = car.reflectance
    return pts.astype(np.float32), refl.astype(np.float32)


CARS = {"000000": Car(12.0, 1.0, -1.7), "000001": Car(20.0, -2.0, -1.7, yaw=-0.5), "000002": Car(8.0, 0.5, -1.7)}


def write_kitti(root: Path, frames=CARS, dontcare: bool = True) -> Path:
    """``root/training/{image_2,velodyne,calib,label_2}`` + ``ImageSets/{train,val}.txt``; returns root.
    Each image is grey with its car's 2D box painted dark (:func:`image`)."""
    rng = np.random.default_rng(0)
    base = root / "training"
    for d in ("image_2", "velodyne", "calib", "label_2"):
        (base / d).mkdir(parents=True, exist_ok=True)
    for fid, car in frames.items():
        cv2.imwrite(str(base / "image_2" / f"{fid}.png"), image([car]))
        xyz, refl = scan(car, rng)
        rec = np.empty((len(xyz), 4), "<f4")
        rec[:, :3], rec[:, 3] = xyz, refl
        (base / "velodyne" / f"{fid}.bin").write_bytes(rec.tobytes())
        (base / "calib" / f"{fid}.txt").write_text(calib_text())
        lines = [label_line(car, truncated=0.1, occluded=1)]
        if dontcare:
            lines.append("DontCare -1 -1 -10 100.00 10.00 120.00 30.00 -1 -1 -1 -1000 -1000 -1000 -10")
        (base / "label_2" / f"{fid}.txt").write_text("\n".join(lines) + "\n")
    (root / "ImageSets").mkdir(exist_ok=True)
    ids = sorted(frames)
    (root / "ImageSets" / "train.txt").write_text("\n".join(ids[:2]) + "\n")
    (root / "ImageSets" / "val.txt").write_text("\n".join(ids[2:] or ids[-1:]) + "\n")
    return root


STF_IDS = ("2018-02-06_14-25-51_00400", "2018-10-29_16-00-52_02660")


def write_stf(root: Path, returns: str = "strongest") -> Path:
    """An STF tree: cam_stereo_left_lut/*.png, lidar_hdl64_<returns>/*.bin (5 floats, intensity 0–255,
    ring), gt_labels/cam_left_labels_TMP/*.txt (27 fields), and one KITTI-form calib.txt (no
    Tr_imu_to_velo, a 16-value Tr_velo_to_cam) beside the tree."""
    rng = np.random.default_rng(1)
    for d in ("cam_stereo_left_lut", f"lidar_hdl64_{returns}", "gt_labels/cam_left_labels_TMP"):
        (root / d).mkdir(parents=True, exist_ok=True)
    for k, fid in enumerate(STF_IDS):
        cv2.imwrite(str(root / "cam_stereo_left_lut" / f"{fid}.png"), np.zeros((HEIGHT, WIDTH, 3), np.uint8))
        car = Car(10.0 + 5 * k, 0.0, -1.7)
        xyz, refl = scan(car, rng)
        rec = np.empty((len(xyz), 5), "<f4")
        rec[:, :3], rec[:, 3], rec[:, 4] = xyz, np.round(refl * 255), np.arange(len(xyz)) % 64
        (root / f"lidar_hdl64_{returns}" / f"{fid}.bin").write_bytes(rec.tobytes())
        extra = ["0.0", "0.0", "0.0", "1.0", "0.0", "0.0", "0.0", "1.0", "True", "True", "False", "True"]
        lines = [label_line(car, "PassengerCar", extra=extra), label_line(Car(25, 4, -1.7), "train", extra=extra)]
        (root / "gt_labels" / "cam_left_labels_TMP" / f"{fid}.txt").write_text("\n".join(lines) + "\n")
    calib = root.parent / f"{root.name}_calib.txt"
    calib.write_text(calib_text(tr16=True, imu=False))
    return calib


def read_kitti_frame(level_root: Path, fid: str, part: str = "training"):
    """A KITTI reader written from the format's description alone: (points N×4 float32, calib {key: values},
    label lines split in fields, (width, height) of the PNG). Asserts the spec: 16-byte records, the seven
    calib keys with 12/9/12/12 values, 15 fields per label line, a PNG signature."""
    import struct

    base = level_root / part
    data = (base / "velodyne" / f"{fid}.bin").read_bytes()
    assert len(data) % 16 == 0
    points = [struct.unpack("<4f", data[i:i + 16]) for i in range(0, len(data), 16)]
    calib = {}
    for line in (base / "calib" / f"{fid}.txt").read_text().splitlines():
        key, values = line.split(":", 1)
        calib[key] = [float(v) for v in values.split()]
    assert set(calib) == {"P0", "P1", "P2", "P3", "R0_rect", "Tr_velo_to_cam", "Tr_imu_to_velo"}
    assert [len(calib[k]) for k in ("P2", "R0_rect", "Tr_velo_to_cam", "Tr_imu_to_velo")] == [12, 9, 12, 12]
    label_file = base / "label_2" / f"{fid}.txt"
    labels = [line.split() for line in label_file.read_text().splitlines()] if label_file.exists() else None
    assert labels is None or all(len(f) == 15 for f in labels)
    png = (base / "image_2" / f"{fid}.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    return np.array(points, np.float32).reshape(-1, 4), calib, labels, struct.unpack(">II", png[16:24])


# ----------------------------------------------------------------------------- a street, ray-cast
#: the street of :func:`street_scan`: ground 1.73 m below the sensor, house fronts 9 m to each side
GROUND_Z, HOUSE_Y = -1.73, 9.0
#: KITTI reflectance of the ground (asphalt, ρ ≈ 0.2 with the hdl64e preset) and of the house fronts
GROUND_REFLECTANCE, HOUSE_REFLECTANCE = 0.08, 0.25


def _box_hits(d: np.ndarray, car: Car, origins: np.ndarray | None = None) -> np.ndarray:
    """Ray parameter t (metres, rays from ``origins`` — default the origin — along unit ``d``) where each ray
    enters the car's box (inf: a miss); the slab method in the box's own frame."""
    c, s = math.cos(car.yaw), math.sin(car.yaw)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    centre = np.array([car.x, car.y, car.z + car.height / 2])
    half = np.array([car.length, car.width, car.height]) / 2
    o, dl = ((0.0 if origins is None else origins) - centre) @ rot, d @ rot
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-half - o) / dl, (half - o) / dl
    near = np.nanmax(np.minimum(t1, t2), axis=1)
    far = np.nanmin(np.maximum(t1, t2), axis=1)
    return np.where((far >= near) & (near > 0), near, np.inf)


def street_scan(cars: list[Car], rng: np.random.Generator, azimuth_deg: float = 60.0, step_deg: float = 0.2,
                max_range: float = 100.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A spinning LiDAR's sweep (the ``hdl64e`` preset's 64 lasers — KITTI's HDL-64E: two blocks, each
    laser's line its ``vertical_offsets_m`` off the origin — ±``azimuth_deg`` about +x) of a street: the
    ground, two house fronts and the cars (their reflectance, else 0.1–0.4), each ray's first hit within
    ``max_range``. Returns (xyz N×3 float32, KITTI reflectance N float32, hit id N: −1 ground, −2 houses,
    k car k)."""
    from fogsim.lidar.sensors import LidarSensor

    sensor = LidarSensor.preset("hdl64e")
    az = np.radians(np.arange(-azimuth_deg, azimuth_deg + 1e-9, step_deg))
    E, A = np.meshgrid(sensor.inclinations_rad, az, indexing="ij")
    H = np.broadcast_to(np.asarray(sensor.vertical_offsets_m)[:, None], E.shape)
    d = np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], -1).reshape(-1, 3)
    o = (H[..., None] * np.stack([-np.sin(E) * np.cos(A), -np.sin(E) * np.sin(A), np.cos(E)], -1)).reshape(-1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ground = np.where(d[:, 2] < 0, (GROUND_Z - o[:, 2]) / d[:, 2], np.inf)
        t_house = np.where(np.abs(d[:, 1]) > 1e-9, (HOUSE_Y * np.sign(d[:, 1]) - o[:, 1]) / d[:, 1], np.inf)
    t = np.stack([t_ground, t_house] + [_box_hits(d, c, o) for c in cars], 1)
    which = np.argmin(t, 1)
    best = t[np.arange(len(t)), which]
    hit = np.isfinite(best) & (best <= max_range)
    which, best, d, o = which[hit], best[hit], d[hit], o[hit]
    xyz = o + d * best[:, None]
    ids = np.where(which == 0, -1, np.where(which == 1, -2, which - 2))
    refl = np.where(ids == -1, GROUND_REFLECTANCE, HOUSE_REFLECTANCE) + rng.normal(0, 0.01, len(ids))
    for k, car in enumerate(cars):
        refl[ids == k] = car.reflectance if car.reflectance is not None else rng.uniform(0.1, 0.4)
    return xyz.astype(np.float32), np.clip(np.round(refl, 3), 0, 1).astype(np.float32), ids


def write_kitti_street(root: Path, frames: dict[str, list[Car]], seed: int = 0) -> Path:
    """A KITTI tree of ray-cast street frames (:func:`street_scan`), each car labelled (and painted: dark
    cars dark, bright cars light) — the fixture of the docs' cross-sensor table."""
    rng = np.random.default_rng(seed)
    base = root / "training"
    for d in ("image_2", "velodyne", "calib", "label_2"):
        (base / d).mkdir(parents=True, exist_ok=True)
    for fid, cars in frames.items():
        img = np.full((HEIGHT, WIDTH, 3), 150, np.uint8)
        for car in sorted(cars, key=lambda c: -c.x):  # far first: near cars cover them
            shade = 40 if (car.reflectance or 0.2) < 0.2 else 230
            img = np.where(image([car], 0, 1).astype(bool), np.uint8(shade), img)
        cv2.imwrite(str(base / "image_2" / f"{fid}.png"), img)
        xyz, refl, _ = street_scan(cars, rng)
        rec = np.empty((len(xyz), 4), "<f4")
        rec[:, :3], rec[:, 3] = xyz, refl
        (base / "velodyne" / f"{fid}.bin").write_bytes(rec.tobytes())
        (base / "calib" / f"{fid}.txt").write_text(calib_text())
        loose = [replace(c, length=c.length + 0.1, width=c.width + 0.1, height=c.height + 0.1, z=c.z - 0.05)
                 for c in cars]  # a label box 5 cm outside the surface, as annotators draw them
        (base / "label_2" / f"{fid}.txt").write_text("".join(label_line(c) + "\n" for c in loose))
    return root


#: six frames of four cars each, 6–75 m ahead, dark (ρ ≈ 0.13) and bright (ρ ≈ 0.9) in turn
STREET = {f"{k:06d}": [Car(d + 3 * k, lane, GROUND_Z, yaw=0.1 * k, reflectance=refl)
                       for d, lane, refl in ((6.0, -3.0, 0.05), (14.0, 3.0, 0.35), (28.0, -3.5, 0.05),
                                             (52.0, 2.5, 0.35))]
          for k in range(6)}
