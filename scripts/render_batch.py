#!/usr/bin/env python3
"""``fogsim render`` for the Blender binary: the thin entry that ``blender -b -P`` needs.

    blender -b -P scripts/render_batch.py -- --preset default --frames 200 --out OUT
    python scripts/render_batch.py --preset default --frames 200 --out OUT   # = fogsim render …

It makes fogsim and its dependencies importable inside Blender's own Python (the checkout,
then ./.venv's site-packages or $FOGSIM_SITE_PACKAGES) and runs :mod:`fogsim.cli.render`:
the same options, frame loop and exit codes (0 done, 1 some frames failed, 2 usage or setup).
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bootstrap() -> None:
    """Make fogsim and its dependencies importable, also inside Debian's Blender binary."""
    sys.path.insert(0, str(ROOT))
    try:
        import cv2  # noqa: F401
        import numpy  # noqa: F401
        return
    except ImportError:
        pass
    candidates = [os.environ.get("FOGSIM_SITE_PACKAGES", "")]
    candidates += [str(p) for p in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages"))]
    for site in filter(None, candidates):
        if Path(site).is_dir():
            sys.path.insert(1, site)
            return
    sys.exit("fogsim: error: this Python lacks numpy/OpenCV; install the project (pip install -e .) "
             "into ./.venv or set FOGSIM_SITE_PACKAGES to a site-packages folder that has them")


def _argv() -> list[str]:
    """Arguments after ``--`` when run by Blender, else the usual ones."""
    if "--" in sys.argv:
        return sys.argv[sys.argv.index("--") + 1:]
    return [] if _inside_blender_binary() else sys.argv[1:]


def main() -> int:
    _bootstrap()
    from fogsim.cli.render import main as render_main

    return render_main(_argv(), prog="render_batch.py")


def _inside_blender_binary() -> bool:
    return Path(sys.argv[0]).name.startswith("blender")


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    if _inside_blender_binary():
        os._exit(code)  # blender -b -P would otherwise exit 0 whatever the script returned
    sys.exit(code)
