"""Documents in and out: text read in bounded memory, JSON decoded under bounds on its size and nesting
(one line naming the file on any problem), JSON written atomically.
"""
from __future__ import annotations

import json
import os

import numpy as np

from fogsim.errors import InputError
from fogsim.io.atomic import atomic_write_bytes

__all__ = ["MAX_DOCUMENT_BYTES", "MAX_JSON_BYTES", "MAX_JSON_DEPTH", "json_depth", "parse_json", "read_json",
           "read_text_bounded", "read_text_file", "write_json"]


def write_json(path: str | os.PathLike, obj) -> None:
    """Write ``obj`` as indented JSON, atomically."""
    atomic_write_bytes(path, (json.dumps(obj, indent=2, sort_keys=False) + "\n").encode())


#: Bounds on every JSON text fogsim reads (files and inline text): nesting deeper than
#: :data:`MAX_JSON_DEPTH` is refused before Python's recursive decoder sees it (fogsim's documents
#: nest ≤ 8 levels); a file larger than :data:`MAX_JSON_BYTES` (fogsim's own COCO and prediction
#: files included) is refused before it is read, and the documents users write (presets, class
#: maps, parameter files, glTF) are bounded by :data:`MAX_DOCUMENT_BYTES`.
MAX_JSON_DEPTH = 100
MAX_JSON_BYTES = 1 << 30
MAX_DOCUMENT_BYTES = 64 << 20
_JSON_MARKS = np.zeros(256, bool)
_JSON_MARKS[[0x22, 0x5B, 0x5D, 0x7B, 0x7D]] = True  # " [ ] { }
_JSON_STEP = np.zeros(256, np.int8)
_JSON_STEP[[0x5B, 0x7B]], _JSON_STEP[[0x5D, 0x7D]] = 1, -1


def json_depth(text: str) -> int:
    """How deep ``text``'s arrays and objects nest (brackets inside strings do not count). Cheap: a
    count when there are few brackets, else one vectorised pass (escaped backslashes and quotes
    dropped, every remaining quote toggling "inside a string")."""
    opens = text.count("[") + text.count("{")
    if opens <= MAX_JSON_DEPTH:
        return opens  # an upper bound, and small
    data = text.encode("utf-8", "surrogatepass").replace(b"\\\\", b"").replace(b'\\"', b"")
    codes = np.frombuffer(data, np.uint8)
    codes = codes[_JSON_MARKS[codes]]
    step = _JSON_STEP[codes]
    step[(np.cumsum(codes == 0x22, dtype=np.int64) & 1) == 1] = 0  # inside a string
    return int(np.cumsum(step, dtype=np.int64).max(initial=0))


def parse_json(text: str | bytes, source: str | os.PathLike):
    """Decode the JSON ``text`` read from ``source`` (a file, or the flag that gave it inline).
    Malformed text, text that is not UTF-8, or nesting deeper than :data:`MAX_JSON_DEPTH` is an
    :class:`InputError` naming ``source``, never a RecursionError. (The nesting is measured before
    decoding for texts up to :data:`MAX_DOCUMENT_BYTES`; a larger one — fogsim's own outputs — is
    caught by the decoder's own recursion bound.)"""
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise InputError(source, f"not readable as JSON (not UTF-8 text: {exc.reason} at byte {exc.start})") \
                from None
    depth = json_depth(text) if len(text) <= MAX_DOCUMENT_BYTES else 0
    if depth > MAX_JSON_DEPTH:
        raise InputError(source, f"not readable as JSON: arrays/objects nest {depth} levels deep "
                                 f"(at most {MAX_JSON_DEPTH})")
    try:
        return json.loads(text)
    except RecursionError:
        raise InputError(source, f"not readable as JSON: arrays/objects nest deeper than {MAX_JSON_DEPTH} "
                                 "levels") from None
    except ValueError as exc:
        raise InputError(source, f"not readable as JSON ({exc})") from None


def _read_at_most(f, limit: int, chunk: int = 1 << 20) -> bytes:
    """At most ``limit`` bytes of the open binary file ``f``, read a chunk at a time: ``f.read(limit)`` would
    allocate ``limit`` bytes up front (a 1 GiB buffer for every small JSON file under a 1 GiB bound)."""
    parts, total = [], 0
    while total < limit:
        part = f.read(min(chunk, limit - total))
        if not part:
            break
        parts.append(part)
        total += len(part)
    return b"".join(parts)


def read_text_bounded(path: str | os.PathLike, max_bytes: int, what: str = "file") -> bytes:
    """The bytes of ``path``, refused (InputError naming it) when it is larger than ``max_bytes``
    — checked on the open file, so a huge or endless file (a FIFO, /dev/zero) is never read whole."""
    try:
        with open(path, "rb") as f:
            data = _read_at_most(f, max_bytes + 1)
    except FileNotFoundError:
        raise InputError(path, "file not found") from None
    except IsADirectoryError:
        raise InputError(path, f"is a folder, not a {what}") from None
    except OSError as exc:
        raise InputError(path, f"cannot read the {what} ({exc.strerror or exc})") from None
    if len(data) > max_bytes:
        bound = f"{max_bytes / 2**20:g} MiB" if max_bytes >= 2**20 else f"{max_bytes} bytes"
        raise InputError(path, f"the {what} is larger than {bound}: not a document fogsim reads")
    return data


def read_text_file(path: str | os.PathLike, what: str = "text file", max_bytes: int = MAX_DOCUMENT_BYTES) -> str:
    """The UTF-8 text of ``path`` (a calibration, a label file …): one line naming it when it is missing,
    unreadable, larger than ``max_bytes`` or not UTF-8 (``what`` names the kind of file)."""
    data = read_text_bounded(path, max_bytes, what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(path, f"not a readable {what} (not UTF-8 text: {exc.reason} at byte {exc.start})") from None


def read_json(path: str | os.PathLike, max_bytes: int = MAX_JSON_BYTES):
    """The decoded JSON file ``path`` (one line naming it when missing, unreadable, malformed,
    nested deeper than :data:`MAX_JSON_DEPTH` or larger than ``max_bytes``)."""
    return parse_json(read_text_bounded(path, max_bytes, "JSON file"), path)
