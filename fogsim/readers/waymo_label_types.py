"""The records Waymo 2D labels are built from, shared by the v1 and v2 parsers.

Units and conventions: 2D boxes (:class:`Box2D`) are as Waymo stores them, centre ``cx, cy`` and
extents in pixels (``length`` along image x, ``width`` along image y); 3D laser box centres
(:class:`LaserBox`) are in the vehicle frame, metres; extrinsics are camera→vehicle 4×4 matrices
(Waymo's camera frame: x forward, y left, z up). The ``SOURCE_*`` strings name the rule that gave
a box its ``distance_m`` (see :mod:`fogsim.readers.waymo_labels`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from fogsim.errors import InputError
from fogsim.readers.base import Labels
from fogsim.readers.waymo import CAMERA_NAMES

#: The Waymo study's class list (YOLO id = index); VEHICLE includes vans, trucks, buses, motorcycles.
WAYMO_CLASSES = ("vehicle", "pedestrian", "cyclist")
#: Label.Type → class name; other types (UNKNOWN 0, SIGN 3) are not 2D objects.
TYPE_CLASS = {1: "vehicle", 2: "pedestrian", 4: "cyclist"}
CAMERA_BY_ID = {v: k for k, v in CAMERA_NAMES.items()}

SOURCE_ASSOCIATION = "laser box centre (association)"
SOURCE_MATCH = "laser box centre (projected-box match)"
SOURCE_POINTS = "lidar points in box (near cluster)"
SOURCE_UNKNOWN = "unknown"

#: A picklable callable ``(camera name, e.g. "FRONT") → (uv, ray)`` giving the LiDAR points that
#: project into that camera: ``uv`` N×2 pixel-edge image coordinates (x along the width, y along
#: the height), ``ray`` N ray distances camera centre → point in metres; or None when it has none.
PointsProvider = Callable[[str], "tuple[np.ndarray, np.ndarray] | None"]


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


def camera_extrinsic(values, source: str) -> np.ndarray | None:
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


def finite_floats(values, what: str, source: str) -> list[float]:
    """``values`` as floats; refused (naming ``what``) unless all are finite numbers."""
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
