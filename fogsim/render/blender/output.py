"""Blender's own terminal output, kept off the terminal: the one place that captures it.

Blender and Cycles print from C (``Fra:1 Mem:… | Sample 1/2``, ``Saved: '….exr'``, `` Time: …``,
Blender 5.0's log lines ``00:05.101  render | Saved: …``) straight to file descriptors 1 and 2,
not through Python's ``sys.stdout``, so ``contextlib.redirect_stdout`` cannot catch them and
they break a tqdm bar and ``--quiet``. :func:`blender_output` points fds 1 and 2 at temporary
files around a call into Blender (a render, the GPU query), restores them afterwards — also
when the call raises — and then sorts what was captured, line by line:

* **progress** (the lines above, Cycles' status lines, blank lines, a stray progress bar): dropped
  always. They only repeat what the progress bar and the frame log already say, and Blender 3.4
  prints about 100 of them per frame.
* **errors** (a line that starts with ``Error``/``ERROR`` or an exception's name, a traceback):
  written to stderr always, ``--quiet`` or not — quiet keeps real errors.
* **anything else** (a warning, e.g. ``WARNING CUEW initialization failed``): passed through
  ``tqdm.write`` to the stream it came from, so it appears above the bar instead of through it;
  dropped when ``quiet``.

Passing the unusual lines through (rather than dropping every line) keeps what a user needs to
see — a missing texture, a device warning — without the per-sample noise.
"""
from __future__ import annotations

import re
import sys
from contextlib import contextmanager

from fogsim.console import PROGRESS_BAR, captured_fds, last_segment

#: Blender 5.0's log prefix, ``00:05.101  render           | `` (time, category, bar)
_LOG_PREFIX = re.compile(r"^\d+:\d+\.\d+\s+\S+\s+\|\s?")
#: lines that only report progress (matched after the log prefix is removed)
PROGRESS = re.compile(
    r"^(Fra:\d+ |Saved: |\s*Time: \d|Read blend: |Read prefs: |Writing: |Blender quit$"
    r"|Sample \d+/\d+|Finished$|Updating |Loading render kernels|Synchronizing object)")
WARNING = re.compile(r"^(WARNING|Warning)\b")
ERROR = re.compile(r"^(ERROR|Error)\b|^Traceback |^\w*(Error|Exception): |\berror: ")


def classify(line: str) -> str:
    """``"progress"``, ``"error"`` or ``"other"`` for one captured line (see the module doc)."""
    text = _LOG_PREFIX.sub("", last_segment(line))
    if not text.strip() or PROGRESS.match(text) or PROGRESS_BAR.match(text):
        return "progress"
    if WARNING.match(text):
        return "other"
    return "error" if ERROR.search(text) else "other"


@contextmanager
def blender_output(quiet: bool = False):
    """Capture fds 1 and 2 while the block runs (a render, a device query); then drop Blender's
    progress lines, always show its errors (stderr), and show its other lines through
    ``tqdm.write`` unless ``quiet``. The descriptors are restored even when the block raises."""
    lines = {"stdout": [], "stderr": []}
    try:
        with captured_fds() as lines:
            yield
    finally:
        show(lines, quiet)


def show(lines: dict, quiet: bool = False) -> None:
    """Print captured ``{"stdout": [...], "stderr": [...]}`` lines by the rules above."""
    from tqdm import tqdm

    for stream, line in [("stdout", s) for s in lines["stdout"]] + [("stderr", s) for s in lines["stderr"]]:
        kind = classify(line)
        if kind == "progress" or (kind == "other" and quiet):
            continue
        target = sys.stderr if kind == "error" or stream == "stderr" else sys.stdout
        tqdm.write(last_segment(line), file=target)
