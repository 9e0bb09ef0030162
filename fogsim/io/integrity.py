"""Is this image file whole? Structural checks of encoded JPEG/PNG data, and the messages
native decoders print (libjpeg, libpng, OpenEXR) captured so they become one clear error.

OpenCV decodes a truncated or damaged JPEG without failing: libjpeg prints a warning and the
missing part comes back grey. Here a JPEG must reach its end-of-image marker and a PNG its IEND
chunk with every chunk's CRC right; what the decoder says while decoding counts too.
"""
from __future__ import annotations

import io
import re
import zlib
from contextlib import contextmanager, redirect_stderr, redirect_stdout

from fogsim.console import captured_fds


@contextmanager
def native_output():
    """Capture what native libraries (libjpeg, libpng, OpenEXR) print to file descriptors 1
    and 2 — and what extensions print through ``sys.stdout`` (pybind11's py::print) — while the
    block runs, instead of letting it reach the user's terminal (:func:`fogsim.console.captured_fds`).

    Yields a list that holds the captured text (one string) once the block has ended. The
    callers turn what matters in it into an :class:`InputError`; the rest is dropped. Not
    for use from several threads at once (the descriptors are process-wide); fogsim decodes
    in one thread per process. Without file descriptors to redirect nothing is captured.
    """
    said: list[str] = []
    python_level = io.StringIO()
    try:
        with captured_fds() as lines, redirect_stdout(python_level), redirect_stderr(python_level):
            yield said
    finally:
        said.append("\n".join(lines["stdout"] + lines["stderr"]) + python_level.getvalue())


def first_line(text: str, strip: str = "") -> str:
    """The first non-empty line of a native message, without a leading ``strip`` prefix."""
    for line in text.splitlines():
        line = line.strip()
        if line.startswith(strip):
            line = line[len(strip):].lstrip(": ")
        if line:
            return line
    return ""


#: What libjpeg / libpng print when the data is damaged but they carry on (OpenCV then returns
#: the image, grey-filled or garbled where the data was bad): each of these is an error here.
DECODER_DAMAGE = re.compile(r"Corrupt JPEG data[^\n]*|Premature end of JPEG file|Invalid SOS parameters"
                             r"[^\n]*|Inconsistent progression sequence[^\n]*|Not enough image data|"
                             r"CRC error[^\n]*", re.IGNORECASE)
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _jpeg_damage(data: bytes) -> str | None:
    """Why a JPEG stream is truncated or malformed, or None: walks its markers from SOI to EOI
    (segment lengths, then each scan's entropy-coded data up to the next marker)."""
    n, pos = len(data), 2
    truncated = "truncated JPEG (the data ends before its end-of-image marker)"
    while True:
        if pos + 2 > n:
            return truncated
        if data[pos] != 0xFF:
            return f"corrupt JPEG (no marker at byte {pos})"
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        pos += 2
        if marker == 0xD9:  # EOI: anything after it is not image data
            return None
        if marker == 0x01 or 0xD0 <= marker <= 0xD7:  # TEM, RSTn: no length field
            continue
        if pos + 2 > n:
            return truncated
        length = int.from_bytes(data[pos:pos + 2], "big")
        if length < 2:
            return f"corrupt JPEG (segment of length {length} at byte {pos})"
        pos += length
        if pos > n:
            return truncated
        if marker == 0xDA:  # SOS: entropy-coded data up to the next marker other than RSTn
            while True:
                pos = data.find(b"\xff", pos)
                if pos < 0 or pos + 1 >= n:
                    return truncated
                follower = data[pos + 1]
                if follower == 0x00 or 0xD0 <= follower <= 0xD7:  # stuffed 0xFF, restart marker
                    pos += 2
                elif follower == 0xFF:
                    pos += 1
                else:
                    break


def _png_damage(data: bytes) -> str | None:
    """Why a PNG stream is truncated or damaged, or None: every chunk complete, its CRC right,
    up to IEND."""
    view, n, pos = memoryview(data), len(data), len(_PNG_SIGNATURE)
    while True:
        if pos + 8 > n:
            return "truncated PNG (the data ends before its IEND chunk)"
        length = int.from_bytes(view[pos:pos + 4], "big")
        kind = bytes(view[pos + 4:pos + 8])
        end = pos + 12 + length
        if end > n:
            return f"truncated PNG (its {kind.decode('latin-1')!r} chunk runs past the end of the data)"
        if zlib.crc32(view[pos + 4:end - 4]) != int.from_bytes(view[end - 4:end], "big"):
            return f"corrupt PNG (CRC mismatch in its {kind.decode('latin-1')!r} chunk at byte {pos})"
        if kind == b"IEND":
            return None
        pos = end


def encoded_image_damage(data: bytes) -> str | None:
    """Why encoded image bytes are truncated or corrupt, or None when nothing is found.

    JPEG and PNG are checked structurally (pure Python, independent of the OpenCV build):
    a JPEG must reach its end-of-image marker, a PNG its IEND chunk with every chunk's CRC
    right. Other formats are left to the decoder.
    """
    if not data:
        return "empty (0 bytes)"
    if data[:3] == b"\xff\xd8\xff":
        return _jpeg_damage(data)
    if data[:8] == _PNG_SIGNATURE:
        return _png_damage(data)
    return None
