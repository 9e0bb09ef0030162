"""A tqdm bar in Blender, then a normal end of the script: Blender 3.4 segfaulted at exit once
tqdm's default (multiprocessing) lock existed; fogsim.render.blender swaps in a thread lock.

Run by tests/test_blender.py: ``blender -b -P tqdm_exit.py`` or ``python tqdm_exit.py``."""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
for site in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")):
    sys.path.insert(1, str(site))

import bpy  # noqa: E402,F401
from tqdm import tqdm  # noqa: E402

import fogsim.render.blender  # noqa: E402,F401

for _ in tqdm(range(3), desc="bar"):
    pass
tqdm.write("written above the bar")
