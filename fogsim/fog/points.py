"""``fogsim fog --points``: LiDAR scans fogged without a dataset — files or a folder of one point format
(:data:`fogsim.lidar.formats.FORMATS`; nuScenes samples and sweeps need no devkit: the ``.pcd.bin``
records are all there is to read).

Layout under ``OUT`` (``<name>`` = the scan's path below the input folder, or its file name, without the
format's suffix :data:`~fogsim.lidar.formats.FORMAT_SUFFIX`)::

    <level>/<name><suffix>           the level's scan in the input's format (β = 0: the input bit for bit)
    <level>/<name>.outcomes.npz      every input point's outcome and row (fogsim.lidar.outcome_file)
    <level>/<name>.pcd               the scan with each point's outcome, for viewers (fogsim.lidar.scan_pcd)
    <level>/<name>.json              the sidecar, written last (it marks the scan's level done): the level,
                                     the fog record's parameters (calibration included), the calibrated
                                     sensor, the counts per outcome, ``empty_rays`` (the sweep's rays
                                     without a return, when the sensor's grid is known:
                                     :func:`fogsim.lidar.rays.empty_rays`; else 0) and
                                     ``empty_ray_clutter`` (how many gained a fog-clutter point, appended
                                     to the scan after the input's points), ``no_returns`` and
                                     ``no_return_clutter`` (rows nearer than the sensor's minimum range,
                                     fogged in place: fogsim.lidar.rays.no_returns)
    fogsim_run.json                  the run's parameters (resume refuses others)

Seeds: the level's generator is ``default_rng(level_seed(run seed, <name>, level key))``
(:data:`fogsim.runs.LEVEL_SEED_RULE`), so shards and workers give the same scans. Homogeneous fog only
(there is no camera to give a density field).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fogsim.errors import InputError
from fogsim.fog.levels import FogLevel
from fogsim.fog.point_files import PointFile, PointFilesJob
from fogsim.lidar.formats import FORMAT_SUFFIX, read_points, write_points
from fogsim.lidar.outcome_file import OUTCOME_SUFFIX, write_outcomes
from fogsim.lidar.rays import empty_rays
from fogsim.lidar.scan_pcd import PCD_SUFFIX, write_level_pcd
from fogsim.lidar.sensors import load_sensor
from fogsim.runs import LEVEL_SEED_RULE, level_seed
from fogsim.schema.lidar import LidarFogSpec

__all__ = ["DEFAULT_SENSOR", "PointsJob"]

#: the sensor each format's data is usually recorded with (PLY and .npy have none: give --sensor)
DEFAULT_SENSOR = {"kitti": "hdl64e", "stf": "hdl64-s3d", "nuscenes": "hdl32e"}


@dataclass(frozen=True)
class PointsJob(PointFilesJob):
    """Fog scans at ``levels`` (β in 1/m) with the fog record's LiDAR part (``fog.lidar``), the ``sensor``
    (a bundled name or a custom block as a dict), reading ``fmt`` files (intensity ``scale`` for PLY/.npy;
    None: the file's or the format's), into ``out``."""

    fmt: str = "kitti"
    scale: str | None = None
    seed: int = 0
    inputs: dict = field(default_factory=dict, hash=False)

    unit = "scans"
    suffixes = FORMAT_SUFFIX
    outcome_suffix = OUTCOME_SUFFIX

    def parameters(self) -> dict:
        """What ``fogsim_run.json`` records (and a resumed run must repeat)."""
        return {"points": True, "levels": [lv.to_dict() for lv in self.levels],
                "lidar_fog": (self.fog.lidar or LidarFogSpec()).model_dump(),
                "sensor": self.sensor, "point_format": self.fmt, "point_scale": self.scale, "seed": self.seed,
                "seed_rule": LEVEL_SEED_RULE, "inputs": self.inputs}

    def pcd_path(self, item: PointFile, level: FogLevel) -> Path:
        """The level's scan as a PCD for viewers (:mod:`fogsim.lidar.scan_pcd`)."""
        base = self.base(item, level)
        return base.with_name(base.name + PCD_SUFFIX)

    def outputs(self, item: PointFile, level: FogLevel) -> tuple[Path, ...]:
        """(scan, outcomes, sidecar) and the PCD: a scan is done when its sidecars and every file they name are
        there."""
        return (*self.paths(item, level), self.pcd_path(item, level))

    def fog_one(self, item: PointFile) -> None:
        """Every level of one scan: scan, outcomes, then the sidecar."""
        scan = read_points(item.source, self.fmt, self.scale)
        sensor = load_sensor(self.sensor)
        try:
            fogger = self.fog.lidar_fogger(scan, sensor, empty_rays(scan, sensor))
        except ValueError as exc:  # a calibration that does not fit this sensor
            raise InputError(item.source, str(exc)) from None
        for level in self.levels:
            seed = level_seed(self.seed, item.key, level.key)
            fogged = fogger(level.beta, np.random.default_rng(seed))
            scan_path, outcome_path, _ = self.paths(item, level)
            try:
                write_points(scan_path, fogged.cloud, self.fmt)
            except ValueError as exc:  # a 5-column format without rings (an .npy / PLY scan has none)
                raise InputError(item.source, str(exc).removeprefix(f"{item.source}: ")) from None
            write_outcomes(outcome_path, fogged)
            pcd = self.pcd_path(item, level)
            write_level_pcd(pcd, fogged)
            self.write_sidecar(item, level, {"scan": scan_path.name, "outcome_file": outcome_path.name,
                                             "pcd": pcd.name, "seed": seed, "seed_rule": LEVEL_SEED_RULE,
                                             **fogged.record(), "sensor": fogger.sensor.to_dict()})
