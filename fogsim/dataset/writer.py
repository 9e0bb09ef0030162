"""Writing the rendered dataset: YOLO labels, COCO files (their content: :mod:`fogsim.dataset.coco`),
split lists, data files, manifest, contact sheet. Every path comes from
:class:`fogsim.dataset.layout.DatasetLayout` (the layout is listed there); the images are written by
the caller. Fog levels are taken as they come (anything with ``key``, ``beta`` and ``to_dict()``, as
:class:`fogsim.fog.levels.FogLevel`): this module imports nothing above the dataset format.

Split rule: a frame is in train when crc32("<seed>/<frame>") % 1000 < 1000·train_fraction,
so adding frames never moves existing ones (except that a split left empty takes the frame
whose hash is nearest the cut, so both lists always hold an image; one frame goes in both: ``dataset.json``'s
``split`` then names it, ``in_both``, with a ``note``, and the commands warn, :func:`split_note`). List entries are
absolute because Ultralytics resolves them against the working directory; run
:func:`finalize` again after moving the dataset.
"""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import cv2
import numpy as np

from fogsim.boxes import yolo_line
from fogsim.colour import to_uint8
from fogsim.dataset.coco import coco_dataset, coco_records, frame_segmentations
from fogsim.dataset.layout import MIXED_SPLIT, PARTS, DatasetLayout, visible_set
from fogsim.dataset.lidar import lidar_summary
from fogsim.dataset.lidar_sheet import LEGEND as LIDAR_LEGEND
from fogsim.dataset.lidar_sheet import lidar_rows
from fogsim.dataset.radar import SHEET_LEGEND as RADAR_LEGEND
from fogsim.dataset.radar import fog_note, radar_rows, radar_summary
from fogsim.dataset.reader import FrameRecords, frame_records, read_checked_meta
from fogsim.dataset.visible import visible_at, visible_counts, write_visible_labels
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.documents import write_json
from fogsim.io.images import read_image, write_image
from fogsim.lidar.objects import MIN_POINTS
from fogsim.runs import split_key
from fogsim.scene.classes import LABELLED
from fogsim.viz import label, legend_row, strip, text_row

__all__ = ["PALETTE", "TRAIN_FRACTION", "check_train_fraction", "contact_sheet", "draw_boxes", "data_yaml", "finalize",
           "frame_split", "split_frames", "split_note", "write_frame_labels"]

#: the share of frames in the train split unless a preset or ``--train-fraction`` says otherwise
#: (declared with the preset schema, :data:`fogsim.schema.presets.TRAIN_FRACTION`)
from fogsim.schema.presets import TRAIN_FRACTION  # noqa: E402

#: box colours (RGB) by class id
PALETTE = ((230, 25, 75), (60, 180, 75), (255, 225, 25), (0, 130, 200), (245, 130, 48),
           (145, 30, 180), (70, 240, 240), (240, 50, 230))


def write_frame_labels(layout: DatasetLayout, frame: str, levels, records: list[dict],
                       width: int, height: int) -> None:
    """YOLO label files of one frame, one per level, from the kept records (may be empty)."""
    text = "".join(yolo_line(r, width, height) + "\n" for r in records if r["kept"])
    for lv in levels:
        atomic_write_bytes(layout.label(lv.key, frame), text.encode())


def check_train_fraction(value, name: str = "train_fraction") -> float:
    """``value`` when it is a share strictly between 0 and 1, else a ValueError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < 1:
        raise ValueError(f"{name} must be in (0, 1), got {value!r}")
    return float(value)


def frame_split(frame: str, train_fraction: float = TRAIN_FRACTION, seed: int = 0) -> str:
    """"train" or "val" for one frame by the split rule alone (no empty-split adjustment)."""
    return "train" if split_key(frame, seed) < round(1000 * train_fraction) else "val"


def split_frames(frames: list[str], train_fraction: float = TRAIN_FRACTION, seed: int = 0,
                 groups: dict[str, str] | None = None) -> tuple[list, list]:
    """Deterministic (train, val) frame lists by hash of name (see the module docstring).

    ``groups`` (frame → group name, e.g. a Waymo segment or a Cityscapes city): the hash is of
    the frame's group instead, so the frames of one group (near-duplicates of one sequence)
    never sit on both sides; the empty-split rule then moves a whole group. With fewer than two
    groups the frames are split by their own names."""
    if len(frames) == 1:
        return list(frames), list(frames)
    cut = round(1000 * train_fraction)
    if groups is not None and len({groups[f] for f in frames}) < 2:
        groups = None
    name = {f: groups[f] if groups is not None else f for f in frames}
    key = {f: split_key(name[f], seed) for f in frames}
    train = sorted(f for f in frames if key[f] < cut)
    val = sorted(f for f in frames if key[f] >= cut)
    if frames and not val:  # never leave a split empty: the frame (group) nearest the cut changes sides
        moved = name[max(train, key=lambda f: (key[f], name[f]))]
        train, val = [f for f in train if name[f] != moved], [f for f in train if name[f] == moved]
    elif frames and not train:
        moved = name[min(val, key=lambda f: (key[f], name[f]))]
        train, val = [f for f in val if name[f] == moved], [f for f in val if name[f] != moved]
    return train, val


def data_yaml(root: Path, train: str, val: str, description: str, classes=LABELLED) -> str:
    """An Ultralytics data file: image lists ``train`` and ``val`` relative to ``root``, class
    names ``classes`` (YOLO id = index)."""
    lines = [f"# {description}", f"path: {json.dumps(str(root.resolve()))}",
             f"train: {json.dumps(train)}", f"val: {json.dumps(val)}", "names:"]
    lines += [f"  {i}: {json.dumps(n)}" for i, n in enumerate(classes)]
    return "\n".join(lines) + "\n"


def _write_lists(layout: DatasetLayout, name: str, split: dict[str, list[Path]], description: str,
                 classes=LABELLED) -> None:
    """The split lists of ``name`` (a level key or MIXED_SPLIT) and its data file."""
    for part, paths in split.items():
        text = "".join(f"{p.resolve()}\n" for p in paths)
        atomic_write_bytes(layout.split_file(name, part), text.encode())
    lists = [layout.relative(layout.split_file(name, part)) for part in PARTS]
    atomic_write_bytes(layout.data_yaml(name), data_yaml(layout.root, *lists, description, classes).encode())


def finalize(layout: DatasetLayout, levels, manifest: dict, train_fraction: float = TRAIN_FRACTION,
             seed: int = 0, classes=LABELLED, split_group=None, records: FrameRecords | None = None,
             lidar_min_points: int = MIN_POINTS) -> dict:
    """Write every dataset-level file from the committed frames; returns ``dataset.json``'s content.

    ``classes``: the dataset's own class list (YOLO ids index it, COCO ids are index + 1; it is
    ``dataset.json``'s ``classes``). Renders keep the default, fogsim's LABELLED.
    ``split_group``: None (split by frame name), or ``(description, meta → group name)`` to keep
    each group's frames on one side (:func:`split_frames`). ``records``: the frames and their
    checked records (default: :func:`~fogsim.dataset.reader.frame_records`); a meta file that
    fails its schema is left out and named in ``dataset.json``'s ``skipped_frames``. Frames with LiDAR
    records (:mod:`fogsim.dataset.lidar`) add ``dataset.json``'s ``lidar`` block (the cross-sensor table,
    an object seen by the LiDAR with ≥ ``lidar_min_points`` points in its box), ``cross_sensor.md``, the
    LiDAR pictures and each KITTI tree's ``ImageSets``; frames with radar records (:mod:`fogsim.dataset.radar`)
    add the radar column, ``dataset.json``'s ``radar`` block and ``radar_bev.png``."""
    levels = list(levels)
    if any(lv.key == MIXED_SPLIT for lv in levels):
        raise ValueError(f"fog level key {MIXED_SPLIT!r} is reserved for the mixed-level split")
    records = frame_records(layout) if records is None else records
    frames, metas = records.frames, records.metas
    if not frames:
        raise ValueError(f"{layout.root}: no finished frames (meta/*.json) to finalize"
                         + (f"; {records.skipped[0]}" if records.skipped else ""))
    groups = None if split_group is None else {f: split_group[1](m) for f, m in zip(frames, metas)}
    train, val = split_frames(frames, train_fraction, seed, groups)
    mixed, mixed_visible = {part: [] for part in PARTS}, {part: [] for part in PARTS}
    segmentations = [frame_segmentations(layout, m) for m in metas]  # the masks are read once, for every level
    write_visible_labels(layout, levels, frames, metas)
    for lv in levels:
        write_json(layout.coco(lv.key), coco_dataset(metas, lv, layout, classes, segmentations))
        what = f"fogsim dataset, fog level {lv.key}: beta = {lv.beta:g} 1/m"
        for name, image, lists, note in ((lv.key, layout.image, mixed, ""),
                                         (visible_set(lv.key), layout.visible_image, mixed_visible,
                                          ", the objects visible at that level only")):
            split = {"train": [image(lv.key, f) for f in train], "val": [image(lv.key, f) for f in val]}
            _write_lists(layout, name, split, what + note, classes)
            for part in lists:
                lists[part] += split[part]
    _write_lists(layout, MIXED_SPLIT, mixed, "fogsim dataset, every fog level mixed", classes)
    _write_lists(layout, visible_set(MIXED_SPLIT), mixed_visible,
                 "fogsim dataset, every fog level mixed, the objects visible at each level only", classes)
    summary = dict(manifest) | _summary(metas, levels, train, val, train_fraction, seed, classes)
    summary["visible_labels"] = visible_counts(levels, metas)
    if groups is not None and len(set(groups.values())) > 1:
        cut = round(1000 * train_fraction)
        summary["split"]["rule"] = (f"crc32('{seed}/<group>') % 1000 < {cut} → train, group = "
                                    f"{split_group[0]}")
        summary["split"]["groups"] = len(set(groups.values()))
    if records.skipped:
        summary["skipped_frames"] = list(records.skipped)
    radar = radar_summary(layout, levels, frames, metas)
    lidar = lidar_summary(layout, levels, frames, metas, train, val, lidar_min_points, radar=radar)
    if lidar is not None:
        summary["lidar"] = lidar
    if radar is not None:
        summary["radar"] = {k: v for k, v in radar.items() if k != "markdown"}
    write_json(layout.manifest(), summary)
    write_image(layout.contact_sheet(), contact_sheet(layout, levels, frames, metas=metas))
    return summary


def _summary(metas: list[dict], levels, train: list, val: list, train_fraction: float, seed: int,
             classes=LABELLED) -> dict:
    records = [r for m in metas for r in m["objects"]]
    kept = Counter(r["class"] for r in records if r["kept"])
    ignored = [m["objects"][i] for m in metas for i, _ in coco_records(m["objects"]) if not m["objects"][i]["kept"]]
    split = {"train": len(train), "val": len(val), "train_fraction": train_fraction,
             "rule": f"crc32('{seed}/<frame>') % 1000 < {round(1000 * train_fraction)} → train"}
    both = sorted(set(train) & set(val))
    if both:
        split |= {"in_both": both, "note": IN_BOTH_NOTE}
    return {"frames": len(metas), "classes": list(classes), "levels": [lv.to_dict() for lv in levels],
            "counts": {c: kept.get(c, 0) for c in classes},
            "filtered": dict(Counter(r["reason"] for r in ignored)),  # a region of every class: once
            "split": split}


#: what ``dataset.json``'s ``split`` says when its lists share frames (a one-frame dataset)
IN_BOTH_NOTE = "a one-frame dataset: its frame is in both train and val, so nothing is held out for validation"


def split_note(summary: dict) -> str | None:
    """The one-line warning of a dataset (``dataset.json``'s content) whose train and val lists share a
    frame — a one-frame dataset, the only case the split rule allows — else None."""
    both = (summary.get("split") or {}).get("in_both") or []
    if not both:
        return None
    return (f"a one-frame dataset: frame {both[0]} is in both train and val, so nothing is held out for "
            "validation (add frames for a real split)")


def contact_sheet(layout: DatasetLayout, levels, frames: list[str], max_frames: int = 4,
                  tile_width: int = 384, metas: list[dict] | None = None) -> np.ndarray:
    """RGB uint8 overview: one row per frame, one column per level, kept boxes drawn, and for a frame
    with a LiDAR its scans (:mod:`fogsim.dataset.lidar_sheet`) (``metas``: the frames' records, if read already)."""
    rows, sensors = [], {}  # the sensors seen: their legends below (and the first frame's record of each)
    for n, frame in enumerate(frames[:max_frames]):
        meta = metas[n] if metas is not None else read_checked_meta(layout, frame)
        records = [r for r in meta["objects"] if r["kept"]]
        tiles, captions = [], []
        for i, lv in enumerate(levels):
            hidden = [not visible_at(r, lv) for r in records]
            tiles.append(_tile(read_image(layout.image(lv.key, frame)), records, tile_width, hidden))
            captions.append((f"frame {frame}: " if i == 0 else "") + _caption(lv)
                            + (f", {sum(hidden)} of {len(records)} hidden" if any(hidden) else ""))
        rows.append(strip(tiles, captions))
        for name, more in (("lidar", lidar_rows(layout, meta, levels, tile_width)),  # a LiDAR: its scans too
                           ("radar", radar_rows(layout, meta, levels, tile_width))):  # a radar: its detections
            rows += more
            if more and name not in sensors:
                sensors[name] = meta
    width = max(r.shape[1] for r in rows)
    rows.append(label(np.zeros((0, width, 3), np.uint8), SHEET_LEGEND, 22))  # how to read it, below it
    if "lidar" in sensors:
        rows.append(legend_row(LIDAR_LEGEND, width))
    if "radar" in sensors:
        rows.append(legend_row(RADAR_LEGEND, width))
        if note := fog_note(sensors["radar"]["radar"].get("levels") or {}):
            rows.append(text_row(note, width))
    gap = np.full((4, width, 3), 255, np.uint8)
    padded = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)), constant_values=255) for r in rows]
    return np.vstack([x for r in padded for x in (r, gap)][:-1])


#: the contact sheet's last line: how to read its boxes
SHEET_LEGEND = ("boxes: solid = visible at that level (contrast >= 5 %; in labels/ and visible/labels/); "
                "dashed, no name = hidden by the fog (contrast < 5 %; in labels/ only)")


def _tile(image: np.ndarray, records: list[dict], width: int, hidden: list[bool] | None = None) -> np.ndarray:
    """The image resized to ``width`` with class-coloured boxes and class names (``hidden``: dashed)."""
    s = width / image.shape[1]
    tile = cv2.resize(to_uint8(image), (width, round(image.shape[0] * s)), interpolation=cv2.INTER_AREA)
    return draw_boxes(tile, records, s, hidden)


def draw_boxes(image: np.ndarray, records: list[dict], scale: float = 1.0,
               hidden: list[bool] | None = None) -> np.ndarray:
    """``image`` (H×W×3 uint8, drawn in place and returned) with each record's box — its
    ``bbox`` [x0, y0, x1, y1) in pixels, times ``scale`` — outlined 1 px inside, in its class's
    colour, and the class name above it (within 10 px above the box's top). A record whose ``hidden``
    entry is True (an object the fog hides) is outlined dashed, without its name."""
    for n, r in enumerate(records):
        x0, y0, x1, y1 = (round(v * scale) for v in r["bbox"])
        colour = PALETTE[r["class_id"] % len(PALETTE)]
        corners = (x0, y0), (max(x0, x1 - 1), max(y0, y1 - 1))
        if hidden is not None and hidden[n]:
            _dashed_rectangle(image, *corners, colour)
            continue
        cv2.rectangle(image, *corners, colour, 1)
        cv2.putText(image, r["class"], (x0, max(8, y0 - 2)), cv2.FONT_HERSHEY_SIMPLEX, 0.3, colour, 1, cv2.LINE_AA)
    return image


def _dashed_rectangle(image: np.ndarray, p0: tuple[int, int], p1: tuple[int, int], colour, dash: int = 3) -> None:
    """A 1-px rectangle outline from ``p0`` to ``p1`` (inclusive corners), ``dash`` pixels on, ``dash`` off."""
    (x0, y0), (x1, y1) = p0, p1
    h, w = image.shape[:2]
    edge = [(x, y0) for x in range(x0, x1 + 1)] + [(x1, y) for y in range(y0 + 1, y1 + 1)]
    edge += [(x, y1) for x in range(x1 - 1, x0 - 1, -1)] + [(x0, y) for y in range(y1 - 1, y0, -1)]
    for i, (x, y) in enumerate(edge):
        if (i // dash) % 2 == 0 and 0 <= x < w and 0 <= y < h:
            image[y, x] = colour


def _caption(level) -> str:
    """Short tile caption: "clear" or "beta 0.06, V 50 m" (OpenCV fonts cannot draw β)."""
    vis = level.to_dict()["visibility_m"]
    return "clear" if vis is None else f"beta {level.beta:g}/m, V {vis:.0f} m"
