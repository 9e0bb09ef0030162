"""What fog does to each object, seen by each sensor: the LiDAR points in every object's 3D box per fog
level, and the cross-sensor table (per level and distance bin: the share of objects the LiDAR still sees
beside the share the camera still sees — and the radar, where the records have radar counts).

* LiDAR: an object is **seen** at a level when its box (LiDAR frame, :class:`~fogsim.lidar.boxes.Box3D`)
  holds at least ``min_points`` (default :data:`MIN_POINTS` = 5) of that level's reported points —
  kept and attenuated returns; clutter lies near the sensor, a lost point nowhere. Records carry the
  counts as ``record["lidar_points"] = {level key: count}`` (:func:`attach_lidar_points`).
* Camera: ``record["visibility"][level]["visible"]`` as :func:`fogsim.fog.visibility.attach_visibility`
  sets it (contrast ≥ 5 %); an object whose visibility is unknown (None) is left out of the camera share.
* Radar (a render with a radar): seen at a level with ≥ 1 detection on the object,
  ``record["radar_detections"] = {level key: count}`` (:mod:`fogsim.render.radar_frame`).
* The table counts the kept records (not ignore regions) with a known ``distance_m`` and a box (LiDAR
  counts) or radar counts, by bins of that distance (metres, ``[low, high)``; default :data:`DISTANCE_BINS`).
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.lidar.boxes import Box3D, box_members, points_in_boxes
from fogsim.lidar.fogged_scan import FoggedScan
from fogsim.lidar.outcomes import KEPT
from fogsim.lidar.points import PointCloud

__all__ = ["DISTANCE_BINS", "MIN_POINTS", "attach_lidar_points", "cross_sensor_table", "distances_and_points",
           "fogged_object_points", "object_points", "seen_by_lidar", "table_markdown"]

MIN_POINTS = 5
DISTANCE_BINS = (0.0, 10.0, 20.0, 40.0, 80.0, math.inf)


def object_points(levels: dict[str, PointCloud], boxes: list[Box3D | None]) -> list[dict[str, int] | None]:
    """Per box, ``{level key: points of that level's cloud inside it}`` (None for a None box)."""
    real = [k for k, b in enumerate(boxes) if b is not None]
    counts = {key: points_in_boxes(cloud.xyz, [boxes[k] for k in real]) for key, cloud in levels.items()}
    out: list[dict[str, int] | None] = [None] * len(boxes)
    for j, k in enumerate(real):
        out[k] = {key: int(c[j]) for key, c in counts.items()}
    return out


def fogged_object_points(clear: PointCloud, levels: dict[str, FoggedScan], boxes: list[Box3D | None]
                         ) -> list[dict[str, int] | None]:
    """:func:`object_points` of the fog levels of one clear scan (each level's ``cloud``), the same counts
    with less work: a level's kept points are the clear points unchanged (checked bit for bit: else all its
    points count as moved), so the clear points are tested against the boxes once, and the moved points of
    every level (attenuated, clutter, the empty rays' clutter) together in one more pass."""
    real = [k for k, b in enumerate(boxes) if b is not None]
    real_boxes = [boxes[k] for k in real]
    keys = list(levels)
    kept_in, moved_xyz, moved_level = [], [], []
    for li, key in enumerate(keys):
        fogged = levels[key]
        is_kept = fogged.outcome == KEPT
        rows = fogged.output_index[is_kept]
        moved = np.ones(len(fogged.cloud), bool)
        if np.array_equal(fogged.cloud.xyz[rows], clear.xyz[is_kept]):
            moved[rows] = False
        else:  # kept points moved after all: count every point of the level afresh
            is_kept = np.zeros_like(is_kept)
        kept_in.append(is_kept)
        moved_xyz.append(fogged.cloud.xyz[moved])
        moved_level.append(np.full(int(moved.sum()), li, np.int64))
    nb, nl = len(real_boxes), len(keys)
    counts = np.zeros((nb, nl), np.int64)
    if nb and nl:
        def flat(members):  # (rows, their box) of every membership
            return (np.concatenate(members), np.repeat(np.arange(nb), [len(m) for m in members]))
        rows, box = flat(box_members(clear.xyz, real_boxes))
        for li, k in enumerate(kept_in):
            counts[:, li] += np.bincount(box[k[rows]], minlength=nb)
        tag = np.concatenate(moved_level)
        rows, box = flat(box_members(np.concatenate(moved_xyz), real_boxes))
        counts += np.bincount(box * nl + tag[rows], minlength=nb * nl).reshape(nb, nl)
    out: list[dict[str, int] | None] = [None] * len(boxes)
    for j, k in enumerate(real):
        out[k] = {key: int(counts[j, li]) for li, key in enumerate(keys)}
    return out


def attach_lidar_points(records: list[dict], levels: dict[str, PointCloud], boxes: list[Box3D | None],
                        counts: list[dict[str, int] | None] | None = None) -> list[dict]:
    """Set ``record["lidar_points"]`` for every record with a box (in place; returns the records); ``counts``:
    per box, already counted (:func:`fogged_object_points`), else :func:`object_points` of ``levels``."""
    for rec, counts in zip(records, object_points(levels, boxes) if counts is None else counts):
        if counts is not None:
            rec["lidar_points"] = counts
    return records


def _bin_label(lo: float, hi: float) -> str:
    return f"{lo:g}–{hi:g} m" if math.isfinite(hi) else f"≥ {lo:g} m"


def cross_sensor_table(records: list[dict], levels: list[str], bins=DISTANCE_BINS,
                       min_points: int = MIN_POINTS) -> list[dict]:
    """One row per level and distance bin: ``objects`` (counted by the LiDAR), ``lidar_seen`` /
    ``lidar_share`` (≥ ``min_points`` in the box), ``camera_objects`` (visibility known), ``camera_seen`` /
    ``camera_share``, and where any record has radar counts ``radar_objects``, ``radar_seen`` /
    ``radar_share`` (≥ 1 detection); shares are None for an empty bin."""
    edges = [float(b) for b in bins]
    if len(edges) < 2 or any(b <= a for a, b in zip(edges, edges[1:])):
        raise ValueError(f"distance bins must be increasing edges, got {bins}")
    usable = [r for r in records if r.get("kept", True) and r.get("distance_m") is not None
              and ("lidar_points" in r or "radar_detections" in r)]
    with_radar = any("radar_detections" in r for r in usable)
    rows = []
    for level in levels:
        for lo, hi in zip(edges, edges[1:]):
            inside = [r for r in usable if lo <= r["distance_m"] < hi]
            lidar = [(r.get("lidar_points") or {}).get(level) for r in inside]
            lidar = [c for c in lidar if c is not None]
            seen = sum(c >= min_points for c in lidar)
            cam = [((r.get("visibility") or {}).get(level) or {}).get("visible") for r in inside]
            cam = [v for v in cam if v is not None]
            rows.append({"level": level, "bin": [lo, hi], "bin_label": _bin_label(lo, hi), "objects": len(lidar),
                         "lidar_seen": int(seen), "lidar_share": seen / len(lidar) if lidar else None,
                         "camera_objects": len(cam), "camera_seen": int(sum(cam)),
                         "camera_share": sum(cam) / len(cam) if cam else None, "min_points": min_points})
            if with_radar:
                radar = [c for c in ((r.get("radar_detections") or {}).get(level) for r in inside) if c is not None]
                seen = sum(c >= 1 for c in radar)
                rows[-1].update(radar_objects=len(radar), radar_seen=int(seen),
                                radar_share=seen / len(radar) if radar else None)
    return rows


def table_markdown(rows: list[dict]) -> str:
    """The table as Markdown: a row per level, per bin a "LiDAR % / camera %" cell — "LiDAR % / radar % /
    camera %" when the rows have a radar column (— for an empty bin)."""
    bins = list(dict.fromkeys(r["bin_label"] for r in rows))
    levels = list(dict.fromkeys(r["level"] for r in rows))
    radar = any("radar_share" in r for r in rows)

    def pct(v):
        return "—" if v is None else f"{100 * v:.0f} %"

    def cell(r):
        shares = [r["lidar_share"], *([r["radar_share"]] if radar else []), r["camera_share"]]
        n = max(r["objects"], r.get("radar_objects", 0))
        return " / ".join(pct(v) for v in shares) + f" (n={n})"
    sensors = "LiDAR / radar / camera" if radar else "LiDAR / camera"
    head = "| level | " + " | ".join(f"{b} ({sensors})" for b in bins) + " |"
    lines = [head, "|" + "---|" * (len(bins) + 1)]
    for level in levels:
        cells = [cell(r) for r in rows if r["level"] == level]
        lines.append(f"| {level} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def seen_by_lidar(record: dict, level: str, min_points: int = MIN_POINTS) -> bool | None:
    """Whether the LiDAR still sees the object at ``level`` (None: no count for it)."""
    c = (record.get("lidar_points") or {}).get(level)
    return None if c is None else bool(c >= min_points)


def distances_and_points(records: list[dict], level: str) -> tuple[np.ndarray, np.ndarray]:
    """(distance_m, points in box) of the records with both, for one level (pictures)."""
    pairs = [(r["distance_m"], r["lidar_points"][level]) for r in records
             if r.get("kept", True) and r.get("distance_m") is not None and level in (r.get("lidar_points") or {})]
    if not pairs:
        return np.zeros(0), np.zeros(0, np.int64)
    d, n = zip(*pairs)
    return np.asarray(d, np.float64), np.asarray(n, np.int64)
