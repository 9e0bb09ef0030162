"""Memory of a long render run with an asset library: RSS and Blender's datablocks per frame.

Run by tests/test_asset_render.py (and by hand for the figure in docs/own-assets.md):
``python asset_rss.py LIB OUT_DIR FRAMES RESULT.json`` (bpy module) or ``blender -b -P asset_rss.py --
…``. Renders FRAMES tiny frames (48×32, 1 sample, clear only) of the default preset with the
models of LIB in one process, as ``fogsim render --assets LIB`` does (LIB ``-``: no library, the
baseline), and writes the resident set size (MiB, /proc/self/status) and the counts of objects,
meshes, materials and images after each.
"""
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
for site in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")):
    sys.path.insert(1, str(site))

import bpy  # noqa: E402

from fogsim.render.blender.job import RenderJob  # noqa: E402
from fogsim.render.job_options import RunOptions  # noqa: E402
from fogsim.render.preset import load_render_preset  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
lib, out, frames, result = args[0], args[1], int(args[2]), Path(args[3])


def rss_mib() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


config = load_render_preset("default", frames=frames, resolution="48x32", samples=1, levels="clear",
                            assets=None if lib == "-" else lib)
job = RenderJob(config, out, RunOptions(resume=False, quiet=True))
rows = []
library_objects = 0
try:
    while job.todo:
        meta = job.step()
        library_objects += sum(o["asset"]["type"] == "library" for o in meta["scene"]["objects"])
        rows.append({"rss_mib": round(rss_mib(), 1), "objects": len(bpy.data.objects), "meshes": len(bpy.data.meshes),
                     "materials": len(bpy.data.materials), "images": len(bpy.data.images)})
finally:
    job.close()
result.write_text(json.dumps({"blender": bpy.app.version_string, "frames": rows,
                              "library_objects": library_objects}, indent=1))
