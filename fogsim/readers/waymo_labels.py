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

Modules: :mod:`~fogsim.readers.waymo_label_types` (records, classes, distance sources),
:mod:`~fogsim.readers.waymo_label_distance` (pixel boxes, matching, distances, the records),
:mod:`~fogsim.readers.waymo_labels_v1` (v1 Frames) and :mod:`~fogsim.readers.waymo_labels_v2`
(v2 tables). This module re-exports their public names.
"""
from __future__ import annotations

from fogsim.readers.waymo_label_distance import (CLUSTER_GAP_FRACTION, CLUSTER_GAP_M, MATCH_IOA, MATCH_IOU,
                                                 build_labels, camera_range, distance_from_points,
                                                 match_projected, pixel_box)
from fogsim.readers.waymo_label_types import (CAMERA_BY_ID, SOURCE_ASSOCIATION, SOURCE_MATCH, SOURCE_POINTS,
                                              SOURCE_UNKNOWN, TYPE_CLASS, WAYMO_CLASSES, Box2D,
                                              CameraFrameLabels, LabelRead, LaserBox, PointsProvider,
                                              camera_extrinsic, camera_label_id, finite_floats)
from fogsim.readers.waymo_labels_v1 import WaymoV1Labels, parse_v1_labels, v1_label_index
from fogsim.readers.waymo_labels_v2 import (V2_ASSOCIATION, V2_CALIBRATION, V2_CAMERA_BOX, V2_LIDAR_BOX,
                                            V2_PROJECTED, WaymoV2Labels, camera_enum, parse_v2_labels,
                                            v2_extrinsics)

__all__ = [
    "CAMERA_BY_ID", "CLUSTER_GAP_FRACTION", "CLUSTER_GAP_M", "MATCH_IOA", "MATCH_IOU", "SOURCE_ASSOCIATION",
    "SOURCE_MATCH", "SOURCE_POINTS", "SOURCE_UNKNOWN", "TYPE_CLASS", "V2_ASSOCIATION", "V2_CALIBRATION",
    "V2_CAMERA_BOX", "V2_LIDAR_BOX", "V2_PROJECTED", "WAYMO_CLASSES", "Box2D", "CameraFrameLabels",
    "LabelRead", "LaserBox", "PointsProvider", "WaymoV1Labels", "WaymoV2Labels", "build_labels",
    "camera_enum", "camera_extrinsic", "camera_label_id", "camera_range", "distance_from_points",
    "finite_floats", "match_projected", "parse_v1_labels", "parse_v2_labels", "pixel_box", "v1_label_index",
    "v2_extrinsics",
]
