"""The on-disk dataset format, one owner: every path under a dataset root and its reserved names.

Layout under the root::

    images/<level>/<frame>.png   fogged RGB per fog level
    labels/<level>/<frame>.txt   YOLO lines, identical across levels (empty = background)
    visible/labels/<level>/<frame>.txt   YOLO lines of the objects still visible at that level (finalize;
                                 fogsim.dataset.visible), visible/images/<level>/<frame>.png hard links to the images
    depth/<frame>.exr            planar depth, metres        masks/<frame>.png  uint16 ids
    meta/<frame>.json            the frame record, written last: its presence marks the frame done
    linear/<level>/<frame>.exr   scene-linear RGB renders (volumetric fog, ``keep_linear``; R, G, B float)
    cityscapes/<kind>/<split>/fogsim/<frame>_<kind>.{png,json}   the stereo pair (``--stereo``)
    lidar/<level>/<frame>.<ext>  the level's LiDAR scan (``fogsim fog --lidar``: the source's point format)
    lidar/<level>/<frame>.outcomes.npz   every input point's outcome and row (fogsim.lidar.outcome_file)
    lidar/<level>/<frame>.pcd    the level's scan for viewers (fogsim.lidar.scan_pcd)
    lidar/<level>/<frame>.label, lidar/sweep/<frame>.{bin,npz}   a render's point labels and clear sweep
    radar/<level>/<frame>.pcd    a render's radar detections (nuScenes radar PCD), beside them .npz labels and
                                 .outcomes.npz; radar/sweep/<frame>.{pcd,npz} the clear sweep
    kitti/<level>/…              each level as a KITTI object tree (fogsim.dataset.kitti)
    semantic_kitti/<level>/…     a render's levels as SemanticKITTI sequences (fogsim.dataset.semantic_kitti)
    coco/<level>.json            COCO detection annotations (objects the filters dropped: iscrowd = 1)
    splits/<level>_{train,val}.txt, splits/all_{train,val}.txt   image lists (absolute paths)
    data/<level>.yaml, data/all.yaml                              Ultralytics data files
    splits/<level>.visible_{train,val}.txt, data/<level>.visible.yaml (and all.visible)   the visible-only sets
    dataset.json                 manifest, counts, levels;       contact_sheet.png
    cross_sensor.md, lidar_bev.png, lidar_points_vs_distance.png, radar_bev.png   what fog does to each object,
                                 per sensor

Two names mean "every fog level at once", one per side, and both are part of the format:

* :data:`MIXED_SPLIT` = ``"all"``: the dataset's split lists and data file over every level
  (``splits/all_*.txt``, ``data/all.yaml``); no fog level may use this key.
* :data:`MIXED_MODEL` = ``"mixed"``: the detector a study trains on every level
  (``runs/mixed``, ``predictions/mixed`` under the study folder, the ``mixed`` report row).

Frame names of fogged real samples: :func:`frame_from_key` (``/`` → ``__``).

Writing is :mod:`fogsim.dataset.writer`'s, reading :mod:`fogsim.dataset.reader`'s; both take
their paths from :class:`DatasetLayout`.
"""
from __future__ import annotations

from pathlib import Path

from fogsim.errors import InputError

MIXED_SPLIT = "all"     # split lists and data file mixing every level (a dataset path)
MIXED_MODEL = "mixed"   # the detector trained on every level at once (a study name, not a dataset path)
VISIBLE = "visible"     # the visible-only label sets: visible/{images,labels}/<level>/, data/<level>.visible.yaml
PARTS = ("train", "val")


#: how a sample key (a relative POSIX path, e.g. Waymo ``ctx/ts_CAM``) becomes a flat frame name
FRAME_SEPARATOR = "__"


def visible_set(level_key: str) -> str:
    """The name of a level's visible-only set in ``splits/`` and ``data/`` (``beta0.12`` → ``beta0.12.visible``)."""
    return f"{level_key}.{VISIBLE}"


def frame_from_key(key: str) -> str:
    """The frame name of a fogged sample in the dataset layout: its key with every ``/`` replaced
    by ``__`` (Waymo ``ctx/ts_CAM`` → ``ctx__ts_CAM``; Cityscapes
    ``leftImg8bit/val/frankfurt/frankfurt_000000_000294_leftImg8bit`` →
    ``leftImg8bit__val__frankfurt__frankfurt_000000_000294_leftImg8bit``). Frame names are flat
    because split lists are read back by file stem (:func:`fogsim.dataset.reader.read_split`).
    Two keys that map to one name (``a/b`` and ``a__b``) are refused by :func:`frames_from_keys`."""
    if not key or key.startswith("/") or any(p in ("", ".", "..") for p in key.split("/")):
        raise ValueError(f"sample key {key!r} is not a relative path")
    return key.replace("/", FRAME_SEPARATOR)


def frames_from_keys(keys, sources=None) -> list[str]:
    """:func:`frame_from_key` of every key; raises :class:`InputError` naming both samples when
    two keys give one frame name (``sources``: what to name, default the keys)."""
    sources = list(keys) if sources is None else list(sources)
    frames, seen = [], {}
    for key, source in zip(keys, sources):
        frame = frame_from_key(key)
        if frame in seen:
            raise InputError(source, f"its frame name {frame!r} is also that of {seen[frame]} "
                                     f"('/' becomes {FRAME_SEPARATOR!r}): their outputs would overwrite each other")
        seen[frame] = source
        frames.append(frame)
    return frames


class DatasetLayout:
    """Paths of one dataset under ``root``."""

    def __init__(self, root: str | Path):
        self.root = Path(root)

    # --- per frame
    def images_dir(self, level_key: str) -> Path:
        return self.root / "images" / level_key

    def labels_dir(self, level_key: str) -> Path:
        return self.root / "labels" / level_key

    def image(self, level_key: str, frame: str) -> Path:
        return self.images_dir(level_key) / f"{frame}.png"

    def label(self, level_key: str, frame: str) -> Path:
        return self.labels_dir(level_key) / f"{frame}.txt"

    def visible_image(self, level_key: str, frame: str) -> Path:
        """The level's image under the visible-only set (a hard link: Ultralytics finds a label by its image's path)."""
        return self.root / VISIBLE / "images" / level_key / f"{frame}.png"

    def visible_label(self, level_key: str, frame: str) -> Path:
        """YOLO lines of the objects visible at that level (:mod:`fogsim.dataset.visible`)."""
        return self.root / VISIBLE / "labels" / level_key / f"{frame}.txt"

    def depth(self, frame: str) -> Path:
        return self.root / "depth" / f"{frame}.exr"

    def mask(self, frame: str) -> Path:
        return self.root / "masks" / f"{frame}.png"

    def linear(self, level_key: str, frame: str) -> Path:
        """Scene-linear float RGB render of one level (volumetric fog with ``keep_linear``; clear too)."""
        return self.root / "linear" / level_key / f"{frame}.exr"

    def meta_dir(self) -> Path:
        return self.root / "meta"

    def meta(self, frame: str) -> Path:
        return self.meta_dir() / f"{frame}.json"

    def cityscapes_root(self) -> Path:
        """The root of the stereo pairs' Cityscapes tree (what Cityscapes' loaders take)."""
        return self.root / "cityscapes"

    def cityscapes(self, kind: str, frame: str, split: str) -> Path:
        """The stereo pair in Cityscapes' tree (city "fogsim"), so its loader reads it:
        ``kind`` = leftImg8bit | rightImg8bit | disparity (.png) | camera (.json)."""
        ext = "json" if kind == "camera" else "png"
        return self.cityscapes_root() / kind / split / "fogsim" / f"{frame}_{kind}.{ext}"

    def lidar(self, level_key: str, frame: str, suffix: str = ".bin") -> Path:
        """One level's LiDAR scan of a frame (``suffix``: its format's, :data:`fogsim.lidar.formats.FORMAT_SUFFIX`)."""
        return self.root / "lidar" / level_key / f"{frame}{suffix}"

    def lidar_outcomes(self, level_key: str, frame: str) -> Path:
        """The outcomes beside a level's scan (:mod:`fogsim.lidar.outcome_file`)."""
        return self.root / "lidar" / level_key / f"{frame}.outcomes.npz"

    def lidar_labels(self, level_key: str, frame: str) -> Path:
        """A rendered level's per-point labels beside its scan (SemanticKITTI ``.label``, uint32 per point)."""
        return self.root / "lidar" / level_key / f"{frame}.label"

    def lidar_sweep(self, frame: str, suffix: str = ".bin") -> Path:
        """A render's clear sweep (the scan every level's outcomes refer to); ``.npz``: what each point hit."""
        return self.root / "lidar" / "sweep" / f"{frame}{suffix}"

    def radar(self, level_key: str, frame: str, suffix: str = ".pcd") -> Path:
        """One level's radar detections of a frame (``.pcd``), their labels (``.npz``) or outcomes
        (``.outcomes.npz``)."""
        return self.root / "radar" / level_key / f"{frame}{suffix}"

    def radar_sweep(self, frame: str, suffix: str = ".pcd") -> Path:
        """A render's clear radar sweep (what every level's outcomes refer to); ``.npz``: its labels."""
        return self.root / "radar" / "sweep" / f"{frame}{suffix}"

    # --- per dataset (written by finalize)
    def split_file(self, level_key: str, part: str) -> Path:
        """The image list of one split: ``splits/<level>_<part>.txt`` (level may be MIXED_SPLIT)."""
        return self.root / "splits" / f"{level_key}_{part}.txt"

    def coco(self, level_key: str) -> Path:
        return self.root / "coco" / f"{level_key}.json"

    def data_yaml(self, level_key: str) -> Path:
        """Ultralytics data file of one level (or of MIXED_SPLIT, or a :func:`visible_set` name)."""
        return self.root / "data" / f"{level_key}.yaml"

    def manifest(self) -> Path:
        return self.root / "dataset.json"

    def contact_sheet(self) -> Path:
        return self.root / "contact_sheet.png"

    def cross_sensor_report(self) -> Path:
        """The cross-sensor table and the LiDAR outcomes as Markdown."""
        return self.root / "cross_sensor.md"

    def lidar_bev(self) -> Path:
        """A bird's-eye view of one frame's scan per level, points coloured by outcome."""
        return self.root / "lidar_bev.png"

    def radar_bev(self) -> Path:
        """A bird's-eye view of one frame's radar detections per level over its LiDAR points."""
        return self.root / "radar_bev.png"

    def lidar_points_plot(self) -> Path:
        """Points per object against distance, per level."""
        return self.root / "lidar_points_vs_distance.png"

    def relative(self, path: Path) -> str:
        """``path`` relative to the root, with forward slashes (as COCO and the data files hold it)."""
        return Path(path).relative_to(self.root).as_posix()

    # --- state
    def frame_done(self, frame: str) -> bool:
        return self.meta(frame).is_file()

    def done_frames(self) -> list[str]:
        """Names of the committed frames (those with a meta file), sorted."""
        return sorted(p.stem for p in self.meta_dir().glob("*.json"))
