"""What a killed render leaves in its dataset folder, and its removal when the render resumes.

Two kinds of leftovers, both hidden and never counted as outputs (a frame is done only when
``meta/<frame>.json`` exists; every reader lists visible names):

* ``.NAME.xxxxxxxx.part`` — an unfinished atomic write (:func:`fogsim.fileio.atomic_path`,
  suffix :data:`fogsim.fileio.PART_SUFFIX`) beside a frame's output (``images/<level>/``,
  ``labels/<level>/``, ``depth/``, ``masks/``, ``meta/``, the Cityscapes tree) or beside a
  dataset-wide file (``coco/``, ``splits/``, ``data/``, the root);
* Cycles' multilayer EXR of a frame, written to :data:`TMP_DIR` in the dataset folder (not
  the system temp folder, where nothing would ever remove it).

A frame's leftovers belong to the job that renders that frame (its shard): a job removes
those of its own frames when it starts, so shards running side by side into one folder never
remove each other's files in flight. Dataset-wide leftovers are removed by the run that
writes the dataset-wide files (the unsharded run or ``--finalize-only``). Pure Python: no bpy.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

from fogsim.dataset.layout import DatasetLayout
from fogsim.fileio import PART_SUFFIX

#: Hidden folder in the dataset root for Cycles' per-frame EXR (removed when empty).
TMP_DIR = ".fogsim_tmp"
_FRAME = re.compile(r"(\d+)[._]")


def render_tmp_dir(layout: DatasetLayout) -> Path:
    return layout.root / TMP_DIR


def part_target(name: str) -> str | None:
    """``".000001.txt.ab12cd_x.part"`` → ``"000001.txt"``; None for a name that is no part file."""
    if not (name.startswith(".") and name.endswith(PART_SUFFIX)):
        return None
    target, dot, _random = name[1:-len(PART_SUFFIX)].rpartition(".")
    return target if dot and target else None


def frame_of(name: str) -> str | None:
    """The frame a file name belongs to (``000001.png``, ``000001_disparity.png``, ``000001.left.exr``)."""
    m = _FRAME.match(name)
    return m.group(1) if m else None


def _subdirs(folder: Path) -> list[Path]:
    try:
        return [Path(e.path) for e in os.scandir(folder) if e.is_dir(follow_symlinks=False)]
    except (FileNotFoundError, NotADirectoryError):
        return []


def _frame_dirs(layout: DatasetLayout) -> list[Path]:
    root = layout.root
    dirs = [*_subdirs(root / "images"), *_subdirs(root / "labels"), root / "depth", root / "masks",
            layout.meta_dir()]
    for kind in _subdirs(layout.cityscapes_root()):
        dirs += [split / "fogsim" for split in _subdirs(kind)]
    return dirs


def _scan(folder: Path):
    try:
        with os.scandir(folder) as it:
            yield from (e for e in it if e.is_file(follow_symlinks=False))
    except (FileNotFoundError, NotADirectoryError):
        return


def _remove(paths: list[Path]) -> list[Path]:
    for p in paths:
        p.unlink(missing_ok=True)
    return paths


def remove_frame_leftovers(layout: DatasetLayout, frames) -> list[Path]:
    """Remove the part files and temporary renders of ``frames`` (names); returns what went."""
    frames = set(frames)
    stale = [Path(e.path) for d in _frame_dirs(layout) for e in _scan(d)
             if (t := part_target(e.name)) is not None and frame_of(t) in frames]
    stale += [Path(e.path) for e in _scan(render_tmp_dir(layout)) if frame_of(e.name) in frames]
    return _remove(stale)


def remove_dataset_leftovers(layout: DatasetLayout) -> list[Path]:
    """Remove the part files of dataset-wide files (root, ``coco/``, ``splits/``, ``data/``)."""
    root = layout.root
    folders = (root, root / "coco", root / "splits", root / "data")
    return _remove([Path(e.path) for d in folders for e in _scan(d) if part_target(e.name) is not None])


def remove_render_tmp(layout: DatasetLayout, frames) -> None:
    """Remove the temporary renders of ``frames``, then :data:`TMP_DIR` if it is empty (another
    shard's render may still be in it)."""
    frames = set(frames)
    _remove([Path(e.path) for e in _scan(render_tmp_dir(layout)) if frame_of(e.name) in frames])
    try:
        render_tmp_dir(layout).rmdir()
    except OSError:
        pass
