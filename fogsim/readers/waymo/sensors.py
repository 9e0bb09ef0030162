"""Waymo's sensor names and camera calibration: the facts every other Waymo module builds on.

Names are the ``CameraName.Name`` and ``LaserName.Name`` enums of WOD ``dataset.proto`` (the v2
tables store the same values in ``key.camera_name`` / ``key.laser_name``). A camera's calibration is
Waymo's pinhole ``f_u, f_v, c_u, c_v`` in pixels (OpenCV convention) with its width and height, plus
the lens distortion ``k1, k2, p1, p2, k3``, which fogsim records but does not remove.
"""
from __future__ import annotations

from typing import Iterable

import numpy as np

from fogsim.camera import Intrinsics
from fogsim.errors import InputError

#: CameraName.Name enum of dataset.proto (UNKNOWN = 0 is not selectable)
CAMERA_NAMES = {"FRONT": 1, "FRONT_LEFT": 2, "FRONT_RIGHT": 3, "SIDE_LEFT": 4, "SIDE_RIGHT": 5,
                "REAR_LEFT": 6, "REAR": 7, "REAR_RIGHT": 8}
#: enum value → camera name
CAMERA_BY_ID = {v: k for k, v in CAMERA_NAMES.items()}
#: LaserName.Name enum of dataset.proto
LASER_NAMES = {"TOP": 1, "FRONT": 2, "SIDE_LEFT": 3, "SIDE_RIGHT": 4, "REAR": 5}
_LASER_BY_ID = {v: k for k, v in LASER_NAMES.items()}
#: the distortion coefficients, in the order Waymo stores them after the pinhole values
DISTORTION = ("k1", "k2", "p1", "p2", "k3")

#: One camera's calibration: its intrinsics (None when incomplete) and distortion {name: value}.
Calibration = tuple[Intrinsics | None, dict]


def camera_ids(cameras: Iterable[str] | str) -> dict[int, str]:
    """Camera names (case-insensitive) → ``{enum value: NAME}`` in the given order."""
    names = [cameras] if isinstance(cameras, str) else list(cameras)
    unknown = [n for n in names if str(n).upper() not in CAMERA_NAMES]
    if unknown or not names:
        given = ", ".join(map(repr, unknown)) or "(none given)"
        raise ValueError(f"unknown Waymo camera(s) {given}; valid: {', '.join(CAMERA_NAMES)}")
    return {CAMERA_NAMES[str(n).upper()]: str(n).upper() for n in names}


def sensor_enum(value, source: str, column: str = "key.camera_name", names: dict[str, int] = CAMERA_NAMES) -> int:
    """A v2 sensor key (``key.camera_name`` / ``key.laser_name``) as its enum value: an integer,
    a numeric string ("1") or a name of ``names`` ("FRONT", as some real files have; "FRONT" is 1
    as a camera, 2 as a lidar); anything else (null, a list, another word) is refused naming
    ``column`` and the value."""
    if isinstance(value, str):
        v = value.strip().upper()
        if v.lstrip("-").isdigit():
            return int(v)
        if v in names:
            return names[v]
    elif isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
        return int(value)
    raise InputError(source, f"malformed {column} {value!r} (a sensor number or one of {', '.join(names)})")


def laser_name(laser: int) -> str:
    """A lidar's name (``"TOP"`` …), or ``"laser <n>"`` for a value outside the enum."""
    return _LASER_BY_ID.get(laser, f"laser {laser}")


def calibration(pinhole: list, width: int | None, height: int | None,
                distortion: dict, source: str) -> Calibration:
    """Intrinsics (None when incomplete) and the distortion coefficients of one camera.

    Values that are there but unusable (non-finite, f ≤ 0) are refused naming ``source``."""
    if len(pinhole) < 4 or None in pinhole[:4] or not width or not height:
        return None, distortion
    try:
        return Intrinsics(*(float(v) for v in pinhole[:4]), int(width), int(height)), distortion
    except (TypeError, ValueError) as exc:
        raise InputError(source, f"unusable camera calibration ({exc})") from None
