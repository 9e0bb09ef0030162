"""Cityscapes: ``leftImg8bit/`` images, ``disparity/`` 16-bit stereo, ``camera/`` JSON.

``ROOT/leftImg8bit/<split>/<city>/<city>_<seq>_<frame>_leftImg8bit.png`` pairs with
``ROOT/disparity/<split>/<city>/…_disparity.png`` and ``ROOT/camera/<split>/<city>/…_camera.json``
(``extrinsic.baseline`` ≈ 0.209 m, ``intrinsic.fx`` ≈ 2262 px, ``u0``, ``v0``). Depth is
planar Z = baseline·fx/d with d = (p − 1)/256, p = 0 a hole. The key keeps the input tree:
``leftImg8bit/<split>/<city>/<name>``.

The files themselves are read by :func:`read_cityscapes_depth` / :func:`read_cityscapes_disparity`
and :func:`load_cityscapes_camera` (defined in :mod:`fogsim.readers.cityscapes_files`, the one
reader of the format, and re-exported here).
"""
from __future__ import annotations

from pathlib import Path

from fogsim.errors import InputError
from fogsim.readers.base import DepthSpec, Sample
from fogsim.readers.cityscapes_files import (load_cityscapes_camera, read_cityscapes_depth,
                                             read_cityscapes_disparity)
from fogsim.readers.files import ImageFile

__all__ = ["SUFFIX", "cityscapes_samples", "load_cityscapes_camera", "read_cityscapes_depth",
           "read_cityscapes_disparity"]

SUFFIX = "_leftImg8bit.png"


def cityscapes_samples(root: str | Path, splits: str | list[str] = "val") -> list[Sample]:
    """Samples of the given split(s) (``train``, ``val``, ``test``, comma-separated or a list)."""
    root = Path(root)
    if isinstance(splits, str):
        splits = [s.strip() for s in splits.split(",") if s.strip()]
    samples = []
    for split in splits:
        img_root = root / "leftImg8bit" / split
        if not img_root.is_dir():
            raise InputError(img_root, "not a Cityscapes split folder (expected ROOT/leftImg8bit/<split>/)")
        for img in sorted(img_root.glob(f"*/*{SUFFIX}")):
            city, base = img.parent.name, img.name[: -len(SUFFIX)]
            disp = root / "disparity" / split / city / f"{base}_disparity.png"
            cam = root / "camera" / split / city / f"{base}_camera.json"
            spec = DepthSpec(str(disp), encoding="disparity", kind="planar", camera_path=str(cam))
            key = f"leftImg8bit/{split}/{city}/{img.name[:-4]}"
            samples.append(Sample(key, str(img), ImageFile(str(img)), spec))
    if not samples:
        raise InputError(root, f"no *{SUFFIX} images in split(s) {', '.join(splits)}")
    return samples
