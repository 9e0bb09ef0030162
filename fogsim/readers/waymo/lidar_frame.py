"""The decoded LiDAR data of one Waymo frame (v1 and v2 readers both produce it) and its checks.

Conventions: extrinsics are 4×4 float64 sensor→vehicle (metres); inclinations in radians;
range images H×W×4 float32 (channel 0 the range in metres along the beam, ≤ 0 = no return);
camera projections H×W×6 int32 (camera id, x, y, then the second projection); per-cell pose
range images H×W×6 (roll, pitch, yaw, x, y, z vehicle→world, TOP only); the frame pose 4×4
vehicle→world. Lidars are identified by the ``LaserName`` enum
(:data:`fogsim.readers.waymo.sensors.LASER_NAMES`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fogsim.errors import InputError
from fogsim.readers.waymo.sensors import laser_name


class NoLidar(InputError):
    """The frame has no LiDAR range images (a test-split or camera-only frame): a per-frame
    problem, which the label reader treats as "no points" and ``--depth-from lidar`` reports."""


@dataclass(frozen=True)
class LaserCalibration:
    """One lidar's calibration: ``extrinsic`` 4×4 lidar→vehicle; inclinations in radians
    (``beam_inclinations`` ascending as stored, or None for uniform spacing in [min, max])."""

    laser: int
    extrinsic: np.ndarray
    inclination_min: float | None = None
    inclination_max: float | None = None
    beam_inclinations: np.ndarray | None = None


@dataclass(frozen=True)
class LaserReturn:
    """One return of one lidar: range image H×W×4 float32 (0 range, 1 intensity, 2 elongation,
    3 no-label zone) and camera projection H×W×6 int32 (or None)."""

    range_image: np.ndarray
    camera_projection: np.ndarray | None


@dataclass
class LidarFrame:
    """The LiDAR data of one frame. ``returns[laser][n]`` is return n (1 or 2); ``pixel_poses``
    holds the per-cell pose range images (H×W×6, TOP only); ``cameras`` the camera→vehicle
    extrinsics (4×4) by camera id; ``pose`` the frame's vehicle→world pose (None if unknown)."""

    source: str
    returns: dict[int, dict[int, LaserReturn]]
    calibrations: dict[int, LaserCalibration]
    cameras: dict[int, np.ndarray] = field(default_factory=dict)
    pose: np.ndarray | None = None
    pixel_poses: dict[int, np.ndarray] = field(default_factory=dict)


def matrix4(values, source: str, what: str) -> np.ndarray:
    """A 4×4 float64 rigid transform from 16 row-major values; refused (naming ``what``) unless
    all are finite and the bottom row is [0, 0, 0, 1] (every Waymo transform is rigid: another
    bottom row is a damaged matrix, and one of zeros cannot be inverted)."""
    m = np.asarray(values, np.float64)
    if m.size != 16 or not np.isfinite(m).all():
        raise InputError(source, f"malformed {what}: expected 16 finite values, got {m.size}")
    m = m.reshape(4, 4)
    if not np.allclose(m[3], (0, 0, 0, 1), atol=1e-6):
        raise InputError(source, f"malformed {what}: its bottom row is {m[3].tolist()}, not [0, 0, 0, 1] "
                                 "(not a rigid transform)")
    return m


def require_lidar(frame: LidarFrame, what: str) -> LidarFrame:
    """``frame`` when it has range images and a calibration for each of their lidars; else
    :class:`NoLidar` (``what`` says what was looked for) or an :class:`InputError`."""
    if not frame.returns:
        raise NoLidar(frame.source, f"frame has no LiDAR range images ({what})")
    missing = [laser_name(k) for k in frame.returns if k not in frame.calibrations]
    if missing:
        raise InputError(frame.source, f"no laser calibration for {', '.join(missing)}")
    return frame


#: the ranges a return may have, metres: above any automotive lidar's reach (Waymo's: 75 m TOP,
#: 20 m the others) and below a millimetre are not measurements (≤ 0 is "no return")
MIN_RANGE_M, MAX_RANGE_M = 1e-3, 1000.0


def check_shapes(image: np.ndarray, proj: np.ndarray | None, pose: np.ndarray | None, where: str) -> None:
    """Refuse a range image that is not H×W×C or holds a range that is not a measurement
    (non-finite, or a return outside [:data:`MIN_RANGE_M`, :data:`MAX_RANGE_M`]), or a camera
    projection / cell pose not H×W×6 of its size."""
    if image.ndim != 3 or image.shape[2] < 1:
        raise InputError(where, f"range image has shape {list(image.shape)}, expected [H, W, 4]")
    ranges = image[..., 0]
    returns = ranges[ranges > 0]
    bad = ~np.isfinite(ranges).all() or (returns.size and (returns.min() < MIN_RANGE_M or returns.max() > MAX_RANGE_M))
    if bad:
        finite = returns[np.isfinite(returns)]
        span = f"{float(finite.min()):g} … {float(finite.max()):g} m" if finite.size else "none finite"
        raise InputError(where, f"range image holds ranges that are not measurements (returns {span}"
                                f"{', and NaN or infinite values' if not np.isfinite(ranges).all() else ''}; "
                                f"a return lies in [{MIN_RANGE_M:g}, {MAX_RANGE_M:g}] m): a damaged frame")
    for what, m in (("camera projection", proj), ("range image pose", pose)):
        if m is not None and (m.ndim != 3 or m.shape[:2] != image.shape[:2] or m.shape[2] < 6):
            raise InputError(where, f"{what} has shape {list(m.shape)}, expected "
                                    f"[{image.shape[0]}, {image.shape[1]}, 6]")
