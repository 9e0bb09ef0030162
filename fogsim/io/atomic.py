"""Atomic writes: every fogsim writer writes a temporary file (or folder) beside its target and renames it
onto the target when complete, so a killed job never leaves a half-written output under the real name —
and never writes into an existing file, which is what lets one file have two names
(:func:`fogsim.io.links.link_or_copy`).
"""
from __future__ import annotations

import os
import shutil
from contextlib import contextmanager
from pathlib import Path

from fogsim.io.parts import target_error, temp_beside, temp_folder_beside

__all__ = ["atomic_folder", "atomic_path", "atomic_write_bytes", "create_exclusive"]


@contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path``; on success it is renamed onto ``path``.

    The temporary file is hidden and removed on any error, so a killed or failed job never
    leaves a half-written output under the real name (a SIGKILL can leave the temporary
    file: :func:`~fogsim.io.parts.remove_stale_parts` clears it on resume). The result gets the usual
    permissions (0666 minus the umask), as any other tool's output would.
    """
    path = Path(path)
    tmp = temp_beside(path)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        named = target_error(exc, path)  # a short write says not which file, a rename names the temporary one
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
    tmp = temp_beside(path)
    try:
        tmp.write_bytes(data)
        os.chmod(tmp, 0o666 & ~_umask())
        os.link(tmp, path)
        return True
    except FileExistsError:
        return False
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def atomic_folder(path: str | os.PathLike):
    """Yield a hidden temporary folder beside ``path``, ``.NAME.<host>-<pid>.<random>.part``; on success it
    replaces ``path`` whole (an existing folder there is renamed away, then deleted: the caller decides that
    it may be), so a failed or killed job never leaves a half-written folder under the real name. A failure
    deletes the temporary folder; a SIGKILL can leave it, which :func:`~fogsim.io.parts.remove_stale_folders` clears."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = temp_folder_beside(path)
    except OSError as exc:
        raise target_error(exc, path) from None
    try:
        yield tmp
        os.chmod(tmp, 0o777 & ~_umask())
        if path.is_dir() and not path.is_symlink():
            old = temp_folder_beside(path)
            os.replace(path, old)  # onto the empty folder just made: the old tree moves whole
            os.replace(tmp, path)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
