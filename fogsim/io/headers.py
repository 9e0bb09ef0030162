"""What a file declares before its body is read: an encoded image's width, height and channels (PNG IHDR,
JPEG frame header, BMP, TIFF's first IFD, WebP), an EXR's data window and channel list, a ``.npy`` array's
dtype and shape — so a reader checks the size against a bound before it decodes or allocates anything.

Each parser reads only the header bytes it is given (the caller reads a bounded prefix) and returns None
when the data is not its format or the header is not in that prefix; the decoder's own checks apply then.
"""
from __future__ import annotations

import io
import os
import struct
from dataclasses import dataclass

import numpy as np

from fogsim.errors import InputError

__all__ = ["HEADER_BYTES", "ImageHeader", "exr_header", "image_header", "npy_header", "read_head", "read_npy"]

#: the prefix of a file read to find its header (JPEG metadata segments before the frame header included)
HEADER_BYTES = 1 << 20


def read_head(path: str | os.PathLike, count: int) -> bytes:
    """The first ``count`` bytes of ``path`` (fewer when it is shorter): where its header is; an
    :class:`InputError` naming the file when it cannot be read."""
    try:
        with open(path, "rb") as f:
            return f.read(count)
    except OSError as exc:
        raise InputError(path, f"cannot read the file ({exc.strerror or exc})") from None


@dataclass(frozen=True)
class ImageHeader:
    """An image as its header declares it: ``width`` × ``height`` pixels of ``channels`` samples each,
    in format ``kind`` (``png``, ``jpeg``, ``bmp``, ``tiff``, ``webp``, ``exr``)."""

    kind: str
    width: int
    height: int
    channels: int

    @property
    def pixels(self) -> int:
        return self.width * self.height


_PNG = b"\x89PNG\r\n\x1a\n"
_PNG_CHANNELS = {0: 1, 2: 3, 3: 3, 4: 2, 6: 4}  # colour type → decoded channels (palette → RGB)
#: JPEG start-of-frame markers (baseline, extended, progressive, lossless; Huffman and arithmetic)
_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}


def _png(data: bytes) -> ImageHeader | None:
    if len(data) < 26 or data[12:16] != b"IHDR":
        return None
    width, height, _, colour = struct.unpack(">IIBB", data[16:26])
    return ImageHeader("png", width, height, _PNG_CHANNELS.get(colour, 4))


def _jpeg(data: bytes) -> ImageHeader | None:
    pos = 2
    while pos + 4 <= len(data):
        if data[pos] != 0xFF:
            return None
        marker = data[pos + 1]
        if marker == 0xFF:
            pos += 1
            continue
        if marker == 0x01 or 0xD0 <= marker <= 0xD8:
            pos += 2
            continue
        if marker in (0xD9, 0xDA):  # end of image, start of scan: no frame header before them
            return None
        length = int.from_bytes(data[pos + 2:pos + 4], "big")
        if marker in _SOF and pos + 10 <= len(data):
            height, width, comps = struct.unpack(">HHB", data[pos + 5:pos + 10])
            return ImageHeader("jpeg", width, height, comps)
        pos += 2 + length
    return None


def _bmp(data: bytes) -> ImageHeader | None:
    if len(data) < 30:
        return None
    (dib,) = struct.unpack("<I", data[14:18])
    if dib == 12:
        width, height = struct.unpack("<HH", data[18:22])
        bits = struct.unpack("<H", data[24:26])[0]
    else:
        width, height = struct.unpack("<ii", data[18:26])
        bits = struct.unpack("<H", data[28:30])[0]
    return ImageHeader("bmp", abs(width), abs(height), 4 if bits == 32 else 3)


def _tiff(data: bytes) -> ImageHeader | None:
    order = "<" if data[:2] == b"II" else ">"
    try:
        (ifd,) = struct.unpack(order + "I", data[4:8])
        (count,) = struct.unpack(order + "H", data[ifd:ifd + 2])
        tags = {}
        for i in range(count):
            tag, kind, _, value = struct.unpack(order + "HHI4s", data[ifd + 2 + 12 * i:ifd + 14 + 12 * i])
            tags[tag] = struct.unpack(order + ("H" if kind == 3 else "I"), value[:2 if kind == 3 else 4])[0]
    except struct.error:
        return None
    if 256 not in tags or 257 not in tags:
        return None
    return ImageHeader("tiff", tags[256], tags[257], tags.get(277, 1))


def _webp(data: bytes) -> ImageHeader | None:
    chunk = data[12:16]
    if chunk == b"VP8X" and len(data) >= 30:
        return ImageHeader("webp", 1 + int.from_bytes(data[24:27], "little"),
                           1 + int.from_bytes(data[27:30], "little"), 4)
    if chunk == b"VP8L" and len(data) >= 25:
        bits = int.from_bytes(data[21:25], "little")
        return ImageHeader("webp", 1 + (bits & 0x3FFF), 1 + ((bits >> 14) & 0x3FFF), 4)
    if chunk == b"VP8 " and len(data) >= 30:
        width, height = struct.unpack("<HH", data[26:30])
        return ImageHeader("webp", width & 0x3FFF, height & 0x3FFF, 3)
    return None


def image_header(data: bytes) -> ImageHeader | None:
    """The size an encoded image (its first bytes, ≤ :data:`HEADER_BYTES` are enough) declares, or None
    for another format or a header not within ``data``."""
    if data[:8] == _PNG:
        return _png(data)
    if data[:3] == b"\xff\xd8\xff":
        return _jpeg(data)
    if data[:2] == b"BM":
        return _bmp(data)
    if data[:4] in (b"II*\0", b"MM\0*"):
        return _tiff(data)
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
        return _webp(data)
    if data[:4] == b"v/1\x01":
        return exr_header(data)
    return None


def _cstring(data: bytes, pos: int) -> tuple[str, int]:
    end = data.index(b"\0", pos)
    return data[pos:end].decode("latin-1"), end + 1


def exr_header(data: bytes) -> ImageHeader | None:
    """The largest data window and the channel count of an EXR file's headers (every part of a multi-part
    file), from its first bytes; None when they are not within ``data``."""
    if data[:4] != b"v/1\x01" or len(data) < 8:
        return None
    multipart = bool(int.from_bytes(data[4:8], "little") & 0x1000)
    pos, width, height, channels = 8, 0, 0, 0
    try:
        while True:
            if data[pos] == 0:  # an empty header: the end of a multi-part file's headers
                break
            while data[pos] != 0:
                name, pos = _cstring(data, pos)
                _, pos = _cstring(data, pos)
                (size,) = struct.unpack_from("<i", data, pos)
                value = data[pos + 4:pos + 4 + size]
                if len(value) != size or size < 0:
                    return None
                if name == "dataWindow" and size == 16:
                    x0, y0, x1, y1 = struct.unpack("<4i", value)
                    width, height = max(width, x1 - x0 + 1), max(height, y1 - y0 + 1)
                elif name == "channels":
                    channels += _chlist_count(value)
                pos += 4 + size
            pos += 1
            if not multipart:
                break
    except (IndexError, ValueError, struct.error):
        return None
    return ImageHeader("exr", width, height, channels) if width and height else None


def _chlist_count(value: bytes) -> int:
    """How many channels an EXR ``chlist`` attribute lists (name\\0, then 16 bytes each)."""
    pos, count = 0, 0
    while pos < len(value) and value[pos] != 0:
        _, pos = _cstring(value, pos)
        pos += 16
        count += 1
    return count


def npy_header(path: str | os.PathLike, max_bytes: int = 64 * 1024) -> tuple[np.dtype, tuple[int, ...], bool, int]:
    """(dtype, shape, fortran order, body offset) of the ``.npy`` file ``path``, from its header alone
    (``numpy.lib.format``, versions 1.0 and 2.0; at most ``max_bytes`` read). An :class:`InputError`
    naming the file when it is not one, is an ``.npz`` archive or declares Python objects (a pickle)."""
    from numpy.lib import format as npf

    try:
        with open(path, "rb") as f:
            head = io.BytesIO(f.read(max_bytes))
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except IsADirectoryError:
        raise InputError(path, "is a folder, not a .npy file") from None
    except OSError as exc:
        raise InputError(path, f"cannot be read ({exc.strerror or exc})") from None
    if head.getvalue().startswith(b"PK\x03\x04"):
        raise InputError(path, "is an .npz archive, not one .npy array")
    try:
        version = npf.read_magic(head)
        if version == (1, 0):
            shape, fortran, dtype = npf.read_array_header_1_0(head, max_header_size=max_bytes)
        elif version == (2, 0):
            shape, fortran, dtype = npf.read_array_header_2_0(head, max_header_size=max_bytes)
        else:
            raise ValueError(f".npy format version {version[0]}.{version[1]} (fogsim reads 1.0 and 2.0)")
    except (ValueError, EOFError, TypeError, SyntaxError) as exc:
        raise InputError(path, f"not a readable .npy header ({exc})") from None
    if dtype.hasobject:
        raise InputError(path, "holds pickled (object) data, which fogsim never loads")
    return dtype, tuple(int(n) for n in shape), bool(fortran), head.tell()


def read_npy(path: str | os.PathLike, check=None) -> np.ndarray:
    """The array in the ``.npy`` file ``path``, read in bounded memory: its header first (:func:`npy_header`),
    then ``check(dtype, shape)`` (the caller's bound; it raises to refuse), then the bytes the header
    declares against the file's size — a header that claims more than the file holds is refused naming
    the header — and only then the body (exactly those bytes)."""
    dtype, shape, fortran, offset = npy_header(path)
    if check is not None:
        check(dtype, shape)
    size = os.stat(path).st_size
    need = int(np.prod(shape, dtype=object)) * dtype.itemsize
    if need > size - offset:
        raise InputError(path, f".npy header declares {dtype} {list(shape)} ({need:,} bytes) but the file holds only "
                               f"{size - offset:,} bytes after its header: truncated, or the header lies")
    with open(path, "rb") as f:
        f.seek(offset)
        data = f.read(need)
    if len(data) != need:
        raise InputError(path, f"ended after {len(data):,} of {need:,} bytes while it was read (changed meanwhile?)")
    return np.frombuffer(data, dtype).reshape(shape, order="F" if fortran else "C")
