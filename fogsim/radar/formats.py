"""Radar sweep files: nuScenes ``RADAR_*`` PCD and ``.npy``, read into :class:`~fogsim.radar.detections.RadarScan`
and written back (atomically).

``nuscenes-radar`` — nuScenes' radar sweeps (``samples/RADAR_FRONT/*.pcd`` …, the Continental ARS 408-21):
PCD v0.7 (:mod:`fogsim.lidar.pcd`, the one codec), ``DATA binary``, 18 fields per detection, little-endian,
packed (43 bytes), as the nuScenes devkit documents them (``RadarPointCloud.from_file``):

==================  ====  ====  ==============================================================
field               SIZE  TYPE  meaning
==================  ====  ====  ==============================================================
x y z               4     F     position, m (x forward, y left; z is 0 for the ARS 408)
dyn_prop            1     I     dynamic property: 0 moving, 1 stationary, 2 oncoming, 3 stationary
                                candidate, 4 unknown, 5 crossing stationary, 6 crossing moving, 7 stopped
id                  2     I     cluster id
rcs                 4     F     radar cross section, dBsm
vx vy               4     F     velocity, m/s (the radial velocity along the ray)
vx_comp vy_comp     4     F     the same, compensated by the ego motion, m/s
is_quality_valid    1     I     the cluster quality message is valid
ambig_state         1     I     Doppler ambiguity: 0 invalid, 1 ambiguous, 2 staggered ramp,
                                3 unambiguous, 4 stationary candidates
x_rms y_rms         1     I     position rms, the sensor's code
invalid_state       1     I     cluster validity (0x00 valid, 0x01 low RCS, … the devkit's table)
pdh0                1     I     false-alarm probability code: 0 invalid, 1 <25 %, 2 50 %, 3 75 %,
                                4 90 %, 5 99 %, 6 99.9 %, 7 ≤100 %
vx_rms vy_rms       1     I     velocity rms, the sensor's code
==================  ====  ====  ==============================================================

fogsim models x y z, rcs and the four velocities; the other ten fields are carried through
(:attr:`RadarScan.extra`) and written back as read. A sweep that has none (a rendered one) is written with
:data:`NUSCENES_DEFAULTS` (dyn_prop from the compensated radial speed: moving above
:data:`STATIONARY_SPEED_MPS`, else stationary). The devkit reads a first record with a NaN as an empty sweep
(and refuses a file of zero records): fogsim reads one record whose modelled fields are all NaN so and
writes an empty sweep that way. A file is refused (one line naming it) when it is not PCD, lacks one of the
modelled fields, has a field of COUNT > 1, declares more detections (or bytes) than
:mod:`fogsim.lidar.bounds` allows, or holds NaN in any other record (a NaN in the first of several records
included: it is not the empty convention). :func:`read_nuscenes_records` gives a sweep's records as stored,
every field in its own type, so a fogged level keeps the input's record layout
(:func:`encode_nuscenes_records`).

``npy`` — a structured array (``np.save``, never pickled) with the record's columns: x y z vx vy vx_comp
vy_comp rcs snr (float32), object_id (int32), kind (int8), index (int64), then any extra fields. Read: x y z
and rcs are required, the others default as :meth:`RadarScan.checked` says. The header's shape is checked
against the bound before the body is read.
"""
from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from fogsim.errors import InputError
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.headers import read_npy
from fogsim.lidar.bounds import check_point_count, check_record, file_size
from fogsim.lidar.formats import check_npy_fields, npy_widest
from fogsim.lidar.pcd import PcdHeader, encode_pcd, read_pcd, read_pcd_header
from fogsim.radar.detections import RadarScan

__all__ = ["EXTRA_FIELDS", "MODELLED_FIELDS", "NPY_DTYPE", "NUSCENES_DEFAULTS", "NUSCENES_RADAR_DTYPE",
           "RADAR_FORMATS", "RADAR_SUFFIX", "STATIONARY_SPEED_MPS", "detect_radar_format", "devkit_readable",
           "encode_nuscenes_records", "encode_radar", "nuscenes_records", "read_nuscenes_records", "read_radar",
           "write_radar"]

RADAR_FORMATS = ("nuscenes-radar", "npy")
#: the file-name ending of each format (what a folder of sweeps is searched for, what levels are named)
RADAR_SUFFIX = {"nuscenes-radar": ".pcd", "npy": ".npy"}

#: nuScenes' radar record: FIELDS, SIZE, TYPE as its devkit documents them (little-endian, packed)
NUSCENES_RADAR_DTYPE = np.dtype([
    ("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("dyn_prop", "i1"), ("id", "<i2"), ("rcs", "<f4"),
    ("vx", "<f4"), ("vy", "<f4"), ("vx_comp", "<f4"), ("vy_comp", "<f4"), ("is_quality_valid", "i1"),
    ("ambig_state", "i1"), ("x_rms", "i1"), ("y_rms", "i1"), ("invalid_state", "i1"), ("pdh0", "i1"),
    ("vx_rms", "i1"), ("vy_rms", "i1")])
MODELLED_FIELDS = ("x", "y", "z", "rcs", "vx", "vy", "vx_comp", "vy_comp")
EXTRA_FIELDS = tuple(n for n in NUSCENES_RADAR_DTYPE.names if n not in MODELLED_FIELDS)
#: what a sweep without nuScenes' own fields is written with: valid, unambiguous, quality valid, the
#: lowest false-alarm class; the rms codes 0 (the finest class) since fogsim does not estimate them
NUSCENES_DEFAULTS = {"is_quality_valid": 1, "ambig_state": 3, "x_rms": 0, "y_rms": 0, "invalid_state": 0,
                     "pdh0": 1, "vx_rms": 0, "vy_rms": 0}
DYN_MOVING, DYN_STATIONARY = 0, 1
#: a compensated radial speed above this (m/s) is written as dyn_prop "moving"
STATIONARY_SPEED_MPS = 0.5
NPY_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("vx", "<f4"), ("vy", "<f4"), ("vx_comp", "<f4"),
                      ("vy_comp", "<f4"), ("rcs", "<f4"), ("snr", "<f4"), ("object_id", "<i4"), ("kind", "i1"),
                      ("index", "<i8")])


def detect_radar_format(path: str | os.PathLike) -> str:
    """The format a file name implies: ``.pcd`` nuScenes radar, ``.npy``."""
    name = Path(path).name.lower()
    for fmt, suffix in RADAR_SUFFIX.items():
        if name.endswith(suffix):
            return fmt
    raise ValueError(f"{path}: unknown radar file type (formats: {', '.join(RADAR_FORMATS)})")


def _check_format(fmt: str) -> str:
    if fmt not in RADAR_FORMATS:
        raise ValueError(f"unknown radar format {fmt!r} (known: {', '.join(RADAR_FORMATS)})")
    return fmt


# ----------------------------------------------------------------------------- reading
def read_radar(path: str | os.PathLike, fmt: str | None = None) -> RadarScan:
    """The sweep in ``path`` (``fmt`` one of :data:`RADAR_FORMATS`; None: from the name)."""
    path = Path(path)
    fmt = _check_format(fmt or detect_radar_format(path))
    return _read_nuscenes(path) if fmt == "nuscenes-radar" else _read_npy(path)


def read_nuscenes_records(path: str | os.PathLike) -> tuple[PcdHeader, np.ndarray]:
    """(header, records) of a nuScenes radar PCD as stored — every field in its own type, extra fields
    included — checked as :func:`read_radar` checks it (the modelled fields present, COUNT 1, from the header
    before the body). The empty sweep's convention — one record whose modelled fields are all NaN, what the
    devkit and fogsim write for no detections — reads as 0 records; a NaN in any other record is the
    sweep's problem (:meth:`RadarScan.checked` names it)."""
    path = Path(path)
    head = read_pcd_header(path)  # the fields checked from the header, before the body is read
    names = head.fields
    missing = [n for n in MODELLED_FIELDS if n not in names]
    if missing:
        raise InputError(path, f"not a nuScenes radar sweep: its PCD fields ({' '.join(names)}) lack "
                               f"{' '.join(missing)}")
    for n in names:
        if head.dtype[n].shape:
            raise InputError(path, f"PCD field {n} has COUNT {int(np.prod(head.dtype[n].shape)):,}; nuScenes radar "
                                   "fields are single values (COUNT 1)")
    _, rec = read_pcd(path)
    if len(rec) == 1 and all(rec.dtype[n].kind == "f" and np.isnan(rec[0][n]) for n in MODELLED_FIELDS):
        rec = rec[:0]  # the devkit's (and fogsim's) empty sweep
    return head, rec


def _read_nuscenes(path: Path) -> RadarScan:
    _, rec = read_nuscenes_records(path)
    extra_names = [n for n in rec.dtype.names if n not in MODELLED_FIELDS]
    xyz = np.stack([rec["x"], rec["y"], rec["z"]], 1)
    v = np.stack([rec["vx"], rec["vy"]], 1)
    vc = np.stack([rec["vx_comp"], rec["vy_comp"]], 1)
    extra = None
    if extra_names:
        extra = np.empty(len(rec), [(n, rec.dtype[n]) for n in extra_names])
        for n in extra_names:
            extra[n] = rec[n]
    return RadarScan.checked(xyz, rec["rcs"], v, vc, source=str(path), extra=extra)


def devkit_readable(path: str | os.PathLike, head: PcdHeader) -> bool:
    """Whether the nuScenes PCD ``path`` (its ``head``) is as the devkit's ``RadarPointCloud.from_file`` reads
    it: a comment line, then VERSION, FIELDS, SIZE, TYPE, COUNT (all 1), WIDTH (> 0), HEIGHT 1, VIEWPOINT,
    POINTS, DATA binary, one a line and split by single spaces (it reads them by position)."""
    with open(path, "rb") as f:
        lines = f.read(head.offset).decode("ascii", "replace").splitlines()
    keys = ["VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "VIEWPOINT", "POINTS", "DATA"]
    return (len(lines) == 11 and lines[0].startswith("#") and head.data == "binary" and head.width > 0
            and head.height == 1 and all(ln.split(" ")[0] == k and "  " not in ln and "\t" not in ln
                                         and ln == ln.strip() for ln, k in zip(lines[1:], keys)))


def encode_nuscenes_records(records: np.ndarray) -> bytes:
    """The bytes of a nuScenes radar PCD holding ``records`` in their own layout (fields, types; 0 records:
    the empty sweep's convention, one record with the modelled fields NaN), as :func:`encode_radar` writes
    them (binary, the devkit's header, a trailing newline)."""
    if not len(records):
        records = np.zeros(1, records.dtype)
        for name in MODELLED_FIELDS:
            records[name] = np.nan
    return encode_pcd(records, "binary") + b"\n"


def _read_npy(path: Path) -> RadarScan:
    size = file_size(path)

    def check(dtype: np.dtype, shape: tuple[int, ...]) -> None:  # the header alone, before the body is read
        if not dtype.names or len(shape) != 1:
            raise InputError(path, f"a radar .npy is a 1-D structured array (fields x y z rcs …), got {dtype} "
                                   f"{list(shape)}")
        check_point_count(path, int(shape[0]), size, ".npy header declares a sweep")
        check_npy_fields(path, dtype, NPY_DTYPE.names)
        check_record(path, dtype.itemsize, int(shape[0]), "a .npy detection record", npy_widest(dtype))

    a = read_npy(path, check).copy()  # fogsim.io.headers: bounded, never unpickled
    names = set(a.dtype.names)
    if not {"x", "y", "z", "rcs"} <= names:
        raise InputError(path, f"a radar .npy needs fields x, y, z, rcs (has {', '.join(a.dtype.names)})")

    def get(*keys):
        return np.stack([a[k] for k in keys], 1) if all(k in names for k in keys) else None
    known = set(NPY_DTYPE.names)
    extra_names = [n for n in a.dtype.names if n not in known]
    extra = None
    if extra_names:
        extra = np.empty(len(a), [(n, a.dtype[n]) for n in extra_names])
        for n in extra_names:
            extra[n] = a[n]
    return RadarScan.checked(get("x", "y", "z"), a["rcs"], get("vx", "vy"), get("vx_comp", "vy_comp"),
                             a["snr"] if "snr" in names else None,
                             a["object_id"] if "object_id" in names else None,
                             a["kind"] if "kind" in names else None,
                             a["index"] if "index" in names else None, str(path), extra)


# ----------------------------------------------------------------------------- writing
def nuscenes_records(scan: RadarScan) -> np.ndarray:
    """The sweep as nuScenes' 18-field records (:data:`NUSCENES_RADAR_DTYPE`; an empty sweep: one NaN record,
    the devkit's convention)."""
    n = len(scan)
    if n == 0:
        rec = np.zeros(1, NUSCENES_RADAR_DTYPE)
        for name in MODELLED_FIELDS:
            rec[name] = np.nan
        return rec
    rec = np.zeros(n, NUSCENES_RADAR_DTYPE)
    rec["x"], rec["y"], rec["z"] = scan.xyz[:, 0], scan.xyz[:, 1], scan.xyz[:, 2]
    rec["rcs"] = scan.rcs_dbsm
    rec["vx"], rec["vy"] = scan.velocity[:, 0], scan.velocity[:, 1]
    rec["vx_comp"], rec["vy_comp"] = scan.velocity_comp[:, 0], scan.velocity_comp[:, 1]
    have = set(scan.extra.dtype.names) if scan.extra is not None else set()
    for name in EXTRA_FIELDS:
        if name in have:
            rec[name] = scan.extra[name]
        elif name == "dyn_prop":
            rec[name] = np.where(np.abs(scan.radial_velocity_comp) > STATIONARY_SPEED_MPS, DYN_MOVING, DYN_STATIONARY)
        elif name == "id":
            rec[name] = np.arange(n) % (np.iinfo(np.int16).max + 1)
        else:
            rec[name] = NUSCENES_DEFAULTS[name]
    return rec


def _npy_records(scan: RadarScan) -> np.ndarray:
    extra = [] if scan.extra is None else [(n, scan.extra.dtype[n]) for n in scan.extra.dtype.names
                                           if n not in NPY_DTYPE.names]
    rec = np.zeros(len(scan), NPY_DTYPE.descr + extra)
    rec["x"], rec["y"], rec["z"] = scan.xyz[:, 0], scan.xyz[:, 1], scan.xyz[:, 2]
    rec["vx"], rec["vy"] = scan.velocity[:, 0], scan.velocity[:, 1]
    rec["vx_comp"], rec["vy_comp"] = scan.velocity_comp[:, 0], scan.velocity_comp[:, 1]
    rec["rcs"], rec["snr"] = scan.rcs_dbsm, scan.snr_db
    rec["object_id"], rec["kind"], rec["index"] = scan.object_id, scan.kind, scan.index
    for name, _ in extra:
        rec[name] = scan.extra[name]
    return rec


def encode_radar(scan: RadarScan, fmt: str) -> bytes:
    """The bytes of ``scan`` in ``fmt`` (what :func:`write_radar` writes). nuScenes: the PCD body is followed
    by one newline byte (the devkit's reader asserts that bytes follow the last field it unpacks) and the header
    is the devkit's: one comment line, then the keys (it reads them by line number)."""
    fmt = _check_format(fmt)
    if fmt == "nuscenes-radar":
        return encode_nuscenes_records(nuscenes_records(scan))  # no comment: the devkit reads lines by position
    buf = io.BytesIO()
    np.save(buf, _npy_records(scan), allow_pickle=False)
    return buf.getvalue()


def write_radar(path: str | os.PathLike, scan: RadarScan, fmt: str | None = None) -> None:
    """Write ``scan`` to ``path`` in ``fmt`` (None: from the name), atomically (temporary file + rename)."""
    fmt = _check_format(fmt or detect_radar_format(path))
    atomic_write_bytes(path, encode_radar(scan, fmt))
