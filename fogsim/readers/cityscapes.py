"""Cityscapes: ``leftImg8bit/`` images, ``disparity/`` 16-bit stereo, ``camera/`` JSON.

``ROOT/leftImg8bit/<split>/<city>/<city>_<seq>_<frame>_leftImg8bit.png`` pairs with
``ROOT/disparity/<split>/<city>/…_disparity.png`` and ``ROOT/camera/<split>/<city>/…_camera.json``
(``extrinsic.baseline`` ≈ 0.209 m, ``intrinsic.fx`` ≈ 2262 px, ``u0``, ``v0``). Depth is
planar Z = baseline·fx/d with d = (p − 1)/256, p = 0 a hole. The key keeps the input tree:
``leftImg8bit/<split>/<city>/<name>``.

The files themselves are read by :func:`read_cityscapes_depth` / :func:`read_cityscapes_disparity`
and :func:`load_cityscapes_camera` (defined in :mod:`fogsim.readers.cityscapes_files`, the one
reader of the format, and re-exported here). Instance labels (``gtFine/``):
:mod:`fogsim.readers.cityscapes_labels`.
"""
from __future__ import annotations

from pathlib import Path

from fogsim.errors import InputError
from fogsim.readers.base import DepthSpec, Sample
from fogsim.readers.cityscapes_files import load_cityscapes_camera, read_cityscapes_depth, read_cityscapes_disparity
from fogsim.readers.files import ImageFile

__all__ = ["SUFFIX", "cityscapes_samples", "load_cityscapes_camera", "read_cityscapes_depth",
           "read_cityscapes_disparity"]

SUFFIX = "_leftImg8bit.png"


def cityscapes_samples(root: str | Path, splits: str | list[str] = "val",
                       labels: bool | None = None) -> list[Sample]:
    """Samples of the given split(s) (``train``, ``val``, ``test``, comma-separated or a list).

    ``labels``: ``None`` (default) gives every sample its instance labels
    (:class:`fogsim.readers.cityscapes_labels.CityscapesLabels`) when ``ROOT/gtFine/<split>/``
    exists for every split, and none when it exists for none; ``True`` requires it, ``False``
    never reads it. A missing gtFine where labels are wanted is an :class:`InputError` telling
    to pass ``--no-labels``."""
    from fogsim.readers.cityscapes_labels import CityscapesLabels, instance_ids_path

    root = Path(root)
    if isinstance(splits, str):
        splits = [s.strip() for s in splits.split(",") if s.strip()]
    for split in splits:
        img_root = root / "leftImg8bit" / split
        if not img_root.is_dir():
            raise InputError(img_root, "not a Cityscapes split folder (expected ROOT/leftImg8bit/<split>/)")
    has_gt = {split: (root / "gtFine" / split).is_dir() for split in splits}
    if labels is None:
        labels = any(has_gt.values())
    if labels:
        for split, ok in has_gt.items():
            if not ok:
                raise InputError(root / "gtFine" / split, "missing: the instance labels (gtFine) of split "
                                 f"{split!r} are needed for a labelled dataset; pass --no-labels to fog "
                                 "the images alone")
            if next((root / "gtFine" / split).glob("*/*_gtFine_instanceIds.png"), None) is None:
                raise InputError(root / "gtFine" / split, "holds no instance labels (no <city>/*_gtFine_instanceIds"
                                 f".png): the labels of split {split!r} are needed for a labelled dataset; pass "
                                 "--no-labels to fog the images alone")
    samples = []
    for split in splits:
        img_root = root / "leftImg8bit" / split
        for img in sorted(img_root.glob(f"*/*{SUFFIX}")):
            city, base = img.parent.name, img.name[: -len(SUFFIX)]
            disp = root / "disparity" / split / city / f"{base}_disparity.png"
            cam = root / "camera" / split / city / f"{base}_camera.json"
            spec = DepthSpec(str(disp), encoding="disparity", kind="planar", camera_path=str(cam))
            key = f"leftImg8bit/{split}/{city}/{img.name[:-4]}"
            reader = None
            if labels:
                reader = CityscapesLabels(str(instance_ids_path(root, split, city, base)), str(img), str(disp),
                                          str(cam))
            samples.append(Sample(key, str(img), ImageFile(str(img)), spec, labels=reader))
    if not samples:
        raise InputError(root, f"no *{SUFFIX} images in split(s) {', '.join(splits)}")
    return samples
