"""The files ``fogsim fog --points`` fogs, whatever the sensor: the inputs found (:func:`point_files`) and the
skeleton every sensor's job shares (:class:`PointFilesJob`: its fields, each file's outputs per level, when a
file is done, the size bound) — a LiDAR's scans (:mod:`fogsim.fog.points`) and a radar's sweeps
(:mod:`fogsim.fog.radar_points`).

Layout under ``OUT``, for every sensor (``<name>`` = the file's path below the input folder, or its file name,
without the format's suffix)::

    <level>/<name><suffix>           the level's scan or sweep in the input's format
    <level>/<name>.outcomes.npz      every input point's (detection's) outcome
    <level>/<name>.json              the sidecar, written last (it marks the file's level done)
    fogsim_run.json                  the run's parameters (resume refuses others)
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

from fogsim._version import __version__
from fogsim.fog.depth_input import SetupError
from fogsim.fog.engine import FogSettings
from fogsim.fog.levels import FogLevel
from fogsim.io.documents import write_json
from fogsim.lidar.bounds import max_scan_points
from fogsim.lidar.formats import FORMAT_SUFFIX
from fogsim.radar.formats import RADAR_SUFFIX

__all__ = ["PointFile", "PointFilesJob", "point_files"]


@dataclass(frozen=True)
class PointFile:
    """One scan to fog: ``key`` its name in the output (POSIX, without the suffix), ``source`` the file."""

    key: str
    source: str


def _key(path: Path, suffix: str) -> str:
    name = path.as_posix()
    return name[: -len(suffix)] if name.lower().endswith(suffix) else path.with_suffix("").as_posix()


def point_files(paths: list[str | os.PathLike], fmt: str) -> list[PointFile]:
    """The scans of ``paths`` (files, or folders searched recursively for the format's suffix — a LiDAR
    format's, :data:`~fogsim.lidar.formats.FORMAT_SUFFIX`, or a radar one's,
    :data:`~fogsim.radar.formats.RADAR_SUFFIX`), sorted by
    name within each folder; a missing path, an empty folder or two scans with one output name is a
    :class:`~fogsim.fog.depth_input.SetupError` (exit 2, before the output folder is claimed)."""
    suffix = FORMAT_SUFFIX[fmt] if fmt in FORMAT_SUFFIX else RADAR_SUFFIX[fmt]
    items: list[PointFile] = []
    for given in paths:
        path = Path(given)
        if path.is_dir():
            found = sorted(p for p in path.rglob("*") if p.is_file() and p.name.lower().endswith(suffix)
                           and not (fmt in ("kitti", "stf") and p.name.lower().endswith(".pcd.bin")))
            if not found:
                raise SetupError(path, f"holds no {suffix} scans (--point-format {fmt})")
            items += [PointFile(_key(p.relative_to(path), suffix), str(p)) for p in found]
        elif path.is_file():
            items.append(PointFile(_key(Path(path.name), suffix), str(path)))
        elif path.exists():
            raise SetupError(path, "is not a regular file or a folder (a FIFO, device or socket): fogsim reads scan "
                                   "files")
        else:
            raise SetupError(path, "not found (no such file or folder)")
    seen: dict[str, str] = {}
    for item in items:
        if item.key in seen:
            raise SetupError(item.source, f"its output name {item.key!r} is also that of {seen[item.key]}: "
                                          "their outputs would overwrite each other")
        seen[item.key] = item.source
    return items


@dataclass(frozen=True)
class PointFilesJob:
    """What every sensor's ``--points`` job shares: fog the files of format ``fmt`` at ``levels`` (β in 1/m)
    with the fog record ``fog`` and the ``sensor`` (a bundled name or a custom block as a dict), into ``out``.

    A sensor's job adds its own fields and ``fog_one``, and sets :attr:`suffixes` (format → its files'
    suffix), :attr:`outcome_suffix` and :attr:`unit` (what :func:`fogsim.fog.batch.run` counts)."""

    levels: tuple[FogLevel, ...]
    out: str
    fog: FogSettings
    sensor: str | dict = field(hash=False)
    fmt: str

    unit: ClassVar[str] = "files"
    suffixes: ClassVar[dict[str, str]] = {}
    outcome_suffix: ClassVar[str] = ".outcomes.npz"

    def paths(self, item: PointFile, level: FogLevel) -> tuple[Path, Path, Path]:
        """(the level's file, outcomes, sidecar) of one input file and level."""
        base = self.base(item, level)
        return (base.with_name(base.name + self.suffixes[self.fmt]), base.with_name(base.name + self.outcome_suffix),
                base.with_name(base.name + ".json"))

    def base(self, item: PointFile, level: FogLevel) -> Path:
        """``OUT/<level>/<name>``: each output of one file and level is this plus a suffix."""
        return Path(self.out) / level.key / item.key

    def outputs(self, item: PointFile, level: FogLevel) -> tuple[Path, ...]:
        """Every file one input file's level writes (:meth:`paths`; a sensor's job may add its own)."""
        return self.paths(item, level)

    def done(self, item: PointFile) -> bool:
        """Every level's sidecar (written last) is there, and so is every file it names: a sidecar whose
        files were deleted or moved does not claim the file done."""
        return all(p.is_file() for lv in self.levels for p in self.outputs(item, lv))

    def check(self, items: list[PointFile]) -> None:
        """The scan-size bound in force (``FOGSIM_MAX_SCAN_POINTS``), before the folder is claimed; each file is
        read (and bounded) in its turn."""
        max_scan_points()

    def write_sidecar(self, item: PointFile, level: FogLevel, record: dict) -> None:
        """The level's sidecar of one file (:meth:`paths`' third), written last: the level, the input, then
        ``record`` (the sensor's own fields), then fogsim's version."""
        write_json(self.paths(item, level)[2], {"level": level.to_dict(), "source": item.source, "key": item.key,
                                                **record, "fogsim_version": __version__})
