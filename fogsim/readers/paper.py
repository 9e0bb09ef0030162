"""The paper's 8-bit depth maps (Chaar & Weidl), decoded exactly as its reference fog code does.

The reference code decodes its 8-bit ILA predictions p ∈ [0, 126] with baseline 22 (cm) ×
focal 5.6, divides by 100 and uses the result directly as the distance in Koschmieder's law
(no planar→ray step): ℓ = 0.22·5.6·256/(p − 1) m, and p < 2 → 320 m. ``--depth-encoding
paper-8bit`` reads depth this way (:class:`fogsim.readers.base.DepthSpec`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fogsim.errors import InputError

PAPER_BASELINE_TIMES_FOCAL = 22 * 5.6 / 100  # = 1.232
PAPER_FAR_DISTANCE = 320.0


def paper_distance_from_8bit(raw: np.ndarray) -> np.ndarray:
    """Distance in metres exactly as the paper's reference code computes it from 8-bit values."""
    p = raw.astype(np.float64)
    with np.errstate(divide="ignore"):
        dist = PAPER_BASELINE_TIMES_FOCAL * 256.0 / (p - 1.0)
    dist[p < 2] = PAPER_FAR_DISTANCE
    return dist.astype(np.float32)


def read_paper_8bit(path: str | Path) -> np.ndarray:
    """An 8-bit depth map (grey, or the first channel of a colour PNG) → distance in metres."""
    from fogsim.io.images import read_stored

    raw = read_stored(path)  # BGR as stored: channel 0 is the file's first
    if raw.ndim == 3:
        raw = raw[:, :, 0]
    if raw.dtype != np.uint8:
        raise InputError(path, f"paper-8bit depth must be 8-bit, got {raw.dtype}")
    return paper_distance_from_8bit(raw)
