"""The sample record every dataset adapter produces, and depth decoding by name.

A :class:`Sample` is cheap and picklable (it holds paths and small numbers, never pixels),
so shards and worker processes can pass samples around; pixels are read on demand.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..camera import (Intrinsics, decode_disparity_png, disparity_to_depth, load_cityscapes_camera,
                      paper_distance_from_8bit)
from ..errors import InputError
from ..io import read_depth_file, read_uint16_map

#: How a depth file is turned into metres (see :class:`DepthSpec`).
DEPTH_ENCODINGS = ("metric", "disparity", "paper-8bit", "ila")


@dataclass(frozen=True)
class DepthSpec:
    """Where a sample's depth comes from and how to decode it.

    ``encoding``:
      * ``metric`` — EXR/.npy in metres, or 16-bit PNG × ``png_scale`` metres per unit.
      * ``disparity`` — Cityscapes 16-bit disparity (p = 256·d + 1, 0 = invalid) decoded with
        the stereo camera JSON at ``camera_path`` into planar depth Z = baseline·fx/d.
      * ``paper-8bit`` — the paper's 8-bit ILA predictions decoded with its constant
        (:func:`fogsim.camera.paper_distance_from_8bit`); already a distance, no ray step.
      * ``ila`` — predicted from the image by the ILA checkpoint at ``path`` (planar depth,
        see :func:`fogsim.ila.predict_depth`); read with :meth:`read_for_image`.
    ``kind``: ``planar`` (Z along the optical axis; needs intrinsics) or ``ray`` (distance).
    """

    path: str
    encoding: str = "metric"
    kind: str = "planar"
    png_scale: float | None = None
    camera_path: str | None = None

    @property
    def is_ray_distance(self) -> bool:
        """True when the decoded values are already ray distances (no planar→ray step)."""
        return self.kind == "ray" or self.encoding == "paper-8bit"

    def read_for_image(self, image: np.ndarray) -> tuple[np.ndarray, Intrinsics | None]:
        """Like :meth:`read`, for encodings that need the image (``ila``)."""
        if self.encoding == "ila":
            from ..ila import cached_model, predict_depth

            model, config, camera = cached_model(self.path)
            return predict_depth(model, config, camera, image), None
        return self.read(image.shape[1], image.shape[0])

    def read(self, width: int, height: int) -> tuple[np.ndarray, Intrinsics | None]:
        """Depth in metres (0 = hole, inf = no hit) and the intrinsics the file implies."""
        if self.encoding == "metric":
            return read_depth_file(self.path, self.png_scale), None
        if self.encoding == "disparity":
            if self.camera_path is None or not Path(self.camera_path).is_file():
                raise InputError(self.path, f"disparity needs its camera JSON "
                                            f"({self.camera_path or 'none given'} not found)")
            raw = read_uint16_map(self.path)
            cam = load_cityscapes_camera(self.camera_path, raw.shape[1], raw.shape[0])
            depth = disparity_to_depth(decode_disparity_png(raw), cam.baseline, cam.intrinsics.fx)
            return depth, cam.intrinsics
        if self.encoding == "paper-8bit":
            import cv2

            raw = cv2.imread(self.path, cv2.IMREAD_UNCHANGED)
            if raw is None:
                raise InputError(self.path, "not a readable image (corrupt or unsupported format)")
            if raw.ndim == 3:
                raw = raw[:, :, 0]
            if raw.dtype != np.uint8:
                raise InputError(self.path, f"paper-8bit depth must be 8-bit, got {raw.dtype}")
            return paper_distance_from_8bit(raw), None
        raise InputError(self.path, f"unknown depth encoding {self.encoding!r} "
                                    f"(use one of {', '.join(DEPTH_ENCODINGS)})")


@dataclass(frozen=True)
class Sample:
    """One image to fog.

    ``key``: output path relative to the output level folder, POSIX, without suffix
    (e.g. ``frankfurt/frankfurt_000000_000294_leftImg8bit``). ``source``: what to name in
    messages. ``read_image``: a picklable callable returning H×W×3 RGB. ``depth``: where
    the depth is (None when the dataset has none). ``intrinsics``: camera of the image,
    when the dataset knows it (needed to turn planar depth into ray distance).
    """

    key: str
    source: str
    read_image: Callable[[], np.ndarray]
    depth: DepthSpec | None = None
    intrinsics: Intrinsics | None = None
    meta: dict = field(default_factory=dict, compare=False)
