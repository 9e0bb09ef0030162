"""The GPU query on this Blender: each backend's devices, fogsim's choice, the frame record (JSON).

Run by tests/test_quiet.py as ``python gpu_backends.py OUT.json`` (bpy module) and
``blender -b -P gpu_backends.py -- OUT.json`` (the binary).
"""
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
for site in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")):
    sys.path.insert(1, str(site))

import bpy  # noqa: E402

from fogsim.render.blender.compat import compute_devices, cycles_preferences  # noqa: E402
from fogsim.render.blender.device import find_gpu, use_device  # noqa: E402
from fogsim.render.blender.output import blender_output  # noqa: E402

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else sys.argv[1]
prefs = cycles_preferences()
backends = {}
with blender_output(quiet=True):
    for kind in ("OPTIX", "CUDA", "HIP", "ONEAPI", "METAL"):
        found = compute_devices(prefs, kind)
        backends[kind] = None if found is None else [d.name for d in found]
scene = bpy.data.scenes.new("gpu_probe")
scene.render.engine = "CYCLES"
record = use_device(scene, True)
result = {"version": list(bpy.app.version), "backends": backends, "find_gpu": list(find_gpu()),
          "record": record, "scene_device": scene.cycles.device, "no_gpu_record": use_device(scene, False)}
Path(out).write_text(json.dumps(result))
sys.stdout.flush()
os._exit(0)
