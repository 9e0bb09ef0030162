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

All or nothing: every frame record is checked before anything is written — each level key by the level key
rule (:func:`fogsim.schema.documents.level_key`: a key names a folder of the export, never a path), each
level file relative to the dataset and inside it once its links are resolved — and the export is written
into a hidden folder beside ``NUSC`` that replaces it whole when every file is written: a failure leaves
``NUSC`` as it was, a killed run's folder is deleted by the next run. ``NUSC`` must be new, empty or an
earlier export, and inside the dataset only as a folder of its own directly in it (``DATASET/nuscenes``),
never in one of the dataset's folders.

Radar: a render with ``--radar`` already writes each level's sweep in nuScenes' radar PCD (18 fields,
:mod:`fogsim.radar.formats`); it is read (checked) and hard-linked (else copied) into the channel nuScenes
gives a radar facing that way (:func:`radar_channel`: the sensor mount's yaw — ``ars408-lr`` RADAR_FRONT,
``srr-corner`` RADAR_BACK_LEFT).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Callable

import numpy as np

from fogsim.dataset.reader import read_metas
from fogsim.errors import InputError
from fogsim.io.atomic import atomic_folder, atomic_write_bytes
from fogsim.io.documents import write_json
from fogsim.io.links import link_or_copy
from fogsim.io.parts import PART_SUFFIX, remove_stale_folders
from fogsim.io.paths import resolve_path
from fogsim.lidar.formats import FORMATS, encode_points, read_points
from fogsim.radar.formats import read_radar
from fogsim.radar.sensors import load_radar_sensor
from fogsim.schema.documents import level_key, relative_path

__all__ = ["CHANNEL", "SUMMARY_NAME", "TABLES_NOT_WRITTEN", "export_nuscenes", "radar_channel", "sample_path"]

CHANNEL = "LIDAR_TOP"
SUMMARY_NAME = "fogsim_nuscenes.json"
TABLES_NOT_WRITTEN = ("attribute", "calibrated_sensor", "category", "ego_pose", "instance", "log", "map", "sample",
                      "sample_annotation", "sample_data", "scene", "sensor", "visibility")


def sample_path(out: str | os.PathLike, level: str, frame: str, channel: str = CHANNEL,
                suffix: str = ".pcd.bin") -> Path:
    """``NUSC/<level>/samples/<channel>/<frame><suffix>`` (default: a LiDAR sample, ``LIDAR_TOP/<frame>.pcd.bin``)."""
    return Path(out) / level / "samples" / channel / f"{frame}{suffix}"


@dataclass(frozen=True)
class ChannelFiles:
    """One sensor's level files of one frame (``files``: level key → file), exported as ``channel``'s samples
    ``<level>/samples/<channel>/<frame><suffix>``, each by ``write(level file, sample path)``."""

    channel: str
    suffix: str
    files: dict[str, Path]
    write: Callable[[Path, Path], None]


def radar_channel(yaw_deg: float) -> str:
    """nuScenes' radar channel for a radar whose mount yaw (degrees, + = to the left of forward) is ``yaw_deg``:
    FRONT within ±45°, FRONT_LEFT / FRONT_RIGHT to ±90°, BACK_LEFT / BACK_RIGHT beyond (nuScenes' five ARS 408)."""
    yaw = (float(yaw_deg) + 180.0) % 360.0 - 180.0
    if abs(yaw) <= 45.0:
        return "RADAR_FRONT"
    side = "LEFT" if yaw > 0 else "RIGHT"
    return f"RADAR_FRONT_{side}" if abs(yaw) <= 90.0 else f"RADAR_BACK_{side}"


def _level_file(root: Path, entry, where: Path, what: str) -> Path:
    """The file a level entry of a frame record names: relative to the dataset, inside it once its links are
    resolved (a record may not make the export read, or link, a file elsewhere)."""
    if not isinstance(entry, dict) or not isinstance(entry.get("file"), str):
        raise InputError(where, f"{what}: has no {'sweep' if what.startswith('radar') else 'scan'} file")
    try:
        relative_path(entry["file"])
    except ValueError as exc:
        raise InputError(where, f"{what}.file: {exc} (got {entry['file']!r})") from None
    path = root / entry["file"]
    real, inside = resolve_path(path), resolve_path(root)
    if inside not in real.parents:
        raise InputError(where, f"{what}.file: {entry['file']} leads to {real}, outside the dataset")
    return path


def _levels(block: dict, where: Path, what: str, levels: list[str] | None) -> dict:
    """The entries of a ``lidar``/``radar`` block's ``levels`` to export, each key held to the level key rule
    (a key names a folder of the export: never a path)."""
    out = {}
    for key, entry in block["levels"].items():
        try:
            level_key(key)
        except ValueError as exc:
            raise InputError(where, f"{what}.levels: {exc}") from None
        if levels is None or key in levels:
            out[key] = entry
    return out


def _radar_plan(root: Path, meta: dict, where: Path, levels: list[str] | None) -> ChannelFiles | None:
    """A frame's radar sweeps to export, checked before anything is written; None without radar."""
    radar = meta.get("radar")
    if not radar:
        return None
    entries = radar.get("levels") if isinstance(radar, dict) else None
    if not isinstance(entries, dict) or radar.get("format") != "nuscenes-radar":
        raise InputError(where, "radar: needs per-level nuScenes radar sweeps (written by fogsim render --radar)")
    try:
        sensor = load_radar_sensor(radar.get("sensor_spec") or radar.get("sensor"))
    except (ValueError, TypeError) as exc:
        raise InputError(where, f"radar.sensor: {exc}") from None
    chosen = _levels(radar, where, "radar", levels)
    return ChannelFiles(radar_channel(sensor.mount_rpy_deg[2]), ".pcd",
                        {k: _level_file(root, e, where, f"radar.levels.{k}") for k, e in chosen.items()}, _radar_sample)


def _radar_sample(path: Path, sample: Path) -> None:
    """A level's sweep as it is (nuScenes' radar PCD already): read (a damaged sweep is named, never exported),
    then hard-linked, else copied."""
    read_radar(path, "nuscenes-radar")
    link_or_copy(path, sample)


def _lidar_plan(root: Path, meta: dict, where: Path, levels: list[str] | None) -> ChannelFiles | None:
    """A frame's LiDAR scans to export, checked before anything is written; None without per-level scans."""
    block = _lidar_block(meta, where)
    if block is None:
        return None
    fmt, _, sensor = block
    chosen = _levels(meta["lidar"], where, "lidar", levels)
    return ChannelFiles(CHANNEL, ".pcd.bin", {k: _level_file(root, e, where, f"lidar.levels.{k}")
                                              for k, e in chosen.items()},
                        partial(_lidar_sample, fmt=fmt, sensor=sensor, where=where))


def _lidar_sample(path: Path, sample: Path, fmt: str, sensor: dict, where: Path) -> None:
    """A level's scan as a nuScenes sample (5 float32 a point), its rings estimated from the recorded sensor's
    inclinations when the scan has none."""
    cloud = read_points(path, fmt, allow_empty=True)  # fogsim's own: a sweep that saw nothing
    if cloud.ring is None:
        inclinations = _inclinations_rad(sensor, where)
        offsets = sensor.get("vertical_offsets_m")  # the lasers' offsets, where recorded
        offsets = offsets if isinstance(offsets, list) and len(offsets) == len(inclinations) else None
        cloud = replace(cloud, ring=cloud.estimated_rings(inclinations, offsets))
    atomic_write_bytes(sample, encode_points(cloud, "nuscenes"))


def _lidar_block(meta: dict, where: Path) -> tuple[str, dict, dict] | None:
    """(format, levels, sensor) of a frame record's ``lidar`` block; None without per-level scans."""
    lidar = meta.get("lidar")
    if not isinstance(lidar, dict) or not lidar.get("levels"):
        return None
    fmt, levels, sensor = lidar.get("format"), lidar["levels"], lidar.get("sensor")
    if fmt not in FORMATS or not isinstance(levels, dict) or not isinstance(sensor, dict):
        raise InputError(where, "lidar: needs a point format (one of " + ", ".join(FORMATS) + "), its levels "
                                "and its sensor (written by fogsim render --lidar or fogsim fog … --lidar)")
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


def _check_dataset(root: Path) -> None:
    """The dataset is a folder with frame records (one line naming it otherwise)."""
    real = resolve_path(root, "the dataset argument")
    if not real.exists():
        raise InputError(root, "not found")
    if not real.is_dir():
        raise InputError(root, "is a file, not a folder (a fogsim dataset is a folder with meta/)")
    if not (real / "meta").is_dir():
        raise InputError(root, "not a fogsim dataset (no meta/ folder of frame records)")


def _earlier_export(out: Path) -> bool:
    """Whether the existing folder ``out`` holds nothing but what an export writes (its summary, level
    folders of ``samples/``, temporary files of a killed writer): what a new export may replace."""
    for folder, dirs, files in os.walk(out):
        rel = Path(folder).relative_to(out).parts
        for name in files:
            if name.endswith(PART_SUFFIX) and name.startswith("."):
                continue
            if not (rel == () and name == SUMMARY_NAME) and not (len(rel) >= 2 and rel[1] == "samples"):
                return False
        if len(rel) == 1 and any(d != "samples" for d in dirs):
            return False
    return True


def _check_out(root: Path, out: Path) -> Path:
    """The resolved output folder: not a file, not the dataset, inside it only as a folder of its own
    directly in it, and new, empty or an earlier export (which the new one replaces whole)."""
    if not str(out).strip():
        raise ValueError("--out must name a folder, got ''")
    target, real_root = resolve_path(out, "--out"), resolve_path(root)
    if target.exists() and not target.is_dir():
        raise InputError(out, "is a file, not a folder: --out names the folder the export is written to")
    if target == real_root:
        raise InputError(out, "is the dataset itself: export to another folder (e.g. DATASET/nuscenes)")
    if target in real_root.parents:
        raise InputError(out, "contains the dataset: export to a folder of its own (e.g. DATASET/nuscenes)")
    if real_root in target.parents and target.parent != real_root:
        where = target.relative_to(real_root).parts[0]
        raise InputError(out, f"lies inside the dataset's {where}/: the export would mix with the dataset's own "
                              "files; export to a new folder directly in it (e.g. DATASET/nuscenes) or outside it")
    if target.is_dir() and not _earlier_export(target):
        inside = " (one of the dataset's own folders)" if target.parent == real_root else ""
        raise InputError(out, f"holds files that are not an earlier export{inside}: export to a new or empty folder, "
                              "which the export fills (an earlier export there is replaced whole)")
    return target


def export_nuscenes(dataset: str | os.PathLike, out: str | os.PathLike, levels: list[str] | None = None) -> dict:
    """Write every committed frame's level scans under ``out`` (the module docstring) and
    ``out/fogsim_nuscenes.json``; return that summary. ``levels``: only these (None: every level). A frame
    without scans is skipped; a record or a scan that cannot be read is an :class:`InputError` naming it.

    All or nothing: every frame record is checked first (level keys by the level key rule, level files inside
    the dataset), then the export is written into a hidden folder beside ``out`` that replaces it whole at the
    end — a failure leaves ``out`` as it was, and a killed run's folder is deleted by the next."""
    root = Path(dataset)
    _check_dataset(root)
    if levels is not None:
        if not levels:
            raise ValueError("--levels names no level (give level keys, e.g. --levels clear,beta0.06)")
        for key in levels:
            level_key(key)
    target = _check_out(root, Path(out))
    metas = read_metas(root)
    plan = []  # (frame, the ChannelFiles of its radar and LiDAR)
    for meta in metas:
        where = root / "meta" / f"{meta['frame']}.json"
        lidar = _lidar_plan(root, meta, where, levels)
        radar = _radar_plan(root, meta, where, levels)
        plan.append((meta["frame"], [c for c in (radar, lidar) if c is not None]))
    per_channel: dict[str, dict[str, int]] = {}  # channel → level → samples
    for _, channels in plan:
        for c in channels:
            for key in c.files:
                per_level = per_channel.setdefault(c.channel, {})
                per_level[key] = per_level.get(key, 0) + 1
    written, radar_written = per_channel.pop(CHANNEL, {}), per_channel
    exported = set(written) | {key for per_level in radar_written.values() for key in per_level}
    if levels is not None and (unknown := sorted(set(levels) - exported)):
        raise InputError(root, f"no frame has LiDAR or radar level(s) {', '.join(unknown)}")
    if not written and not radar_written:
        raise InputError(root, "no frame has per-level LiDAR scans or radar sweeps to export (render with --lidar "
                               "or --radar, or fogsim fog --kitti/--stf/--waymo … --lidar)")
    remove_stale_folders(target)  # a killed export's hidden folder
    with atomic_folder(target) as stage:
        for frame, channels in plan:
            for c in channels:
                for key, path in c.files.items():
                    c.write(path, sample_path(stage, key, frame, c.channel, c.suffix))
        summary = _summary(root, plan, written, radar_written)
        write_json(stage / SUMMARY_NAME, summary)
    return summary


def _summary(root: Path, plan: list, written: dict, radar: dict) -> dict:
    lidar = {frame for frame, channels in plan if any(c.channel == CHANNEL for c in channels)}
    return {"dataset": str(root.resolve()), "layout": f"<level>/samples/{CHANNEL}/<frame>.pcd.bin",
            "point_record": "5 × float32 little-endian: x, y, z (m, the sensor frame), intensity 0-255, ring",
            "frames": [frame for frame, _ in plan if frame in lidar],
            "samples_per_level": written, "frames_without_lidar": [frame for frame, _ in plan if frame not in lidar],
            "tables_not_written": list(TABLES_NOT_WRITTEN),
            "why_no_tables": "nuScenes' tables describe a timed drive in a mapped world (tokens, ego poses, "
                             "timestamps, maps, global boxes); fogsim's frames are none, so only the sample "
                             "files are written",
            "radar": {"layout": "<level>/samples/<RADAR channel>/<frame>.pcd (nuScenes radar PCD, 18 fields, "
                                "the render's own files: hard links where the file system allows)",
                      "samples_per_channel_and_level": radar} if radar else "no radar in this dataset"}
