"""The temporary files of unfinished writes: hidden, beside their target, named
``.NAME.<host>-<pid>.<random>.part`` so a later run can tell a dead writer's leftovers and delete them
(:func:`remove_stale_parts`, :func:`remove_stale_folders`); what the writers of :mod:`fogsim.io.atomic`
and :mod:`fogsim.io.links` write first.
"""
from __future__ import annotations

import errno
import glob
import os
import shutil
import socket
import tempfile
import time
from pathlib import Path

__all__ = ["PART_SUFFIX", "STALE_FOREIGN_PART_S", "remove_stale_folders", "remove_stale_parts", "target_error",
           "temp_beside", "temp_folder_beside"]

#: the suffix of every temporary file or folder of an unfinished write
PART_SUFFIX = ".part"
STALE_FOREIGN_PART_S = 24 * 3600  # another host's (or an unnamed) leftover is stale after a day
_HOST = socket.gethostname().replace(".", "_").replace("-", "_") or "host"


def temp_beside(path: Path) -> Path:
    """A new empty temporary file beside ``path`` (its folder made if need be); an error names ``path``."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{_HOST}-{os.getpid()}.", suffix=PART_SUFFIX,
                                   dir=path.parent)
    except OSError as exc:
        raise target_error(exc, path) from None
    os.close(fd)
    return Path(tmp)


def temp_folder_beside(path: Path) -> Path:
    """A new empty temporary folder beside ``path`` (``path``'s folder must exist)."""
    return Path(tempfile.mkdtemp(prefix=f".{path.name}.{_HOST}-{os.getpid()}.", suffix=PART_SUFFIX, dir=path.parent))


def target_error(exc: OSError, path: Path) -> OSError:
    """``exc`` as the user would read it: naming the target ``path``, never the hidden temporary file
    (a folder where the file should go, a read-only folder, a full disk …)."""
    if isinstance(exc, IsADirectoryError) or (path.is_dir() and exc.errno in (errno.EISDIR, errno.ENOTEMPTY,
                                                                              errno.EEXIST)):
        return IsADirectoryError(errno.EISDIR, "is a folder, not a file that can be written", str(path))
    named = exc.filename is None or Path(str(exc.filename)).name.endswith(PART_SUFFIX)
    if named and exc.errno is not None:
        return type(exc)(exc.errno, exc.strerror or str(exc), str(path))
    return exc


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
