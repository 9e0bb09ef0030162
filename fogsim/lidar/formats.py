"""Point-cloud files: KITTI ``.bin``, nuScenes ``.pcd.bin``, STF ``.bin``, PLY and ``.npy``, read into
:class:`~fogsim.lidar.points.PointCloud` and written back (atomically, bit for bit).

=============  ===========================================  =======  ======================================
format         record (little-endian)                       scale    where
=============  ===========================================  =======  ======================================
``kitti``      4 × float32: x, y, z, reflectance            0-1      KITTI ``velodyne/*.bin``
``nuscenes``   5 × float32: x, y, z, intensity, ring        0-255    nuScenes ``LIDAR_TOP/*.pcd.bin``
``stf``        5 × float32: x, y, z, intensity, ring        0-255    STF ``lidar_hdl64_{strongest,last}``
``ply``        PLY vertex element (binary or ASCII):        comment  any tool (CloudCompare, Open3D …)
               x, y, z [, intensity] [, ring] [, return_index]
``npy``        N×3 / N×4 / N×5 float (x y z [i [ring]]) or  given    NumPy, ``np.load(allow_pickle=False)``
               a structured array with fields x, y, z [,
               intensity] [, ring] [, return_index]
=============  ===========================================  =======  ======================================

* A ``.bin`` whose size is not a whole number of records, NaN/inf coordinates, intensities outside the
  scale, fractional rings, an empty scan: one :class:`~fogsim.errors.InputError` naming the file.
* A scan written back in its own format is bit-identical (the raw intensities are kept; the ring, a
  whole number, round-trips through float32). Written in another format, intensities go through the
  normalised value (``0-255`` raw = normalised × 255, …); a 5-column format needs rings.
* PLY: fogsim writes binary little-endian with ``comment fogsim intensity_scale <scale>``; reading,
  that comment (else the caller's ``scale``, else ``0-1``) gives the scale; a file without
  ``intensity`` reads as intensity 0. ``plyfile`` writes (see docs/dependencies.md); reading takes the
  vertex element alone, bounded (:mod:`fogsim.lidar.ply`: plyfile reads every element whole).
* ``.npy``: float32 layouts round-trip bit for bit; float64 is read and converted to float32; a
  structured array is written back as plain float32 N×k. Pickled (object) files are refused.
* Reading is bounded (:mod:`fogsim.lidar.bounds`): the points a file declares — a ``.bin``'s size over its
  record, a ``.npy``'s header shape, a PLY's ``element vertex`` count — are checked against the file's size
  (a header that claims more than the file holds is refused naming the header), against
  :func:`~fogsim.lidar.bounds.max_scan_points` and, by bytes, a record against
  :func:`~fogsim.lidar.bounds.check_record` (a ``.npy`` field of 100 MB) *before* the body is read, so a
  sparse 16 GB file or a lying header costs a ``stat`` and a few kilobytes.
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
from fogsim.lidar.ply import read_ply_vertices
from fogsim.lidar.points import PointCloud
from fogsim.lidar.scales import scale as scale_named
from fogsim.schema.lidar import SCALES

__all__ = ["FORMATS", "FORMAT_SCALE", "FORMAT_SUFFIX", "detect_format", "read_points", "write_points", "encode_points"]

FORMATS = ("kitti", "nuscenes", "stf", "ply", "npy")
#: the intensity scale each binary format stores (PLY and .npy: the file's comment or the caller's)
FORMAT_SCALE = {"kitti": "0-1", "nuscenes": "0-255", "stf": "0-255"}
COLUMNS = {"kitti": 4, "nuscenes": 5, "stf": 5}
#: the file-name ending of each format (what a folder of scans is searched for, what fogged levels are named)
FORMAT_SUFFIX = {"kitti": ".bin", "nuscenes": ".pcd.bin", "stf": ".bin", "ply": ".ply", "npy": ".npy"}
PLY_SCALE_COMMENT = "fogsim intensity_scale"


def detect_format(path: str | os.PathLike) -> str:
    """The format a file name implies: ``.pcd.bin`` nuScenes, ``.ply``, ``.npy``; a bare ``.bin``
    (KITTI's 4 columns or STF's 5) is ambiguous: a ValueError asks for the format."""
    name = Path(path).name.lower()
    if name.endswith(".pcd.bin"):
        return "nuscenes"
    if name.endswith(".ply"):
        return "ply"
    if name.endswith(".npy"):
        return "npy"
    if name.endswith(".bin"):
        raise ValueError(f"{path}: a .bin scan is KITTI (4 float32 per point) or STF (5): say which format "
                         f"({', '.join(FORMATS)})")
    raise ValueError(f"{path}: unknown point-cloud file type (formats: {', '.join(FORMATS)})")


def _check_format(fmt: str) -> str:
    if fmt not in FORMATS:
        raise ValueError(f"unknown point-cloud format {fmt!r} (known: {', '.join(FORMATS)})")
    return fmt


def _read_exactly(path: Path, offset: int, count: int) -> bytes:
    """``count`` bytes of ``path`` from ``offset`` (already checked against the bound and the file's size)."""
    try:
        with open(path, "rb") as f:
            f.seek(offset)
            data = f.read(count)
    except IsADirectoryError:
        raise InputError(path, "is a folder, not a point-cloud file") from None
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror or exc})") from None
    if len(data) != count:
        raise InputError(path, f"ended after {len(data):,} of {count:,} bytes while it was read (changed meanwhile?)")
    return data


# ----------------------------------------------------------------------------- reading
def read_points(path: str | os.PathLike, fmt: str | None = None, scale: str | None = None, *,
                allow_empty: bool = False) -> PointCloud:
    """The scan in ``path`` (``fmt`` one of :data:`FORMATS`; None: from the name, see
    :func:`detect_format`). ``scale`` declares the intensity scale: for the binary formats it must
    match theirs (or be None); for PLY it is used when the file does not say; for ``.npy`` it is the
    scale of its intensity column (default ``0-1``). ``allow_empty``: a scan of no points is read (fogsim's
    own outputs: a sweep that saw nothing) rather than refused (an input to fog)."""
    path = Path(path)
    fmt = _check_format(fmt or detect_format(path))
    if scale is not None and scale not in SCALES:
        raise ValueError(f"unknown intensity scale {scale!r} (known: {', '.join(SCALES)})")
    if fmt in COLUMNS:
        if scale is not None and scale != FORMAT_SCALE[fmt]:
            raise ValueError(f"{fmt} scans store intensities on the {FORMAT_SCALE[fmt]} scale, not {scale}")
        return _read_bin(path, fmt, allow_empty)
    if fmt == "ply":
        return _read_ply(path, scale, allow_empty)
    return _read_npy(path, scale or "0-1", allow_empty)


def _read_bin(path: Path, fmt: str, allow_empty: bool = False) -> PointCloud:
    size = file_size(path)
    k = COLUMNS[fmt]
    record = 4 * k
    check_point_count(path, size // record, size, f"{fmt} scan")
    if size % record:
        raise InputError(path, f"size {size} bytes is not a whole number of {record}-byte {fmt} records "
                               f"({k} float32 per point): truncated, or another format")
    a = np.frombuffer(_read_exactly(path, 0, size), "<f4").reshape(-1, k)
    ring = a[:, 4] if k == 5 else None
    if ring is not None and not np.isfinite(ring).all():
        raise InputError(path, "ring column holds NaN or infinite values")
    return PointCloud.from_raw(a[:, :3], a[:, 3], FORMAT_SCALE[fmt], str(path), ring=ring, allow_empty=allow_empty)


def _read_npy(path: Path, scale: str, allow_empty: bool = False) -> PointCloud:
    size = file_size(path)

    def check(dtype: np.dtype, shape: tuple[int, ...]) -> None:
        if dtype.names:
            if len(shape) != 1:
                raise InputError(path, f"a structured point array must be 1-D (one record per point), got shape "
                                       f"{list(shape)}")
            check_npy_fields(path, dtype, ("x", "y", "z", "intensity", "ring", "return_index"))
        elif len(shape) != 2 or shape[1] not in (3, 4, 5) or dtype.kind not in "fiu":
            raise InputError(path, f"expected a numeric N×3, N×4 or N×5 array (x y z [intensity [ring]]) or a "
                                   f"structured array, got {dtype} {list(shape)}")
        check_point_count(path, shape[0], size, ".npy header declares a scan")
        record = dtype.itemsize * (1 if dtype.names else shape[1])
        check_record(path, record, shape[0], "a .npy point record", npy_widest(dtype))

    a = read_npy(path, check)
    if a.dtype.names:
        names = set(a.dtype.names)
        if not {"x", "y", "z"} <= names:
            raise InputError(path, f"structured array needs fields x, y, z (has {', '.join(a.dtype.names)})")
        xyz = np.stack([a["x"], a["y"], a["z"]], 1)
        inten = a["intensity"] if "intensity" in names else np.zeros(len(a), np.float32)
        ring = a["ring"] if "ring" in names else None
        ret = a["return_index"] if "return_index" in names else None
    else:
        xyz = a[:, :3]
        inten = a[:, 3] if a.shape[1] > 3 else np.zeros(len(a), np.float32)
        ring = a[:, 4] if a.shape[1] > 4 else None
        ret = None
    if ring is not None and not np.isfinite(np.asarray(ring, np.float64)).all():
        raise InputError(path, "ring column holds NaN or infinite values")
    return PointCloud.from_raw(xyz, inten, scale, str(path), ring=ring, return_index=ret, allow_empty=allow_empty)


def npy_widest(dtype: np.dtype) -> str:
    """What makes a structured ``.npy`` record large: its widest field (``field pad: |V100000000``)."""
    if not dtype.names:
        return ""
    name = max(dtype.names, key=lambda n: dtype[n].itemsize)
    return f"field {name}: {dtype[name].str if not dtype[name].shape else dtype[name]}"


def check_npy_fields(path, dtype: np.dtype, used: tuple[str, ...]) -> None:
    """The fields of a structured ``.npy`` that fogsim reads (``used``) are single numbers (not a sub-array,
    not text or bytes): an :class:`InputError` naming the field otherwise, from the header alone."""
    for name in used:
        if name not in dtype.names:
            continue
        sub = dtype[name]
        if sub.shape:
            raise InputError(path, f"field {name} is a sub-array of shape {sub.shape}: a point's {name} must be one "
                                   "number")
        if sub.kind not in "fiub":
            raise InputError(path, f"field {name} is {sub} (not a number): a point's {name} must be one number")


def _read_ply(path: Path, scale: str | None, allow_empty: bool = False) -> PointCloud:
    v, comments = read_ply_vertices(path)  # the vertex element alone, bounded (fogsim.lidar.ply)
    names = set(v.dtype.names or ())
    if not {"x", "y", "z"} <= names:
        raise InputError(path, f"PLY vertices need x, y, z (have {', '.join(sorted(names))})")
    said = next((c[len(PLY_SCALE_COMMENT):].strip() for c in comments if c.startswith(PLY_SCALE_COMMENT)), None)
    if said is not None and said not in SCALES:
        raise InputError(path, f"PLY comment names an unknown intensity scale {said!r} (known: {', '.join(SCALES)})")
    if said is not None and scale is not None and said != scale:
        raise InputError(path, f"PLY file says its intensity scale is {said}, not the declared {scale}")
    xyz = np.stack([v["x"], v["y"], v["z"]], 1)
    inten = v["intensity"] if "intensity" in names else np.zeros(len(v), np.float32)
    ring = v["ring"] if "ring" in names else None
    ret = v["return_index"] if "return_index" in names else None
    if ring is not None and not np.isfinite(np.asarray(ring, np.float64)).all():
        raise InputError(path, "ring property holds NaN or infinite values")
    return PointCloud.from_raw(xyz, inten, said or scale or "0-1", str(path), ring=ring, return_index=ret,
                               allow_empty=allow_empty)


# ----------------------------------------------------------------------------- writing
def _raw_for(cloud: PointCloud, target_scale: str) -> np.ndarray:
    """The cloud's intensities as ``target_scale`` stores them (its own raw values when it is its scale)."""
    if cloud.scale == target_scale:
        return cloud.raw_intensity
    sc = scale_named(target_scale)
    return sc.from_linear(sc.to_linear(cloud.intensity))[1]


def encode_points(cloud: PointCloud, fmt: str) -> bytes:
    """The bytes of ``cloud`` in ``fmt`` (what :func:`write_points` writes)."""
    fmt = _check_format(fmt)
    if fmt in COLUMNS:
        cols = [cloud.xyz.astype("<f4"), _raw_for(cloud, FORMAT_SCALE[fmt]).astype("<f4")[:, None]]
        if COLUMNS[fmt] == 5:
            if cloud.ring is None:
                raise ValueError(f"{cloud.source}: the {fmt} format stores a ring per point and this scan has "
                                 "none (estimate them with PointCloud.estimated_rings)")
            cols.append(cloud.ring.astype("<f4")[:, None])
        return np.ascontiguousarray(np.hstack(cols)).tobytes()
    if fmt == "npy":
        cols = [cloud.xyz.astype(np.float32), cloud.raw_intensity.astype(np.float32)[:, None]]
        if cloud.ring is not None:
            cols.append(cloud.ring.astype(np.float32)[:, None])
        buf = io.BytesIO()
        np.save(buf, np.ascontiguousarray(np.hstack(cols)), allow_pickle=False)
        return buf.getvalue()
    from plyfile import PlyData, PlyElement

    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")]
    if cloud.ring is not None:
        fields.append(("ring", "<i2"))
    if cloud.return_index is not None:
        fields.append(("return_index", "i1"))
    v = np.empty(len(cloud), fields)
    v["x"], v["y"], v["z"] = cloud.xyz[:, 0], cloud.xyz[:, 1], cloud.xyz[:, 2]
    v["intensity"] = cloud.raw_intensity
    if cloud.ring is not None:
        v["ring"] = cloud.ring
    if cloud.return_index is not None:
        v["return_index"] = cloud.return_index
    buf = io.BytesIO()
    PlyData([PlyElement.describe(v, "vertex")], byte_order="<",
            comments=[f"{PLY_SCALE_COMMENT} {cloud.scale}"]).write(buf)
    return buf.getvalue()


def write_points(path: str | os.PathLike, cloud: PointCloud, fmt: str | None = None) -> None:
    """Write ``cloud`` to ``path`` in ``fmt`` (None: from the name), atomically (temporary file + rename)."""
    fmt = _check_format(fmt or detect_format(path))
    atomic_write_bytes(path, encode_points(cloud, fmt))
