"""The BEV dataset of one study variant: each fog level's rasters, oriented-box labels and ground truth.

A *variant* is what the detectors of one table see: ``lidar`` (the dataset's own fogged scans),
``lidar+radar`` (the same plus the level's radar detections) or ``lidar@<model>`` (the clear scans fogged
again by the LiDAR fog model ``<model>`` through the LiDAR fog spec — what ``fogsim fog --lidar-model`` and
a render's ``lidar_fog.model`` set — at the dataset's levels, with the range noise seeded by
:func:`fogsim.runs.level_seed` of the study's seed, the KITTI id and the level).

Layout under the variant's data folder (:class:`BevLayout`)::

    build.json                 the parameters (a rerun with others is refused)
    images/<level>/<id>.png    LiDAR rasters: height, intensity, density as R, G, B
    images/<level>/<id>.tiff   LiDAR + radar rasters: five single-channel pages (height, intensity,
                               density, rcs, radial_velocity) — Ultralytics reads the pages as channels
    labels/<level>/<id>.txt    Ultralytics OBB lines (the same at every level: the objects do not move)
    gt/<id>.json               the frame's ground truth (:class:`fogsim.schema.bev.BevFrameTruth`), written
                               last: it marks the frame done, so an interrupted build resumes

Training labels are the scored classes' objects whose centre lies in the grid (neighbouring classes are
not trained on, as in KITTI practice); the ground truth keeps every object of the study's classes with its
footprint, its LiDAR points per level (in the field of view) and whether it is scored.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from fogsim.detection.bev.boxes import footprint, obb_line
from fogsim.detection.bev.grid import LIDAR_CHANNELS, RADAR_CHANNELS, BevGrid, lidar_raster, radar_raster
from fogsim.detection.bev.source import BEV_CLASSES, LidarLevels, bev_range
from fogsim.errors import InputError
from fogsim.fog.engine import FogSettings
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.documents import write_json
from fogsim.io.images import encode_image
from fogsim.lidar.boxes import points_in_boxes
from fogsim.lidar.fog import lidar_fog_spec
from fogsim.lidar.rays import empty_rays
from fogsim.runs import claim_output, level_seed

LIDAR, FUSED = "lidar", "lidar+radar"


@dataclass(frozen=True)
class Variant:
    """What one table's detectors see (the module docstring): ``radar`` adds the radar channels,
    ``fog_model`` fogs the clear scans again with that LiDAR fog model."""

    radar: bool = False
    fog_model: str | None = None

    @property
    def name(self) -> str:
        return FUSED if self.radar else LIDAR if self.fog_model is None else f"{LIDAR}@{self.fog_model}"

    @property
    def folder(self) -> str:
        return self.name.replace("+", "_").replace("@", "_fog_")

    @property
    def channels(self) -> tuple[str, ...]:
        return LIDAR_CHANNELS + (RADAR_CHANNELS if self.radar else ())

    @property
    def suffix(self) -> str:
        return ".png" if len(self.channels) == 3 else ".tiff"


class BevLayout:
    """Paths of a variant's BEV dataset under ``root`` (the module docstring)."""

    def __init__(self, root: str | Path, variant: Variant):
        self.root, self.variant = Path(root), variant

    def build_file(self) -> Path:
        return self.root / "build.json"

    def images_dir(self, level: str) -> Path:
        return self.root / "images" / level

    def labels_dir(self, level: str) -> Path:
        return self.root / "labels" / level

    def image(self, level: str, kitti_id: str) -> Path:
        return self.images_dir(level) / f"{kitti_id}{self.variant.suffix}"

    def label(self, level: str, kitti_id: str) -> Path:
        return self.labels_dir(level) / f"{kitti_id}.txt"

    def truth(self, kitti_id: str) -> Path:
        return self.root / "gt" / f"{kitti_id}.json"


def encode_raster(raster: np.ndarray) -> bytes:
    """PNG (three channels as R, G, B) or a TIFF of one page per channel."""
    if raster.shape[2] == 3:
        return encode_image(raster, ".png")
    import cv2

    ok, buf = cv2.imencodemulti(".tiff", [np.ascontiguousarray(raster[..., c]) for c in range(raster.shape[2])])
    if not ok:
        raise RuntimeError("OpenCV could not encode a TIFF")
    return buf.tobytes()


def decode_raster(path: str | Path) -> np.ndarray:
    """The channels of a raster file, in the order written (H × W × C uint8)."""
    import cv2

    from fogsim.io.images import read_image

    path = Path(path)
    if path.suffix == ".png":
        return read_image(path)
    ok, pages = cv2.imreadmulti(str(path), flags=cv2.IMREAD_UNCHANGED)
    if not ok or not pages:
        raise InputError(path, "unreadable BEV raster (TIFF)")
    return np.stack(pages, axis=2)


class Refogger:
    """One frame's clear scan fogged again by a LiDAR fog model at any level (the module docstring)."""

    def __init__(self, source: LidarLevels, kitti_id: str, model: str, seed: int):
        clear = source.clear
        if clear is None:
            raise InputError(source.layout.manifest(), "--fog-models fogs the clear scans again: the dataset has "
                                                       "no clear level (β = 0)")
        self.cloud = source.scan(clear, kitti_id)
        sensor = source.lidar_sensor(kitti_id)
        settings = FogSettings(lidar=lidar_fog_spec({"model": model}))
        self.fogger = settings.lidar_fogger(self.cloud, sensor, empty_rays(self.cloud, sensor))
        self.source, self.kitti_id, self.seed = source, kitti_id, seed

    def __call__(self, level: str):
        beta = self.source.betas[level]
        return self.fogger(beta, np.random.default_rng(level_seed(self.seed, self.kitti_id, level))).cloud


def build_variant(source: LidarLevels, layout: BevLayout, grid: BevGrid, seed: int = 0,
                  progress: bool = True) -> None:
    """Write (or complete) the variant's BEV dataset (the module docstring)."""
    variant = layout.variant
    if variant.radar and not source.has_radar:
        raise InputError(source.root / "radar", "--sensor lidar+radar needs each level's radar detections "
                                                "(a render with --radar); this dataset has none")
    params = {"dataset": str(source.root), "variant": variant.name, "channels": list(variant.channels),
              "grid": grid.to_dict(), "levels": source.levels, "split": source.split}
    if variant.fog_model is not None:
        params["refog"] = {"model": variant.fog_model, "seed": seed}
    claim_output(layout.build_file(), params, what="BEV dataset")
    frames = [(i, part) for part in ("train", "val") for i in source.split[part]]
    todo = [(i, part) for i, part in frames if not layout.truth(i).is_file()]
    for kitti_id, part in tqdm(todo, desc=f"BEV {variant.name}", unit="frame", disable=not progress or not todo):
        write_frame(source, layout, grid, kitti_id, part, seed)


def write_frame(source: LidarLevels, layout: BevLayout, grid: BevGrid, kitti_id: str, part: str,
                seed: int = 0) -> None:
    """One frame's rasters and labels at every level, then its ground truth."""
    variant = layout.variant
    labels = source.labels(kitti_id)
    objects = [o for o in labels.objects if grid.inside(o.box.centre[None, :2])[0]]
    corners = [footprint(o.box) for o in objects]
    lines = [obb_line(BEV_CLASSES.index(o.cls), c, grid) for o, c in zip(objects, corners) if o.scored]
    label_text = "".join(line + "\n" for line in lines).encode()
    refog = Refogger(source, kitti_id, variant.fog_model, seed) if variant.fog_model else None
    points = {}
    for lv in source.levels:
        cloud = refog(lv) if refog is not None else source.scan(lv, kitti_id)
        view = source.in_view(cloud.xyz, labels)
        xyz, intensity = cloud.xyz[view], cloud.intensity[view]
        raster = lidar_raster(grid, xyz, intensity)
        if variant.radar:
            det = source.radar(lv, kitti_id)
            det = det.select(source.in_view(det.xyz, labels))
            raster = np.concatenate([raster, radar_raster(grid, det.xyz, det.rcs_dbsm, det.radial_velocity)], 2)
        points[lv] = points_in_boxes(xyz, [o.box for o in objects]) if objects else np.zeros(0, np.int64)
        atomic_write_bytes(layout.label(lv, kitti_id), label_text)
        atomic_write_bytes(layout.image(lv, kitti_id), encode_raster(raster))
    truth = {"id": kitti_id, "frame": source.frame(kitti_id), "split": part,
             "objects": [{"class": o.cls, "scored": o.scored, "difficulty": o.difficulty, "kitti_type": o.kitti_type,
                          "corners_m": np.round(c, 4).tolist(), "distance_m": round(bev_range(o.box), 3),
                          "points": {lv: int(points[lv][k]) for lv in source.levels}}
                         for k, (o, c) in enumerate(zip(objects, corners))],
             "dontcare": [[round(v, 2) for v in box] for box in labels.dontcare], "ground_z": round(labels.ground_z, 4),
             "projection": np.round(labels.calib.projection(2), 9).tolist(), "image_size": list(labels.image_size)}
    write_json(layout.truth(kitti_id), truth)
