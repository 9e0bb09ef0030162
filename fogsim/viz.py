"""Pictures for people: fog strips and colourised depth (RGB uint8 arrays)."""
from __future__ import annotations

import cv2
import numpy as np

from fogsim.colour import to_uint8

__all__ = ["colorize_depth", "fitted_scale", "label", "legend_row", "ring_labels", "strip", "text_row", "to_uint8"]


def fitted_scale(text: str, width: int, scale: float, font: int = cv2.FONT_HERSHEY_SIMPLEX,
                 thickness: int = 1) -> float:
    """``scale``, or the smaller font scale at which ``text`` fits ``width`` pixels (never clipped)."""
    # OpenCV rounds each glyph's advance, so the width is not proportional to the scale: shrink until it fits.
    for _ in range(50):
        drawn = cv2.getTextSize(text, font, scale, thickness)[0][0]
        if drawn <= width:
            return scale
        scale *= min(width / drawn, 0.98)
    return scale


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


#: how a legend entry's swatch is drawn: a filled disc, a hollow ring, a one-pixel dot, a box outline, the
#: sensor's triangle
SWATCHES = ("disc", "ring", "dot", "box", "sensor")


def _swatch(img: np.ndarray, kind: str, x: int, y: int, colour) -> None:
    colour = tuple(int(c) for c in colour)
    if kind == "disc":
        cv2.circle(img, (x + 6, y), 4, colour, -1, cv2.LINE_AA)
    elif kind == "ring":
        cv2.circle(img, (x + 6, y), 4, colour, 1, cv2.LINE_AA)
    elif kind == "dot":
        img[y - 2:y + 2, x + 4:x + 8] = colour
    elif kind == "box":
        cv2.rectangle(img, (x + 1, y - 4), (x + 11, y + 4), colour, 1)
    elif kind == "sensor":
        cv2.drawMarker(img, (x + 6, y + 1), colour, cv2.MARKER_TRIANGLE_UP, 9, 2)
    else:
        raise ValueError(f"legend swatch must be one of {', '.join(SWATCHES)}, got {kind!r}")


def legend_row(entries: list[tuple[str, tuple, str]], width: int, height: int = 20, scale: float = 0.42) -> np.ndarray:
    """A legend, RGB uint8 ``width`` wide: each entry ``(swatch kind, RGB colour, text)`` (:data:`SWATCHES`)
    left to right, wrapped onto as many rows of ``height`` pixels as it needs."""
    font, gap = cv2.FONT_HERSHEY_SIMPLEX, 14
    lines, line, x = [], [], 6
    for entry in entries:
        w = 16 + cv2.getTextSize(entry[2], font, scale, 1)[0][0]
        if line and x + w > width - 6:
            lines.append(line)
            line, x = [], 6
        line.append((x, entry))
        x += w + gap
    lines.append(line)
    img = np.full((height * len(lines), width, 3), 255, np.uint8)
    for n, line in enumerate(lines):
        y = n * height + height // 2
        for x, (kind, colour, text) in line:
            _swatch(img, kind, x, y, colour)
            cv2.putText(img, text, (x + 16, y + 4), font, fitted_scale(text, width - x - 22, scale), (30, 30, 30), 1,
                        cv2.LINE_AA)
    return img


def text_row(text: str, width: int, height: int = 20, scale: float = 0.42) -> np.ndarray:
    """One line of dark text on white, ``width`` wide (made smaller where it would not fit)."""
    img = np.full((height, width, 3), 255, np.uint8)
    cv2.putText(img, text, (6, height // 2 + 4), cv2.FONT_HERSHEY_SIMPLEX, fitted_scale(text, width - 12, scale),
                (30, 30, 30), 1, cv2.LINE_AA)
    return img


def ring_labels(img: np.ndarray, centre: tuple[int, int], radii_m, px_per_m: float, angle_deg: float = -35.0,
                colour=(120, 120, 120), scale: float = 0.38) -> np.ndarray:
    """Write each range ring's distance (``"20 m"``) on ``img`` (in place; returned), on a white patch, where
    the ring of radius r metres about ``centre`` (column, row) meets the ray at ``angle_deg`` (0 = right,
    counter-clockwise); a label that would not fit inside the image is left out."""
    a = np.deg2rad(angle_deg)
    for r in radii_m:
        text = f"{r:g} m"
        (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
        x = int(round(centre[0] + r * px_per_m * np.cos(a))) - tw // 2
        y = int(round(centre[1] - r * px_per_m * np.sin(a))) + th // 2
        if 1 <= x and x + tw < img.shape[1] - 1 and th + 1 <= y and y + base < img.shape[0] - 1:
            img[y - th - 1:y + base, x - 1:x + tw + 1] = 255
            cv2.putText(img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv2.LINE_AA)
    return img


def colorize_depth(depth: np.ndarray, max_m: float = 100.0) -> np.ndarray:
    """Depth or distance in metres → RGB (turbo, log scale, near = red); inf/holes black."""
    d = np.asarray(depth, np.float32)
    valid = np.isfinite(d) & (d > 0)
    x = np.zeros(d.shape, np.float32)
    x[valid] = np.log1p(np.minimum(d[valid], max_m)) / np.log1p(max_m)
    rgb = cv2.applyColorMap(((1 - x) * 255).astype(np.uint8), cv2.COLORMAP_TURBO)[:, :, ::-1].copy()
    rgb[~valid] = 0
    return rgb
