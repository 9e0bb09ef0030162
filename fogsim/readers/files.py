"""Picklable image readers for samples (worker processes receive them by pickling)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsim.io.images import read_image


@dataclass(frozen=True)
class ImageFile:
    """Reads an image file as RGB when called."""

    path: str

    def __call__(self) -> np.ndarray:
        return read_image(self.path)
