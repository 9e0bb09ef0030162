"""Register the add-on, build a scene and render a dataset through bpy.ops, headless.

``python addon_ops.py OUT_DIR [volumetric MEDIUM]`` (bpy module) or ``blender -b -P addon_ops.py -- OUT_DIR …``.
Prints one JSON line with what happened.
"""
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
for site in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")):
    sys.path.insert(1, str(site))

import bpy  # noqa: E402

import blender_addon  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
out = args[0]
blender_addon.register()
s = bpy.context.scene.fogsim
s.preset, s.seed, s.frame, s.frames = "default", 3, 0, 1
s.resolution, s.samples, s.output = "96x64", 2, out
if len(args) > 1:  # "volumetric MEDIUM": the panel's fog model choice
    s.fog_model, s.fog_medium = args[1], args[2]
objects_before = len(bpy.data.objects)
r1 = bpy.ops.fogsim.build_scene()
built = len(bpy.data.objects) - objects_before
r2 = bpy.ops.fogsim.clear_scene()
cleared = len(bpy.data.objects) - objects_before
r3 = bpy.ops.fogsim.render_dataset()
status = s.status
blender_addon.unregister()
print("RESULT " + json.dumps({"build": list(r1), "built_objects": built, "clear": list(r2),
                              "left_after_clear": cleared, "render": list(r3), "status": status,
                              "unregistered": not hasattr(bpy.types.Scene, "fogsim")}))
