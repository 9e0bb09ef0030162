"""TFRecord files without TensorFlow: index, read and write records.

Framing of each record (all integers little endian)::

    uint64 length | uint32 masked_crc32c(length bytes) | data[length] | uint32 masked_crc32c(data)

with ``masked_crc = ((crc >> 15) | (crc << 17)) + 0xa282ead8 (mod 2**32)`` and CRC32C the
Castagnoli CRC. Record numbers in messages count from 0, e.g. ``seg.tfrecord#record 3``.
Header CRCs are always checked (a small pure-Python CRC); data CRCs are checked only when the
``google_crc32c`` (C build) or ``crc32c`` module is installed, since pure Python is too slow for
multi-megabyte records. The writer always writes correct CRCs.
"""
from __future__ import annotations

import os
import struct
import tempfile
from pathlib import Path
from typing import Callable, Iterable

from fogsim.errors import InputError

_HEADER = struct.Struct("<QI")  # length, masked CRC of the 8 length bytes
_FOOTER = struct.Struct("<I")  # masked CRC of the data
_MASK_DELTA = 0xA282EAD8


def _make_table() -> list[int]:
    table = []
    for n in range(256):
        crc = n
        for _ in range(8):
            crc = (crc >> 1) ^ 0x82F63B78 if crc & 1 else crc >> 1  # reflected Castagnoli poly
        table.append(crc)
    return table


_TABLE = _make_table()


def crc32c_python(data: bytes) -> int:
    """CRC32C of ``data`` in pure Python (correct for any size, about 1 MB/s)."""
    crc = 0xFFFFFFFF
    for byte in bytes(data):
        crc = _TABLE[(crc ^ byte) & 0xFF] ^ (crc >> 8)
    return crc ^ 0xFFFFFFFF


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


def masked_crc32c(data: bytes, crc: Callable[[bytes], int] | None = None) -> int:
    """TFRecord's masked CRC32C of ``data`` (compiled CRC when available)."""
    value = (crc or _FAST_CRC32C or crc32c_python)(bytes(data))
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
            if offset + length + _FOOTER.size > size:
                raise InputError(source, f"truncated TFRecord file (record of {length} bytes "
                                         f"runs past the end)")
            records.append((offset, length))
            f.seek(offset + length + _FOOTER.size)
    return records


def read_record(path: str | os.PathLike, offset: int, length: int,
                source: str | None = None) -> bytes:
    """The data of the record at ``offset`` (from :func:`index_tfrecord`).

    ``source`` names the record in errors (default: the file and byte offset). The data CRC
    is verified when a compiled CRC32C module is installed.
    """
    source = source or f"{path}@byte {offset}"
    try:
        with open(path, "rb") as f:
            f.seek(offset)
            blob = f.read(length + _FOOTER.size)
    except OSError as exc:
        raise InputError(path, f"cannot read TFRecord ({exc.strerror or exc})") from None
    if len(blob) < length + _FOOTER.size:
        raise InputError(source, "truncated TFRecord file (record runs past the end)")
    data = blob[:length]
    if _FAST_CRC32C is not None and masked_crc32c(data) != _FOOTER.unpack(blob[length:])[0]:
        raise InputError(source, "corrupt TFRecord (data CRC mismatch)")
    return data


def write_tfrecord(path: str | os.PathLike, records: Iterable[bytes]) -> None:
    """Write ``records`` as a TFRecord file, atomically (temporary file and rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            for data in records:
                length = struct.pack("<Q", len(data))
                f.write(length + _FOOTER.pack(masked_crc32c(length)))
                f.write(data)
                f.write(_FOOTER.pack(masked_crc32c(data)))
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
