"""File I/O: images, depth maps and JSON, with atomic writes and clear errors.

Conventions: RGB arrays are H×W×3 in RGB order (OpenCV's BGR never leaves this module);
depth arrays are H×W float32 in metres. Every writer writes a temporary file beside the
target and renames it, so a killed job never leaves a half-written output — and never writes
into an existing file, which is what lets one file have two names (:func:`link_or_copy`).
"""
from __future__ import annotations

import errno
import glob
import json
import os
import re
import shutil
import socket
import tempfile
import time
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

import numpy as np

from fogsim.errors import InputError
from fogsim.headers import HEADER_BYTES, ImageHeader, exr_header, image_header, read_npy
from fogsim.integrity import DECODER_DAMAGE, encoded_image_damage, first_line, native_output

os.environ.setdefault("OPENCV_IO_ENABLE_OPENEXR", "1")
import cv2  # noqa: E402  (the variable above must be set before the import)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")
DEPTH_SUFFIXES = (".exr", ".npy", ".png", ".tif", ".tiff")


# ----------------------------------------------------------------------------- atomic writes
#: Temporary files of unfinished writes: hidden, beside their target, ending in this suffix,
#: named ``.NAME.<host>-<pid>.<random>.part`` so a later run can tell a dead writer's leftovers.
PART_SUFFIX = ".part"
STALE_FOREIGN_PART_S = 24 * 3600  # another host's (or an unnamed) leftover is stale after a day


def _temp_beside(path: Path) -> Path:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{_HOST}-{os.getpid()}.", suffix=PART_SUFFIX,
                                   dir=path.parent)
    except OSError as exc:
        raise _naming(exc, path) from None
    os.close(fd)
    return Path(tmp)


def _naming(exc: OSError, path: Path) -> OSError:
    """``exc`` as the user would read it: naming the target ``path``, never the hidden temporary file
    (a folder where the file should go, a read-only folder, a full disk …)."""
    if isinstance(exc, IsADirectoryError) or (path.is_dir() and exc.errno in (errno.EISDIR, errno.ENOTEMPTY,
                                                                              errno.EEXIST)):
        return IsADirectoryError(errno.EISDIR, "is a folder, not a file that can be written", str(path))
    named = exc.filename is None or Path(str(exc.filename)).name.endswith(PART_SUFFIX)
    if named and exc.errno is not None:
        return type(exc)(exc.errno, exc.strerror or str(exc), str(path))
    return exc


@contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path``; on success it is renamed onto ``path``.

    The temporary file is hidden and removed on any error, so a killed or failed job never
    leaves a half-written output under the real name (a SIGKILL can leave the temporary
    file: :func:`remove_stale_parts` clears it on resume). The result gets the usual
    permissions (0666 minus the umask), as any other tool's output would.
    """
    path = Path(path)
    tmp = _temp_beside(path)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        named = _naming(exc, path)  # a short write says not which file, a rename names the temporary one
        if named is not exc:
            raise named from None
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def create_exclusive(path: str | os.PathLike, data: bytes) -> bool:
    """Write ``data`` to ``path`` only if no file is there; True when this call created it.

    Atomic with no check-then-write race: the complete temporary file is hard-linked to
    ``path``, which fails when ``path`` exists (two concurrent callers: exactly one wins).
    """
    path = Path(path)
    tmp = _temp_beside(path)
    try:
        tmp.write_bytes(data)
        os.chmod(tmp, 0o666 & ~_umask())
        os.link(tmp, path)
        return True
    except FileExistsError:
        return False
    finally:
        tmp.unlink(missing_ok=True)


def link_or_copy(source: str | os.PathLike, target: str | os.PathLike) -> str:
    """Make ``target`` hold the bytes of ``source`` (a finished file of the same output): a **hard link**
    where the file system allows one (same device), else a copy; never a symbolic link (a symlinked
    ``source``, which may name a file outside the output, is copied). Returns ``"link"`` or ``"copy"``.

    Atomic as :func:`atomic_path`: the link (or copy) is made beside ``target`` under a temporary name and
    renamed onto it, so a killed run leaves no half-made file and an existing ``target`` is replaced, never
    written into. Two names of one file stay safe because every fogsim writer replaces a file (a new
    inode under the old name) instead of writing into it: rewriting either name leaves the other's bytes
    as they were."""
    source, target = Path(source), Path(target)
    try:
        if not target.is_symlink() and target.exists() and os.path.samefile(source, target):
            return "link"  # already one file (a resumed run): rename(2) of a link onto its twin does nothing
    except OSError:
        pass
    tmp = _temp_beside(target)
    tmp.unlink()
    try:
        if source.is_symlink():  # link(2) would link the symlink itself
            raise OSError(errno.EPERM, "a symbolic link is copied, never linked", str(source))
        os.link(source, tmp)
    except OSError:  # another device (EXDEV), a file system without hard links, too many links …
        tmp.unlink(missing_ok=True)
        with atomic_path(target) as part:
            shutil.copyfile(source, part)
        return "copy"
    try:
        os.replace(tmp, target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise _naming(exc, target) from None
    return "link"


@contextmanager
def atomic_folder(path: str | os.PathLike):
    """Yield a hidden temporary folder beside ``path``, ``.NAME.<host>-<pid>.<random>.part``; on success it
    replaces ``path`` whole (an existing folder there is renamed away, then deleted: the caller decides that
    it may be), so a failed or killed job never leaves a half-written folder under the real name. A failure
    deletes the temporary folder; a SIGKILL can leave it, which :func:`remove_stale_folders` clears."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.{_HOST}-{os.getpid()}.", suffix=PART_SUFFIX,
                                    dir=path.parent))
    except OSError as exc:
        raise _naming(exc, path) from None
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_umask())
        if path.is_dir() and not path.is_symlink():
            old = Path(tempfile.mkdtemp(prefix=f".{path.name}.{_HOST}-{os.getpid()}.", suffix=PART_SUFFIX,
                                        dir=path.parent))
            os.replace(path, old)  # onto the empty folder just made: the old tree moves whole
            os.replace(tmp, path)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def remove_stale_folders(path: str | os.PathLike) -> int:
    """Delete the temporary folders :func:`atomic_folder` left beside ``path`` when its writer was killed
    (the same staleness rule as :func:`remove_stale_parts`); returns how many."""
    path = Path(path)
    removed = 0
    for part in path.parent.glob(f".{glob.escape(path.name)}.*{PART_SUFFIX}"):
        if part.is_dir() and not part.is_symlink() and _stale(part):
            shutil.rmtree(part, ignore_errors=True)
            removed += 1
    return removed


def _stale(part: Path) -> bool:
    """Whether the writer of the temporary ``part`` is gone (this host: its process; another: a day)."""
    host, pid = _writer_of(part.name)
    if host == _HOST:
        return not _alive(pid)
    try:
        return time.time() - part.stat().st_mtime > STALE_FOREIGN_PART_S
    except FileNotFoundError:
        return False


def remove_stale_parts(root: str | os.PathLike) -> int:
    """Delete the temporary files of dead writers under ``root``; returns how many.

    A ``.part`` file of this host whose writer process is gone is stale at once; one of
    another host (or of an older fogsim, which did not name its writer) after a day, so
    concurrent shards writing into one folder never lose a file they are still writing.
    """
    removed = 0
    for part in Path(root).rglob(f".*{PART_SUFFIX}"):
        if not part.is_dir() and _stale(part):
            part.unlink(missing_ok=True)
            removed += 1
    return removed


_HOST = socket.gethostname().replace(".", "_").replace("-", "_") or "host"


def _writer_of(name: str) -> tuple[str | None, int]:
    """``(host, pid)`` from ``.NAME.<host>-<pid>.<random>.part``; ``(None, 0)`` if unnamed."""
    parts = name[: -len(PART_SUFFIX)].split(".")
    host, _, pid = parts[-2].rpartition("-") if len(parts) >= 3 else ("", "", "")
    return (host, int(pid)) if host and pid.isdigit() else (None, 0)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_json(path: str | os.PathLike, obj) -> None:
    """Write ``obj`` as indented JSON, atomically."""
    atomic_write_bytes(path, (json.dumps(obj, indent=2, sort_keys=False) + "\n").encode())


# ----------------------------------------------------------------------------- JSON in
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


# ----------------------------------------------------------------------------- paths in
def resolve_path(path: str | os.PathLike, flag: str | None = None) -> Path:
    """``path`` made absolute with its symlinks resolved (as :meth:`Path.resolve`); a symlink loop
    on the way is an :class:`InputError` naming the path (and ``flag``), never a RuntimeError."""
    try:
        return Path(path).resolve()
    except RuntimeError:  # Python ≤ 3.12 reports a loop so ("Symlink loop from …"); 3.13 raises OSError
        pass
    except OSError as exc:
        if exc.errno != errno.ELOOP:
            raise
    raise InputError(path, loop_problem(flag))


def loop_problem(flag: str | None = None) -> str:
    """The one problem text of a symlink loop (``flag``: the argument that named the path)."""
    return (f"{flag + ' ' if flag else ''}is, or passes through, a symlink loop (links that point back at each "
            "other): nothing can be read or written there")


def check_path_arguments(args, positional: frozenset[str] = frozenset()) -> None:
    """Refuse a symlink loop in any path argument of a parsed command line, before the command runs.

    Every string (or list of strings) in ``vars(args)`` is tried as a path: one that the system
    cannot look up because of a loop of links (ELOOP) is one line naming it and its flag (``positional``:
    the names of arguments given without a flag, named "the NAME argument"), exit 2.
    Strings that are not paths (a level list, inline JSON) do not exist and pass; so a new flag is
    guarded without being declared a path."""
    for dest, value in vars(args).items():
        for given in (value if isinstance(value, (list, tuple)) else [value]):
            if not isinstance(given, (str, os.PathLike)) or not str(given):
                continue
            try:
                os.stat(given)
            except OSError as exc:
                if exc.errno == errno.ELOOP:
                    flag = f"the {dest} argument" if dest in positional else f"--{dest.replace('_', '-')}"
                    raise InputError(given, loop_problem(flag)) from None
            except ValueError:  # an embedded NUL: not a path
                continue


def with_checked_paths(command, positional: frozenset[str] = frozenset()):
    """``command(args)`` preceded by :func:`check_path_arguments` (the front doors' one path guard)."""
    def guarded(args):
        check_path_arguments(args, positional)
        return command(args)

    return guarded


# ----------------------------------------------------------------------------- images
#: Default bound on an image's size, width × height, for ``fogsim render`` and ``fogsim fog``
#: (about 8192 × 4883; the Waymo front camera is 2.5 MP): a frame's arrays, its fog levels and
#: Cycles' buffers grow with it; raise it with ``--max-pixels`` when a larger image is meant.
MAX_PIXELS = 40_000_000


def pixel_limit_problem(width: int, height: int, max_pixels: int, action: str = "render") -> str | None:
    """Why a ``width`` × ``height`` image is refused under ``max_pixels`` (``--max-pixels``), or None;
    ``action`` is what raising the flag would let happen ("render", "fog")."""
    if width * height > max_pixels:
        return (f"{width}×{height} = {width * height / 1e6:.1f} MP is above the limit of {max_pixels / 1e6:g} MP "
                f"(--max-pixels {max_pixels}); raise --max-pixels to {action} it")
    return None


#: the most channels a decoded image may declare (an RGBA PNG has 4; a multi-layer EXR render ≈ 10)
MAX_CHANNELS = 32
#: the most bytes an image file may take per pixel of the bound (16: RGBA float32 stored uncompressed)
MAX_FILE_BYTES_PER_PIXEL = 16
_PIXEL_BOUND: ContextVar[int] = ContextVar("fogsim_max_pixels", default=MAX_PIXELS)


@contextmanager
def pixel_bound(max_pixels: int):
    """Within the block, every image and depth file is read under ``max_pixels`` (``--max-pixels``)
    instead of :data:`MAX_PIXELS` (the readers decode before the job sees the image)."""
    token = _PIXEL_BOUND.set(int(max_pixels))
    try:
        yield
    finally:
        _PIXEL_BOUND.reset(token)


def max_pixels_now() -> int:
    """The pixel bound in force (:func:`pixel_bound`, else :data:`MAX_PIXELS`)."""
    return _PIXEL_BOUND.get()


def check_declared(header: ImageHeader | None, source) -> None:
    """Refuse an image whose header declares more pixels than :func:`max_pixels_now` or more than
    :data:`MAX_CHANNELS` channels — before anything is decoded or allocated."""
    if header is None:
        return
    bound = max_pixels_now()
    if pixel_limit_problem(header.width, header.height, bound):
        raise InputError(source, f"its {header.kind.upper()} header declares {header.width}×{header.height} = "
                                 f"{header.pixels / 1e6:.1f} MP, above the limit of {bound / 1e6:g} MP (--max-pixels "
                                 f"{bound}): refused before decoding; raise --max-pixels to read it")
    if header.channels > MAX_CHANNELS:
        raise InputError(source, f"its {header.kind.upper()} header declares {header.channels} channels (at most "
                                 f"{MAX_CHANNELS})")


def decode_image(data: bytes, source: str) -> np.ndarray:
    """Decode encoded image bytes (PNG, JPEG, ...) to an RGB array of the file's bit depth.

    The size its header declares is checked first (:func:`check_declared`); truncated or corrupt data
    is an :class:`InputError` naming ``source``, never an image with the decoder's grey fill: the
    structural check of :func:`encoded_image_damage` first, then any damage the decoder reports
    (libjpeg only warns about corrupt data).
    """
    return _to_rgb(_decode(data, source), source)


def _decode(data: bytes, source) -> np.ndarray:
    """The stored pixels (BGR, any bit depth) of encoded image bytes, or InputError."""
    check_declared(image_header(data[:HEADER_BYTES]), source)
    damage = encoded_image_damage(data)
    if damage:
        raise InputError(source, damage)
    with native_output() as said:
        arr = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    said = said[0] if said else ""
    if arr is None:
        detail = first_line(said)
        raise InputError(source, "not a readable image (corrupt or unsupported format"
                                 + (f"; the decoder says: {detail})" if detail else ")"))
    damage = DECODER_DAMAGE.search(said)
    if damage:
        raise InputError(source, f"corrupt image data (the decoder says: {damage.group(0).strip()})")
    return arr


def _read_head(path: Path, count: int) -> bytes:
    try:
        with open(path, "rb") as f:
            return f.read(count)
    except OSError as exc:
        raise InputError(path, f"cannot read the file ({exc.strerror or exc})") from None


def read_stored(path: str | os.PathLike) -> np.ndarray:
    """The stored pixels of an image file, as OpenCV decodes them (BGR, any bit depth), read in bounded
    memory: a header declaring too many pixels or channels, and a file larger than the pixel bound can
    need (:data:`MAX_FILE_BYTES_PER_PIXEL` a pixel), are refused before the body is read."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    size = path.stat().st_size
    bound = max_pixels_now()
    check_declared(image_header(_read_head(path, HEADER_BYTES)), path)
    if size > bound * MAX_FILE_BYTES_PER_PIXEL + HEADER_BYTES:
        raise InputError(path, f"{size:,} bytes is more than an image of at most {bound:,} pixels takes "
                               f"({MAX_FILE_BYTES_PER_PIXEL} bytes a pixel; --max-pixels {bound}): not an image "
                               "fogsim reads")
    return _decode(_read_head(path, size + 1), path)


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as RGB (uint8 or uint16, as stored; float32 for EXR)."""
    return _to_rgb(read_stored(path), str(path))


def _to_rgb(arr: np.ndarray, source: str) -> np.ndarray:
    if arr.ndim == 2:
        return np.repeat(arr[:, :, None], 3, axis=2)
    if arr.shape[2] == 4:
        arr = arr[:, :, :3]
    if arr.shape[2] != 3:
        raise InputError(source, f"expected an RGB image, got {arr.shape[2]} channels")
    return np.ascontiguousarray(arr[:, :, ::-1])


#: the one 16 → 8 bit conversion (JPEG holds 8 bits): v8 = round(v16 · 255 / 65535)
TO_8BIT = "round(v * 255 / 65535)"


def to_8bit(rgb: np.ndarray) -> np.ndarray:
    """An 8-bit copy of a uint8/uint16 image, scaled by :data:`TO_8BIT` (uint8 is returned as is)."""
    if rgb.dtype == np.uint8:
        return rgb
    if rgb.dtype != np.uint16:
        raise ValueError(f"only uint8 and uint16 images convert to 8 bit, got {rgb.dtype}")
    return np.rint(rgb.astype(np.float32) * np.float32(255.0 / 65535.0)).astype(np.uint8)


def encode_image(rgb: np.ndarray, suffix: str = ".png") -> bytes:
    """Encode an RGB uint8/uint16 array (PNG keeps 16 bit). JPEG takes uint8 only: a 16-bit
    array is refused rather than saturated (convert it with :func:`to_8bit` first)."""
    if suffix.lower() in (".jpg", ".jpeg") and rgb.dtype != np.uint8:
        raise ValueError(f"JPEG holds 8-bit values, got a {rgb.dtype} image: convert it first (fileio.to_8bit)")
    if rgb.ndim == 3:
        rgb = np.ascontiguousarray(rgb[:, :, ::-1])
    ok, buf = cv2.imencode(suffix, rgb)
    if not ok:
        raise ValueError(f"OpenCV could not encode a {rgb.dtype} {rgb.shape} array as {suffix}")
    return buf.tobytes()


def write_image(path: str | os.PathLike, rgb: np.ndarray) -> None:
    """Write an RGB (or single-channel) array atomically; the format follows the suffix."""
    atomic_write_bytes(path, encode_image(rgb, Path(path).suffix or ".png"))


# ----------------------------------------------------------------------------- depth
def read_exr_channels(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """All channels of an EXR file (single- or multi-layer), name → H×W array."""
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise InputError(path, "file not found")
    check_declared(exr_header(_read_head(path, HEADER_BYTES)), path)
    error = None
    with native_output() as said:  # OpenEXR prints its own lines on damaged files: keep them off the terminal
        try:
            with OpenEXR.File(str(path), separate_channels=True) as f:
                channels = {name: np.array(ch.pixels) for name, ch in f.channels().items()}
        except Exception as exc:  # OpenEXR raises plain RuntimeError/ValueError on corrupt files
            error = exc
    said = said[0] if said else ""
    damage = first_line(said, str(path))
    if error is not None or _EXR_DAMAGE.search(said):
        detail = damage or str(error)
        raise InputError(path, f"not a readable EXR file (truncated or corrupt: {detail})" if damage
                         else f"not a readable EXR file ({detail})")
    return channels


#: what OpenEXR prints when it skips damaged data
_EXR_DAMAGE = re.compile(r"EXR_ERR_|Exception raised reading|corrupt", re.IGNORECASE)


#: channel names tried, in order, when an EXR holds depth
EXR_DEPTH_CHANNELS = ("Z", "depth", "Depth", "ViewLayer.Depth.Z", "Depth.Z", "Y", "R", "V")


def write_depth(path: str | os.PathLike, depth: np.ndarray) -> None:
    """Write H×W float32 metres as EXR (one float channel ``Y``, ZIP) or ``.npy``, by suffix.

    EXR goes through OpenCV when its build has an EXR encoder (the 4.x wheels), because this
    also runs inside Debian's Blender 3.4, where the OpenEXR package crashes the process;
    OpenCV builds without one (the 5.x wheels) write through the OpenEXR package instead.
    """
    path = Path(path)
    depth = np.ascontiguousarray(depth, dtype=np.float32)
    if path.suffix == ".npy":
        import io as _io

        buf = _io.BytesIO()
        np.save(buf, depth)
        atomic_write_bytes(path, buf.getvalue())
        return
    if not cv2.haveImageWriter(".exr"):
        _write_exr_openexr(path, depth)
        return
    ok, data = cv2.imencode(".exr", depth, [cv2.IMWRITE_EXR_TYPE, cv2.IMWRITE_EXR_TYPE_FLOAT,
                                            cv2.IMWRITE_EXR_COMPRESSION, cv2.IMWRITE_EXR_COMPRESSION_ZIP])
    if not ok:
        raise ValueError(f"OpenCV could not encode a {depth.shape} depth map as EXR")
    atomic_write_bytes(path, data.tobytes())


def _write_exr_openexr(path: Path, depth: np.ndarray) -> None:
    """The same file (one float channel ``Y``, ZIP) through the OpenEXR package."""
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_path(path) as tmp:
        with OpenEXR.File(header, {"Y": depth}) as f:
            f.write(str(tmp))


def write_rgb_exr(path: str | os.PathLike, rgb: np.ndarray) -> None:
    """Write an H×W×3 float32 scene-linear RGB image as EXR (channels R, G, B, ZIP), atomically.

    Same route as :func:`write_depth`: OpenCV when it has an EXR encoder, else the OpenEXR package.
    """
    path = Path(path)
    rgb = np.ascontiguousarray(rgb, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"an RGB EXR needs an H×W×3 array, got shape {rgb.shape}")
    if not cv2.haveImageWriter(".exr"):
        import OpenEXR

        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        with atomic_path(path) as tmp:
            with OpenEXR.File(header, {c: np.ascontiguousarray(rgb[:, :, i]) for i, c in enumerate("RGB")}) as f:
                f.write(str(tmp))
        return
    ok, data = cv2.imencode(".exr", np.ascontiguousarray(rgb[:, :, ::-1]),
                            [cv2.IMWRITE_EXR_TYPE, cv2.IMWRITE_EXR_TYPE_FLOAT,
                             cv2.IMWRITE_EXR_COMPRESSION, cv2.IMWRITE_EXR_COMPRESSION_ZIP])
    if not ok:
        raise ValueError(f"OpenCV could not encode a {rgb.shape} image as EXR")
    atomic_write_bytes(path, data.tobytes())


def read_rgb_exr(path: str | os.PathLike) -> np.ndarray:
    """An EXR's R, G, B channels as H×W×3 float32 (what :func:`write_rgb_exr` writes)."""
    ch = read_exr_channels(path)
    if not all(c in ch for c in "RGB"):
        raise InputError(path, f"not an RGB EXR (channels {sorted(ch)})")
    return np.stack([ch[c] for c in "RGB"], axis=-1).astype(np.float32)


def read_depth_file(path: str | os.PathLike, png_scale: float | None = None) -> np.ndarray:
    """Read a depth map in metres as H×W float32.

    ``.exr``: the first channel of ``EXR_DEPTH_CHANNELS`` present. ``.npy``: a 2-D array.
    ``.png``/``.tif``: 16-bit integers times ``png_scale`` metres per unit (required; an
    8-bit file is refused because it cannot hold metric depth). Values are returned as
    stored: 0 means a hole, +inf no hit; the caller validates.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "depth file not found")
    suffix = path.suffix.lower()
    if suffix == ".exr":
        channels = read_exr_channels(path)
        name = next((c for c in EXR_DEPTH_CHANNELS if c in channels), None)
        if name is None:
            raise InputError(path, f"no depth channel (looked for {', '.join(EXR_DEPTH_CHANNELS)}; "
                                   f"found {', '.join(channels) or 'none'})")
        depth = channels[name]
    elif suffix == ".npy":
        depth = read_npy(path, lambda dtype, shape: _check_depth_npy(path, dtype, shape))
        if depth.ndim == 3 and depth.shape[2] == 1:
            depth = depth[:, :, 0]
    elif suffix in (".png", ".tif", ".tiff"):
        raw = read_uint16_map(path)
        if png_scale is None:
            raise InputError(path, "a 16-bit depth image needs a scale in metres per unit "
                                   "(--depth-scale)")
        depth = raw.astype(np.float32) * np.float32(png_scale)
    else:
        raise InputError(path, f"unsupported depth format {suffix!r} (use .exr, .npy or 16-bit .png)")
    if depth.ndim != 2:
        raise InputError(path, f"depth must be a single-channel map, got shape {depth.shape}")
    return depth.astype(np.float32, copy=False)


def _check_depth_npy(path: Path, dtype: np.dtype, shape: tuple[int, ...]) -> None:
    """A depth ``.npy``'s header: real numbers, H×W (or H×W×1), within the pixel bound."""
    if dtype.kind not in "fiu" or dtype.names:
        raise InputError(path, f"depth must hold real numbers (a float or integer array), got {dtype}")
    if len(shape) not in (2, 3) or (len(shape) == 3 and shape[2] != 1):
        raise InputError(path, f"depth must be a single-channel map, got shape {shape}")
    check_declared(ImageHeader("npy", shape[1], shape[0], 1), path)


def read_uint16_map(path: str | os.PathLike) -> np.ndarray:
    """Read a single-channel 16-bit PNG/TIFF exactly (never through OpenCV's 8-bit default)."""
    path = Path(path)
    raw = read_stored(path)
    if raw.ndim == 3:
        raise InputError(path, f"expected a single-channel 16-bit map, got {raw.shape[2]} channels")
    if raw.dtype != np.uint16:
        raise InputError(path, f"expected 16-bit integers, got {raw.dtype} (an 8-bit image cannot "
                               "hold this map; was an RGB or preview image passed?)")
    return raw
