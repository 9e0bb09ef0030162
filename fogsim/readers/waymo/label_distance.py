"""Pixel boxes and distances of Waymo 2D labels, and the :class:`Labels` records built from them.

Conventions: boxes are pixel-edge ``[x0, y0, x1, y1)`` (edges rounded half up, clamped to the
image); ``distance_m`` is the ray distance (Euclidean range) camera centre → object in metres,
``planar_depth_m`` the camera-frame x (forward) in metres. Rules, in order: laser box centre by
association, laser box centre by projected-box match (:func:`match_projected`), the near cluster
of the LiDAR points in the box (:func:`distance_from_points`), else unknown.
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.readers.base import Labels
from fogsim.readers.waymo.labels import (
    SOURCE_ASSOCIATION,
    SOURCE_MATCH,
    SOURCE_POINTS,
    SOURCE_UNKNOWN,
    TYPE_CLASS,
    WAYMO_CLASSES,
    Box2D,
    CameraFrameLabels,
    LabelRead,
    PointsProvider,
)

#: Projected-box matching thresholds (camera boxes are tight, projected ones amodal and loose).
MATCH_IOU, MATCH_IOA = 0.3, 0.7
#: Near-cluster split of :func:`distance_from_points`: a gap between consecutive sorted ray
#: distances larger than max(CLUSTER_GAP_M, CLUSTER_GAP_FRACTION · distance) starts a new cluster.
CLUSTER_GAP_M, CLUSTER_GAP_FRACTION = 1.0, 0.1


def pixel_box(cx: float, cy: float, length: float, width: float,
              image_width: int | None, image_height: int | None) -> list[int]:
    """Pixel-edge ``[x0, y0, x1, y1)`` of a Waymo 2D label, edges rounded half up and clamped to
    the image (an unknown size clamps at 0 only). May be empty (x1 ≤ x0 or y1 ≤ y0)."""
    edges = [cx - length / 2, cy - width / 2, cx + length / 2, cy + width / 2]
    x0, y0, x1, y1 = (math.floor(v + 0.5) for v in edges)
    hi_x = math.inf if image_width is None else image_width
    hi_y = math.inf if image_height is None else image_height
    return [int(min(max(x0, 0), hi_x)), int(min(max(y0, 0), hi_y)),
            int(min(max(x1, 0), hi_x)), int(min(max(y1, 0), hi_y))]


def _float_box(b: Box2D, width: int | None, height: int | None) -> tuple[float, float, float, float]:
    hi_x = math.inf if width is None else float(width)
    hi_y = math.inf if height is None else float(height)
    return (min(max(b.cx - b.length / 2, 0.0), hi_x), min(max(b.cy - b.width / 2, 0.0), hi_y),
            min(max(b.cx + b.length / 2, 0.0), hi_x), min(max(b.cy + b.width / 2, 0.0), hi_y))


def _area(b) -> float:
    return max(b[2] - b[0], 0.0) * max(b[3] - b[1], 0.0)


def _overlap(a, b) -> tuple[float, float]:
    """(IoU of a and b, intersection / area of a)."""
    inter = _area((max(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), min(a[3], b[3])))
    union = _area(a) + _area(b) - inter
    return (inter / union if union > 0 else 0.0), (inter / _area(a) if _area(a) > 0 else 0.0)


def match_projected(boxes: list[Box2D], projected: list[Box2D], width: int | None, height: int | None,
                    exclude: set[str] = frozenset()) -> dict[int, tuple[int, float]]:
    """One-to-one matches camera box index → (projected box index, IoU): same type only, IoU ≥
    :data:`MATCH_IOU` and IoA(camera box) ≥ :data:`MATCH_IOA`, greedy by decreasing IoU (ties by
    index); projected boxes whose laser id is in ``exclude`` are not matched."""
    cam = [_float_box(b, width, height) for b in boxes]
    proj = [_float_box(p, width, height) for p in projected]
    pairs = []
    for i, b in enumerate(boxes):
        for j, p in enumerate(projected):
            if p.type != b.type or p.id in exclude:
                continue
            iou, ioa = _overlap(cam[i], proj[j])
            if iou >= MATCH_IOU and ioa >= MATCH_IOA:
                pairs.append((-iou, i, j))
    matches, used = {}, set()
    for neg_iou, i, j in sorted(pairs):
        if i not in matches and j not in used:
            matches[i] = (j, -neg_iou)
            used.add(j)
    return matches


def camera_range(center, extrinsic: np.ndarray) -> tuple[float, float]:
    """(Euclidean range camera centre → ``center``, planar depth p_cam.x), metres, for a point
    in the vehicle frame and the camera→vehicle 4×4 ``extrinsic``."""
    p = np.linalg.solve(extrinsic, np.array([*center, 1.0]))
    return float(np.linalg.norm(p[:3])), float(p[0])


def distance_from_points(bbox, uv: np.ndarray, ray: np.ndarray, min_points: int = 5) -> float | None:
    """Distance (metres) of the object in a 2D box from the LiDAR points projected into it.

    ``bbox``: pixel-edge ``[x0, y0, x1, y1)``; ``uv``: N×2 pixel-edge point coordinates (x, y);
    ``ray``: N ray distances camera centre → point (non-finite or ≤ 0 are ignored). The points
    inside the box are sorted by distance and split into 1-D clusters wherever the gap to the
    next one exceeds max(:data:`CLUSTER_GAP_M`, :data:`CLUSTER_GAP_FRACTION` · distance); the
    result is the **median of the nearest cluster with at least ``min_points`` points** (the
    background seen past the object's edges falls into farther clusters). None when there is
    no such cluster (fewer than ``min_points`` points in the box, or all clusters smaller).
    """
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    ray = np.asarray(ray, dtype=np.float64).ravel()
    if uv.shape[0] != ray.size:
        raise ValueError(f"{uv.shape[0]} point coordinates but {ray.size} distances")
    x0, y0, x1, y1 = bbox
    with np.errstate(invalid="ignore"):
        inside = ((uv[:, 0] >= x0) & (uv[:, 0] < x1) & (uv[:, 1] >= y0) & (uv[:, 1] < y1)
                  & np.isfinite(ray) & (ray > 0))
    d = np.sort(ray[inside])
    if d.size < min_points:
        return None
    gaps = np.flatnonzero(np.diff(d) > np.maximum(CLUSTER_GAP_M, CLUSTER_GAP_FRACTION * d[:-1])) + 1
    bounds = np.concatenate([[0], gaps, [d.size]])
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a >= min_points:
            return float(np.median(d[a:b]))
    return None


# ----------------------------------------------------------------------------- labels
def build_labels(frame: CameraFrameLabels, points: PointsProvider | None = None,
                 min_points: int = 5) -> LabelRead:
    """The :class:`Labels` of one camera image (records in annotation order) and the drop counts.

    ``points`` is called (once, with the camera name) only when some box has no laser-box distance.
    """
    dropped = {"not a 2D class": 0, "empty after clamping": 0}
    kept: list[tuple[Box2D, list[int]]] = []
    for b in frame.boxes:
        if b.type not in TYPE_CLASS:
            dropped["not a 2D class"] += 1
            continue
        box = pixel_box(b.cx, b.cy, b.length, b.width, frame.width, frame.height)
        if box[2] <= box[0] or box[3] <= box[1]:
            dropped["empty after clamping"] += 1
            continue
        kept.append((b, box))
    laser_of: dict[int, tuple[str, str]] = {}  # kept index → (laser id, source)
    if frame.extrinsic is not None:
        for i, (b, _) in enumerate(kept):
            if b.laser_id and b.laser_id in frame.laser:
                laser_of[i] = (b.laser_id, SOURCE_ASSOCIATION)
        rest = [i for i in range(len(kept)) if i not in laser_of]
        claimed = {lid for lid, _ in laser_of.values()}
        matches = match_projected([kept[i][0] for i in rest], frame.projected, frame.width, frame.height,
                                  exclude=claimed)
        for k, (j, _) in matches.items():
            if frame.projected[j].id in frame.laser:
                laser_of[rest[k]] = (frame.projected[j].id, SOURCE_MATCH)
    cloud: list = []  # the points, fetched on first need: [] not yet, [None] none
    objects = []
    for i, (b, box) in enumerate(kept):
        distance = planar = laser_id = laser_points = laser_box = None
        source = SOURCE_UNKNOWN
        if i in laser_of:
            laser_id, source = laser_of[i]
            distance, planar = camera_range(frame.laser[laser_id].center, frame.extrinsic)
            laser_points = frame.laser[laser_id].num_points
            laser_box = frame.laser[laser_id].record()
        elif points is not None:
            if not cloud:
                cloud.append(points(frame.camera))
            if cloud[0] is not None:
                distance = distance_from_points(box, *cloud[0], min_points=min_points)
                source = SOURCE_POINTS if distance is not None else SOURCE_UNKNOWN
        name = TYPE_CLASS[b.type]
        x0, y0, x1, y1 = box
        objects.append({
            "object_id": b.id, "class": name, "class_id": WAYMO_CLASSES.index(name), "bbox": box,
            "pixels": (x1 - x0) * (y1 - y0), "kept": True, "reason": None,
            "truncated": x0 == 0 or y0 == 0 or x1 == frame.width or y1 == frame.height,
            "difficulty": b.difficulty,
            "distance_m": None if distance is None else round(distance, 3), "distance_source": source,
            "planar_depth_m": None if planar is None else round(planar, 3), "laser_id": laser_id,
            "laser_points_in_box": laser_points} | ({"laser_box": laser_box} if laser_box else {}))
    return LabelRead(Labels(WAYMO_CLASSES, objects), {k: v for k, v in dropped.items() if v})
