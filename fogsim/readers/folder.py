"""Any folder of images with depth maps matched by name.

``images/a/b/x.png`` pairs with ``depth/a/b/x<depth_suffix>.{exr,npy,png,tif}``; the
sample key is ``a/b/x``. Intrinsics come from ``--intrinsics FILE.json`` or ``--hfov``
(needed when the depth is planar), one camera for the whole folder.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from fogsim.camera import Intrinsics
from fogsim.errors import InputError
from fogsim.fileio import DEPTH_SUFFIXES, IMAGE_SUFFIXES
from fogsim.readers.base import DepthSpec, Sample
from fogsim.readers.files import ImageFile


def find_depth(depth_dir: Path, stem: str, suffix: str = "") -> Path | None:
    """The first ``depth_dir/<stem><suffix><ext>`` that exists, for ext in DEPTH_SUFFIXES."""
    for ext in DEPTH_SUFFIXES:
        cand = depth_dir / f"{stem}{suffix}{ext}"
        if cand.is_file():
            return cand
    return None


def folder_samples(images_dir: str | Path, depth_dir: str | Path | None,
                   depth: DepthSpec = DepthSpec(""), depth_suffix: str = "",
                   intrinsics: Intrinsics | None = None) -> list[Sample]:
    """Samples for every image under ``images_dir`` (recursive, sorted by path)."""
    images_dir = Path(images_dir)
    if not images_dir.is_dir():
        raise InputError(images_dir, "image folder not found")
    depth_dir = Path(depth_dir) if depth_dir is not None else None
    if depth_dir is not None and not depth_dir.is_dir():
        raise InputError(depth_dir, "depth folder not found")
    samples, seen = [], {}
    for path in sorted(p for p in images_dir.rglob("*") if p.suffix.lower() in IMAGE_SUFFIXES):
        rel = path.relative_to(images_dir).with_suffix("").as_posix()
        if rel in seen:
            raise InputError(path, f"has the same name as {seen[rel]} but another extension: their "
                                   "outputs would overwrite each other")
        seen[rel] = path
        spec = None
        if depth_dir is not None:
            found = find_depth(depth_dir, rel, depth_suffix)
            # a missing file is reported when the sample is processed, naming the expected path
            spec = replace(depth, path=str(found or depth_dir / f"{rel}{depth_suffix}.exr"))
        samples.append(Sample(rel, str(path), ImageFile(str(path)), spec, intrinsics))
    if not samples:
        raise InputError(images_dir, f"no images ({', '.join(IMAGE_SUFFIXES)}) found")
    return samples
