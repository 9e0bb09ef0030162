"""The LiDAR part of a labelled dataset: what a frame record holds for it, and what :func:`finalize` writes
from the committed frames — the cross-sensor table (``dataset.json``'s ``lidar`` block and
``cross_sensor.md``), the pictures (``lidar_bev.png``, ``lidar_points_vs_distance.png``), each KITTI
tree's ``ImageSets`` and each SemanticKITTI sequence's calib, poses and yaml
(:func:`fogsim.dataset.semantic_kitti.write_sequences`). Any producer (``fogsim fog --lidar``, a render
with a synthetic LiDAR) feeds it the same records; paths are :class:`~fogsim.dataset.layout.DatasetLayout`'s.

The frame record (``meta/<frame>.json``) — what the table and the pictures read:

* per object (``objects[i]``): ``distance_m`` (metres, camera centre → object; None = unknown),
  ``kept`` (ignore regions are not counted), ``visibility[<level>]["visible"]`` (the camera: contrast
  ≥ 5 %, :mod:`fogsim.fog.visibility`; None = unknown) and, for an object with a 3D box,
  ``lidar_points`` = ``{<level key>: points of that level's scan inside the box}`` (clear included) —
  the table counts the kept objects with ``distance_m`` and ``lidar_points``; ``lidar_box`` (optional,
  ``{"centre_m", "axes", "half_m"}``: the box in the sensor frame, :class:`~fogsim.lidar.boxes.Box3D`)
  is drawn in the bird's-eye view;
* ``lidar`` (optional, for the pictures and the outcome totals): ``{"format": point format, "levels":
  {<level key>: {"file": the level's scan, "outcome_file": its outcomes (both relative to the root),
  "outcomes": {outcome: count}, …}}, "input": {"file": the clear scan (absolute or relative to the root,
  or None), "format"}}`` — each level's entry is :meth:`fogsim.lidar.fogged_scan.FoggedScan.record` (its
  ``outcomes`` counts are summed per level) plus the two paths; ``kitti`` = ``{"id", "part"}`` when the
  frame is in the KITTI trees (``kitti/<level>/…``).

A picture that cannot be drawn (no frame with scans on disk) is left out and said in ``dataset.json``.
"""
from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import numpy as np

from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.semantic_kitti import write_sequences
from fogsim.errors import InputError
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.documents import write_json
from fogsim.lidar.boxes import Box3D
from fogsim.lidar.fogged_scan import FoggedScan
from fogsim.lidar.formats import read_points
from fogsim.lidar.objects import DISTANCE_BINS, MIN_POINTS, cross_sensor_table, table_markdown
from fogsim.lidar.outcome_file import read_outcomes
from fogsim.lidar.outcomes import OUTCOMES
from fogsim.lidar.pictures import bev_levels, points_vs_distance, write_png

__all__ = ["KITTI_IDS", "box_record", "has_lidar", "lidar_summary", "record_box"]

#: the KITTI trees' id → frame map, beside them
KITTI_IDS = "frame_ids.json"


def box_record(box: Box3D) -> dict:
    """A :class:`Box3D` as a frame record's ``lidar_box`` (sensor frame, metres; ``axes`` row-major 3×3,
    its columns the length, width and height directions)."""
    return {"centre_m": [round(float(v), 4) for v in box.centre], "axes": np.round(box.axes, 6).tolist(),
            "half_m": [round(float(v), 4) for v in box.half]}


def record_box(record: dict) -> Box3D:
    """The :class:`Box3D` of a ``lidar_box`` record."""
    return Box3D(np.asarray(record["centre_m"], np.float64), np.asarray(record["axes"], np.float64),
                 np.asarray(record["half_m"], np.float64))


def has_lidar(metas: list[dict]) -> bool:
    """Whether any frame record holds LiDAR counts or scans."""
    return any(m.get("lidar") or any("lidar_points" in r for r in m["objects"]) for m in metas)


def _json_bins(bins) -> list:
    return [None if math.isinf(b) else float(b) for b in bins]


def _totals(metas: list[dict], keys: list[str]) -> dict:
    out = {}
    for key in keys:
        total = Counter()
        for m in metas:
            level = ((m.get("lidar") or {}).get("levels") or {}).get(key) or {}
            total.update(level.get("outcomes") or {})
        if total:
            n = sum(total.values())  # 0: every sweep of the level saw nothing (shares of 0 points: 0)
            out[key] = {"points": n, **{k: int(total.get(k, 0)) for k in OUTCOMES},
                        "shares": {k: round(total.get(k, 0) / n, 6) if n else 0.0 for k in OUTCOMES}}
    return out


def _models(metas: list[dict]) -> list[str]:
    """The LiDAR fog models the frames' level records name (with hahner2021's variant), in first-seen order."""
    seen = {}
    for m in metas:
        for level in (((m.get("lidar") or {}).get("levels")) or {}).values():
            model = level.get("model")
            if model:
                variant = level.get("hahner_variant")
                seen[f"{model} ({variant})" if model == "hahner2021" and variant else model] = None
    return list(seen)


def _path(layout: DatasetLayout, given: str) -> Path:
    path = Path(given)
    return path if path.is_absolute() else layout.root / path


def _bev(layout: DatasetLayout, levels, frames: list[str], metas: list[dict]) -> tuple[str | None, str | None]:
    """Draw the first frame with scans on disk; (its frame, None) or (None, why not)."""
    why = "no frame record has LiDAR scans"
    for frame, meta in zip(frames, metas):
        lidar = meta.get("lidar") or {}
        entries = lidar.get("levels") or {}
        if not entries:
            continue
        fmt = lidar.get("format")
        clear = next((lv.key for lv in levels if lv.beta == 0 and lv.key in entries), None)
        try:
            if clear is not None:
                scan = read_points(_path(layout, entries[clear]["file"]), fmt)
            elif (lidar.get("input") or {}).get("file"):
                scan = read_points(_path(layout, lidar["input"]["file"]), lidar["input"].get("format", fmt))
            else:
                why = "no clear level and no readable input scan to draw the lost points at"
                continue
            fogged = {}
            for lv in levels:
                if lv.key not in entries:
                    continue
                if lv.beta == 0:
                    fogged[lv.key] = None
                    continue
                cloud = read_points(_path(layout, entries[lv.key]["file"]), fmt)
                outcome, index = read_outcomes(_path(layout, entries[lv.key]["outcome_file"]))
                extra = int(entries[lv.key].get("empty_ray_clutter") or 0)  # appended after the input's points
                added = int(entries[lv.key].get("added_points") or 0)  # then the model's own (stf2020)
                if len(outcome) != len(scan) or (index >= 0).sum() + extra + added != len(cloud):
                    raise InputError(entries[lv.key]["outcome_file"], "outcomes do not match the scans beside them")
                fogged[lv.key] = FoggedScan(cloud, outcome, index, {}, int(entries[lv.key].get("empty_rays") or 0),
                                            extra, added)
        except (InputError, ValueError, KeyError) as exc:
            why = f"frame {frame}: {exc}"
            continue
        boxes = [record_box(r["lidar_box"]) for r in meta["objects"] if r.get("kept") and r.get("lidar_box")]
        write_png(layout.lidar_bev(), bev_levels(scan, fogged, boxes=boxes))
        return frame, None
    return None, why


def _kitti_image_sets(layout: DatasetLayout, frames: list[str], metas: list[dict], train: list[str],
                      val: list[str]) -> dict | None:
    """Each KITTI tree's ``ImageSets`` from the dataset's split (ids as the trees name them), and the id map."""
    ids = {f: (m.get("lidar") or {}).get("kitti") for f, m in zip(frames, metas)}
    ids = {f: k for f, k in ids.items() if k}
    root = layout.root / "kitti"
    if not ids or not root.is_dir():
        return None
    testing = {f for f, k in ids.items() if k.get("part") == "testing"}
    sets = {"train": [ids[f]["id"] for f in train if f in ids and f not in testing],
            "val": [ids[f]["id"] for f in val if f in ids and f not in testing]}
    sets["trainval"] = sorted(sets["train"] + sets["val"])
    sets["test"] = sorted(ids[f]["id"] for f in testing)
    for tree in sorted(p for p in root.iterdir() if p.is_dir()):
        for name, listed in sets.items():
            atomic_write_bytes(tree / "ImageSets" / f"{name}.txt", "".join(f"{i}\n" for i in sorted(listed)).encode())
    write_json(root / KITTI_IDS, {k["id"]: f for f, k in sorted(ids.items())})
    return {name: len(listed) for name, listed in sets.items()}


def lidar_summary(layout: DatasetLayout, levels, frames: list[str], metas: list[dict], train: list[str],
                  val: list[str], min_points: int = MIN_POINTS, bins=DISTANCE_BINS,
                  radar: dict | None = None) -> dict | None:
    """Write the LiDAR files of the dataset (the module docstring) and return ``dataset.json``'s ``lidar``
    block; None when no frame has LiDAR records (nor radar counts). ``radar``: the radar block
    (:func:`fogsim.dataset.radar.radar_summary`) whose ``markdown`` and ``pictures`` the report gains; the
    table gets its radar column from the records' ``radar_detections``."""
    lidar = has_lidar(metas)
    if not lidar and radar is None:
        return None
    keys = [lv.key for lv in levels]
    records = [r for m in metas for r in m["objects"]]
    rows = cross_sensor_table(records, keys, bins, min_points)
    for row in rows:
        row["bin"] = _json_bins(row["bin"])
    totals = _totals(metas, keys)
    bev_frame, bev_missing = _bev(layout, levels, frames, metas)
    if lidar:
        write_png(layout.lidar_points_plot(), points_vs_distance(records, keys, min_points))
    counted = sum(1 for r in records if r.get("kept", True) and r.get("distance_m") is not None
                  and ("lidar_points" in r or "radar_detections" in r))
    radar_rule = "the radar with ≥ 1 detection on the object, " if radar is not None else ""
    models = _models(metas)
    model_rule = f" (LiDAR fog model: {', '.join(models)})" if models else ""
    md = ["# What fog does to each object, seen by each sensor", "",
          f"Share of the kept objects with a 3D box and a distance ({counted} in {len(metas)} frames) that each "
          f"sensor still sees, per fog level and distance bin: the LiDAR with ≥ {min_points} points in the box"
          f"{model_rule}, {radar_rule}the camera with a contrast ≥ 5 % (n = objects in the bin).", "",
          table_markdown(rows)]
    if totals:
        md += ["", "## LiDAR outcomes per level", "", "| level | points | " + " | ".join(OUTCOMES) + " |",
               "|---|---|" + "---|" * len(OUTCOMES)]
        md += [f"| {k} | {t['points']} | " + " | ".join(f"{100 * t['shares'][o]:.1f} %" for o in OUTCOMES) + " |"
               for k, t in totals.items()]
    pictures = [layout.relative(layout.lidar_points_plot())] if lidar else []
    if bev_frame is not None:
        pictures.insert(0, layout.relative(layout.lidar_bev()))
        md += ["", f"![bird's-eye view of frame {bev_frame} per level]({layout.relative(layout.lidar_bev())})"]
    if lidar:
        md += ["", f"![points per object against distance]({layout.relative(layout.lidar_points_plot())})"]
    if radar is not None:
        md += radar["markdown"]
        pictures += radar["pictures"]
    md += [""]
    atomic_write_bytes(layout.cross_sensor_report(), "\n".join(md).encode())
    out = {"min_points": min_points, "distance_bins_m": _json_bins(bins), "objects_counted": counted,
           "frames_with_scans": sum(1 for m in metas if (m.get("lidar") or {}).get("levels")),
           "lidar_fog_models": models, "cross_sensor": rows, "outcomes": totals,
           "report": layout.relative(layout.cross_sensor_report()), "pictures": pictures, "bev_frame": bev_frame}
    if bev_missing is not None:
        out["bev_missing"] = bev_missing
    kitti = _kitti_image_sets(layout, frames, metas, train, val)
    if kitti is not None:
        out["kitti_image_sets"] = kitti
    semantic = write_sequences(layout, frames, metas)
    if semantic is not None:
        out["semantic_kitti"] = semantic
    return out
