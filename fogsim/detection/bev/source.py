"""A fogsim dataset's LiDAR (and radar) levels, read for the bird's-eye-view study.

The input is what ``fogsim render --lidar`` and ``fogsim fog --kitti/--stf --lidar`` both write: each
fog level as a KITTI object tree, ``kitti/<level>/training/{image_2,velodyne,calib,label_2}`` with
``kitti/<level>/ImageSets/{train,val}.txt`` (:mod:`fogsim.dataset.kitti`), the levels and their β in
``dataset.json``; ``kitti/frame_ids.json`` maps KITTI ids to the dataset's frame names where they differ
(fogged real data). A render with ``--radar`` adds ``radar/<level>/<frame>.pcd`` (nuScenes radar, the
radar's frame) and the poses in ``meta/<frame>.json`` (``radar.radar_to_world``, ``lidar.lidar_to_world``)
that put the detections in the LiDAR's frame.

Labels (:func:`frame_labels`) follow KITTI's object benchmark: the classes ``Car``, ``Pedestrian``,
``Cyclist`` are scored; ``Van`` (for cars) and ``Person_sitting`` (for pedestrians) are *neighbouring*
classes — ignored, neither found nor missed — as in KITTI's evaluation; ``DontCare`` rows are image
regions (:mod:`fogsim.detection.bev.evaluate` says how a BEV detection falls in one); every other type is
not an object of the study (a detection on it is a false alarm, as in KITTI). Seeing Through Fog's types
map the same way (PassengerCar → car, RidableVehicle → cyclist; Vehicle is a neighbouring car class).
KITTI's difficulty (1 easy, 2 moderate, 3 hard, 0 none) is kept per object.

Only what the camera sees is labelled (KITTI's labels stop at image 2's edges), so the scans and radar
detections are cut to the camera's field of view (:meth:`LidarLevels.in_view`): a detector is never
trained on, nor charged for, objects nobody labelled.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from fogsim.dataset.kitti import KittiTree
from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.lidar import KITTI_IDS
from fogsim.dataset.reader import dataset_levels
from fogsim.errors import InputError
from fogsim.io.documents import read_json, read_text_file
from fogsim.io.headers import image_header
from fogsim.lidar.boxes import Box3D
from fogsim.lidar.formats import read_points
from fogsim.lidar.points import PointCloud
from fogsim.lidar.sensors import LidarSensor, load_sensor, sensor_names
from fogsim.radar.detections import RadarScan
from fogsim.radar.formats import read_radar
from fogsim.readers.kitti.boxes import label_box
from fogsim.readers.kitti.calib import KittiCalib, read_kitti_calib
from fogsim.readers.kitti.labels import KITTI_CLASSES, label_records

#: the study's classes (YOLO id = index)
BEV_CLASSES = ("car", "pedestrian", "cyclist")
#: label type → (class, scored): scored False is a neighbouring class, ignored in that class's score
TYPES = {"Car": ("car", True), "Van": ("car", False), "Pedestrian": ("pedestrian", True),
         "Person_sitting": ("pedestrian", False), "Cyclist": ("cyclist", True),
         "PassengerCar": ("car", True), "Vehicle": ("car", False), "RidableVehicle": ("cyclist", True)}
DONT_CARE = "DontCare"
#: KITTI's LiDAR is 1.73 m above the road: the ground of a frame without labelled objects
DEFAULT_GROUND_Z = -1.73


@dataclass(frozen=True)
class BevObject:
    """One labelled object: ``cls`` (a :data:`BEV_CLASSES` name), ``box`` (LiDAR frame), ``scored``
    (False: a neighbouring class, ignored), KITTI's ``difficulty`` and the label's ``kitti_type``."""

    cls: str
    box: Box3D
    scored: bool
    difficulty: int
    kitti_type: str


@dataclass(frozen=True)
class FrameLabels:
    """A frame's objects, its DontCare regions (image-2 boxes, pixel edges: left, top, right, bottom),
    the ground's height in the LiDAR frame (the median bottom of its boxes, else KITTI's) and the
    calibration."""

    objects: list[BevObject]
    dontcare: list[list[float]]
    ground_z: float
    calib: KittiCalib
    image_size: tuple[int, int]


class LidarLevels:
    """The LiDAR levels of the fogsim dataset at ``root`` (the module docstring)."""

    def __init__(self, root: str | Path):
        self.root = Path(root).resolve()
        self.layout = DatasetLayout(self.root)
        self.levels = dataset_levels(self.layout)
        manifest = read_json(self.layout.manifest())
        self.betas = {lv["key"]: float(lv.get("beta") or 0.0) for lv in manifest["levels"]}
        self.is_render = isinstance(manifest.get("preset"), dict)
        self.trees = {lv: KittiTree(self.root, lv) for lv in self.levels}
        for lv, tree in self.trees.items():
            if not (tree.base / "velodyne").is_dir():
                raise InputError(tree.base, f"no KITTI tree of fog level {lv!r}: the dataset has no LiDAR levels "
                                            "(render with --lidar, or fogsim fog --kitti/--stf … --lidar)")
        ids = self.root / "kitti" / KITTI_IDS
        self.frame_of = read_json(ids) if ids.is_file() else {}
        if not isinstance(self.frame_of, dict):
            raise InputError(ids, "must map KITTI ids to frame names (a JSON object)")
        self.split = {part: self._image_set(part) for part in ("train", "val")}
        if not self.split["val"]:
            raise InputError(self.trees[self.levels[0]].root / "ImageSets" / "val.txt",
                             "no validation frames: the study scores every model on them")

    def _image_set(self, part: str) -> list[str]:
        """The ids of ``ImageSets/<part>.txt``, the same in every level's tree (else an error naming it)."""
        found = None
        for lv, tree in self.trees.items():
            path = tree.root / "ImageSets" / f"{part}.txt"
            if not path.is_file():
                raise InputError(path, f"missing: the KITTI tree's {part} split")
            ids = [line.strip() for line in read_text_file(path, "image set").splitlines() if line.strip()]
            if found is not None and ids != found:
                raise InputError(path, f"lists other {part} frames than level {self.levels[0]!r}'s")
            found = ids
        return found or []

    @property
    def clear(self) -> str | None:
        """The clear level's key (β = 0), None when the dataset has none."""
        return next((lv for lv in self.levels if self.betas[lv] == 0), None)

    def frame(self, kitti_id: str) -> str:
        """The dataset's frame name of a KITTI id."""
        return str(self.frame_of.get(kitti_id, kitti_id))

    # ------------------------------------------------------------------ per frame
    def calib(self, kitti_id: str) -> KittiCalib:
        return read_kitti_calib(self.trees[self.levels[0]].path("calib", kitti_id), require_imu=False)

    def image_size(self, kitti_id: str) -> tuple[int, int]:
        path = self.trees[self.levels[0]].path("image_2", kitti_id)
        try:
            with open(path, "rb") as f:
                header = image_header(f.read(1 << 16))
        except OSError as exc:
            raise InputError(path, f"cannot read the image ({exc.strerror or exc})") from None
        if header is None:
            raise InputError(path, "not an image fogsim reads (PNG, JPEG, …)")
        return header.width, header.height

    def labels(self, kitti_id: str) -> FrameLabels:
        """The frame's labels in the LiDAR frame (the module docstring)."""
        path = self.trees[self.levels[0]].path("label_2", kitti_id)
        if not path.is_file():
            raise InputError(path, "missing label file: the study needs labelled frames (KITTI's training part)")
        text = read_text_file(path, "label file")
        types = {line.split()[0] for line in text.splitlines() if line.strip()}
        variant = "kitti" if types <= set(KITTI_CLASSES) | {DONT_CARE} else "stf"
        calib, size = self.calib(kitti_id), self.image_size(kitti_id)
        _, records = label_records(text, str(path), size[0], size[1], calib, variant)
        objects, dontcare, seen = [], [], set()
        for rec in records:
            if rec.get("reason") in ("DontCare region",) or (not rec["kept"] and rec.get("reason") != "group"):
                if rec["line"] not in seen:  # one region per label line (the records are per class)
                    seen.add(rec["line"])
                    dontcare.append([float(v) for v in rec["bbox"]])
                continue
            kind = rec["kitti_type"].removesuffix("_is_group")
            if kind not in TYPES:
                continue
            cls, scored = TYPES[kind]
            objects.append(BevObject(cls, label_box(rec, calib), scored and rec["kept"], int(rec.get("difficulty", 0)),
                                     rec["kitti_type"]))
        bottoms = [float(o.box.centre[2] - o.box.half[2]) for o in objects]
        ground = float(np.median(bottoms)) if bottoms else DEFAULT_GROUND_Z
        return FrameLabels(objects, dontcare, ground, calib, size)

    def scan(self, level: str, kitti_id: str) -> PointCloud:
        """The level's scan (KITTI's 4 × float32, LiDAR frame)."""
        return read_points(self.trees[level].path("velodyne", kitti_id), "kitti")

    def in_view(self, xyz: np.ndarray, labels: FrameLabels) -> np.ndarray:
        """Which points (N×3, LiDAR frame) project into image 2 in front of the camera."""
        uv, depth, _ = labels.calib.project_velo(xyz)
        w, h = labels.image_size
        with np.errstate(invalid="ignore"):
            return (depth > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)

    def meta(self, kitti_id: str) -> dict:
        path = self.layout.meta(self.frame(kitti_id))
        if not path.is_file():
            raise InputError(path, "missing frame record (the KITTI tree's frame has none)")
        return read_json(path)

    def lidar_sensor(self, kitti_id: str) -> LidarSensor:
        """The sensor that made the frame's scans: a render's ``lidar.sensor_spec`` (its preset block), else
        the bundled sensor its record ``lidar.sensor`` names, in the recorded return mode."""
        lidar = self.meta(kitti_id).get("lidar") or {}
        if lidar.get("sensor_spec"):
            return load_sensor(lidar["sensor_spec"])
        record = lidar.get("sensor")
        name = record.get("name") if isinstance(record, dict) else record
        if name not in sensor_names():
            raise InputError(self.layout.meta(self.frame(kitti_id)), f"the frame's LiDAR sensor {name!r} is not a "
                             "bundled one and its block is not recorded: its scans cannot be fogged again")
        sensor = load_sensor(name)
        mode = record.get("return_mode") if isinstance(record, dict) else None
        return replace(sensor, return_mode=mode) if mode and mode != sensor.return_mode else sensor

    @cached_property
    def has_radar(self) -> bool:
        return all((self.root / "radar" / lv).is_dir() for lv in self.levels)

    def radar(self, level: str, kitti_id: str) -> RadarDetections:
        """The level's radar detections in the LiDAR frame (a render with ``--radar``)."""
        frame = self.frame(kitti_id)
        meta = self.meta(kitti_id)
        try:
            radar_pose = np.asarray(meta["radar"]["radar_to_world"], np.float64).reshape(4, 4)
            lidar_pose = np.asarray(meta["lidar"]["lidar_to_world"], np.float64).reshape(4, 4)
        except (KeyError, TypeError, ValueError):
            raise InputError(self.layout.meta(frame), "no radar.radar_to_world and lidar.lidar_to_world 4×4 "
                                                      "poses: the radar cannot be put in the LiDAR's frame") from None
        if not (np.isfinite(radar_pose).all() and np.isfinite(lidar_pose).all()):
            raise InputError(self.layout.meta(frame), "non-finite sensor pose")
        scan = read_radar(self.layout.radar(level, frame), "nuscenes-radar")
        return RadarDetections.in_lidar_frame(scan, np.linalg.inv(lidar_pose) @ radar_pose)


@dataclass(frozen=True)
class RadarDetections:
    """Radar detections for the grid: positions in the LiDAR frame (N×3, m), RCS (dBsm) and the
    ego-compensated radial velocity (m/s, + receding) along the radar's own rays."""

    xyz: np.ndarray
    rcs_dbsm: np.ndarray
    radial_velocity: np.ndarray

    @classmethod
    def in_lidar_frame(cls, scan: RadarScan, radar_to_lidar: np.ndarray) -> "RadarDetections":
        """The sweep's detections moved by the 4×4 ``radar_to_lidar`` (velocities stay radial to the radar)."""
        xyz = scan.xyz.astype(np.float64) @ radar_to_lidar[:3, :3].T + radar_to_lidar[:3, 3]
        return cls(xyz, scan.rcs_dbsm.astype(np.float64), scan.radial_velocity_comp)

    def select(self, which) -> "RadarDetections":
        return RadarDetections(self.xyz[which], self.rcs_dbsm[which], self.radial_velocity[which])


def bev_range(box: Box3D) -> float:
    """The ground distance (m) from the LiDAR to the box's centre."""
    return float(math.hypot(box.centre[0], box.centre[1]))
