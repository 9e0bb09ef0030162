"""How big a scan file fogsim reads: the one bound every point-cloud reader checks *before* it allocates.

A real sweep is small — an HDL-64E scan ≈ 120 k points (≈ 2 MB as KITTI ``.bin``), a Waymo frame's
returns ≈ 180 k, a 128-beam Ouster at 2048 columns ≈ 262 k, a radar sweep a few hundred detections. A
file that declares (by its size or its header) more than :data:`MAX_SCAN_POINTS` points is refused in
one line naming the file, the size and the bound, without reading its body: a sparse 16 GB file or a
PLY header that lies costs nothing. ``FOGSIM_MAX_SCAN_POINTS`` raises (or lowers) the bound for a
user whose merged maps are larger.

Points alone do not bound the bytes: a PCD field of COUNT 10⁸ or a ``.npy`` record with a 100 MB void
field makes 5 points 4 GB. So a point's record may take at most :data:`MAX_RECORD_BYTES` (32 doubles;
a radar detection takes 43, a nuScenes LiDAR point 20), and a scan at most
:data:`SCAN_BYTES_PER_POINT` × the point bound (640 MB at the default) — both checked from the header
(:func:`check_record`) before a body is read.
"""
from __future__ import annotations

import os
from pathlib import Path

from fogsim.errors import InputError

__all__ = ["MAX_RECORD_BYTES", "MAX_SCAN_POINTS", "SCAN_BYTES_PER_POINT", "check_point_count", "check_record",
           "file_size", "max_scan_bytes", "max_scan_points"]

#: the most points one scan file may hold (≈ 80 full HDL-64E sweeps; 10 M × 5 float32 = 200 MB)
MAX_SCAN_POINTS = 10_000_000
ENV = "FOGSIM_MAX_SCAN_POINTS"
#: the most bytes one point's record may take (32 float64 fields)
MAX_RECORD_BYTES = 256
#: the bytes a scan may take per point of the bound (10 M points → 640 MB)
SCAN_BYTES_PER_POINT = 64


def max_scan_points() -> int:
    """The bound in force: ``FOGSIM_MAX_SCAN_POINTS`` when set to a positive integer, else :data:`MAX_SCAN_POINTS`."""
    text = os.environ.get(ENV, "").strip()
    if not text:
        return MAX_SCAN_POINTS
    try:
        value = int(text)
    except ValueError:
        raise InputError(ENV, f"must be a positive whole number of points, got {text!r}") from None
    if value <= 0:
        raise InputError(ENV, f"must be a positive whole number of points, got {value}")
    return value


def file_size(path: str | os.PathLike) -> int:
    """The size in bytes of a file about to be read (an :class:`InputError` naming it when missing or a folder)."""
    path = Path(path)
    try:
        st = path.stat()
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror or exc})") from None
    if path.is_dir():
        raise InputError(path, "is a folder, not a point-cloud file")
    return st.st_size


def check_point_count(path: str | os.PathLike, points: int, size_bytes: int | None = None,
                      what: str = "scan") -> int:
    """``points`` when within the bound, else an :class:`InputError` naming the file, its size and the bound."""
    bound = max_scan_points()
    if points > bound:
        size = f"{size_bytes:,} bytes, " if size_bytes is not None else ""
        raise InputError(path, f"{what} of {size}{points:,} points exceeds the bound of {bound:,} points per scan "
                               f"(a real sweep has ≈ 10⁵; raise it with {ENV} if this file is meant to be read)")
    return points


def max_scan_bytes() -> int:
    """The most bytes one scan's records may take: :data:`SCAN_BYTES_PER_POINT` × :func:`max_scan_points`."""
    return SCAN_BYTES_PER_POINT * max_scan_points()


def check_record(path: str | os.PathLike, record_bytes: int, points: int, what: str = "a point's record",
                 why: str = "") -> int:
    """``points`` × ``record_bytes`` (the bytes the records take) when a record takes at most
    :data:`MAX_RECORD_BYTES` and the scan at most :func:`max_scan_bytes`; else an :class:`InputError` naming
    the file (``what`` names the record, ``why`` says what makes it so large)."""
    why = f" ({why})" if why else ""
    if record_bytes > MAX_RECORD_BYTES:
        raise InputError(path, f"{what} takes {record_bytes:,} bytes{why}, more than the {MAX_RECORD_BYTES} "
                               "bytes a point's record may take: refused before reading the body")
    total = points * record_bytes
    if total > max_scan_bytes():
        raise InputError(path, f"{points:,} points × {record_bytes:,} bytes = {total:,} bytes exceeds the bound "
                               f"of {max_scan_bytes():,} bytes per scan ({SCAN_BYTES_PER_POINT} bytes per point of "
                               f"the {max_scan_points():,}-point bound; raise it with {ENV})")
    return total
