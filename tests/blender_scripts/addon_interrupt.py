"""The add-on's *Render dataset* batch, interrupted: ``python addon_interrupt.py OUT`` (bpy module,
``SIGINT_AT_RENDER=N`` set by the test) renders 2 frames of the default preset through bpy.ops;
the hook sends Ctrl-C inside render N. Prints ``AFTER`` if the operator returned (it must not:
Ctrl-C ends the process, exit 130)."""
import runpy
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
runpy.run_path(str(HERE / "sigint_at_render.py"), run_name="hook")

import bpy  # noqa: E402

import blender_addon  # noqa: E402

out = sys.argv[1]
blender_addon.register()
s = bpy.context.scene.fogsim
s.preset, s.seed, s.frame, s.frames = "default", 3, 0, 2
s.resolution, s.samples, s.output = "48x32", 2, out
result = bpy.ops.fogsim.render_dataset()
print("AFTER", list(result), s.status)
