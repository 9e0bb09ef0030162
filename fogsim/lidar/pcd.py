"""PCD files (the Point Cloud Library's format, v0.7): a structured NumPy array ↔ a ``.pcd`` file.

The one PCD codec of fogsim: LiDAR levels written for viewers (open3d, pypcd4, CloudCompare, PCL) and the
radar's nuScenes ``RADAR_*`` files go through it. Written from PCL's published file-format spec:

* an ASCII header, one ``KEY value…`` line each, in this order: ``VERSION`` (0.7), ``FIELDS`` (names),
  ``SIZE`` (bytes per element: 1, 2, 4, 8), ``TYPE`` (``I`` signed, ``U`` unsigned, ``F`` float), ``COUNT``
  (elements per field), ``WIDTH``, ``HEIGHT`` (1 for an unorganised cloud), ``VIEWPOINT`` (tx ty tz qw qx
  qy qz), ``POINTS`` (= WIDTH·HEIGHT), ``DATA`` (``ascii``, ``binary`` or ``binary_compressed``); ``#`` lines
  are comments;
* the body: ``ascii`` one point a line; ``binary`` the packed little-endian records (array of structs);
  ``binary_compressed`` two uint32 (compressed, uncompressed size) then LZF-compressed field-by-field
  columns (read when the ``lzf`` module is installed; fogsim writes ``binary`` or ``ascii``).

Reading is bounded: the header (≤ :data:`MAX_HEADER_BYTES`) is parsed first, its POINTS checked against
:func:`fogsim.lidar.bounds.check_point_count`, its record (a field of COUNT 10⁸ …) and the bytes of all
records against :func:`fogsim.lidar.bounds.check_record`, and both against what the file's size can hold —
a header that claims more points than the body holds is refused naming the header, and so is a body far
longer than its points need (a file copied whole stays bounded) — and only then is the body read: a
binary body exactly the records' bytes; a binary_compressed body its 8-byte size prefix first (checked
against the header and the file), then only the compressed bytes; an ASCII body a chunk at a time
(:data:`ASCII_CHUNK_BYTES`), each row at most :data:`ASCII_CHARS_PER_ELEMENT` characters a number.
"""
from __future__ import annotations

import io
import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fogsim.errors import InputError
from fogsim.io.atomic import atomic_write_bytes
from fogsim.lidar.bounds import check_point_count, check_record, file_size

__all__ = ["DATA_KINDS", "MAX_HEADER_BYTES", "PcdHeader", "encode_pcd", "read_pcd", "read_pcd_header", "write_pcd"]

DATA_KINDS = ("ascii", "binary", "binary_compressed")
MAX_HEADER_BYTES = 64 * 1024
KEYS = ("VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "VIEWPOINT", "POINTS", "DATA")
#: the longest text an ASCII number may take, per element (bounds an ASCII body before it is parsed)
ASCII_CHARS_PER_ELEMENT = 48
IDENTITY_VIEWPOINT = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class PcdHeader:
    """A parsed PCD header: the record's ``dtype`` (little-endian, one field per FIELDS name, a sub-array
    where COUNT > 1), ``width`` × ``height`` = ``points``, the body's encoding ``data``, the ``viewpoint``
    and ``offset`` (bytes from the file's start to the body)."""

    dtype: np.dtype
    width: int
    height: int
    points: int
    data: str
    viewpoint: tuple[float, ...]
    offset: int
    version: str = "0.7"

    @property
    def fields(self) -> tuple[str, ...]:
        return tuple(self.dtype.names)


def _code(kind: str, size: int) -> str:
    if kind == "F" and size in (4, 8):
        return f"<f{size}"
    if kind in "IU" and size in (1, 2, 4, 8):
        return f"<{'i' if kind == 'I' else 'u'}{size}"
    raise ValueError(f"TYPE {kind} with SIZE {size} is not a PCD element type")


def _parse_header(raw: bytes, source) -> PcdHeader:
    """The header at the start of ``raw`` (an :class:`InputError` naming ``source`` when it is not one)."""
    values: dict[str, list[str]] = {}
    offset = 0
    while True:
        end = raw.find(b"\n", offset)
        if end < 0:
            what = "no DATA line" + (f" in its first {MAX_HEADER_BYTES} bytes" if len(raw) >= MAX_HEADER_BYTES else "")
            raise InputError(source, f"not a PCD file ({what})")
        line = raw[offset:end].decode("ascii", "replace").strip()
        offset = end + 1
        if not line or line.startswith("#"):
            continue
        key, *rest = line.split()
        if key not in KEYS:
            raise InputError(source, f"PCD header line {line[:60]!r}: unknown key {key!r}")
        if key in values:
            raise InputError(source, f"PCD header repeats {key}")
        values[key] = rest
        if key == "DATA":
            break
    missing = [k for k in ("FIELDS", "SIZE", "TYPE", "WIDTH", "POINTS", "DATA") if k not in values]
    if missing:
        raise InputError(source, f"PCD header lacks {', '.join(missing)}")
    names = values["FIELDS"]
    counts = values.get("COUNT", ["1"] * len(names))
    if not (len(values["SIZE"]) == len(values["TYPE"]) == len(counts) == len(names)) or not names:
        raise InputError(source, f"PCD header: FIELDS ({len(names)}), SIZE ({len(values['SIZE'])}), TYPE "
                                 f"({len(values['TYPE'])}) and COUNT ({len(counts)}) must list one entry per field")
    if len(set(names)) != len(names):
        raise InputError(source, "PCD header: FIELDS names a field twice")
    try:
        sizes, counts_i = [int(s) for s in values["SIZE"]], [int(c) for c in counts]
        width, points = int(values["WIDTH"][0]), int(values["POINTS"][0])
        height = int(values.get("HEIGHT", ["1"])[0])
        viewpoint = tuple(float(v) for v in values.get("VIEWPOINT", IDENTITY_VIEWPOINT))
        fields = []
        for name, kind, size, count in zip(names, values["TYPE"], sizes, counts_i):
            if count < 1:
                raise ValueError(f"field {name}: COUNT {count} < 1")
            code = _code(kind, size)
            fields.append((name, code) if count == 1 else (name, code, (count,)))
        dtype = np.dtype(fields)
    except (ValueError, IndexError) as exc:
        raise InputError(source, f"PCD header is malformed ({exc})") from None
    if min(width, height, points) < 0 or width * height != points or len(viewpoint) != 7:
        raise InputError(source, f"PCD header is inconsistent: WIDTH {width} × HEIGHT {height} ≠ POINTS {points}"
                         if width * height != points else "PCD header: negative sizes or a VIEWPOINT not of 7 numbers")
    data = values["DATA"][0] if values["DATA"] else ""
    if data not in DATA_KINDS:
        raise InputError(source, f"PCD DATA {data!r} is not one of {', '.join(DATA_KINDS)}")
    version = values.get("VERSION", ["0.7"])[0]
    return PcdHeader(dtype, width, height, points, data, viewpoint, offset, version)


def read_pcd_header(path: str | os.PathLike) -> PcdHeader:
    """The header of the PCD file ``path`` (reads at most :data:`MAX_HEADER_BYTES`)."""
    file_size(path)
    with open(path, "rb") as f:
        return _parse_header(f.read(MAX_HEADER_BYTES), path)


def _widest(head: PcdHeader) -> str:
    """What makes a record large: its widest field (``field junk: COUNT 100,000,000 × SIZE 8``)."""
    name = max(head.fields, key=lambda n: head.dtype[n].itemsize)
    sub = head.dtype[name]
    count = int(np.prod(sub.shape or (1,)))
    return f"field {name}: COUNT {count:,} × SIZE {sub.base.itemsize}"


def read_pcd(path: str | os.PathLike) -> tuple[PcdHeader, np.ndarray]:
    """(header, records) of the PCD file ``path``: a structured array of ``header.points`` rows with the
    header's fields, in bounded memory (see the module docstring)."""
    path = Path(path)
    size = file_size(path)
    with open(path, "rb") as f:
        head = _parse_header(f.read(MAX_HEADER_BYTES), path)
        check_point_count(path, head.points, size, "PCD header declares a cloud")
        need = check_record(path, head.dtype.itemsize, head.points, "the PCD header's point record", _widest(head))
        body = size - head.offset
        f.seek(head.offset)
        if head.data == "binary":
            if need > body:
                raise InputError(path, f"PCD header declares {head.points:,} points ({need:,} bytes) but the file "
                                       f"holds {body:,} bytes after its header: truncated, or the header lies")
            if body > need + MAX_HEADER_BYTES:  # what a caller copying the file whole would read
                raise InputError(path, f"PCD binary body of {body:,} bytes is far longer than its {head.points:,} "
                                       f"points need ({need:,} bytes): the header lies or the file is not PCD")
            data = bytearray(need)
            if f.readinto(data) != need:
                raise InputError(path, "ended while it was read (changed meanwhile?)")
            array = np.frombuffer(data, head.dtype)
        elif head.data == "ascii":
            if body > max(head.points, 1) * _elements(head) * ASCII_CHARS_PER_ELEMENT:
                raise InputError(path, f"PCD ASCII body of {body:,} bytes is far longer than {head.points:,} points "
                                       "need: the header lies or the file is not PCD")
            array = _ascii_body(f, body, head, path)
        else:
            array = _compressed_body(f, body, head, path)
    return head, array


def _elements(head: PcdHeader) -> int:
    """The numbers one ASCII row holds (a field of COUNT n: n of them)."""
    return sum(int(np.prod(head.dtype[n].shape or (1,))) for n in head.fields)


#: how much of an ASCII body is read and parsed at a time
ASCII_CHUNK_BYTES = 1 << 20


def _ascii_rows(f, body: int, longest: int, source):
    """The non-blank lines of an ASCII body of ``body`` bytes, read a chunk at a time: per chunk, (the number
    of its first row, counted from 1, and each row's words); a line longer than ``longest`` characters is
    refused as soon as it is seen (a body without newlines is never held whole)."""
    left, rest, row = body, b"", 0
    while True:
        chunk = f.read(min(ASCII_CHUNK_BYTES, left)) if left > 0 else b""
        left -= len(chunk)
        data = rest + chunk
        cut = len(data) if not chunk else data.rfind(b"\n") + 1
        rest = data[cut:]
        rows = []
        for line in data[:cut].split(b"\n") + [rest]:
            if len(line) > longest:
                raise InputError(source, f"PCD ASCII row {row + len(rows) + 1:,} is longer than the {longest:,} "
                                         "characters its numbers may take: the file is not an ASCII PCD")
            if line is not rest and (words := line.split()):
                rows.append(words)
        if rows:
            yield row + 1, rows
            row += len(rows)
        if not chunk:
            return


def _ascii_body(f, body: int, head: PcdHeader, source) -> np.ndarray:
    """The records of an ASCII body, parsed a chunk at a time (memory: the records and one chunk)."""
    flat = [(name, head.dtype[name].base, int(np.prod(head.dtype[name].shape or (1,)))) for name in head.fields]
    width = _elements(head)
    out = np.zeros(head.points, head.dtype)
    done = 0
    for first, rows in _ascii_rows(f, body, width * ASCII_CHARS_PER_ELEMENT, source):
        if done + len(rows) > head.points:
            raise InputError(source, f"PCD header declares {head.points:,} points, the ASCII body has more lines")
        for i, words in enumerate(rows):
            if len(words) != width:
                raise InputError(source, f"PCD ASCII row {first + i:,} has {len(words)} numbers, the header declares "
                                         f"{width} per point")
        try:
            table = np.array(rows).astype(np.float64)
        except ValueError:
            bad = next(i for i, words in enumerate(rows) if not _numbers(words))
            raise InputError(source, f"PCD ASCII row {first + bad:,} is not numbers "
                                     f"({b' '.join(rows[bad]).decode('ascii', 'replace')[:60]!r})") from None
        col = 0
        part = out[done:done + len(rows)]
        for name, base, count in flat:
            values = table[:, col:col + count]
            if base.kind in "iu":
                if not np.isfinite(values).all() or (values != np.round(values)).any():
                    raise InputError(source, f"PCD field {name} ({base}) holds values that are not whole numbers")
                info = np.iinfo(base)
                if values.size and (values.min() < info.min or values.max() > info.max):
                    raise InputError(source, f"PCD field {name} holds values outside its type {base}")
            part[name] = values.reshape(part[name].shape).astype(base)
            col += count
        done += len(rows)
    if done != head.points:
        raise InputError(source, f"PCD header declares {head.points:,} points, the ASCII body has {done:,} lines")
    return out


def _numbers(words: list[bytes]) -> bool:
    try:
        [float(w) for w in words]
    except ValueError:
        return False
    return True


def _compressed_body(f, body: int, head: PcdHeader, source) -> np.ndarray:
    """The records of a binary_compressed body: its 8-byte size prefix checked against the header and the
    file first, then only the compressed bytes read."""
    try:
        import lzf  # python-lzf: optional, only binary_compressed files need it
    except ImportError:
        raise InputError(source, "PCD DATA binary_compressed (LZF) needs the 'python-lzf' package "
                                 "(pip install python-lzf), or save the file as DATA binary") from None
    prefix = f.read(8)
    if len(prefix) < 8:
        raise InputError(source, "PCD binary_compressed body is shorter than its 8-byte size prefix")
    compressed, uncompressed = struct.unpack("<II", prefix)
    need = head.points * head.dtype.itemsize
    if uncompressed != need or compressed > body - 8 or (need and not compressed):
        raise InputError(source, f"PCD binary_compressed sizes ({compressed:,} → {uncompressed:,} bytes) do not "
                                 f"match the header's {head.points:,} points ({need:,} bytes) or the file")
    if body - 8 - compressed > MAX_HEADER_BYTES:
        raise InputError(source, f"PCD binary_compressed body of {body:,} bytes is far longer than its "
                                 f"{compressed:,} compressed bytes: the header lies or the file is not PCD")
    raw = f.read(compressed)
    columns = lzf.decompress(raw, uncompressed) if need else b""
    if columns is None or len(columns) != need:
        raise InputError(source, "PCD binary_compressed body does not decompress to the declared size")
    out = np.zeros(head.points, head.dtype)
    start = 0
    for name in head.fields:  # field by field (structure of arrays)
        sub = head.dtype[name]
        nbytes = head.points * sub.itemsize
        out[name] = np.frombuffer(columns[start:start + nbytes], sub.base).reshape(out[name].shape)
        start += nbytes
    return out


def _element(dt: np.dtype) -> tuple[str, int]:
    base = dt.base
    if base.kind not in "fiu" or (base.kind == "f" and base.itemsize not in (4, 8)):
        raise ValueError(f"a PCD field must be a float32/64 or an integer, not {base}")
    return {"f": "F", "i": "I", "u": "U"}[base.kind], base.itemsize


def encode_pcd(records: np.ndarray, data: str = "binary", viewpoint=IDENTITY_VIEWPOINT,
               comment: str | None = None) -> bytes:
    """The bytes of a PCD v0.7 file holding ``records`` (a structured array; one PCD field per field, in
    order; an unorganised cloud, HEIGHT 1) as ``data`` ``binary`` (little-endian records) or ``ascii``."""
    if data not in ("ascii", "binary"):
        raise ValueError(f"fogsim writes PCD DATA ascii or binary, not {data!r}")
    records = np.asarray(records).reshape(-1)
    if not records.dtype.names:
        raise ValueError("encode_pcd needs a structured array (one named field per PCD field)")
    kinds = [_element(records.dtype[n]) for n in records.dtype.names]
    counts = [int(np.prod(records.dtype[n].shape or (1,))) for n in records.dtype.names]
    for name in records.dtype.names:
        if not name or any(c.isspace() for c in name):
            raise ValueError(f"PCD field name {name!r} must be one word")
    n = len(records)
    lines = ["# .PCD v0.7 - Point Cloud Data file format"] + ([f"# {comment}"] if comment else []) + [
        "VERSION 0.7",
        "FIELDS " + " ".join(records.dtype.names),
        "SIZE " + " ".join(str(s) for _, s in kinds),
        "TYPE " + " ".join(k for k, _ in kinds),
        "COUNT " + " ".join(str(c) for c in counts),
        f"WIDTH {n}", "HEIGHT 1",
        "VIEWPOINT " + " ".join(f"{float(v):g}" for v in viewpoint),
        f"POINTS {n}", f"DATA {data}"]
    header = ("\n".join(lines) + "\n").encode("ascii")
    little = np.dtype([(name, records.dtype[name].base.newbyteorder("<"), records.dtype[name].shape)
                       for name in records.dtype.names])
    packed = np.empty(n, little)
    for name in records.dtype.names:
        packed[name] = records[name]
    if data == "binary":
        return header + packed.tobytes()
    rows = []
    for name, (kind, _), count in zip(records.dtype.names, kinds, counts):
        col = packed[name].reshape(n, count)
        rows.append(col.astype(np.float64) if kind == "F" else col.astype(np.int64))
    buf = io.StringIO()
    parts = []
    for (kind, size), col in zip(kinds, rows):
        fmt = ("%.9g" if size == 4 else "%.17g") if kind == "F" else "%d"
        parts.extend([fmt] * col.shape[1])
    if n:
        np.savetxt(buf, np.hstack([c.astype(object) for c in rows]), fmt=" ".join(parts))
    return header + buf.getvalue().encode("ascii")


def write_pcd(path: str | os.PathLike, records: np.ndarray, data: str = "binary", viewpoint=IDENTITY_VIEWPOINT,
              comment: str | None = None) -> None:
    """Write ``records`` as a PCD file at ``path``, atomically (temporary file + rename)."""
    atomic_write_bytes(path, encode_pcd(records, data, viewpoint, comment))
