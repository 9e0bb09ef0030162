"""The LiDAR side of ``fogsim fog --lidar``: each fog level of a sample's scan, fogged by the run's fog
record, written beside the camera's level, and counted in each object's 3D box.

Per sample with a scan source (:class:`fogsim.readers.base.ScanSource`, ``Sample.meta["lidar_points"]``)
and per level (β in 1/m, the camera level's β):

* the fogger is the run's (:meth:`fogsim.fog.engine.FogSettings.lidar_fogger`: its ``lidar_fog`` spec,
  its calibration included), with the scan's empty rays when the sensor's grid is known
  (:func:`fogsim.lidar.rays.empty_rays`: each level's record then counts ``empty_rays`` and
  ``empty_ray_clutter``, the fog-clutter points appended after the input's; a scan cropped to the camera,
  KITTI's and STF's, gets the empty rays inside the camera's view, :meth:`ScanSource.camera_view`),
  the sensor the run's ``--lidar-sensor`` or the source's usual one (completed from the data; a source
  that says its return mode — STF's ``lidar_hdl64_last`` — sets the sensor's);
* β per point: :meth:`~fogsim.fog.engine.FogSettings.point_betas` — β × the camera's density field at
  the pixel each point projects to with ``--heterogeneity``, β elsewhere; homogeneous fog: β;
* the range noise's generator: ``numpy.random.default_rng(level_seed(run seed, scan key, level key))``
  (:data:`fogsim.runs.LEVEL_SEED_RULE`): the same for a level whatever the shard, the worker and the
  other levels;
* files: ``lidar/<level>/<scan frame>.<ext>`` (the source's point format; β = 0 is the input bit for
  bit), ``lidar/<level>/<scan frame>.outcomes.npz`` (:mod:`fogsim.lidar.outcome_file`) and
  ``lidar/<level>/<scan frame>.pcd`` (the scan with each point's outcome, for viewers:
  :mod:`fogsim.lidar.scan_pcd`); for a KITTI-style
  source also ``kitti/<level>/<part>/{image_2,velodyne,calib,label_2}/<id>`` (:mod:`fogsim.dataset.kitti`).
  The scan frame is :func:`~fogsim.dataset.layout.frame_from_key` of the source's ``key``;
* per object with a 3D box: ``lidar_points[level]`` = the level's reported points inside it, and
  ``lidar_box`` (the box, sensor frame) — the record :mod:`fogsim.dataset.lidar` reads.

All of it is written before the frame's meta (labelled) or the level's sidecar (images only), so a frame
that is done has its scans.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from fogsim.dataset.kitti import KittiTree
from fogsim.dataset.layout import DatasetLayout, frame_from_key
from fogsim.dataset.lidar import box_record
from fogsim.fog.engine import FogSettings
from fogsim.lidar.boxes import points_in_boxes
from fogsim.lidar.fogged_scan import FoggedScan
from fogsim.lidar.formats import FORMAT_SUFFIX, write_points
from fogsim.lidar.objects import MIN_POINTS
from fogsim.lidar.outcome_file import write_outcomes
from fogsim.lidar.rays import empty_rays
from fogsim.lidar.scan_pcd import PCD_SUFFIX, write_level_pcd
from fogsim.readers.base import SCAN_SOURCE, Sample
from fogsim.runs import LEVEL_SEED_RULE, level_seed

__all__ = ["FrameLidar", "LidarOutput", "scan_source"]


@dataclass(frozen=True)
class LidarOutput:
    """What ``--lidar`` adds to a run: ``sensor`` (None: each source's usual one; a bundled name, or a
    custom sensor block as a dict), ``min_points`` (an object is seen by the LiDAR with at least this many
    points in its box), ``kitti`` (write each level as a KITTI tree for KITTI-style sources)."""

    sensor: str | dict | None = field(default=None, hash=False)
    min_points: int = MIN_POINTS
    kitti: bool = True

    def __post_init__(self):
        if isinstance(self.min_points, bool) or not isinstance(self.min_points, int) or self.min_points < 1:
            raise ValueError(f"--lidar-min-points must be a whole number ≥ 1, got {self.min_points!r}")

    def parameters(self) -> dict:
        """What ``fogsim_run.json`` records (beside the fog record's ``lidar_fog``)."""
        return {"sensor": self.sensor, "min_points": self.min_points, "kitti_trees": self.kitti,
                "seed_rule": LEVEL_SEED_RULE}


def scan_source(sample: Sample):
    """The sample's scan source, or None (a sample without one is fogged for the camera alone)."""
    return (sample.meta or {}).get(SCAN_SOURCE)


class FrameLidar:
    """One sample's scan through the run's levels (the module docstring). ``density``: the camera's
    density field of this image (None: homogeneous); ``records``: the frame's label records (None: no
    labels); ``seed``: the run seed."""

    def __init__(self, fog: FogSettings, output: LidarOutput, source, out: str, seed: int,
                 density: np.ndarray | None = None, records: list[dict] | None = None):
        self.fog, self.output, self.source, self.seed, self.density = fog, output, source, seed, density
        self.layout = DatasetLayout(out)
        self.cloud = source.cloud()
        sensor = source.sensor(output.sensor)
        if source.return_mode is not None and source.return_mode != sensor.return_mode:
            sensor = replace(sensor, return_mode=source.return_mode)
        self.fogger = fog.lidar_fogger(self.cloud, sensor, empty_rays(self.cloud, sensor, source.camera_view()))
        self.sensor = self.fogger.sensor  # under the run's calibration
        self.uv = source.image_uv(self.cloud) if density is not None else None
        self.records = records
        self.boxes = source.boxes(records) if records is not None else []
        self.frame = frame_from_key(source.key)
        self.calib = source.kitti_calib() if output.kitti else None
        self.levels: dict[str, dict] = {}
        self.counts: dict[str, np.ndarray] = {}

    def level(self, level) -> FoggedScan:
        """Fog the scan at ``level`` (key, β), write its scan, outcome and PCD files, count the points in each box."""
        beta = self.fog.point_betas(level.beta, self.density, self.uv)
        seed = level_seed(self.seed, self.source.key, level.key)
        fogged = self.fogger(beta, np.random.default_rng(seed))
        fmt = self.source.fmt
        scan_path = self.layout.lidar(level.key, self.frame, FORMAT_SUFFIX[fmt])
        outcome_path = self.layout.lidar_outcomes(level.key, self.frame)
        write_points(scan_path, fogged.cloud, fmt)
        write_outcomes(outcome_path, fogged)
        pcd_path = self.layout.lidar(level.key, self.frame, PCD_SUFFIX)
        write_level_pcd(pcd_path, fogged)
        real = [b for b in self.boxes if b is not None]
        self.counts[level.key] = points_in_boxes(fogged.cloud.xyz, real) if real else np.zeros(0, np.int64)
        self.levels[level.key] = {**fogged.record(), "seed": seed, "file": self.layout.relative(scan_path),
                                  "outcome_file": self.layout.relative(outcome_path),
                                  "pcd": self.layout.relative(pcd_path)}
        return fogged

    @property
    def kitti_part(self) -> str:
        """The KITTI tree's part of this frame: the source's (KITTI's training / testing), else training."""
        return getattr(self.source, "part", None) or "training"

    def write_kitti(self, level, png: bytes | Path, fogged: FoggedScan) -> None:
        """The level's KITTI-tree frame (KITTI-style sources only): the fogged image (PNG bytes, or the level's
        PNG file: linked), scan (a KITTI-format level scan: linked to its file), calibration, labels."""
        if self.calib is None:
            return
        fmt = self.source.fmt
        scan = self.layout.lidar(level.key, self.frame, FORMAT_SUFFIX[fmt]) if fmt == "kitti" else fogged.cloud
        KittiTree(self.layout.root, level.key, self.kitti_part).write_frame(
            self.source.kitti_id, png, scan, self.calib, self.records)

    def attach(self, records: list[dict]) -> None:
        """Set ``lidar_points`` ({level: count}) and ``lidar_box`` on every record with a 3D box (in place)."""
        j = 0
        for rec, box in zip(records, self.boxes):
            if box is None:
                continue
            rec["lidar_points"] = {key: int(c[j]) for key, c in self.counts.items()}
            rec["lidar_box"] = box_record(box)
            j += 1

    def record(self) -> dict:
        """The frame record's ``lidar`` block (:mod:`fogsim.dataset.lidar`)."""
        out = {"key": self.source.key, "format": self.source.fmt, "points": int(len(self.cloud)),
               "sensor": self.sensor.to_dict(), "input": self.source.describe(), "seed_rule": LEVEL_SEED_RULE,
               "levels": self.levels}
        if self.calib is not None:
            out["kitti"] = {"id": self.source.kitti_id, "part": self.kitti_part}
        return out
