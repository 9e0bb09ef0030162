"""Cycles' temporary renders of a dataset, and their removal when a render resumes.

Cycles writes each frame's multilayer EXR to :data:`TMP_DIR` in the dataset folder (not the
system temp folder, where nothing would ever remove it). A frame's temporary renders belong
to the job that renders that frame (its shard): a job removes those of its own frames when it
starts and when it closes, so shards running side by side never remove each other's files in
flight. Unfinished atomic writes (``.part`` files) are removed by
:func:`fogsim.io.parts.remove_stale_parts`, the same rule as for every fogsim output. Pure
Python: no bpy.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

from fogsim.dataset.layout import DatasetLayout

#: Hidden folder in the dataset root for Cycles' per-frame EXR (removed when empty).
TMP_DIR = ".fogsim_tmp"
_FRAME = re.compile(r"(\d+)[._]")


def render_tmp_dir(layout: DatasetLayout) -> Path:
    return layout.root / TMP_DIR


def frame_of(name: str) -> str | None:
    """The frame a file name belongs to (``000001.left.exr`` → ``000001``)."""
    m = _FRAME.match(name)
    return m.group(1) if m else None


def remove_render_tmp(layout: DatasetLayout, frames) -> None:
    """Remove the temporary renders of ``frames``, then :data:`TMP_DIR` if it is empty (another
    shard's render may still be in it)."""
    frames = set(frames)
    try:
        entries = list(os.scandir(render_tmp_dir(layout)))
    except (FileNotFoundError, NotADirectoryError):
        return
    for entry in entries:
        if entry.is_file(follow_symlinks=False) and frame_of(entry.name) in frames:
            Path(entry.path).unlink(missing_ok=True)
    try:
        render_tmp_dir(layout).rmdir()
    except OSError:
        pass
