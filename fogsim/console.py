"""What reaches the terminal: output captured at the file-descriptor level, and ``--quiet``.

Blender, Cycles and child processes write to file descriptors 1 and 2 directly, not through
Python's ``sys.stdout``/``sys.stderr``, so ``contextlib.redirect_stdout`` cannot hold them back.
:func:`captured_fds` points both descriptors at temporary files while a block runs and restores
them afterwards, also when the block raises (Python's and C's buffers are flushed either side,
so nothing written inside leaks out later). Two users:

* :func:`fogsim.render.blender.output.blender_output` — around every call into Blender;
* :func:`summary_only` — ``--quiet`` for the benches, whose report ends with one summary line.

:func:`progress_bar` is the progress display of the long commands (``fogsim render``, ``fogsim fog``).
"""
from __future__ import annotations

import ctypes
import os
import re
import sys
import tempfile
from contextlib import contextmanager

#: a tqdm progress bar as captured (``desc:  50%|█████     | 1/2 [00:05<00:05, …]``)
PROGRESS_BAR = re.compile(r"^[^|]*\d+%\|.*\|")
#: the size (columns, lines) of a terminal that reports none: a pseudo-terminal opened without a size, as
#: ``script``, an IDE or a CI runner opens one, reports 0 × 0, and tqdm then draws nothing at all
FALLBACK_SIZE = (80, 24)


def progress_bar(total: int, desc: str, unit: str, quiet: bool = False):
    """The progress bar of a long command: a tqdm bar on stderr (``desc: 50%|█████     | 1/2 [00:05<00:05,
    5.0s/unit]``), redrawn in place on a terminal, one line per update elsewhere; none with ``quiet``. Lines
    meant to appear above it go through its ``write``. A terminal that reports a size of 0 is taken as
    ``$COLUMNS`` × ``$LINES`` (default :data:`FALLBACK_SIZE`)."""
    from tqdm import tqdm

    size = {}
    try:
        fd = sys.stderr.fileno()
        if os.isatty(fd) and 0 in os.get_terminal_size(fd):
            env = [os.environ.get(k, "") for k in ("COLUMNS", "LINES")]
            cols, lines = (int(e) if e.isdigit() and int(e) > 0 else d for e, d in zip(env, FALLBACK_SIZE))
            size = {"ncols": cols, "nrows": lines}
    except (OSError, ValueError, AttributeError):  # no stderr descriptor (captured, closed)
        pass
    return tqdm(total=total, desc=desc, unit=unit, disable=quiet, **size)


def last_segment(line: str) -> str:
    """What a terminal shows of a captured line: the text after its last carriage return."""
    return line.rsplit("\r", 1)[-1].rstrip()


def flush_all() -> None:
    """Flush Python's stdout/stderr and every C stdio stream (printf output waits in C's buffer
    when fd 1 is not a terminal)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, ValueError, OSError):
            pass
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):  # no C library to ask (not a POSIX system)
        pass


@contextmanager
def captured_fds():
    """Capture file descriptors 1 and 2 while the block runs. Yields a dict that holds, once the
    block has ended and the descriptors are restored, ``{"stdout": [lines], "stderr": [lines]}``.
    Where there is nothing to redirect (a daemon without fds 1 and 2) the block runs as is."""
    lines: dict[str, list[str]] = {"stdout": [], "stderr": []}
    flush_all()
    try:
        saved = (os.dup(1), os.dup(2))
    except OSError:
        yield lines
        return
    files = {"stdout": tempfile.TemporaryFile(), "stderr": tempfile.TemporaryFile()}
    try:
        os.dup2(files["stdout"].fileno(), 1)
        os.dup2(files["stderr"].fileno(), 2)
        yield lines
    finally:
        flush_all()
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in saved:
            os.close(fd)
        for name, f in files.items():
            f.seek(0)
            lines[name] += f.read().decode("utf-8", "replace").splitlines()
            f.close()


@contextmanager
def summary_only(quiet: bool):
    """``--quiet`` for a command whose report ends with its one-line summary (the benches): hold
    back everything the block prints — Python's, C libraries' and child processes' output — then
    print only the last non-empty stdout line, and every stderr line that is not a progress bar
    (errors stay visible, at the end). Without ``quiet`` the block runs untouched."""
    if not quiet:
        yield
        return
    lines = {"stdout": [], "stderr": []}
    try:
        with captured_fds() as lines:
            yield
    finally:  # also when the block raised: its errors must still be seen
        for line in map(last_segment, lines["stderr"]):
            if line.strip() and not PROGRESS_BAR.match(line):
                print(line, file=sys.stderr)
        shown = [line for line in map(last_segment, lines["stdout"]) if line.strip()]
        if shown:
            print(shown[-1])
