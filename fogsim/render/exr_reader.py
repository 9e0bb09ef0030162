"""A small reader for the EXR files Blender writes: scanline, single- or multi-part, NONE/ZIPS/ZIP.

Why not the OpenEXR package here: inside Debian's Blender 3.4 process, importing it works but
reading or writing a file crashes Blender (its OpenEXR libraries clash with Blender's own). The
renderer reads its render passes with this module in every Blender; everything outside Blender
(user depth maps) still goes through the OpenEXR package (:mod:`fogsim.io`). Reference: the
"OpenEXR File Layout" document (magic 20000630, attribute headers, offset tables, chunks).
"""
from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from fogsim.errors import InputError
from fogsim.io.headers import HEADER_BYTES, exr_header

MAGIC = 20000630
_PIXEL = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}  # UINT, HALF, FLOAT
_LINES = {0: 1, 2: 1, 3: 16}  # NONE, ZIPS, ZIP: scanlines per chunk
_MULTIPART, _TILED, _DEEP = 0x1000, 0x200, 0x800


def _cstr(buf: bytes, pos: int) -> tuple[str, int]:
    end = buf.index(b"\0", pos)
    return buf[pos:end].decode("latin-1"), end + 1


def _header(buf: bytes, pos: int) -> tuple[dict, int]:
    attrs = {}
    while buf[pos] != 0:
        name, pos = _cstr(buf, pos)
        kind, pos = _cstr(buf, pos)
        (size,) = struct.unpack_from("<i", buf, pos)
        attrs[name] = (kind, buf[pos + 4:pos + 4 + size])
        pos += 4 + size
    return attrs, pos + 1


def _channels(raw: bytes) -> list[tuple[str, np.dtype]]:
    out, pos = [], 0
    while raw[pos] != 0:
        name, pos = _cstr(raw, pos)
        ptype, _, xs, ys = struct.unpack_from("<iB3xii", raw, pos)
        if (xs, ys) != (1, 1):
            raise ValueError(f"channel {name} is subsampled ({xs}×{ys}); not supported")
        out.append((name, _PIXEL[ptype]))
        pos += 16
    return out


def _undo_zip(data: bytes, expected: int) -> bytes:
    if len(data) == expected:  # stored raw when compression would not shrink it
        return data
    t = np.frombuffer(zlib.decompress(data), np.uint8).astype(np.int32)
    t[1:] -= 128
    t = (np.cumsum(t) & 0xFF).astype(np.uint8)  # undo the byte-delta predictor
    half = (t.size + 1) // 2
    out = np.empty_like(t)
    out[0::2], out[1::2] = t[:half], t[half:]  # undo the even/odd byte split
    return out.tobytes()


def _read_part(buf: bytes, attrs: dict, offsets: list[int], multipart: bool) -> dict[str, np.ndarray]:
    x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"][1])
    width, height = x1 - x0 + 1, y1 - y0 + 1
    compression = attrs["compression"][1][0]
    if compression not in _LINES:
        raise ValueError(f"compression code {compression} is not supported (use NONE, ZIPS or ZIP)")
    chans = _channels(attrs["channels"][1])
    row_bytes = sum(width * dt.itemsize for _, dt in chans)
    planes = {name: np.empty((height, width), dt) for name, dt in chans}
    for off in offsets:
        pos = off + (4 if multipart else 0)
        y, size = struct.unpack_from("<ii", buf, pos)
        rows = min(_LINES[compression], y1 - y + 1)
        data = buf[pos + 8:pos + 8 + size]
        if compression:
            data = _undo_zip(data, rows * row_bytes)
        r0, col = y - y0, 0
        block = np.frombuffer(data, np.uint8).reshape(rows, row_bytes)
        for name, dt in chans:
            n = width * dt.itemsize
            planes[name][r0:r0 + rows] = block[:, col:col + n].copy().view(dt).reshape(rows, width)
            col += n
    return planes


def _check_size(path: Path) -> None:
    """Refuse a file larger than its header's data windows and channels can take stored uncompressed
    (4 bytes a value, with each scanline's offset and chunk header), before it is read whole."""
    size = path.stat().st_size
    with open(path, "rb") as f:
        declared = exr_header(f.read(HEADER_BYTES))
    if declared is None:
        return  # not an EXR, or a header not within the prefix: the parser below names the problem
    channels = max(declared.channels, 1)
    most = declared.pixels * channels * 4 + declared.height * 24 * channels + HEADER_BYTES
    if size > most:
        raise InputError(path, f"{size:,} bytes is more than its header's {declared.width}×{declared.height} × "
                               f"{channels} channels can take ({most:,} bytes): not an EXR fogsim reads")


def read_exr(path: str | Path) -> dict[str, np.ndarray]:
    """Every channel of a scanline EXR (all parts), name → H×W array (float16/float32/uint32). The file is
    read whole only when its size fits what its header declares (:func:`_check_size`)."""
    path = Path(path)
    try:
        _check_size(path)
        buf = path.read_bytes()
    except OSError as exc:
        raise InputError(path, f"cannot read ({exc.strerror})") from None
    try:
        magic, version = struct.unpack_from("<iI", buf, 0)
        if magic != MAGIC:
            raise ValueError("not an EXR file (bad magic number)")
        if version & (_TILED | _DEEP):
            raise ValueError("tiled or deep EXR files are not supported")
        multipart, pos, headers = bool(version & _MULTIPART), 8, []
        while True:
            attrs, pos = _header(buf, pos)
            headers.append(attrs)
            if not multipart or buf[pos] == 0:
                pos += 1 if multipart else 0
                break
        channels = {}
        for attrs in headers:
            x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"][1])
            lines = _LINES.get(attrs["compression"][1][0], 1)
            count = (struct.unpack("<i", attrs["chunkCount"][1])[0] if "chunkCount" in attrs
                     else -(-(y1 - y0 + 1) // lines))
            offsets = list(struct.unpack_from(f"<{count}Q", buf, pos))
            pos += 8 * count
            channels.update(_read_part(buf, attrs, offsets, multipart))
        return channels
    except (ValueError, KeyError, IndexError, struct.error, zlib.error) as exc:
        raise InputError(path, f"not a readable EXR file ({exc})") from None
