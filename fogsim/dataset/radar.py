"""The radar part of a labelled dataset: what :func:`finalize` writes from a render's radar records — the
radar column of the cross-sensor table (its counts: ``radar_detections`` per object, read by
:func:`fogsim.lidar.objects.cross_sensor_table`), ``dataset.json``'s ``radar`` block (detections per level
and kind), the bird's-eye picture ``radar_bev.png`` (each level's radar detections over the LiDAR's points)
and the contact sheet's radar row (each level's detections marked on its image).

The frame record (``meta/<frame>.json``) — what this module reads:

* per object ``radar_detections`` = ``{<level key>: kind-0 detections on the object}``: the radar **sees**
  the object at a level with ≥ 1;
* ``radar``: ``{"levels": {<level key>: {"file", "labels", "outcome_file", "outcomes", …}}, "input":
  {"file", "labels"}, "radar_to_world"}`` (:func:`fogsim.render.radar_frame.write_radar_files`); the labels
  files (:class:`fogsim.schema.radar_labels.RadarLabels`) give each detection's kind and its row in the clear
  sweep, so a level's lost detections are the sweep's rows it lacks.

Conventions of the pictures: the view is the LiDAR's frame when the frame has one (else the radar's), x
forward up, y left to the left, metres, range rings every 10 m with their distances; radar detections are
discs coloured by kind (:data:`KIND_COLOURS`), a detection the fog removed a hollow grey ring where it was in
clear air; a legend (:data:`BEV_LEGEND`) and a line saying what the densest level's fog costs the radar
against light (:func:`fog_note`: at 77 GHz the panels look alike because fog barely attenuates radar, not
because it was left out) make ``radar_bev.png`` read alone.
"""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import cv2
import numpy as np

from fogsim.camera import Intrinsics
from fogsim.colour import to_uint8
from fogsim.dataset.layout import DatasetLayout
from fogsim.errors import InputError
from fogsim.io.images import read_image
from fogsim.lidar.formats import read_points
from fogsim.lidar.pictures import write_png
from fogsim.radar.detections import KINDS
from fogsim.schema.base import load_npz
from fogsim.schema.radar_labels import LABEL_COLUMNS, RadarLabels
from fogsim.viz import legend_row, ring_labels, strip, text_row

__all__ = ["BEV_LEGEND", "KIND_COLOURS", "SHEET_LEGEND", "fog_note", "has_radar", "radar_bev_image", "radar_rows",
           "radar_summary", "read_labels"]

#: detection colours by kind (RGB): object red, ghost purple, ground clutter brown, false alarm black; a
#: detection on scenery (an object the table does not count: buildings, poles, trees) slate blue
KIND_COLOURS = {0: (214, 39, 40), 1: (148, 103, 189), 2: (140, 86, 75), 3: (0, 0, 0)}
SCENERY_COLOUR, LOST_COLOUR, LIDAR_COLOUR = (70, 110, 160), (150, 150, 150), (150, 165, 185)
BOX_COLOUR = (90, 90, 90)
#: the legend of ``radar_bev.png`` (:func:`fogsim.viz.legend_row`)
BEV_LEGEND = [("disc", KIND_COLOURS[0], "radar: on an object"), ("disc", SCENERY_COLOUR, "on scenery"),
              ("disc", KIND_COLOURS[1], "ghost (via the road)"), ("disc", KIND_COLOURS[2], "ground clutter"),
              ("disc", KIND_COLOURS[3], "false alarm"), ("ring", LOST_COLOUR, "removed by the fog"),
              ("dot", LIDAR_COLOUR, "that level's LiDAR points"), ("box", BOX_COLOUR, "object's 3D box"),
              ("sensor", (0, 0, 0), "origin; x forward up, rings every 10 m")]
#: the legend of the contact sheet's radar rows (detections marked on the images)
SHEET_LEGEND = [("disc", KIND_COLOURS[0], "radar: on an object"), ("disc", SCENERY_COLOUR, "on scenery"),
                ("ring", KIND_COLOURS[1], "ghost"), ("ring", KIND_COLOURS[2], "ground clutter"),
                ("ring", KIND_COLOURS[3], "false alarm")]
#: the distance of :func:`fog_note`'s comparison (m)
NOTE_RANGE_M = 100.0


def has_radar(metas: list[dict]) -> bool:
    """Whether any frame record holds radar counts or files."""
    return any(m.get("radar") or any("radar_detections" in r for r in m["objects"]) for m in metas)


def read_labels(path: str | Path) -> dict[str, np.ndarray]:
    """A radar label file's columns (:data:`~fogsim.schema.radar_labels.LABEL_COLUMNS`), checked: equal
    lengths, known kinds."""
    doc = load_npz(path, RadarLabels)
    cols = {k: np.asarray(getattr(doc, k)) for k in LABEL_COLUMNS}
    n = {len(v) for v in cols.values()}
    if len(n) > 1:
        raise InputError(path, f"radar label file: columns of unequal length ({sorted(n)})")
    if len(cols["kind"]) and not np.isin(cols["kind"], [k for k in KINDS if k >= 0]).all():
        raise InputError(path, f"radar label file: kind must be one of 0–{max(KINDS)}")
    return cols


def _xyz(labels: dict) -> np.ndarray:
    r, a, e = (labels[k].astype(np.float64) for k in ("range_m", "azimuth_rad", "elevation_rad"))
    return np.stack([r * np.cos(e) * np.cos(a), r * np.cos(e) * np.sin(a), r * np.sin(e)], 1)


def _view(meta: dict) -> np.ndarray:
    """Radar → the picture's frame (the LiDAR's when the frame has one)."""
    r2w = np.asarray(meta["radar"]["radar_to_world"], np.float64)
    l2w = (meta.get("lidar") or {}).get("lidar_to_world")
    return r2w if l2w is None else np.linalg.inv(np.asarray(l2w, np.float64)) @ r2w


def radar_bev_image(sweep_xyz: np.ndarray, kinds: np.ndarray, kept: np.ndarray | None,
                    lidar_xyz: np.ndarray | None = None, boxes=None, scenery: np.ndarray | None = None,
                    forward_m: float = 90.0, side_m: float = 40.0, px_per_m: float = 5.0) -> np.ndarray:
    """One level's bird's-eye view (the module docstring): x ∈ [−10, ``forward_m``] up, y ∈ ±``side_m``;
    ``sweep_xyz`` the clear sweep's detections (view frame), ``kinds`` their kinds, ``kept`` which the level
    still reports (None: all), ``lidar_xyz`` the level's LiDAR points, ``boxes`` Box3D footprints,
    ``scenery`` which detections lie on scenery (drawn :data:`SCENERY_COLOUR`)."""
    h, w = int(round((forward_m + 10) * px_per_m)), int(round(2 * side_m * px_per_m))
    img = np.full((h, w, 3), 255, np.uint8)
    origin = (int(round(side_m * px_per_m)), int(round(forward_m * px_per_m)))

    def px(xyz):
        xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
        return np.floor((side_m - xyz[:, 1]) * px_per_m).astype(np.int64), \
            np.floor((forward_m - xyz[:, 0]) * px_per_m).astype(np.int64)
    rings = list(range(10, int(forward_m) + 1, 10))
    for r in rings:
        cv2.circle(img, origin, int(r * px_per_m), (232, 232, 232), 1, cv2.LINE_AA)
    if lidar_xyz is not None and len(lidar_xyz):
        c, r = px(lidar_xyz)
        ok = (c >= 0) & (c < w) & (r >= 0) & (r < h)
        img[r[ok], c[ok]] = LIDAR_COLOUR
    for box in boxes or []:
        corners = box.corners()[[0, 2, 6, 4]]
        c, r = px(corners)
        cv2.polylines(img, [np.stack([c, r], 1).astype(np.int32)], True, BOX_COLOUR, 1, cv2.LINE_AA)
    ring_labels(img, origin, rings, px_per_m, angle_deg=76.0)  # over the points, under the detections
    kept = np.ones(len(kinds), bool) if kept is None else kept
    scenery = np.zeros(len(kinds), bool) if scenery is None else scenery
    c, r = px(sweep_xyz)
    for j in np.flatnonzero(~kept):
        cv2.circle(img, (int(c[j]), int(r[j])), 4, LOST_COLOUR, 1, cv2.LINE_AA)
    for j in np.flatnonzero(kept & scenery):
        cv2.circle(img, (int(c[j]), int(r[j])), 2, SCENERY_COLOUR, -1, cv2.LINE_AA)
    for kind in (2, 3, 1, 0):  # objects on top
        for j in np.flatnonzero(kept & (kinds == kind) & ~scenery):
            cv2.circle(img, (int(c[j]), int(r[j])), 3, KIND_COLOURS[kind], -1, cv2.LINE_AA)
    cv2.drawMarker(img, origin, (0, 0, 0), cv2.MARKER_TRIANGLE_UP, 10, 2)
    return img


def _frame_bev(layout: DatasetLayout, levels, meta: dict) -> np.ndarray:
    from fogsim.dataset.lidar import record_box

    radar = meta["radar"]
    sweep = read_labels(layout.root / radar["input"]["labels"])
    view = _view(meta)
    xyz = _xyz(sweep) @ view[:3, :3].T + view[:3, 3]
    boxes = [record_box(r["lidar_box"]) for r in meta["objects"] if r.get("kept") and r.get("lidar_box")]
    counted = [o["id"] for o in radar.get("objects") or []]
    kinds = sweep["kind"].astype(np.int64)
    scenery = (kinds == 0) & ~np.isin(sweep["object_id"], counted)
    lidar = meta.get("lidar") or {}
    panels, captions = [], []
    for lv in levels:
        entry = radar["levels"].get(lv.key)
        if entry is None:
            continue
        rows = read_labels(layout.root / entry["labels"])["sweep_row"].astype(np.int64)
        kept = np.zeros(len(sweep["kind"]), bool)
        kept[rows[(rows >= 0) & (rows < len(kept))]] = True
        points = None
        if lv.key in (lidar.get("levels") or {}):
            points = read_points(layout.root / lidar["levels"][lv.key]["file"], lidar["format"]).xyz
        panels.append(radar_bev_image(xyz, kinds, kept, points, boxes, scenery))
        lost = int((~kept).sum())
        gamma = entry.get("attenuation_db_per_km")
        captions.append(f"{lv.key}: {int(kept.sum())} det., lost {100 * lost / max(1, len(kept)):.0f}%"
                        + (f", {gamma:.2g} dB/km" if gamma else ""))
    row = strip(panels, captions, width=360)
    rows = [row, legend_row(BEV_LEGEND, row.shape[1])]
    if note := fog_note(radar["levels"]):
        rows.append(text_row(note, row.shape[1]))
    return np.vstack(rows)


def fog_note(levels: dict) -> str | None:
    """What the densest level's fog costs the radar against light, in one line (None without a foggy level):
    the two-way loss of a target :data:`NOTE_RANGE_M` away, 2·γ·R for the radar (γ: the level's ITU-R P.840
    attenuation, dB/km) and 2·β·R·10/ln 10 for light (Koschmieder's β)."""
    from fogsim.radar.attenuation import two_way_loss_db

    foggy = [e for e in levels.values() if (e.get("beta") or 0) > 0 and e.get("attenuation_db_per_km") is not None]
    if not foggy:
        return None
    e = max(foggy, key=lambda e: e["beta"])
    radar_db = float(two_way_loss_db(e["attenuation_db_per_km"], NOTE_RANGE_M))
    light_db = 2 * e["beta"] * NOTE_RANGE_M * 10 / np.log(10)
    ghz = e.get("frequency_ghz")
    return (f"{'' if ghz is None else f'{ghz:g} GHz '}radar in fog: at beta {e['beta']:g}/m a target "
            f"{NOTE_RANGE_M:g} m away loses {radar_db:.1f} dB there and back (ITU-R P.840), light {light_db:.0f} dB "
            "- the panels look alike because fog barely attenuates radar, not because it was left out")


def _bev(layout: DatasetLayout, levels, frames: list[str], metas: list[dict]) -> tuple[str | None, str | None]:
    """Draw the first frame with radar files; (its frame, None) or (None, why not)."""
    why = "no frame record has radar files"
    for frame, meta in zip(frames, metas):
        if not ((meta.get("radar") or {}).get("levels")):
            continue
        try:
            write_png(layout.radar_bev(), _frame_bev(layout, levels, meta))
        except (InputError, ValueError, KeyError) as exc:
            why = f"frame {frame}: {exc}"
            continue
        return frame, None
    return None, why


def _totals(metas: list[dict], keys: list[str]) -> dict:
    """Per level: detections reported, kept and lost of the sweeps, and the reported ones by kind."""
    out = {}
    for key in keys:
        outcomes, kinds = Counter(), Counter()
        for m in metas:
            entry = ((m.get("radar") or {}).get("levels") or {}).get(key)
            if entry:
                outcomes.update(entry.get("outcomes") or {})
                kinds.update(entry.get("kinds") or {})
        if outcomes:
            out[key] = {"outcomes": dict(outcomes), **({"kinds": dict(kinds)} if kinds else {})}
    return out


def radar_summary(layout: DatasetLayout, levels, frames: list[str], metas: list[dict]) -> dict | None:
    """Write ``radar_bev.png`` and return ``dataset.json``'s ``radar`` block, with ``markdown`` (the lines
    ``cross_sensor.md`` gains) and ``pictures``; None without radar records."""
    if not has_radar(metas):
        return None
    keys = [lv.key for lv in levels]
    totals = _totals(metas, keys)
    frame, missing = _bev(layout, levels, frames, metas)
    md = []
    if totals:
        md += ["", "## Radar detections per level (clear sweep → the level)", "", "| level | kept | lost |",
               "|---|---|---|"]
        md += [f"| {k} | {t['outcomes'].get('kept', 0)} | {t['outcomes'].get('lost', 0)} |" for k, t in totals.items()]
    pictures = []
    if frame is not None:
        pictures.append(layout.relative(layout.radar_bev()))
        md += ["", f"![radar detections over the LiDAR points, frame {frame}, per level]"
                   f"({layout.relative(layout.radar_bev())})"]
    out = {"seen_rule": "the radar sees an object at a level with >= 1 detection on it (kind object)",
           "frames_with_radar": sum(1 for m in metas if (m.get("radar") or {}).get("levels")),
           "levels": totals, "pictures": pictures, "bev_frame": frame, "markdown": md}
    if missing is not None:
        out["bev_missing"] = missing
    return out


def radar_rows(layout: DatasetLayout, meta: dict, levels, tile_width: int) -> list[np.ndarray]:
    """The contact sheet's radar row of one frame: each level's image with that level's detections marked
    where they project (discs by kind), or [] without a radar."""
    radar = meta.get("radar") or {}
    if "radar_to_world" not in radar:
        return []
    K = Intrinsics.from_dict(meta["camera"]["intrinsics"])
    r2c = np.asarray(meta["camera"]["world_to_camera"], np.float64) @ np.asarray(radar["radar_to_world"], np.float64)
    counted = [o["id"] for o in radar.get("objects") or []]
    tiles, captions = [], []
    for lv in levels:
        entry = (radar.get("levels") or {}).get(lv.key)
        if entry is None:
            continue
        labels = read_labels(layout.root / entry["labels"])
        img = to_uint8(read_image(layout.image(lv.key, meta["frame"])))
        s = tile_width / img.shape[1]
        tile = cv2.resize(img, (tile_width, round(img.shape[0] * s)), interpolation=cv2.INTER_AREA)
        cam = _xyz(labels) @ r2c[:3, :3].T + r2c[:3, 3]
        kinds = labels["kind"].astype(np.int64)
        scenery = (kinds == 0) & ~np.isin(labels["object_id"], counted)
        marks = [(scenery, SCENERY_COLOUR, 2, -1)] + [((kinds == k) & ~scenery, KIND_COLOURS[k], 3, -1 if k == 0 else 1)
                                                    for k in (2, 3, 1, 0)]
        for pick, colour, radius, fill in marks:
            for p in cam[pick & (cam[:, 2] > 0.1)]:
                u, v = (K.fx * p[0] / p[2] + K.cx + 0.5) * s, (K.fy * p[1] / p[2] + K.cy + 0.5) * s
                if 0 <= u < tile.shape[1] and 0 <= v < tile.shape[0]:
                    cv2.circle(tile, (int(u), int(v)), radius, colour, fill, cv2.LINE_AA)
        tiles.append(tile)
        on, gamma = int((kinds == 0).sum() - scenery.sum()), entry.get("attenuation_db_per_km")
        captions.append(f"radar {lv.key}: {on} on objects" + (f", {gamma:.2g} dB/km" if gamma else ""))
    return [strip(tiles, captions)] if tiles else []
