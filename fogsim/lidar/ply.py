"""Reading a PLY point cloud's vertex element, in bounded memory (writing: :mod:`fogsim.lidar.formats`,
through ``plyfile``).

PLY (Greg Turk's format): an ASCII header — ``ply``, ``format ascii|binary_little_endian|binary_big_endian
1.0``, ``comment …`` lines, then per element ``element NAME COUNT`` and its ``property TYPE NAME`` (or
``property list COUNT_TYPE ITEM_TYPE NAME``) lines, ``end_header`` — then each element's rows in the order
declared: packed records (binary) or one line of numbers per row (ASCII).

Only the vertex element is read: its bytes (binary) found past the fixed-size elements before it, or its
lines (ASCII) read a chunk at a time past the rows before it; whatever follows it (a mesh's faces, another
element) is never read. Before anything is read, every element's row count is checked against the point
bound, the vertex record against :func:`fogsim.lidar.bounds.check_record`, and the bytes the declared rows
take at the least against the file's size. An ASCII line longer than its numbers may take is refused as
soon as it is seen, so a body of NULs without a newline is never held.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsim.errors import InputError
from fogsim.lidar.bounds import check_point_count, check_record, file_size, max_scan_points

__all__ = ["MAX_HEADER_BYTES", "PLY_TYPES", "PlyHeader", "ply_header", "read_ply_vertices"]

#: the most bytes a PLY header (up to ``end_header``) may take before it is refused
MAX_HEADER_BYTES = 64 * 1024
#: the NumPy type of each PLY scalar type (``char``/``int8`` … ``double``/``float64``)
PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
             "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
             "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
#: the longest text one ASCII value may take (a line may take this × its values)
ASCII_CHARS_PER_VALUE = 48
#: the longest list an ASCII line is allowed for, per list property (a face's vertex indices)
ASCII_LIST_ITEMS = 256
ASCII_CHUNK_BYTES = 1 << 20


@dataclass(frozen=True)
class PlyHeader:
    """A parsed PLY header: ``fmt``, ``elements`` [(name, count, [property words…])…], ``comments`` and the
    body's ``offset`` (bytes from the file's start)."""

    fmt: str
    elements: list
    comments: list
    offset: int

    def index(self, name: str) -> int | None:
        return next((i for i, (n, _, _) in enumerate(self.elements) if n == name), None)


def ply_header(path: Path) -> PlyHeader:
    """The header of the PLY file ``path``, from at most :data:`MAX_HEADER_BYTES` (an :class:`InputError`
    naming the header when it is not one)."""
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_HEADER_BYTES)
    except IsADirectoryError:
        raise InputError(path, "is a folder, not a point-cloud file") from None
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror or exc})") from None
    if not raw.startswith(b"ply"):
        raise InputError(path, "not a readable PLY file (it does not start with 'ply')")
    end = raw.find(b"end_header")
    stop = raw.find(b"\n", end) if end >= 0 else -1
    if stop < 0:
        raise InputError(path, f"not a readable PLY file (no end_header line in its first {len(raw):,} bytes)")
    fmt, elements, comments = None, [], []
    for line in raw[:end].decode("ascii", "replace").splitlines()[1:]:
        words = line.split()
        if not words or words[0] == "obj_info":
            continue
        if words[0] == "comment":
            comments.append(line.strip()[len("comment"):].strip())
            continue
        try:
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                count = int(words[2])
                if count < 0:
                    raise ValueError(f"negative count {count}")
                elements.append((words[1], count, []))
            elif words[0] == "property" and elements:
                prop = tuple(words[1:])
                types = prop[1:3] if prop[0] == "list" else prop[:1]
                if len(prop) < (4 if prop[0] == "list" else 2) or any(t not in PLY_TYPES for t in types):
                    raise ValueError(f"property line {line.strip()[:60]!r}")
                elements[-1][2].append(prop)
            else:
                raise ValueError(f"unexpected line {line.strip()[:60]!r}")
        except (IndexError, ValueError) as exc:
            raise InputError(path, f"PLY header is malformed ({exc})") from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise InputError(path, f"PLY header names no known format (got {fmt!r})")
    return PlyHeader(fmt, elements, comments, stop + 1)


def _row_bytes(props, fmt: str) -> int:
    """The fewest bytes one row takes (a list: its count alone; ASCII: a digit and a space a value)."""
    if fmt == "ascii":
        return 2 * len(props)
    return sum(np.dtype(PLY_TYPES[p[1] if p[0] == "list" else p[0]]).itemsize for p in props)


def _vertex_dtype(path, props, fmt: str) -> np.dtype:
    if any(p[0] == "list" for p in props):
        name = next(p[-1] for p in props if p[0] == "list")
        raise InputError(path, f"PLY vertex property {name} is a list: a point's values are single numbers")
    order = ">" if fmt == "binary_big_endian" else "<"
    names = [p[1] for p in props]
    if len(set(names)) != len(names):
        raise InputError(path, "PLY vertex element names a property twice")
    return np.dtype([(p[1], order + PLY_TYPES[p[0]]) for p in props])


def read_ply_vertices(path: str | os.PathLike) -> tuple[np.ndarray, list[str]]:
    """(the vertex element as a structured array, the header's comments) of the PLY file ``path``, in
    bounded memory (the module docstring)."""
    path = Path(path)
    size = file_size(path)
    head = ply_header(path)
    at = head.index("vertex")
    if at is None:
        raise InputError(path, "PLY file has no vertex element")
    bound = max_scan_points()
    for name, count, _ in head.elements:
        if name != "vertex" and count > bound:
            raise InputError(path, f"PLY element {name} of {count:,} rows exceeds the bound of {bound:,} rows per "
                                   "element (fogsim reads the vertex element alone)")
    vertex, props = head.elements[at][1], head.elements[at][2]
    need = sum(count * _row_bytes(p, head.fmt) for _, count, p in head.elements)
    body = size - head.offset
    if need > body:
        raise InputError(path, f"PLY header claims {vertex:,} points (element vertex; at least {need:,} bytes of "
                               f"{head.fmt} data) but the file holds only {body:,} bytes after its header: "
                               "truncated, or the header lies")
    check_point_count(path, vertex, size, "PLY header declares a scan")
    dtype = _vertex_dtype(path, props, head.fmt)
    check_record(path, dtype.itemsize, vertex, "a PLY vertex record")
    if head.fmt == "ascii":
        return _ascii_vertices(path, head, at, dtype), head.comments
    skip = 0
    for name, count, p in head.elements[:at]:
        if any(w[0] == "list" for w in p):
            raise InputError(path, f"PLY element {name} comes before the vertex element and has a list property: "
                                   "its size is not known from the header (write the vertex element first)")
        skip += count * _row_bytes(p, head.fmt)
    data = bytearray(vertex * dtype.itemsize)
    with open(path, "rb") as f:
        f.seek(head.offset + skip)
        if f.readinto(data) != len(data):
            raise InputError(path, f"ended before its {vertex:,} vertices ({len(data):,} bytes): truncated")
    return np.frombuffer(data, dtype), head.comments


def _longest_line(props) -> int:
    return ASCII_CHARS_PER_VALUE * sum(1 + ASCII_LIST_ITEMS if p[0] == "list" else 1 for p in props)


def _ascii_vertices(path: Path, head: PlyHeader, at: int, dtype: np.dtype) -> np.ndarray:
    """The vertex rows of an ASCII body: the rows before them skipped, theirs parsed a chunk at a time."""
    before = sum(count for _, count, _ in head.elements[:at])
    vertex = head.elements[at][1]
    limits = [(count, _longest_line(p)) for _, count, p in head.elements[:at + 1]]
    longest = max(line for _, line in limits)
    out = np.zeros(vertex, dtype)
    names = dtype.names
    row, done, rest = 0, 0, b""
    with open(path, "rb") as f:
        f.seek(head.offset)
        while done < vertex:
            chunk = f.read(ASCII_CHUNK_BYTES)
            data = rest + chunk
            lines = data.split(b"\n")
            rest = lines.pop() if chunk else b""
            rows = []
            for line in lines:
                if row >= before + vertex:
                    break  # what follows the vertices is never read
                if len(line) > _limit(limits, row):
                    raise InputError(path, f"PLY ASCII line {row + 1:,} is longer than the {_limit(limits, row):,} "
                                           "characters its values may take: the file is not an ASCII PLY")
                words = line.split()
                if not words:
                    continue
                if row >= before:
                    if len(words) != len(names):
                        raise InputError(path, f"PLY ASCII vertex {done + len(rows) + 1:,} has {len(words)} values, "
                                               f"the header declares {len(names)}")
                    rows.append(words)
                row += 1
            if row < before + vertex and len(rest) > longest:
                raise InputError(path, f"PLY ASCII line {row + 1:,} is longer than the {longest:,} characters its "
                                       "values may take: the file is not an ASCII PLY")
            if rows:
                try:
                    table = np.array(rows).astype(np.float64)
                except ValueError:
                    raise InputError(path, f"PLY ASCII vertices {done + 1:,}–{done + len(rows):,} are not all "
                                           "numbers") from None
                for j, name in enumerate(names):
                    col = table[:, j]
                    if dtype[name].kind in "iu":
                        info = np.iinfo(dtype[name])
                        if not (np.isfinite(col).all() and (col == np.round(col)).all()) or \
                                col.min() < info.min or col.max() > info.max:
                            raise InputError(path, f"PLY vertex property {name} ({dtype[name].base}) holds values "
                                                   "that are not whole numbers of its type")
                    out[name][done:done + len(rows)] = col
                done += len(rows)
            if not chunk:
                break
    if done < vertex:
        raise InputError(path, f"PLY header declares {vertex:,} vertices, the ASCII body has {done:,}")
    return out


def _limit(limits, row: int) -> int:
    """The longest line allowed for body row ``row`` (counted from 0): its element's."""
    for count, longest in limits:
        if row < count:
            return longest
        row -= count
    return limits[-1][1]
