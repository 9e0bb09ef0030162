"""One file under two names: a hard link where the file system allows one, else a copy — never a symbolic
link."""
from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

from fogsim.io.atomic import atomic_path
from fogsim.io.parts import target_error, temp_beside

__all__ = ["link_or_copy"]


def link_or_copy(source: str | os.PathLike, target: str | os.PathLike) -> str:
    """Make ``target`` hold the bytes of ``source`` (a finished file of the same output): a **hard link**
    where the file system allows one (same device), else a copy; never a symbolic link (a symlinked
    ``source``, which may name a file outside the output, is copied). Returns ``"link"`` or ``"copy"``.

    Atomic as :func:`~fogsim.io.atomic.atomic_path`: the link (or copy) is made beside ``target`` under a
    temporary name and renamed onto it, so a killed run leaves no half-made file and an existing ``target``
    is replaced, never written into. Two names of one file stay safe because every fogsim writer replaces a
    file (a new inode under the old name) instead of writing into it: rewriting either name leaves the
    other's bytes as they were."""
    source, target = Path(source), Path(target)
    try:
        if not target.is_symlink() and target.exists() and os.path.samefile(source, target):
            return "link"  # already one file (a resumed run): rename(2) of a link onto its twin does nothing
    except OSError:
        pass
    tmp = temp_beside(target)
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
        raise target_error(exc, target) from None
    return "link"
