"""Reading a fogsim dataset (read-only): its levels, split lists, ground truth, frames and stereo
pairs, by the paths of :class:`fogsim.dataset.layout.DatasetLayout`.

Every function takes the dataset root (``str`` or ``Path``) or a ``DatasetLayout``. A missing
or malformed file raises :class:`fogsim.errors.InputError` naming it.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsim.camera import Intrinsics, StereoCamera, planar_to_ray
from fogsim.dataset.coco import expand_every_class
from fogsim.dataset.layout import PARTS, DatasetLayout
from fogsim.errors import InputError
from fogsim.io.depth_files import read_depth_file
from fogsim.io.documents import read_json
from fogsim.io.images import read_image
from fogsim.readers.cityscapes_files import read_cityscapes_depth
from fogsim.schema.base import check, load_json
from fogsim.schema.documents import CocoFile, DatasetManifest, FrameMeta


def as_layout(dataset: str | Path | DatasetLayout) -> DatasetLayout:
    return dataset if isinstance(dataset, DatasetLayout) else DatasetLayout(dataset)


# --- the detection side: levels, splits, COCO -----------------------------------------------------
def dataset_levels(dataset: str | Path | DatasetLayout) -> list[str]:
    """Fog level keys of a fogsim dataset, in its order (from ``dataset.json``)."""
    layout = as_layout(dataset)
    manifest = layout.manifest()
    if not manifest.is_file():
        raise InputError(layout.root, "not a fogsim dataset (no dataset.json): render one with "
                                      "scripts/render_batch.py or pass --render, or fog a labelled dataset "
                                      "with fogsim fog (after sharded runs: fogsim fog --finalize-only)")
    data = load_json(manifest, DatasetManifest)
    return [lv.key for lv in data.levels]


def clear_level(dataset: str | Path | DatasetLayout) -> str | None:
    """The key of the dataset's clear level (β = 0 in ``dataset.json``), None when it has none."""
    layout = as_layout(dataset)
    dataset_levels(layout)  # the manifest's checks
    for record in read_json(layout.manifest())["levels"]:
        if record.get("beta") == 0:
            return record["key"]
    return None


def dataset_classes(dataset: str | Path | DatasetLayout) -> list[str]:
    """The dataset's own class list (``dataset.json``'s ``classes``; YOLO id = index, COCO id =
    index + 1): fogsim's renderer classes for renders, e.g. Cityscapes' 8 for a fogged Cityscapes."""
    layout = as_layout(dataset)
    return list(load_json(layout.manifest(), DatasetManifest).classes)


def read_split(dataset: str | Path | DatasetLayout, level: str, part: str) -> list[str]:
    """Frame names of one split list (``splits/<level>_<part>.txt``), by file stem, so a moved
    dataset still works."""
    path = as_layout(dataset).split_file(level, part)
    if not path.is_file():
        raise InputError(path, "missing split list: run scripts/render_batch.py --finalize-only")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, f"unreadable split list ({exc})") from None
    frames = [Path(line.strip()).stem for line in text.splitlines() if line.strip()]
    if not frames:
        raise InputError(path, "split list is empty")
    return frames


def val_ground_truth(dataset: str | Path | DatasetLayout, level: str) -> dict:
    """The level's COCO ground truth restricted to its validation frames, each ignore region of every
    class (KITTI's DontCare) as one crowd annotation per class (:func:`~fogsim.dataset.coco.expand_every_class`:
    the study evaluates per category)."""
    layout = as_layout(dataset)
    path = layout.coco(level)
    if not path.is_file():
        raise InputError(path, "missing COCO ground truth: run scripts/render_batch.py --finalize-only")
    gt = read_json(path)
    check(gt, CocoFile, path)  # the fields the study reads; file names inside the dataset
    val = set(read_split(layout, level, "val"))
    images = [im for im in gt["images"] if Path(im["file_name"]).stem in val]
    ids = {im["id"] for im in images}
    annotations = [a for a in gt["annotations"] if a["image_id"] in ids]
    return expand_every_class({**gt, "images": images, "annotations": annotations})


def missing_files(dataset: str | Path | DatasetLayout, levels: list[str]) -> list[Path]:
    """The images and labels every split list of ``levels`` names that are not in the dataset
    (a training run needs all of them; Ultralytics would name its own links, not these)."""
    layout = as_layout(dataset)
    missing = []
    for lv in levels:
        for part in PARTS:
            for frame in read_split(layout, lv, part):
                missing += [p for p in (layout.image(lv, frame), layout.label(lv, frame)) if not p.is_file()]
    return missing


# --- frames ---------------------------------------------------------------------------------------
def read_meta(dataset: str | Path | DatasetLayout, frame: str) -> dict:
    """The frame record ``meta/<frame>.json``, checked (:func:`read_checked_meta`)."""
    return read_checked_meta(dataset, frame)


def read_metas(dataset: str | Path | DatasetLayout, frames: list[str] | None = None) -> list[dict]:
    """The records of ``frames`` (default: every committed frame, sorted), each checked
    (:func:`read_checked_meta`): the first bad one raises."""
    layout = as_layout(dataset)
    return [read_checked_meta(layout, f) for f in (layout.done_frames() if frames is None else frames)]


def read_checked_meta(dataset: str | Path | DatasetLayout, frame: str, model=FrameMeta) -> dict:
    """``meta/<frame>.json`` checked against ``model`` (:class:`~fogsim.schema.documents.FrameMeta`,
    or a fogged run's ``FogFrameMeta``), its ``frame`` equal to the file's name; an
    :class:`InputError` naming the file otherwise."""
    path = as_layout(dataset).meta(frame)
    meta = read_json(path)
    check(meta, model, path)
    if meta["frame"] != frame:
        raise InputError(path, f"frame: names frame {meta['frame']!r}, not this file's {frame!r} "
                               "(a stray or copied file in meta/?)")
    return meta


@dataclass
class FrameRecords:
    """The committed frames whose records pass the schema (sorted), their records, and one line
    per meta file that does not (skipped: a per-frame document)."""

    frames: list[str]
    metas: list[dict]
    skipped: list[str]


def frame_records(dataset: str | Path | DatasetLayout, model=FrameMeta) -> FrameRecords:
    """Every committed frame's record checked against ``model``, a damaged or stray
    ``meta/*.json`` skipped and named."""
    layout = as_layout(dataset)
    frames, metas, skipped = [], [], []
    for frame in layout.done_frames():
        try:
            metas.append(read_checked_meta(layout, frame, model))
        except InputError as exc:
            skipped.append(str(exc))
            continue
        frames.append(frame)
    return FrameRecords(frames, metas, skipped)


def read_distance(dataset: str | Path | DatasetLayout, frame: str) -> np.ndarray:
    """The frame's ray distance ℓ in metres (H×W float32, +inf = no hit) from its depth file and
    the camera in its record (planar Z → ray); an InputError when the frame has no depth."""
    layout = as_layout(dataset)
    meta = read_meta(layout, frame)
    record = meta.get("depth") or {}
    path = layout.root / record["file"] if record.get("file") else layout.depth(frame)
    if not path.is_file():
        raise InputError(path, "no depth for this frame: fog from depth needs a rendered dataset (depth/<frame>.exr)")
    depth = read_depth_file(path)
    if str(record.get("kind", "planar")).startswith("planar"):
        try:
            K = Intrinsics.from_dict(meta["camera"]["intrinsics"], str(layout.meta(frame)))
        except (KeyError, TypeError):
            raise InputError(layout.meta(frame), "planar depth but no camera.intrinsics in the frame record") from None
        return planar_to_ray(depth, K)
    return depth.astype(np.float32, copy=False)


def frame_count(dataset: str | Path | DatasetLayout) -> int:
    """How many frames are committed (have a meta file); 0 for a folder that is no dataset yet."""
    return len(as_layout(dataset).done_frames())


# --- stereo pairs (the depth benchmark) -----------------------------------------------------------
@dataclass
class StereoFrame:
    """One committed stereo frame: the views, the exact depth and the SGBM depth beside them."""

    name: str
    left: np.ndarray        # RGB uint8
    right: np.ndarray
    exact: np.ndarray       # planar depth, metres, inf = sky
    sgbm: np.ndarray        # planar depth from SGBM, 0 = hole
    camera: StereoCamera


def stereo_split(dataset: str | Path | DatasetLayout, frame: str, meta: dict | None = None) -> str:
    """The split the frame's stereo files are in (from its meta); ValueError when it has none."""
    layout = as_layout(dataset)
    meta = read_json(layout.meta(frame)) if meta is None else meta
    if not meta.get("stereo"):
        raise ValueError(f"{layout.meta(frame)}: frame has no stereo pair (render with --stereo)")
    return meta["stereo"]["split"]


def stereo_frames(dataset: str | Path | DatasetLayout, split: str) -> list[str]:
    """Committed frames whose stereo pair is in ``split``, sorted."""
    layout = as_layout(dataset)
    return [f for f in layout.done_frames() if stereo_split(layout, f) == split]


def read_stereo_frame(dataset: str | Path | DatasetLayout, frame: str) -> StereoFrame:
    """Read a committed stereo frame; its Cityscapes files go through the Cityscapes reader."""
    layout = as_layout(dataset)
    split = stereo_split(layout, frame)
    sgbm, camera = read_cityscapes_depth(layout.cityscapes("disparity", frame, split),
                                         layout.cityscapes("camera", frame, split))
    return StereoFrame(frame, read_image(layout.cityscapes("leftImg8bit", frame, split)),
                       read_image(layout.cityscapes("rightImg8bit", frame, split)),
                       read_depth_file(layout.depth(frame)), sgbm, camera)
