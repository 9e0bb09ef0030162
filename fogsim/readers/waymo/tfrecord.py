"""TFRecord files without TensorFlow: index, read and write records.

Framing of each record (all integers little endian)::

    uint64 length | uint32 masked_crc32c(length bytes) | data[length] | uint32 masked_crc32c(data)

with ``masked_crc = ((crc >> 15) | (crc << 17)) + 0xa282ead8 (mod 2**32)`` and CRC32C the
Castagnoli CRC. Record numbers in messages count from 0, e.g. ``seg.tfrecord#record 3``.
Header and data CRCs are both checked on every read (``verify=False`` skips the data CRC:
``fogsim fog --no-verify``). The data CRC uses the compiled ``google_crc32c`` (the ``waymo``
extra) or ``crc32c`` module when one is installed, else :func:`crc32c_numpy`, a table-driven
fallback on numpy that computes thousands of interleaved lanes at once and joins them with
CRC shift operators (≈ 100–200 MB/s on records of megabytes, against ≈ 5–10 MB/s for a byte
loop; a compiled module does several GB/s). The writer always writes correct CRCs.

A record's length is checked against the file's size and against :data:`MAX_RECORD_BYTES` when the file
is indexed and again before a record is read, so a lying or damaged length never becomes an allocation.
"""
from __future__ import annotations

import os
import struct
from functools import lru_cache
from pathlib import Path
from typing import Callable, Iterable

from fogsim.errors import InputError

_HEADER = struct.Struct("<QI")  # length, masked CRC of the 8 length bytes
_FOOTER = struct.Struct("<I")  # masked CRC of the data
_MASK_DELTA = 0xA282EAD8
#: the largest record read (a Waymo v1 frame — five JPEG images and the compressed range images — is ≈ 1–30 MB)
MAX_RECORD_BYTES = 1 << 28


_POLY = 0x82F63B78  # the Castagnoli polynomial, bit-reflected


def _make_table() -> list[int]:
    table = []
    for n in range(256):
        crc = n
        for _ in range(8):
            crc = (crc >> 1) ^ _POLY if crc & 1 else crc >> 1
        table.append(crc)
    return table


_TABLE = _make_table()


def _register(data, crc: int = 0) -> int:
    """The CRC register after feeding ``data`` to it (no pre/post inversion), one byte a step."""
    for byte in data:
        crc = _TABLE[(crc ^ byte) & 0xFF] ^ (crc >> 8)
    return crc


def crc32c_python(data: bytes) -> int:
    """CRC32C of ``data`` in pure Python, a byte at a time (≈ 5–10 MB/s: for short data)."""
    return _register(bytes(data), 0xFFFFFFFF) ^ 0xFFFFFFFF


# --- the numpy fallback. CRC arithmetic is over GF(2): feeding n zero bytes to a register r
# gives r·x^(8n) mod P (a linear map of r), and the register of A‖B is reg(A)·x^(8|B|) ⊕ reg(B)
# (both started at 0). So the data is cut into 2^k equal lanes, all lanes are fed byte by byte
# at once (one numpy step per byte of a lane), and the lane registers are joined pairwise.
def _multmodp(a: int, b: int) -> int:
    """a·b mod P for reflected 32-bit polynomials (bit 31 is x^0)."""
    m, p = 1 << 31, 0
    while a:
        if a & m:
            p ^= b
            a ^= m
        m >>= 1
        b = (b >> 1) ^ _POLY if b & 1 else b >> 1
    return p


_X2N = [1 << 30]  # x^(2^k) mod P, k = 0, 1, …
for _ in range(63):
    _X2N.append(_multmodp(_X2N[-1], _X2N[-1]))


def _x8n(n: int) -> int:
    """x^(8n) mod P: the factor of a register fed n zero bytes."""
    p, k = 1 << 31, 3
    while n:
        if n & 1:
            p = _multmodp(_X2N[k], p)
        n >>= 1
        k += 1
    return p


@lru_cache(maxsize=256)
def _shift_tables(n: int):
    """Four 256-entry tables of the linear map r ↦ r·x^(8n) mod P, one per byte of r."""
    import numpy as np

    factor = _x8n(n)
    columns = [_multmodp(factor, 1 << i) for i in range(32)]
    byte = np.arange(256, dtype=np.uint32)
    tables = np.zeros((4, 256), dtype=np.uint32)
    for i, column in enumerate(columns):
        tables[i // 8][(byte >> (i % 8)) & 1 == 1] ^= np.uint32(column)
    tables.flags.writeable = False
    return tables


#: most lanes, fewest bytes a lane, and below how many bytes the byte loop is faster
_LANES_MAX, _LANE_MIN, _SHORT = 1 << 14, 64, 32768


def _register_numpy(data) -> int:
    """:func:`_register` from 0 of a bytes-like object, computed on interleaved lanes."""
    import numpy as np

    n = len(data)
    if n < _SHORT:
        return _register(data)
    lanes = 1 << min(_LANES_MAX.bit_length() - 1, (n // _LANE_MIN).bit_length() - 1)
    length = n // lanes
    head = lanes * length
    rows = np.frombuffer(data, dtype=np.uint8, count=head).reshape(lanes, length).T.copy()
    table = np.array(_TABLE, dtype=np.uint32)
    reg = np.zeros(lanes, dtype=np.uint32)
    for row in rows:  # byte j of every lane
        reg = table[(reg ^ row) & 0xFF] ^ (reg >> 8)
    while len(reg) > 1:  # join neighbours: reg(A‖B) = reg(A)·x^(8|B|) ⊕ reg(B)
        t = _shift_tables(length)
        a = reg[0::2]
        reg = t[0][a & 0xFF] ^ t[1][(a >> 8) & 0xFF] ^ t[2][(a >> 16) & 0xFF] ^ t[3][a >> 24] ^ reg[1::2]
        length *= 2
    tail = memoryview(data)[head:]
    return _multmodp(_x8n(len(tail)), int(reg[0])) ^ _register_numpy(tail)


def crc32c_numpy(data: bytes) -> int:
    """CRC32C of ``data``, table-driven on numpy: exact for any size; ≈ 100–200 MB/s on one core
    for megabytes (a Waymo frame), the byte loop's speed below :data:`_SHORT` bytes."""
    data = memoryview(data).cast("B")
    # starting from 0xFFFFFFFF instead of 0 adds 0xFFFFFFFF·x^(8n) (linearity)
    return _register_numpy(data) ^ _multmodp(_x8n(len(data)), 0xFFFFFFFF) ^ 0xFFFFFFFF


def _fast_crc32c() -> Callable[[bytes], int] | None:
    """A compiled CRC32C if one is importable, else None."""
    try:
        import google_crc32c

        if getattr(google_crc32c, "implementation", "") == "c":
            return google_crc32c.value
    except ImportError:
        pass
    try:
        import crc32c

        return crc32c.crc32c
    except (ImportError, AttributeError):
        return None


_FAST_CRC32C = _fast_crc32c()


def crc32c(data: bytes) -> int:
    """CRC32C of ``data``: the compiled module when installed, else :func:`crc32c_numpy`."""
    return (_FAST_CRC32C or crc32c_numpy)(data)


def masked_crc32c(data: bytes, crc: Callable[[bytes], int] | None = None) -> int:
    """TFRecord's masked CRC32C of ``data`` (``crc``: the CRC32C function, default :func:`crc32c`)."""
    value = (crc or crc32c)(bytes(data))
    return ((((value >> 15) | (value << 17)) & 0xFFFFFFFF) + _MASK_DELTA) & 0xFFFFFFFF


def index_tfrecord(path: str | os.PathLike) -> list[tuple[int, int]]:
    """(offset of the data, length in bytes) of every record, reading only the headers.

    Raises InputError naming the file and record number on a truncated file or a bad
    length CRC (which is what a file of another format, or a corrupted one, looks like).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    size = path.stat().st_size
    records = []
    with open(path, "rb") as f:
        while (start := f.tell()) < size:
            source = f"{path}#record {len(records)}"
            header = f.read(_HEADER.size)
            if len(header) < _HEADER.size:
                raise InputError(source, "truncated TFRecord file (incomplete record header)")
            length, length_crc = _HEADER.unpack(header)
            if masked_crc32c(header[:8], crc32c_python) != length_crc:
                raise InputError(source, "corrupt TFRecord (length CRC mismatch; not a TFRecord "
                                         "file, or damaged)")
            offset = start + _HEADER.size
            if length > MAX_RECORD_BYTES:
                raise InputError(source, f"TFRecord record of {length:,} bytes exceeds the bound of "
                                         f"{MAX_RECORD_BYTES:,} bytes per record (a Waymo frame is ≈ 1–30 MB)")
            if offset + length + _FOOTER.size > size:
                raise InputError(source, f"truncated TFRecord file (record of {length} bytes "
                                         f"runs past the end)")
            records.append((offset, length))
            f.seek(offset + length + _FOOTER.size)
    return records


def read_record(path: str | os.PathLike, offset: int, length: int,
                source: str | None = None, verify: bool = True) -> bytes:
    """The data of the record at ``offset`` (from :func:`index_tfrecord`).

    ``source`` names the record in errors (default: the file and byte offset). The data CRC
    is verified unless ``verify`` is false.
    """
    source = source or f"{path}@byte {offset}"
    if not 0 <= length <= MAX_RECORD_BYTES:
        raise InputError(source, f"TFRecord record of {length:,} bytes exceeds the bound of {MAX_RECORD_BYTES:,} "
                                 "bytes per record")
    try:
        with open(path, "rb") as f:
            f.seek(offset)
            blob = f.read(length + _FOOTER.size)
    except OSError as exc:
        raise InputError(path, f"cannot read TFRecord ({exc.strerror or exc})") from None
    if len(blob) < length + _FOOTER.size:
        raise InputError(source, "truncated TFRecord file (record runs past the end)")
    data = blob[:length]
    if verify and masked_crc32c(data) != _FOOTER.unpack(blob[length:])[0]:
        raise InputError(source, "corrupt TFRecord (data CRC mismatch: the file is damaged; "
                                 "--no-verify skips this check)")
    return data


def write_tfrecord(path: str | os.PathLike, records: Iterable[bytes]) -> None:
    """Write ``records`` as a TFRecord file, atomically (:func:`fogsim.io.atomic.atomic_path`: a
    temporary file and a rename; the file gets 0666 minus the umask, as any tool's output)."""
    from fogsim.io.atomic import atomic_path

    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        for data in records:
            length = struct.pack("<Q", len(data))
            f.write(length + _FOOTER.pack(masked_crc32c(length)))
            f.write(data)
            f.write(_FOOTER.pack(masked_crc32c(data)))
