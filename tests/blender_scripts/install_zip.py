"""Install a packaged add-on zip into a clean Blender and build a scene with it.

``blender -b --factory-startup -P install_zip.py -- ZIP legacy`` or ``python install_zip.py ZIP extension``
(bpy module). Uses only what the zip brings: no checkout, no venv on sys.path.
"""
import json
import sys

import bpy

args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
path, kind = args
if kind == "legacy":
    bpy.ops.preferences.addon_install(filepath=path)
    bpy.ops.preferences.addon_enable(module="fogsim_blender")
else:
    bpy.ops.extensions.package_install_files(filepath=path, repo="user_default", enable_on_install=True)
import cv2  # noqa: E402  (from the zip's wheels)

import fogsim  # noqa: E402  (from the zip's lib/)

s = bpy.context.scene.fogsim
s.preset, s.resolution = "default", "96x64"
n = len(bpy.data.objects)
result = bpy.ops.fogsim.build_scene()
print("RESULT " + json.dumps({"build": list(result), "objects": len(bpy.data.objects) - n,
                              "fogsim": fogsim.__file__, "cv2": cv2.__file__}))
