"""A fogsim dataset's LiDAR levels as nuScenes-style sample files (``fogsim export nuscenes``), one nuScenes
data root per fog level, so nuScenes users' point loaders read them as they are::

    NUSC/<level>/samples/LIDAR_TOP/<frame>.pcd.bin   5 × float32 LE per point: x y z intensity (0–255) ring
    NUSC/<level>/samples/RADAR_<SIDE>/<frame>.pcd     a render's radar (--radar): nuScenes' radar PCD as it is
    NUSC/fogsim_nuscenes.json                         what was written, from what, and what was not

Works on any dataset with per-level scans in its frame records (``meta/<frame>.json``'s ``lidar.levels``):
a render with ``--lidar``, a ``fogsim fog --kitti/--stf/--waymo … --lidar`` run. Per point:

* x y z: the level's scan as it is, in its sensor's frame (KITTI / a render: x forward, y left, z up; a
  nuScenes sensor: x right, y forward — fogsim writes no ``calibrated_sensor`` table, so no loader moves
  the points either);
* intensity on nuScenes' 0–255 scale (a 0–1 scan: 255 × its normalised intensity, :mod:`fogsim.lidar.formats`);
* ring: the scan's own where it has one (renders, nuScenes, STF, Waymo), else the nearest beam by elevation
  among the recorded sensor's inclinations (``lidar.sensor.inclinations_deg``, with its lasers'
  ``vertical_offsets_m`` where recorded: :meth:`~fogsim.lidar.points.PointCloud.estimated_rings`; KITTI's
  ``.bin`` holds none).

Not written — nuScenes' 13 JSON tables (``attribute``, ``calibrated_sensor``, ``category``, ``ego_pose``,
``instance``, ``log``, ``map``, ``sample``, ``sample_annotation``, ``sample_data``, ``scene``, ``sensor``,
``visibility``), listed in :data:`TABLES_NOT_WRITTEN`: ``nuscenes-devkit``'s ``NuScenes`` class needs all of
them linked by tokens, with ego poses in a global frame over a timed drive, a map per log, and every box in
global coordinates with nuScenes' categories, attributes and visibility bins. fogsim's frames are not a
timed drive in a mapped world (renders are independent scenes; KITTI's object set has no poses), so such
tables would state times and places that never were. The sample files are what ``LidarPointCloud.from_file``
(the devkit), mmdetection3d's ``LoadPointsFromFile(load_dim=5)`` and OpenPCDet's nuScenes loader read.

Radar: a render with ``--radar`` already writes each level's sweep in nuScenes' radar PCD (18 fields,
:mod:`fogsim.radar.formats`); it is read (checked) and hard-linked (else copied) into the channel nuScenes
gives a radar facing that way (:func:`radar_channel`: the sensor mount's yaw — ``ars408-lr`` RADAR_FRONT,
``srr-corner`` RADAR_BACK_LEFT).
"""
from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

import numpy as np

from fogsim.dataset.reader import read_metas
from fogsim.errors import InputError
from fogsim.fileio import atomic_write_bytes, link_or_copy, write_json
from fogsim.lidar.formats import FORMATS, encode_points, read_points
from fogsim.radar.formats import read_radar
from fogsim.radar.sensors import load_radar_sensor

__all__ = ["CHANNEL", "SUMMARY_NAME", "TABLES_NOT_WRITTEN", "export_nuscenes", "radar_channel", "sample_path"]

CHANNEL = "LIDAR_TOP"
SUMMARY_NAME = "fogsim_nuscenes.json"
TABLES_NOT_WRITTEN = ("attribute", "calibrated_sensor", "category", "ego_pose", "instance", "log", "map", "sample",
                      "sample_annotation", "sample_data", "scene", "sensor", "visibility")


def sample_path(out: str | os.PathLike, level: str, frame: str) -> Path:
    """``NUSC/<level>/samples/LIDAR_TOP/<frame>.pcd.bin``."""
    return Path(out) / level / "samples" / CHANNEL / f"{frame}.pcd.bin"


def radar_channel(yaw_deg: float) -> str:
    """nuScenes' radar channel for a radar whose mount yaw (degrees, + = to the left of forward) is ``yaw_deg``:
    FRONT within ±45°, FRONT_LEFT / FRONT_RIGHT to ±90°, BACK_LEFT / BACK_RIGHT beyond (nuScenes' five ARS 408)."""
    yaw = (float(yaw_deg) + 180.0) % 360.0 - 180.0
    if abs(yaw) <= 45.0:
        return "RADAR_FRONT"
    side = "LEFT" if yaw > 0 else "RIGHT"
    return f"RADAR_FRONT_{side}" if abs(yaw) <= 90.0 else f"RADAR_BACK_{side}"


def _export_radar(root: Path, out: Path, meta: dict, where: Path, levels: list[str] | None,
                  written: dict[str, dict[str, int]]) -> None:
    """Link (else copy) a frame's radar level sweeps into their nuScenes channel, each read (checked) first."""
    radar = meta["radar"]
    entries = radar.get("levels") if isinstance(radar, dict) else None
    if not isinstance(entries, dict) or radar.get("format") != "nuscenes-radar":
        raise InputError(where, "radar: needs per-level nuScenes radar sweeps (written by fogsim render --radar)")
    try:
        sensor = load_radar_sensor(radar.get("sensor_spec") or radar.get("sensor"))
    except (ValueError, TypeError) as exc:
        raise InputError(where, f"radar.sensor: {exc}") from None
    channel = radar_channel(sensor.mount_rpy_deg[2])
    for key, entry in entries.items():
        if levels is not None and key not in levels:
            continue
        if not isinstance(entry, dict) or not isinstance(entry.get("file"), str):
            raise InputError(where, f"radar.levels.{key}: has no sweep file")
        path = Path(entry["file"])
        path = path if path.is_absolute() else root / path
        read_radar(path, "nuscenes-radar")  # a damaged sweep is named, never exported
        link_or_copy(path, Path(out) / key / "samples" / channel / f"{meta['frame']}.pcd")
        written.setdefault(channel, {})[key] = written.setdefault(channel, {}).get(key, 0) + 1


def _lidar_block(meta: dict, where: Path) -> tuple[str, dict, dict] | None:
    """(format, levels, sensor) of a frame record's ``lidar`` block; None without per-level scans."""
    lidar = meta.get("lidar")
    if not isinstance(lidar, dict) or not lidar.get("levels"):
        return None
    fmt, levels, sensor = lidar.get("format"), lidar["levels"], lidar.get("sensor")
    if fmt not in FORMATS or not isinstance(levels, dict) or not isinstance(sensor, dict):
        raise InputError(where, "lidar: needs a point format (one of " + ", ".join(FORMATS) + "), its levels "
                                "and its sensor (written by fogsim render --lidar or fogsim fog … --lidar)")
    for key, entry in levels.items():
        if not isinstance(entry, dict) or not isinstance(entry.get("file"), str):
            raise InputError(where, f"lidar.levels.{key}: has no scan file")
    return fmt, levels, sensor


def _inclinations_rad(sensor: dict, where: Path) -> np.ndarray:
    """The recorded sensor's beam inclinations (``inclinations_deg``, :meth:`LidarSensor.to_dict`) in radians."""
    incl = sensor.get("inclinations_deg")
    try:
        out = np.radians(np.asarray(incl, np.float64).reshape(-1))
    except (TypeError, ValueError):
        out = np.zeros(0)
    if not out.size or not np.isfinite(out).all():
        raise InputError(where, "lidar.sensor.inclinations_deg: the scan has no rings and the record gives no "
                                "beam inclinations to estimate them from")
    return out


def export_nuscenes(dataset: str | os.PathLike, out: str | os.PathLike, levels: list[str] | None = None) -> dict:
    """Write every committed frame's level scans under ``out`` (the module docstring) and
    ``out/fogsim_nuscenes.json``; return that summary. ``levels``: only these (None: every level). A frame
    without scans is skipped; a record or a scan that cannot be read is an :class:`InputError` naming it."""
    root, out = Path(dataset), Path(out)
    if out.resolve() == root.resolve():
        raise InputError(out, "is the dataset itself: export to another folder (e.g. DATASET/nuscenes)")
    metas = read_metas(root)
    written: dict[str, int] = {}
    frames, without = [], []
    radar: dict[str, dict[str, int]] = {}
    for meta in metas:
        where = root / "meta" / f"{meta['frame']}.json"
        block = _lidar_block(meta, where)
        if meta.get("radar"):
            _export_radar(root, out, meta, where, levels, radar)
        if block is None:
            without.append(meta["frame"])
            continue
        fmt, entries, sensor_block = block
        inclinations = None
        for key, entry in entries.items():
            if levels is not None and key not in levels:
                continue
            path = Path(entry["file"])
            cloud = read_points(path if path.is_absolute() else root / path, fmt)
            if cloud.ring is None:
                if inclinations is None:
                    inclinations = _inclinations_rad(sensor_block, where)
                offsets = sensor_block.get("vertical_offsets_m")  # the lasers' offsets, where recorded
                offsets = offsets if isinstance(offsets, list) and len(offsets) == len(inclinations) else None
                cloud = replace(cloud, ring=cloud.estimated_rings(inclinations, offsets))
            atomic_write_bytes(sample_path(out, key, meta["frame"]), encode_points(cloud, "nuscenes"))
            written[key] = written.get(key, 0) + 1
        frames.append(meta["frame"])
    exported = set(written) | {key for per_level in radar.values() for key in per_level}
    if levels is not None and (unknown := sorted(set(levels) - exported)):
        raise InputError(root, f"no frame has LiDAR or radar level(s) {', '.join(unknown)}")
    if not written and not radar:
        raise InputError(root, "no frame has per-level LiDAR scans or radar sweeps to export (render with --lidar "
                               "or --radar, or fogsim fog --kitti/--stf/--waymo … --lidar)")
    summary = {"dataset": str(root.resolve()), "layout": f"<level>/samples/{CHANNEL}/<frame>.pcd.bin",
               "point_record": "5 × float32 little-endian: x, y, z (m, the sensor frame), intensity 0-255, ring",
               "frames": frames, "samples_per_level": written, "frames_without_lidar": without,
               "tables_not_written": list(TABLES_NOT_WRITTEN),
               "why_no_tables": "nuScenes' tables describe a timed drive in a mapped world (tokens, ego poses, "
                                "timestamps, maps, global boxes); fogsim's frames are none, so only the sample "
                                "files are written",
               "radar": {"layout": "<level>/samples/<RADAR channel>/<frame>.pcd (nuScenes radar PCD, 18 fields, "
                                   "the render's own files: hard links where the file system allows)",
                         "samples_per_channel_and_level": radar} if radar else "no radar in this dataset"}
    write_json(out / SUMMARY_NAME, summary)
    return summary
