"""Reading a fogsim dataset (read-only): its levels, split lists, ground truth, frames and stereo
pairs, by the paths of :class:`fogsim.dataset.layout.DatasetLayout`.

Every function takes the dataset root (``str`` or ``Path``) or a ``DatasetLayout``. A missing
or malformed file raises :class:`fogsim.errors.InputError` naming it.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsim.camera import StereoCamera
from fogsim.dataset.layout import PARTS, DatasetLayout
from fogsim.errors import InputError
from fogsim.fileio import read_depth_file, read_image, read_json
from fogsim.readers.cityscapes import read_cityscapes_depth


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
    data = read_json(manifest)
    records = data.get("levels") if isinstance(data, dict) else None
    if not isinstance(records, list) or not all(isinstance(lv, dict) and isinstance(lv.get("key"), str)
                                                 and lv["key"] for lv in records):
        raise InputError(manifest, "malformed fogsim dataset manifest: 'levels' must be a list of "
                                   "{\"key\": …} records (rewrite it with fogsim render --finalize-only)")
    levels = [lv["key"] for lv in records]
    if not levels:
        raise InputError(manifest, "lists no fog levels")
    if len(set(levels)) != len(levels) or any(not _safe_key(k) for k in levels):
        raise InputError(manifest, f"malformed fog level keys {levels} (unique names without '/' or '..')")
    return levels


def dataset_classes(dataset: str | Path | DatasetLayout) -> list[str]:
    """The dataset's own class list (``dataset.json``'s ``classes``; YOLO id = index, COCO id =
    index + 1): fogsim's renderer classes for renders, e.g. Cityscapes' 8 for a fogged Cityscapes."""
    layout = as_layout(dataset)
    dataset_levels(layout)  # a manifest that exists and is well formed
    classes = read_json(layout.manifest()).get("classes")
    if not isinstance(classes, list) or not classes or not all(isinstance(c, str) and c for c in classes) \
            or len(set(classes)) != len(classes):
        raise InputError(layout.manifest(), "malformed fogsim dataset manifest: 'classes' must be a list of "
                                            "distinct class names (rewrite it with --finalize-only)")
    return classes


def _safe_key(key: str) -> bool:
    """A level key is a folder name under images/ and labels/: no path of its own."""
    return "/" not in key and "\\" not in key and key not in (".", "..")


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
    """The level's COCO ground truth restricted to its validation frames."""
    layout = as_layout(dataset)
    path = layout.coco(level)
    if not path.is_file():
        raise InputError(path, "missing COCO ground truth: run scripts/render_batch.py --finalize-only")
    gt = read_json(path)
    val = set(read_split(layout, level, "val"))
    try:
        images = [im for im in gt["images"] if Path(im["file_name"]).stem in val]
        ids = {im["id"] for im in images}
        annotations = [a for a in gt["annotations"] if a["image_id"] in ids]
    except (KeyError, TypeError, AttributeError) as exc:
        raise InputError(path, f"malformed COCO file ({type(exc).__name__}: {exc}): rewrite it with "
                               "fogsim render --finalize-only") from None
    return {**gt, "images": images, "annotations": annotations}


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
    """The frame record ``meta/<frame>.json``."""
    return read_json(as_layout(dataset).meta(frame))


def read_metas(dataset: str | Path | DatasetLayout, frames: list[str] | None = None) -> list[dict]:
    """The records of ``frames`` (default: every committed frame, sorted)."""
    layout = as_layout(dataset)
    return [read_json(layout.meta(f)) for f in (layout.done_frames() if frames is None else frames)]


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
