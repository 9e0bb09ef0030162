"""``fogsim fog --points … --point-format nuscenes-radar``: radar sweeps fogged without a dataset — files or a
folder of nuScenes ``RADAR_*`` PCD sweeps (no devkit needed: the ``.pcd`` records are all there is to read).

Layout under ``OUT`` (``<name>`` = the sweep's path below the input folder, or its file name, without
``.pcd``), as ``--points`` writes LiDAR scans (:mod:`fogsim.fog.points`)::

    <level>/<name>.pcd               the level's sweep in nuScenes' format: the kept detections, every field
                                     as read, in its own type (a level that keeps every detection — β = 0 —
                                     is the input file, byte for byte, when the devkit can read that file:
                                     DATA binary, its header lines in order; else re-encoded so)
    <level>/<name>.outcomes.npz      every input detection's outcome, row and SNR in fog (fogsim.radar.outcome_file)
    <level>/<name>.json              the sidecar, written last (it marks the sweep's level done)
    fogsim_run.json                  the run's parameters (resume refuses others)

The fog is the run's record (:meth:`fogsim.fog.engine.FogSettings.radar_fogger`: its ``radar`` block); the
model is deterministic (no seed). Homogeneous fog only (there is no camera to give a density field).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from fogsim.fog.point_files import PointFile, PointFilesJob
from fogsim.io.atomic import atomic_write_bytes
from fogsim.radar.fog import KEPT
from fogsim.radar.formats import (
    RADAR_SUFFIX,
    devkit_readable,
    encode_nuscenes_records,
    read_nuscenes_records,
    read_radar,
    write_radar,
)
from fogsim.radar.outcome_file import OUTCOME_SUFFIX, write_radar_outcomes
from fogsim.radar.sensors import load_radar_sensor
from fogsim.schema.radar import RadarFogSpec

__all__ = ["DEFAULT_RADAR_SENSOR", "RadarPointsJob"]

#: the sensor each radar format's data is recorded with
DEFAULT_RADAR_SENSOR = {"nuscenes-radar": "ars408-lr"}


@dataclass(frozen=True)
class RadarPointsJob(PointFilesJob):
    """Fog radar sweeps at ``levels`` (β in 1/m) with the fog record's radar part (``fog.radar``), the
    ``sensor`` (a bundled name or a custom block as a dict), reading ``fmt`` files, into ``out``."""

    fmt: str = "nuscenes-radar"
    inputs: dict = field(default_factory=dict, hash=False)

    unit = "sweeps"
    suffixes = RADAR_SUFFIX
    outcome_suffix = OUTCOME_SUFFIX

    def parameters(self) -> dict:
        """What ``fogsim_run.json`` records (and a resumed run must repeat)."""
        return {"points": True, "radar": True, "levels": [lv.to_dict() for lv in self.levels],
                "radar_fog": (self.fog.radar or RadarFogSpec()).model_dump(), "sensor": self.sensor,
                "point_format": self.fmt, "inputs": self.inputs}

    def fog_one(self, item: PointFile) -> None:
        """Every level of one sweep: sweep, outcomes, then the sidecar. A nuScenes level is the input's kept
        records in the input's own layout (every field, its type); the input's bytes when every detection is
        kept and the file is as the devkit reads it."""
        scan = read_radar(item.source, self.fmt)
        sensor = load_radar_sensor(self.sensor)
        fogger = self.fog.radar_fogger(scan, sensor)
        records = original = None
        if self.fmt == "nuscenes-radar":
            head, records = read_nuscenes_records(item.source)
            original = Path(item.source).read_bytes() if devkit_readable(item.source, head) else None
        for level in self.levels:
            fogged = fogger(level.beta)
            sweep_path, outcome_path, _ = self.paths(item, level)
            kept = fogged.outcome == KEPT
            if kept.all() and original is not None:
                atomic_write_bytes(sweep_path, original)  # nothing lost: the input, byte for byte
            elif records is not None:
                atomic_write_bytes(sweep_path, encode_nuscenes_records(records[kept]))
            else:
                write_radar(sweep_path, fogged.scan, self.fmt)
            write_radar_outcomes(outcome_path, fogged)
            self.write_sidecar(item, level, {"sweep": sweep_path.name, "outcome_file": outcome_path.name,
                                             **fogged.record(), "sensor": sensor.to_dict()})
