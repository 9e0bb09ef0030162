"""Each fog level as a KITTI object tree that mmdetection3d and OpenPCDet read as they are:

    OUT/kitti/<level>/training/{image_2,velodyne,calib,label_2}/<id>.{png,bin,txt,txt}
    OUT/kitti/<level>/ImageSets/{train,val}.txt

(``part=None`` writes the four folders straight under ``kitti/<level>/``). ``velodyne`` holds the
level's scan as KITTI stores it (4 × float32 little-endian: x, y, z, reflectance 0–1; a 0–255 source
such as STF goes through its normalised intensity), ``calib`` the frame's calibration with every KITTI
key (:func:`fogsim.readers.kitti.calib.format_kitti_calib`; STF's missing Tr_imu_to_velo as identity),
``label_2`` the frame's labels as 15-field lines (:func:`fogsim.readers.kitti.labels.format_label_line`,
one line per label line read: the per-class copies of a DontCare region are written once), ``image_2`` the
level's image as PNG. Every file is written atomically (temporary file + rename), so a killed run leaves
no half-written frame; a frame is complete when its four files exist (:func:`frame_complete`).

``image_2`` and ``velodyne`` hold what the level folders already hold (``images/<level>/<frame>.png``, a
KITTI-format ``lidar/<level>/<frame>.bin``): given those files, they are **hard links** to them where the
file system allows, copies otherwise (:func:`fogsim.io.links.link_or_copy`; never a symbolic link), so a
dataset does not store its images and scans twice. Every writer replaces files instead of writing into
them, so rewriting one name never changes its twin.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.images import encode_image
from fogsim.io.links import link_or_copy
from fogsim.lidar.formats import encode_points
from fogsim.lidar.points import PointCloud
from fogsim.readers.kitti.calib import KittiCalib, format_kitti_calib
from fogsim.readers.kitti.labels import format_label_line

__all__ = ["KITTI_DIR", "KittiTree", "kitti_label_text"]

KITTI_DIR = "kitti"
FOLDERS = {"image_2": ".png", "velodyne": ".bin", "calib": ".txt", "label_2": ".txt"}


def kitti_label_text(records: list[dict]) -> str:
    """The ``label_2`` text of a frame's records: one line per label line (records carrying the same
    ``line`` number — a DontCare region's per-class copies — are written once), in order."""
    seen, lines = set(), []
    for rec in records:
        key = rec.get("line")
        if key is not None:
            if key in seen:
                continue
            seen.add(key)
        lines.append(format_label_line(rec))
    return "".join(line + "\n" for line in lines)


class KittiTree:
    """One fog level's KITTI tree under ``OUT/kitti/<level>`` (the module docstring)."""

    def __init__(self, out: str | os.PathLike, level: str, part: str | None = "training"):
        self.root = Path(out) / KITTI_DIR / level
        self.base = self.root / part if part else self.root

    def path(self, folder: str, frame_id: str) -> Path:
        return self.base / folder / f"{frame_id}{FOLDERS[folder]}"

    def frame_complete(self, frame_id: str, labels: bool = True) -> bool:
        """Whether the frame's files exist (all four; three without ``labels``, as in ``testing/``)."""
        return all(self.path(f, frame_id).is_file() for f in FOLDERS if labels or f != "label_2")

    def write_frame(self, frame_id: str, image: np.ndarray | bytes | Path, cloud: PointCloud | Path,
                    calib: KittiCalib, records: list[dict] | None) -> None:
        """Write one frame: ``image`` an RGB array (encoded as PNG), PNG bytes, or the path of the level's
        PNG in this output (linked), ``cloud`` the level's scan in the LiDAR frame or the path of its
        KITTI-format file in this output (linked), ``calib`` its calibration, ``records`` its label records
        (None: no ``label_2`` file, as KITTI's ``testing/``). The label and calibration go first and the
        image last, so an image means a written frame."""
        if records is not None:
            atomic_write_bytes(self.path("label_2", frame_id), kitti_label_text(records).encode("utf-8"))
        atomic_write_bytes(self.path("calib", frame_id), format_kitti_calib(calib).encode("utf-8"))
        if isinstance(cloud, PointCloud):
            atomic_write_bytes(self.path("velodyne", frame_id), encode_points(cloud, "kitti"))
        else:
            link_or_copy(cloud, self.path("velodyne", frame_id))
        if isinstance(image, (str, os.PathLike)):
            link_or_copy(image, self.path("image_2", frame_id))
        else:
            data = image if isinstance(image, (bytes, bytearray)) else encode_image(image, ".png")
            atomic_write_bytes(self.path("image_2", frame_id), bytes(data))

    def write_image_sets(self, splits: dict[str, list[str]]) -> None:
        """``ImageSets/<name>.txt`` (one id per line) for each split, e.g. {"train": [...], "val": [...]}."""
        for name, ids in splits.items():
            atomic_write_bytes(self.root / "ImageSets" / f"{name}.txt", "".join(f"{i}\n" for i in ids).encode())
