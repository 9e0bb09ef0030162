"""Paths from the command line: resolved with a symlink loop as one line naming it, and every path argument
of a command checked for loops before the command runs.
"""
from __future__ import annotations

import errno
import os
from pathlib import Path

from fogsim.errors import InputError

__all__ = ["check_path_arguments", "loop_problem", "resolve_path", "with_checked_paths"]


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
