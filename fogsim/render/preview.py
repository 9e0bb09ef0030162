"""The fog preview of one frame (pure Python): a one-frame dataset read back, boxes drawn.

The add-on's *Preview fog* renders frame N through the dataset path itself — a render job over
that frame alone with the levels :func:`preview_levels` (clear and the preview β) into a temporary
folder — so what it shows is exactly the dataset's image at that β, whatever the preset does
(Koschmieder with its airlight, blend space and kernel, or volumetric fog; the camera model, the
asset library, the sky). :func:`read_preview` reads that frame back and draws its kept boxes as
the contact sheet does.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.reader import read_meta
from fogsim.dataset.writer import draw_boxes
from fogsim.fog.levels import FogLevel, level_from_beta
from fogsim.io.depth_files import EXR_DEPTH_CHANNELS
from fogsim.io.images import read_image
from fogsim.render.exr_reader import read_exr


def preview_levels(beta: float) -> tuple[FogLevel, ...]:
    """The levels a preview at ``beta`` (1/m) renders: clear, and that β unless it is 0."""
    clear = level_from_beta(0.0)
    return (clear,) if beta == 0 else (clear, level_from_beta(beta))


@dataclass(frozen=True)
class FogPreview:
    """``clear`` and ``foggy``: the frame's clear and β images (H×W×3 uint8 sRGB, as written);
    ``depth``: H×W float32 planar Z in metres (+inf = sky); ``meta``: the frame record
    (camera intrinsics, objects, fog); ``records``: its kept objects; ``image``: ``foggy`` with
    their boxes drawn (what the add-on shows)."""

    beta: float
    clear: np.ndarray
    foggy: np.ndarray
    depth: np.ndarray
    meta: dict
    records: list
    image: np.ndarray

    @property
    def model(self) -> str:
        """"koschmieder" or "volumetric": how the fog was made."""
        return self.meta["fog"]["model"]

    @property
    def caption(self) -> str:
        vis = level_from_beta(self.beta).to_dict()["visibility_m"]
        fog = "clear" if vis is None else f"β {self.beta:g}/m, V {vis:.0f} m"
        return f"{self.model}, {fog}, {len(self.records)} boxes"


def read_preview(root: str | Path, frame: str, beta: float, boxes: bool = True) -> FogPreview:
    """Frame ``frame`` of the one-frame dataset at ``root`` as a preview at ``beta``."""
    layout = DatasetLayout(root)
    meta = read_meta(layout, frame)
    foggy = read_image(layout.image(level_from_beta(beta).key, frame))
    kept = [r for r in meta["objects"] if r["kept"]]
    image = draw_boxes(foggy.copy(), kept) if boxes else foggy.copy()
    # fogsim's own EXR reader: the OpenEXR package crashes inside Debian's Blender 3.4 (exr_reader)
    channels = read_exr(layout.depth(frame))
    depth = next(channels[c] for c in EXR_DEPTH_CHANNELS if c in channels).astype(np.float32)
    return FogPreview(beta, read_image(layout.image("clear", frame)), foggy, depth, meta, kept, image)
