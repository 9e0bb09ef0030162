"""Waymo 2D camera labels as fogsim :class:`~fogsim.readers.base.Labels`, with a distance per box:
what they are made of, and the records the v1 and v2 parsers fill.

Sources (field numbers and columns as in WOD ``dataset.proto``, ``label.proto`` and
``v2/perception/*.py``; ``docs/real-data.md`` tells how to use them):

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

The readers (:class:`~.labels_v1.WaymoV1Labels`, :class:`~.labels_v2.WaymoV2Labels`) are picklable
and hold where the labels are (a :class:`~.address.V1Record`, or a :class:`~.address.V2Frame` and
the file name), never the labels.

Modules: this one (records, classes, distance sources), :mod:`.label_distance` (pixel boxes,
matching, distances, the :class:`Labels` built from them), :mod:`.labels_v1` (v1 Frames) and
:mod:`.labels_v2` (v2 tables).

Units and conventions of the records: 2D boxes (:class:`Box2D`) are as Waymo stores them, centre
``cx, cy`` and extents in pixels (``length`` along image x, ``width`` along image y); 3D laser box
centres (:class:`LaserBox`) are in the vehicle frame, metres; extrinsics are camera→vehicle 4×4
matrices (Waymo's camera frame: x forward, y left, z up).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from fogsim.errors import InputError
from fogsim.readers.base import Labels
from fogsim.readers.waymo.lidar_frame import matrix4

#: The Waymo study's class list (YOLO id = index); VEHICLE includes vans, trucks, buses, motorcycles.
WAYMO_CLASSES = ("vehicle", "pedestrian", "cyclist")
#: Label.Type → class name; other types (UNKNOWN 0, SIGN 3) are not 2D objects.
TYPE_CLASS = {1: "vehicle", 2: "pedestrian", 4: "cyclist"}

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
    """One 3D laser label: its id, type, box centre in the vehicle frame (metres), and — where the data
    has them — its size (length along the heading, width, height; metres) and heading (rad about z)."""

    id: str
    type: int
    center: tuple[float, float, float]
    num_points: int | None = None
    size: tuple[float, float, float] | None = None
    heading: float | None = None

    def record(self) -> dict | None:
        """``{"center_m", "size_m": [l, w, h], "heading_rad"}`` (vehicle frame), None without a size."""
        if self.size is None or min(self.size) <= 0:
            return None
        return {"center_m": [round(v, 4) for v in self.center], "size_m": [round(v, 4) for v in self.size],
                "heading_rad": round(self.heading or 0.0, 6)}


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
    m = matrix4(values, source, "camera extrinsic")
    if abs(np.linalg.det(m[:3, :3])) < 1e-9:
        raise InputError(source, "unusable camera extrinsic (its rotation is singular)")
    return m


#: the largest magnitude a label coordinate may have (pixels, or metres for 3D boxes): far beyond
#: any image or LiDAR range, small enough that box edges (centre ± extent / 2) stay finite
MAX_LABEL_COORDINATE = 1e7


def finite_floats(values, what: str, source: str) -> list[float]:
    """``values`` as floats; refused (naming ``what``) unless all are finite numbers of magnitude
    ≤ :data:`MAX_LABEL_COORDINATE`."""
    try:
        out = [float(v) for v in values]
    except (TypeError, ValueError):
        out = [math.nan]
    if not all(math.isfinite(v) for v in out):
        raise InputError(source, f"malformed {what}: {[_python(v) for v in values]!r}")
    if any(abs(v) > MAX_LABEL_COORDINATE for v in out):
        raise InputError(source, f"malformed {what}: {out!r} (a value beyond ±{MAX_LABEL_COORDINATE:g}, "
                                 "far outside any image or LiDAR range)")
    return out


def _python(v):
    return v.item() if isinstance(v, np.generic) else v


def camera_label_id(projected_id: str, camera: str) -> str:
    """The laser label id of a projected laser label id ``"<laser id>_<CAMERA>"`` (unchanged when
    it has no such suffix, as v2's ``key.laser_object_id``)."""
    suffix = f"_{camera}"
    return projected_id[:-len(suffix)] if projected_id.endswith(suffix) else projected_id
