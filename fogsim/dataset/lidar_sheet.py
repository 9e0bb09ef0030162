"""The contact sheet's LiDAR rows: for a frame whose record has a LiDAR (``meta["lidar"]``), one row with
each level's reported points projected on that level's image and one with each level's bird's-eye view,
points coloured by outcome (:mod:`fogsim.lidar.pictures`; its :data:`~fogsim.lidar.pictures.BEV_LEGEND` is the
sheet's LiDAR legend, :data:`LEGEND`), read back from the frame's files."""
from __future__ import annotations

import cv2
import numpy as np

from fogsim.camera import Intrinsics
from fogsim.colour import to_uint8
from fogsim.dataset.layout import DatasetLayout
from fogsim.io.images import read_image
from fogsim.lidar.fogged_scan import FoggedScan
from fogsim.lidar.formats import read_points
from fogsim.lidar.outcome_file import read_outcomes
from fogsim.lidar.pictures import BEV_LEGEND, bev_image, projected_image
from fogsim.lidar.points import PointCloud
from fogsim.viz import strip

#: the contact sheet's legend of its LiDAR rows
LEGEND = BEV_LEGEND


def read_level(layout: DatasetLayout, meta: dict, key: str) -> FoggedScan:
    """A level's fogged scan of a frame, from its scan file and outcome file (as ``meta["lidar"]`` names them)."""
    lv = meta["lidar"]["levels"][key]
    cloud = read_points(layout.root / lv["file"], meta["lidar"]["format"])
    outcome, index = read_outcomes(layout.root / lv["outcome_file"])
    return FoggedScan(cloud, outcome, index)


def read_sweep(layout: DatasetLayout, meta: dict) -> PointCloud:
    """A frame's clear sweep (``meta["lidar"]["input"]``), the scan every level's outcomes refer to."""
    sweep = meta["lidar"]["input"]
    return read_points(layout.root / sweep["file"], sweep["format"])


def lidar_rows(layout: DatasetLayout, meta: dict, levels, tile_width: int) -> list[np.ndarray]:
    """The two rows of one frame (points on the images; bird's-eye views), or [] without a LiDAR."""
    if "lidar_to_camera" not in (meta.get("lidar") or {}):  # a render's LiDAR (a real dataset's: its own pictures)
        return []
    K = Intrinsics.from_dict(meta["camera"]["intrinsics"])
    l2c = np.asarray(meta["lidar"]["lidar_to_camera"], np.float64)
    fogged = {lv.key: read_level(layout, meta, lv.key) for lv in levels if lv.key in meta["lidar"]["levels"]}
    clear = read_sweep(layout, meta)
    projected, bev, captions = [], [], []
    for key, f in fogged.items():
        img = to_uint8(read_image(layout.image(key, meta["frame"])))
        projected.append(projected_image(img, f, K, l2c))
        side = round(tile_width * 2 / 3)  # as tall as an image tile, drawn at that size (its labels readable)
        bev.append(bev_image(clear, f, extent_m=40.0, px_per_m=side / 80.0))
        c, n = f.counts(), max(1, len(f.outcome))
        captions.append(f"LiDAR {key}: lost {100 * c['lost'] / n:.0f}%, clutter {100 * c['clutter'] / n:.0f}%")
    tiles = [cv2.resize(p, (tile_width, round(p.shape[0] * tile_width / p.shape[1])), interpolation=cv2.INTER_NEAREST)
             for p in projected]
    return [strip(tiles, captions), strip(bev, [f"LiDAR top view {k}" for k in fogged])]
