"""Pictures for people: fog strips and colourised depth (RGB uint8 arrays)."""
from __future__ import annotations

import cv2
import numpy as np

from fogsim.colour import to_uint8

__all__ = ["colorize_depth", "fitted_scale", "label", "strip", "to_uint8"]


def fitted_scale(text: str, width: int, scale: float, font: int = cv2.FONT_HERSHEY_SIMPLEX,
                 thickness: int = 1) -> float:
    """``scale``, or the smaller font scale at which ``text`` fits ``width`` pixels (never clipped)."""
    drawn = cv2.getTextSize(text, font, scale, thickness)[0][0]
    return scale if drawn <= width else scale * width / drawn


def label(image: np.ndarray, text: str, height: int = 28) -> np.ndarray:
    """The image with a white caption bar above it (the text made smaller where it would not fit)."""
    img = to_uint8(image)
    bar = np.full((height, img.shape[1], 3), 255, np.uint8)
    scale = fitted_scale(text, img.shape[1] - 12, height / 40.0)
    cv2.putText(bar, text, (6, int(height * 0.72)), cv2.FONT_HERSHEY_SIMPLEX, scale, (20, 20, 20), 1,
                cv2.LINE_AA)
    return np.vstack([bar, img])


def strip(images: list[np.ndarray], captions: list[str], width: int | None = None,
          gap: int = 4) -> np.ndarray:
    """Images side by side with captions; each resized to ``width`` pixels if given."""
    tiles = []
    for img, cap in zip(images, captions):
        img = to_uint8(img)
        if width and img.shape[1] != width:
            h = round(img.shape[0] * width / img.shape[1])
            img = cv2.resize(img, (width, h), interpolation=cv2.INTER_AREA)
        tiles.append(label(img, cap))
    h = max(t.shape[0] for t in tiles)
    spacer = np.full((h, gap, 3), 255, np.uint8)
    row = []
    for t in tiles:
        pad = np.full((h - t.shape[0], t.shape[1], 3), 255, np.uint8)
        row += [np.vstack([t, pad]), spacer]
    return np.hstack(row[:-1])


def colorize_depth(depth: np.ndarray, max_m: float = 100.0) -> np.ndarray:
    """Depth or distance in metres → RGB (turbo, log scale, near = red); inf/holes black."""
    d = np.asarray(depth, np.float32)
    valid = np.isfinite(d) & (d > 0)
    x = np.zeros(d.shape, np.float32)
    x[valid] = np.log1p(np.minimum(d[valid], max_m)) / np.log1p(max_m)
    rgb = cv2.applyColorMap(((1 - x) * 255).astype(np.uint8), cv2.COLORMAP_TURBO)[:, :, ::-1].copy()
    rgb[~valid] = 0
    return rgb
