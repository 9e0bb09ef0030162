"""Waymo ``MatrixFloat`` / ``MatrixInt32`` protos (WOD ``dataset.proto``) ↔ numpy arrays.

A matrix message is ``data`` (field 1: packed little-endian float32, or int32 varints) and
``shape`` (field 2: a ``MatrixShape`` whose ``dims``, field 1, are varints), usually
zlib-compressed as the v1 ``*_compressed`` range-image fields store it. Varints are decoded
vectorised with numpy (no per-value Python loop); negative int32 values are 10-byte
sign-extended varints (two's complement). Malformed input → :class:`fogsim.errors.InputError`
naming ``source``.

Public API: :func:`decode_matrix`, :func:`encode_matrix` (its inverse, for fixtures and the benchmark),
and the packed-varint codecs they are built on (:func:`decode_varints`, :func:`decode_varints_int32`,
:func:`encode_varints`).
"""
from __future__ import annotations

import struct
import zlib

import numpy as np

from fogsim.errors import InputError
from fogsim.readers.waymo import protobuf_wire as pw

#: field numbers of MatrixFloat / MatrixInt32 (data, shape) and MatrixShape (dims)
MATRIX_DATA, MATRIX_SHAPE, SHAPE_DIMS = 1, 2, 1


def _varint_spans(buf: np.ndarray, source: str) -> tuple[np.ndarray, np.ndarray]:
    """Start offset and byte length of every varint in a packed run (a byte < 0x80 ends one)."""
    ends = np.flatnonzero(buf < 0x80)
    if ends.size == 0 or ends[-1] != buf.size - 1:
        raise InputError(source, "malformed matrix (truncated varint)")
    starts = np.empty_like(ends)
    starts[0], starts[1:] = 0, ends[:-1] + 1
    return starts, ends - starts + 1


def decode_varints(buf: np.ndarray, source: str) -> np.ndarray:
    """Decode a packed run of base-128 varints (uint8 array) into int64 (two's complement)."""
    if buf.size == 0:
        return np.zeros(0, np.int64)
    if not (buf & 0x80).any():
        return buf.astype(np.int64)
    starts, lengths = _varint_spans(buf, source)
    if lengths.max() > 10:
        raise InputError(source, "malformed matrix (overlong varint)")
    values = (buf[starts] & 0x7F).astype(np.uint64)
    longer = np.flatnonzero(lengths > 1)  # byte k of the values longer than k, k = 1 … 9
    for k in range(1, int(lengths.max())):
        values[longer] |= (buf[starts[longer] + k] & 0x7F).astype(np.uint64) << np.uint64(7 * k)
        longer = longer[lengths[longer] > k + 1]
    return values.view(np.int64)


def decode_varints_int32(buf: np.ndarray, source: str) -> np.ndarray:
    """Packed int32 varints → int32, faster than :func:`decode_varints`: a valid int32 is 1–5 bytes
    (0 … 2³¹−1) or exactly 10 (negative, sign-extended to 64 bits), and its 32 bits are the low
    bits of its first 5 bytes; anything else (6–9 bytes, a 5-byte value ≥ 2³¹, a 10-byte one
    that is not a sign-extended int32) is refused as out of the int32 range."""
    if buf.size == 0 or not (buf & 0x80).any():
        return buf.astype(np.int32)
    starts, lengths = _varint_spans(buf, source)
    values = (buf[starts] & 0x7F).astype(np.uint32)
    longer = np.flatnonzero(lengths > 1)
    for k in range(1, 5):
        if not longer.size:
            break
        values[longer] |= (buf[starts[longer] + k] & 0x7F).astype(np.uint32) << np.uint32(7 * k)
        longer = longer[lengths[longer] > k + 1]
    five, ten = np.flatnonzero(lengths == 5), np.flatnonzero(lengths == 10)
    ok = ((lengths <= 5) | (lengths == 10)).all() and not (buf[starts[five] + 4] & 0x78).any()
    if ok and ten.size:
        tail = buf[starts[ten, None] + np.arange(4, 10)]
        # byte 4: continuation + bits 31–34 set (0xF8); bytes 5–8: 0xFF; byte 9: 0x01
        ok = bool(((tail[:, 0] & 0xF8) == 0xF8).all() and (tail[:, 1:5] == 0xFF).all() and (tail[:, 5] == 1).all())
    if not ok:
        raise InputError(source, "malformed MatrixInt32 (value out of the int32 range)")
    return values.view(np.int32)


def _ints(values: list, source: str) -> np.ndarray:
    """A repeated int field's entries (packed blobs and/or unpacked varints) as int64."""
    out = []
    for v in values:
        if isinstance(v, memoryview):
            out.append(decode_varints(np.frombuffer(v, np.uint8), source))
        elif isinstance(v, int):
            out.append(np.array([v], np.uint64).view(np.int64))
        else:
            raise InputError(source, "malformed matrix (integer field with a fixed-size wire type)")
    return np.concatenate(out) if out else np.zeros(0, np.int64)


#: the largest range image (beams × columns) a matrix may hold, far above any Waymo lidar (TOP:
#: 64 × 2650, the others 200 × 600); with the channels (≤ 6) and the bytes a value takes
#: (float32: 4; an int32 varint: ≤ 10) it bounds what a compressed matrix may inflate to, so a
#: zlib bomb is refused before it is inflated (:func:`decode_matrix`)
MAX_BEAMS, MAX_COLUMNS, MAX_CHANNELS = 256, 8192, 6
MAX_BYTES = {"float": MAX_BEAMS * MAX_COLUMNS * MAX_CHANNELS * 4, "int32": MAX_BEAMS * MAX_COLUMNS * MAX_CHANNELS * 10}
_SHAPE_SLACK = 1024  # the shape message and field tags beside the values


def _bounded_inflate(data: bytes, kind: str, source: str) -> bytes:
    """zlib-inflate a matrix message, refusing one whose values field declares (or whose stream
    inflates to) more than :data:`MAX_BYTES` allows: memory stays bounded whatever the stream."""
    limit = MAX_BYTES.get(kind, MAX_BYTES["int32"]) + _SHAPE_SLACK
    d = zlib.decompressobj()
    try:
        head = d.decompress(data, 16)
        if head[:1] == b"\x0a":  # field 1 (the values), length-delimited: its declared size comes first
            size, pos = 0, 1
            for shift in range(0, 70, 7):
                if pos >= len(head):
                    break
                byte = head[pos]
                size |= (byte & 0x7F) << shift
                pos += 1
                if byte < 0x80:
                    if size > limit:
                        raise InputError(source, f"malformed matrix: its values field declares {size:,} bytes, more "
                                                 f"than a range image holds (≤ {MAX_BEAMS} beams × {MAX_COLUMNS} "
                                                 f"columns × {MAX_CHANNELS} channels: {limit:,} bytes); not inflated")
                    break
        chunks, size = [head], len(head)
        while not d.eof and size <= limit:  # 1 MiB at a time: the refusal costs ≤ limit
            chunk = d.decompress(d.unconsumed_tail, 1 << 20)
            if not chunk and not d.unconsumed_tail:
                break  # input used up before the end of the stream: truncated
            chunks.append(chunk)
            size += len(chunk)
    except zlib.error as exc:
        raise InputError(source, f"corrupt zlib data ({exc})") from None
    if size > limit:
        raise InputError(source, f"malformed matrix: it inflates to more than {limit:,} bytes, more than a range "
                                 f"image holds (≤ {MAX_BEAMS} beams × {MAX_COLUMNS} columns × {MAX_CHANNELS} "
                                 "channels); inflation stopped there")
    if not d.eof:
        raise InputError(source, "corrupt zlib data (incomplete or truncated stream)")
    return b"".join(chunks)


def decode_matrix(data: bytes, kind: str, source: str, compressed: bool = True) -> np.ndarray:
    """A serialized ``MatrixFloat`` (``kind="float"``) or ``MatrixInt32`` (``"int32"``) as an array.

    ``data`` is zlib-compressed unless ``compressed`` is false. MatrixFloat data is packed
    little-endian float32 (unpacked fixed32 entries are accepted too); MatrixInt32 data is
    varints, packed or not, negative values as 10-byte sign-extended varints. ``shape.dims``
    may be packed or unpacked. Returns float32 or int32 of that shape (read-only for floats).
    Corrupt zlib, malformed protobuf, a size/shape mismatch or a matrix larger than any range
    image (:data:`MAX_BYTES`, checked before inflating) → :class:`InputError` (``source``).
    """
    if compressed:
        data = _bounded_inflate(data, kind, source)
    fields = pw.decode_fields(data, source)
    shape = pw.submessage(fields, MATRIX_SHAPE, source)
    dims = tuple(int(d) for d in _ints(shape.get(SHAPE_DIMS, []), source))
    entries = fields.get(MATRIX_DATA, [])
    if kind == "float":
        chunks = []
        for v in entries:
            if isinstance(v, int) or (isinstance(v, bytes) and len(v) != 4) or len(v) % 4:
                raise InputError(source, "malformed MatrixFloat (data is not float32)")
            chunks.append(np.frombuffer(v, "<f4"))
        values = np.concatenate(chunks).astype(np.float32, copy=False) if chunks else np.zeros(0, np.float32)
    elif kind == "int32":
        if len(entries) == 1 and isinstance(entries[0], memoryview):  # packed: the usual case
            values = decode_varints_int32(np.frombuffer(entries[0], np.uint8), source)
        else:
            wide = _ints(entries, source)
            if wide.size and (wide.min() < -(1 << 31) or wide.max() >= 1 << 31):
                raise InputError(source, "malformed MatrixInt32 (value out of the int32 range)")
            values = wide.astype(np.int32)
    else:
        raise ValueError(f"matrix kind must be 'float' or 'int32', not {kind!r}")
    if not dims or any(d < 0 for d in dims) or int(np.prod(dims)) != values.size:
        raise InputError(source, f"malformed matrix: shape {list(dims)} does not hold its "
                                 f"{values.size} values")
    return values.reshape(dims)


def encode_varints(values: np.ndarray) -> bytes:
    """Packed varints of int64 ``values`` (negative → 10-byte two's complement), vectorised."""
    v = np.asarray(values, np.int64).ravel().view(np.uint64)
    nbytes = np.ones(v.size, np.int64)
    for k in range(1, 10):
        nbytes += v >= np.uint64(1) << np.uint64(7 * k)
    k = np.arange(10, dtype=np.uint64)
    out = ((v[:, None] >> (k * np.uint64(7))) & np.uint64(0x7F)).astype(np.uint8)
    out[np.arange(10)[None, :] < (nbytes[:, None] - 1)] |= 0x80
    return out[np.arange(10)[None, :] < nbytes[:, None]].tobytes()


def encode_matrix(array: np.ndarray, *, packed_shape: bool = True, packed_data: bool = True,
                  compress: bool = True) -> bytes:
    """Serialize ``array`` as MatrixFloat (float dtypes, as float32) or MatrixInt32 (integer
    dtypes), optionally zlib-compressed: the inverse of :func:`decode_matrix`, for fixtures and
    the benchmark. ``packed_shape`` / ``packed_data`` choose the two legal encodings of the
    repeated fields (unpacked float data = one fixed32 entry per value)."""
    a = np.asarray(array)
    dims = np.array(a.shape, np.int64)
    if packed_shape:
        shape = pw.bytes_field(SHAPE_DIMS, encode_varints(dims))
    else:
        shape = b"".join(pw.varint_field(SHAPE_DIMS, int(d)) for d in dims)
    if np.issubdtype(a.dtype, np.floating):
        flat = a.astype("<f4").ravel()
        data = (pw.bytes_field(MATRIX_DATA, flat.tobytes()) if packed_data else
                b"".join(b"\x0d" + struct.pack("<f", x) for x in flat))  # tag 1, wire type 5
    else:
        flat = a.astype(np.int64).ravel()
        data = (pw.bytes_field(MATRIX_DATA, encode_varints(flat)) if packed_data else
                b"".join(pw.varint_field(MATRIX_DATA, int(x)) for x in flat))
    message = data + pw.bytes_field(MATRIX_SHAPE, shape)
    return zlib.compress(message, 6) if compress else message
