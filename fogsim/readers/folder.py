"""Any folder of images with depth maps matched by name.

``images/a/b/x.png`` pairs with ``depth/a/b/x<depth_suffix>.{exr,npy,png,tif}``; the
sample key is ``a/b/x``. Extensions match in any case (``X.PNG`` pairs with ``X.EXR``).
Symlinked sub-folders are followed in both trees, a symlink back to a folder above it
(a cycle) is not. Intrinsics come from ``--intrinsics FILE.json`` or ``--hfov`` (needed
when the depth is planar), one camera for the whole folder.
"""
from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from fogsim.camera import Intrinsics
from fogsim.errors import InputError
from fogsim.io.depth_files import DEPTH_SUFFIXES
from fogsim.io.images import IMAGE_SUFFIXES
from fogsim.readers.base import DepthSpec, Sample
from fogsim.readers.files import ImageFile


def find_depth(depth_dir: Path, stem: str, suffix: str = "",
               listings: dict | None = None) -> Path | None:
    """The first ``depth_dir/<stem><suffix><ext>`` that exists, for ext in DEPTH_SUFFIXES, the
    extension in any case (``.exr`` before ``.EXR``). ``listings``: a dict kept between calls
    as a cache of folder listings (the case-insensitive look-up lists a folder once)."""
    base = Path(depth_dir) / f"{stem}{suffix}"
    for ext in DEPTH_SUFFIXES:
        cand = base.with_name(base.name + ext)
        if cand.is_file():
            return cand
    listings = {} if listings is None else listings
    folder = base.parent
    if folder not in listings:
        try:
            listings[folder] = sorted(os.listdir(folder))
        except OSError:
            listings[folder] = []
    prefix = base.name
    by_ext = {}
    for name in listings[folder]:
        ext = name[len(prefix):].lower()
        if name.startswith(prefix) and ext in DEPTH_SUFFIXES and (folder / name).is_file():
            by_ext.setdefault(ext, folder / name)
    return next((by_ext[ext] for ext in DEPTH_SUFFIXES if ext in by_ext), None)


def image_files(root: Path) -> list[Path]:
    """Every image file under ``root`` (extension in any case), sorted, following symlinked
    sub-folders but never into a folder that is already on the way down (a symlink cycle)."""
    found: list[Path] = []

    def walk(folder: Path, above: frozenset) -> None:
        try:
            entries = sorted(os.scandir(folder), key=lambda e: e.name)
        except OSError as exc:
            raise InputError(folder, f"cannot list the folder ({exc.strerror or exc})") from None
        for entry in entries:
            path = folder / entry.name
            try:
                if entry.is_dir():  # follows symlinks
                    st = os.stat(path)
                    here = (st.st_dev, st.st_ino)
                    if here not in above:
                        walk(path, above | {here})
                elif entry.is_file() and path.suffix.lower() in IMAGE_SUFFIXES:
                    found.append(path)
            except OSError:  # a dangling symlink, or one that vanished: not an image
                continue

    st = os.stat(root)
    walk(root, frozenset({(st.st_dev, st.st_ino)}))
    return sorted(found)


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
    samples, seen, listings = [], {}, {}
    for path in image_files(images_dir):
        rel = path.relative_to(images_dir).with_suffix("").as_posix()
        if rel in seen:
            raise InputError(path, f"has the same name as {seen[rel]} but another extension: their "
                                   "outputs would overwrite each other")
        seen[rel] = path
        spec = None
        if depth_dir is not None:
            found = find_depth(depth_dir, rel, depth_suffix, listings)
            # a missing file is reported when the sample is processed, naming the expected path
            spec = replace(depth, path=str(found or depth_dir / f"{rel}{depth_suffix}.exr"))
        samples.append(Sample(rel, str(path), ImageFile(str(path)), spec, intrinsics))
    if not samples:
        raise InputError(images_dir, f"no images ({', '.join(IMAGE_SUFFIXES)}) found")
    return samples
