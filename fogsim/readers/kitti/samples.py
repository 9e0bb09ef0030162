"""KITTI object detection and Seeing Through Fog as fogsim :class:`~fogsim.readers.base.Sample` lists:
image 2 (or STF's left camera), its labels, its intrinsics, and the LiDAR scan as a picklable points
source projected into the image.

KITTI: ``ROOT/training/{image_2,velodyne,calib,label_2}/NNNNNN.{png,bin,txt,txt}`` (``testing/`` has no
``label_2``); the split is every image (``split=None``), a list in ``ROOT/ImageSets/<name>.txt``
(``train``, ``val``, ``test``, ``trainval``: one id per line) or any such file (a path).

STF: ``ROOT/cam_stereo_left_lut/*.png`` (the 8-bit images it was labelled on),
``ROOT/lidar_hdl64_strongest/*.bin`` or ``ROOT/lidar_hdl64_last/*.bin`` (``returns``),
``ROOT/gt_labels/cam_left_labels_TMP/*.txt``; ids ``YYYY-MM-DD_hh-mm-ss_NNNNN``; split files as in the
repository's ``splits/*.txt`` (``YYYY-MM-DD_hh-mm-ss,NNNNN`` per line) or one id per line. Its
calibration is not in the download: ``calib`` is a KITTI-form file for every frame (the repository's
``tools/ProjectionTools/Sweden2KittiCalib/kitti_stereo_velodynehdl_calib.txt``), or the folder of its
ROS files (``tools/DatasetViewer/calibs``: :func:`~.calib.stf_calib_from_tf`), or None when
``ROOT/calib/<id>.txt`` exist (converted trees).

Every frame of the split must have all its files: a missing one is one :class:`InputError` naming it
(and how many frames miss files). Depth: ``Sample.depth`` is None here and ``meta["lidar_points"]`` the
:class:`KittiPoints` source; :func:`fogsim.depth.lidar_source.lidar_samples` with
``points_source=fogsim.depth.lidar_source.meta_points_source`` makes it the LiDAR-completed depth (the
readers may not import the depth layer above them).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsim.errors import InputError
from fogsim.lidar.boxes import Box3D
from fogsim.lidar.formats import read_points
from fogsim.lidar.points import PointCloud
from fogsim.lidar.rays import CameraView
from fogsim.lidar.sensors import LidarSensor, load_sensor
from fogsim.readers.base import Sample
from fogsim.readers.cityscapes_labels import png_size
from fogsim.readers.files import ImageFile
from fogsim.readers.kitti.boxes import label_boxes
from fogsim.readers.kitti.calib import KittiCalib, read_kitti_calib, stf_calib_from_tf
from fogsim.readers.kitti.labels import KittiLabels

__all__ = ["KITTI_PARTS", "KITTI_SPLITS", "KittiPoints", "SENSORS", "STF_RETURNS", "kitti_samples", "read_split",
           "stf_samples"]

KITTI_SPLITS = ("train", "val", "test", "trainval")
KITTI_PARTS = ("training", "testing")
STF_RETURNS = ("strongest", "last")
#: the sensor each scan format's dataset was recorded with (the bundled presets)
SENSORS = {"kitti": "hdl64e", "stf": "hdl64-s3d"}


@dataclass(frozen=True)
class KittiPoints:
    """Picklable points source of one frame: ``KittiPoints(scan, calib)() → (uv N×2 float64 pixel-edge
    coordinates in image 2, ray N float32 metres from camera 2's centre)`` for the points in front of the
    camera (the image bounds are :class:`fogsim.depth.lidar_source.LidarDepth`'s to apply). ``fmt``:
    ``kitti`` (4 floats) or ``stf`` (5); ``calib``: a file (or a :class:`KittiCalib`).

    It is also the frame's scan source (:class:`fogsim.readers.base.ScanSource`) for ``fogsim fog --lidar``:
    ``key`` names the LiDAR frame (the sample key), ``kitti_id`` its id in a KITTI tree (KITTI's own;
    STF's a 6-digit number, as mmdetection3d's converter reads ids as integers), ``part`` the tree's part
    it belongs in (``training`` or ``testing``), ``return_mode`` the scan's (STF: the folder read),
    ``image_size`` image 2's (width, height) in pixels (None: unknown)."""

    scan: str
    calib: "str | KittiCalib"
    fmt: str = "kitti"
    key: str = ""
    kitti_id: str = ""
    return_mode: str | None = None
    part: str = "training"
    image_size: tuple[int, int] | None = None

    def calibration(self) -> KittiCalib:
        if isinstance(self.calib, KittiCalib):
            return self.calib
        return read_kitti_calib(self.calib, require_imu=self.fmt == "kitti")

    def cloud(self) -> PointCloud:
        """The scan as a :class:`PointCloud` (the LiDAR frame)."""
        return read_points(self.scan, self.fmt)

    # ------------------------------------------------------------------ the scan source
    def sensor(self, base: "LidarSensor | str | None" = None) -> LidarSensor:
        """``base`` (a name, a ``.json`` file or a sensor), default the format's usual sensor."""
        return load_sensor(base or SENSORS[self.fmt])

    def image_uv(self, cloud: PointCloud) -> np.ndarray:
        """Each point's pixel-edge coordinates in image 2 (N×2; NaN behind the camera)."""
        return self.calibration().project_velo(cloud.xyz)[0]

    def boxes(self, records: list[dict]) -> list[Box3D | None]:
        """The records' label boxes in the LiDAR frame (None for ignore regions)."""
        return label_boxes(records, self.calibration())

    def camera_view(self) -> CameraView | None:
        """Camera 2's view of the LiDAR's rays (its projection and image size), which a scan cropped to it
        (``velodyne_reduced``) covers: :func:`fogsim.lidar.rays.empty_rays` finds the empty rays inside it."""
        if self.image_size is None:
            return None
        return CameraView(self.calibration().projection(2), *self.image_size)

    def kitti_calib(self) -> KittiCalib:
        """The calibration a KITTI tree of this frame holds."""
        return self.calibration()

    def describe(self) -> dict:
        """What the frame record says of the input scan (``lidar.input``)."""
        return {"file": self.scan, "format": self.fmt, "calibration": self.calibration().source}

    def __call__(self) -> tuple[np.ndarray, np.ndarray]:
        uv, depth, ray = self.calibration().project_velo(self.cloud().xyz)
        front = depth > 0
        return uv[front], ray[front].astype(np.float32)


def read_split(path: str | os.PathLike, variant: str = "kitti") -> list[str]:
    """The frame ids of a split file (blank lines skipped; STF's ``date,frame`` → ``date_frame``)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise InputError(path, "split file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, f"not a readable split file ({exc})") from None
    ids = []
    for n, line in enumerate(lines, 1):
        item = line.strip()
        if not item:
            continue
        if variant == "stf" and "," in item:
            item = "_".join(p.strip() for p in item.split(","))
        if "/" in item or "\\" in item or item.startswith(".") or " " in item:
            raise InputError(path, f"line {n}: {line.strip()[:40]!r} is not a frame id")
        ids.append(item)
    if not ids:
        raise InputError(path, "split file lists no frames")
    return ids


def _missing(root: Path, frames: dict[str, dict[str, Path]]) -> None:
    """One InputError naming the first missing file, if any frame lacks one."""
    lacking = [(fid, what, p) for fid, files in frames.items() for what, p in files.items() if not p.is_file()]
    if lacking:
        fid, what, p = lacking[0]
        others = len({f for f, _, _ in lacking}) - 1
        more = f" ({others} more frame{'s' if others != 1 else ''} miss files)" if others else ""
        raise InputError(root, f"frame {fid}: no {what} {p.relative_to(root).as_posix()}: the image, scan, "
                               f"calibration and label sets do not match{more}")


def _size(image: Path) -> tuple[int, int]:
    size = png_size(image)
    if size is None:
        raise InputError(image, "not a PNG image (KITTI and STF images are PNG)")
    return size


def kitti_samples(root: str | os.PathLike, split: str | os.PathLike | None = None, labels: bool | None = None,
                  part: str = "training") -> list[Sample]:
    """The samples of a KITTI object tree (the module docstring). ``labels``: None → when ``label_2``
    exists; True requires it; False never reads it."""
    root = Path(root)
    base = root / part if (root / part / "image_2").is_dir() else root
    if not (base / "image_2").is_dir():
        raise InputError(root, f"not a KITTI object tree (expected {part}/image_2/ under it)")
    if labels is None:
        labels = (base / "label_2").is_dir()
    if split is None:
        ids = sorted(p.stem for p in (base / "image_2").glob("*.png"))
        if not ids:
            raise InputError(base / "image_2", "holds no .png images")
    elif isinstance(split, str) and split in KITTI_SPLITS:
        listing = root / "ImageSets" / f"{split}.txt"
        if not listing.is_file():
            raise InputError(root, f"no split list ImageSets/{split}.txt (give a split file instead)")
        ids = read_split(listing)
    else:
        ids = read_split(split)
    frames = {}
    for fid in ids:
        files = {"image": base / "image_2" / f"{fid}.png", "scan": base / "velodyne" / f"{fid}.bin",
                 "calibration": base / "calib" / f"{fid}.txt"}
        if labels:
            files["label file"] = base / "label_2" / f"{fid}.txt"
        frames[fid] = files
    _missing(root, frames)
    samples = []
    for fid, files in frames.items():
        w, h = _size(files["image"])
        calib = read_kitti_calib(files["calibration"])
        key = f"{base.name}/image_2/{fid}"
        points = KittiPoints(str(files["scan"]), str(files["calibration"]), "kitti", key, fid,
                             part=base.name if base.name in KITTI_PARTS else part, image_size=(w, h))
        meta = {"dataset": "kitti", "frame": fid, "part": base.name, "scan": str(files["scan"]),
                "calib": str(files["calibration"]), "lidar_points": points, "lidar_format": "kitti",
                "lidar_sensor": SENSORS["kitti"]}
        reader = KittiLabels(str(files["label file"]), str(files["calibration"]), w, h) if labels else None
        samples.append(Sample(key, str(files["image"]), ImageFile(str(files["image"])),
                              None, calib.intrinsics(w, h), meta, reader))
    return samples


def _stf_calibration(calib, root: Path) -> "KittiCalib | None":
    if calib is None:
        if (root / "calib").is_dir():
            return None  # per frame
        raise InputError(root, "Seeing Through Fog has no calibration in its download: pass calib= a KITTI-form "
                               "file (the repository's kitti_stereo_velodynehdl_calib.txt) or its "
                               "tools/DatasetViewer/calibs folder")
    calib = Path(calib)
    if calib.is_dir():
        return stf_calib_from_tf(calib)
    return read_kitti_calib(calib, require_imu=False)


def stf_samples(root: str | os.PathLike, split: str | os.PathLike | None = None, returns: str = "strongest",
                calib: str | os.PathLike | None = None, labels: bool | None = None) -> list[Sample]:
    """The samples of a Seeing Through Fog tree (the module docstring); ``returns``: ``strongest`` or
    ``last`` (which scan folder; ``meta["return_mode"]`` says it to the fog model)."""
    root = Path(root)
    if returns not in STF_RETURNS:
        raise ValueError(f"STF returns are {' or '.join(STF_RETURNS)}, not {returns!r}")
    images = root / "cam_stereo_left_lut"
    if not images.is_dir():
        raise InputError(root, "not a Seeing Through Fog tree (expected cam_stereo_left_lut/ under it)")
    label_dir = root / "gt_labels" / "cam_left_labels_TMP"
    if labels is None:
        labels = label_dir.is_dir()
    shared = _stf_calibration(calib, root)
    ids = sorted(p.stem for p in images.glob("*.png")) if split is None else read_split(split, "stf")
    if not ids:
        raise InputError(images, "holds no .png images")
    frames = {}
    for fid in ids:
        files = {"image": images / f"{fid}.png", "scan": root / f"lidar_hdl64_{returns}" / f"{fid}.bin"}
        if shared is None:
            files["calibration"] = root / "calib" / f"{fid}.txt"
        if labels:
            files["label file"] = label_dir / f"{fid}.txt"
        frames[fid] = files
    _missing(root, frames)
    samples = []
    for n, (fid, files) in enumerate(frames.items()):
        w, h = _size(files["image"])
        cal = shared if shared is not None else read_kitti_calib(files["calibration"], require_imu=False)
        cal_ref = shared if shared is not None else str(files["calibration"])
        key = f"cam_stereo_left_lut/{fid}"
        points = KittiPoints(str(files["scan"]), cal_ref, "stf", key, f"{n:06d}", returns, image_size=(w, h))
        meta = {"dataset": "stf", "frame": fid, "scan": str(files["scan"]), "calib": cal.source,
                "lidar_points": points, "lidar_format": "stf", "lidar_sensor": SENSORS["stf"],
                "return_mode": returns}
        reader = KittiLabels(str(files["label file"]), cal_ref, w, h, "stf") if labels else None
        samples.append(Sample(key, str(files["image"]), ImageFile(str(files["image"])),
                              None, cal.intrinsics(w, h), meta, reader))
    return samples
