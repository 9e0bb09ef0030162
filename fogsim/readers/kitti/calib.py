"""KITTI object-detection calibration files (``calib/NNNNNN.txt``), and the Seeing Through Fog (STF)
calibration in the same form.

A file holds lines ``KEY: v1 v2 …``: ``P0``–``P3`` (3×4, row-major: the projection of each rectified
camera; P2 = the left colour camera), ``R0_rect`` (3×3), ``Tr_velo_to_cam`` (3×4; STF's converted
files write 4×4) and ``Tr_imu_to_velo`` (3×4; STF has none). Conventions:

* A LiDAR point X (homogeneous) lands in image 2 at ``P2 · R0_rect(4×4) · Tr_velo_to_cam(4×4) · X``
  divided by its third row. The rectified camera frame: x right, y down, z forward (metres).
* Pixel coordinates from P: integer values are pixel **centres** (as OpenCV); fogsim's pixel-edge
  coordinates (:func:`fogsim.camera.pixel_index`) are those + 0.5 (:meth:`KittiCalib.project_velo`).
* Camera 2's centre is not the rectified frame's origin: P2 = K·[I | t] puts it at C2 = −t (≈ 6 cm to
  the left of camera 0); ray distances are measured from C2 (:meth:`KittiCalib.camera_centre`).
* A missing key, a wrong number of values, a non-finite value, or a singular matrix (R0_rect, the
  rotation of Tr_velo_to_cam, the left 3×3 of P2) is one :class:`~fogsim.errors.InputError` naming the file.

STF (:func:`stf_calib_from_tf`): the repository's ``tools/DatasetViewer/calibs`` hold the camera's ROS
CameraInfo (``calib_cam_stereo_left.json``: ``P`` 3×4, already rectified, so R0_rect = I) and the TF tree
(``calib_tf_tree_full.json``: each frame's translation + quaternion in its parent, ROS order, all in
``body``): Tr_velo_to_cam = inv(body→camera) · body→lidar, with the frames ``cam_stereo_left_optical``
and ``lidar_hdl64_s3_roof``, as the repository's ``lib/read.py`` composes them.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsim.camera import Intrinsics
from fogsim.errors import InputError
from fogsim.io.documents import read_text_file

__all__ = ["KEYS", "KittiCalib", "format_kitti_calib", "read_kitti_calib", "stf_calib_from_tf"]

KEYS = ("P0", "P1", "P2", "P3", "R0_rect", "Tr_velo_to_cam", "Tr_imu_to_velo")
SHAPES = {"P0": (3, 4), "P1": (3, 4), "P2": (3, 4), "P3": (3, 4), "R0_rect": (3, 3), "Tr_velo_to_cam": (3, 4),
          "Tr_imu_to_velo": (3, 4)}
#: |det| below this is a singular matrix (a rotation has det 1; a P2's left 3×3 has det ≈ f², ~10⁵–10⁷)
SINGULAR = 1e-6


def _pad(m: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[: m.shape[0], : m.shape[1]] = m
    return out


@dataclass(frozen=True)
class KittiCalib:
    """One frame's calibration (float64): ``P`` = (P0, P1, P2, P3) 3×4, ``R0_rect`` 3×3,
    ``Tr_velo_to_cam`` 4×4, ``Tr_imu_to_velo`` 4×4 or None; ``source`` the file."""

    P: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
    R0_rect: np.ndarray
    Tr_velo_to_cam: np.ndarray
    Tr_imu_to_velo: np.ndarray | None
    source: str

    @property
    def velo_to_rect(self) -> np.ndarray:
        """4×4: LiDAR frame → rectified camera frame (R0_rect · Tr_velo_to_cam)."""
        return _pad(self.R0_rect) @ self.Tr_velo_to_cam

    @property
    def rect_to_velo(self) -> np.ndarray:
        return np.linalg.inv(self.velo_to_rect)

    def projection(self, camera: int = 2) -> np.ndarray:
        """3×4: LiDAR point → image ``camera`` (P · R0_rect · Tr_velo_to_cam)."""
        return self.P[camera] @ self.velo_to_rect

    def camera_centre(self, camera: int = 2) -> np.ndarray:
        """The centre of camera ``camera`` in the rectified frame: C = −M⁻¹·p₄ (P = [M | p₄])."""
        P = self.P[camera]
        return -np.linalg.solve(P[:, :3], P[:, 3])

    def intrinsics(self, width: int, height: int, camera: int = 2) -> Intrinsics:
        """The image's pinhole intrinsics from P (fx, fy, cx, cy; centre convention as OpenCV)."""
        P = self.P[camera]
        return Intrinsics(float(P[0, 0]), float(P[1, 1]), float(P[0, 2]), float(P[1, 2]), int(width), int(height))

    def project_velo(self, xyz: np.ndarray, camera: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(uv N×2 fogsim pixel-edge coordinates, depth N along the camera axis, ray N = distance from the
        camera's centre) of LiDAR points; points with depth ≤ 0 get uv = NaN."""
        xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
        h = np.hstack([xyz, np.ones((len(xyz), 1))])
        p = h @ self.projection(camera).T
        depth = p[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = p[:, :2] / depth[:, None] + 0.5
        uv[depth <= 0] = np.nan
        rect = h @ self.velo_to_rect.T
        ray = np.linalg.norm(rect[:, :3] - self.camera_centre(camera), axis=1)
        return uv, depth, ray

    def velo_from_rect(self, xyz_rect: np.ndarray) -> np.ndarray:
        """Rectified-camera points (N×3) → the LiDAR frame."""
        xyz_rect = np.asarray(xyz_rect, np.float64).reshape(-1, 3)
        m = self.rect_to_velo
        return xyz_rect @ m[:3, :3].T + m[:3, 3]


def _check(calib: KittiCalib) -> KittiCalib:
    src = calib.source
    for what, m in (("R0_rect", calib.R0_rect), ("the rotation of Tr_velo_to_cam", calib.Tr_velo_to_cam[:3, :3]),
                    ("the left 3×3 of P2", calib.P[2][:, :3])):
        if abs(np.linalg.det(m)) < SINGULAR:
            raise InputError(src, f"{what} is singular (determinant {np.linalg.det(m):.3g}): a damaged calibration")
    return calib


def read_kitti_calib(path: str | os.PathLike, require_imu: bool = True) -> KittiCalib:
    """The calibration in ``path`` (the module docstring's keys; ``require_imu=False`` for STF's files,
    which have no Tr_imu_to_velo)."""
    path = Path(path)
    text = read_text_file(path, "calibration file")
    values: dict[str, np.ndarray] = {}
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        key, sep, rest = line.partition(":")
        if not sep:
            raise InputError(path, f"line {n}: expected 'KEY: values', got {line.strip()[:40]!r}")
        try:
            values[key.strip()] = np.array([float(v) for v in rest.split()], np.float64)
        except ValueError:
            raise InputError(path, f"line {n} ({key.strip()}): values are not all numbers") from None
    wanted = [k for k in KEYS if require_imu or k != "Tr_imu_to_velo"]
    missing = [k for k in wanted if k not in values]
    if missing:
        raise InputError(path, f"missing calibration key{'s' if len(missing) > 1 else ''} {', '.join(missing)}")
    mats = {}
    for key in KEYS:
        if key not in values:
            continue
        v, shape = values[key], SHAPES[key]
        if key.startswith("Tr_") and v.size == 16:
            if not np.allclose(v[12:], (0, 0, 0, 1)):
                raise InputError(path, f"{key}: a 4×4 transform's bottom row must be 0 0 0 1, got {v[12:].tolist()}")
            v = v[:12]
        if v.size != shape[0] * shape[1]:
            raise InputError(path, f"{key} has {v.size} values, expected {shape[0] * shape[1]} ({shape[0]}×{shape[1]})")
        if not np.isfinite(v).all():
            raise InputError(path, f"{key} holds NaN or infinite values")
        mats[key] = v.reshape(shape)
    return _check(KittiCalib(tuple(mats[f"P{i}"] for i in range(4)), mats["R0_rect"], _pad(mats["Tr_velo_to_cam"]),
                             _pad(mats["Tr_imu_to_velo"]) if "Tr_imu_to_velo" in mats else None, str(path)))


def format_kitti_calib(calib: KittiCalib) -> str:
    """The calibration as a KITTI ``calib/*.txt`` (every key; an absent Tr_imu_to_velo as identity)."""
    def row(m):
        return " ".join(f"{float(v):.12e}" for v in np.asarray(m).ravel())
    imu = calib.Tr_imu_to_velo if calib.Tr_imu_to_velo is not None else np.eye(4)
    lines = [f"P{i}: {row(calib.P[i])}" for i in range(4)]
    lines += [f"R0_rect: {row(calib.R0_rect)}", f"Tr_velo_to_cam: {row(calib.Tr_velo_to_cam[:3])}",
              f"Tr_imu_to_velo: {row(imu[:3])}"]
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- STF's ROS calibration
STF_CAMERA, STF_LIDAR = "cam_stereo_left_optical", "lidar_hdl64_s3_roof"
STF_CAMERA_FILE, STF_TF_FILE = "calib_cam_stereo_left.json", "calib_tf_tree_full.json"


def _quaternion_matrix(x: float, y: float, z: float, w: float) -> np.ndarray:
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not n > 0:
        raise ValueError("zero quaternion")
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _read_json(path: Path):
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(path, f"not a readable JSON file ({exc})") from None


def stf_calib_from_tf(folder: str | os.PathLike, camera: str = STF_CAMERA, lidar: str = STF_LIDAR) -> KittiCalib:
    """The KITTI-form calibration of STF's left camera and HDL-64 from the repository's ROS files in
    ``folder`` (the module docstring). P0–P3 are all the camera's P (only P2 is used)."""
    folder = Path(folder)
    cam_path, tf_path = folder / STF_CAMERA_FILE, folder / STF_TF_FILE
    cam = _read_json(cam_path)
    try:
        P = np.asarray(cam["P"], np.float64).reshape(3, 4)
    except (KeyError, TypeError, ValueError):
        raise InputError(cam_path, "needs 'P': 12 numbers (the rectified 3×4 projection)") from None
    tree = _read_json(tf_path)
    frames = {}
    try:
        for item in tree:
            t, q = item["transform"]["translation"], item["transform"]["rotation"]
            m = np.eye(4)
            m[:3, :3] = _quaternion_matrix(q["x"], q["y"], q["z"], q["w"])
            m[:3, 3] = (t["x"], t["y"], t["z"])
            frames[item["child_frame_id"]] = (item["header"]["frame_id"], m)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(tf_path, f"not a TF tree (list of header/transform/child_frame_id): {exc}") from None
    for name in (camera, lidar):
        if name not in frames:
            raise InputError(tf_path, f"no transform for frame {name!r}")
    (p_cam, body_cam), (p_lid, body_lid) = frames[camera], frames[lidar]
    if p_cam != p_lid:
        raise InputError(tf_path, f"{camera} is given in {p_cam!r} and {lidar} in {p_lid!r}: expected one parent")
    tr = np.linalg.inv(body_cam) @ body_lid
    return _check(KittiCalib((P, P, P, P), np.eye(3), tr, None, f"{cam_path} + {tf_path.name}"))
