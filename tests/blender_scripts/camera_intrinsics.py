"""Project points with fogsim's K of a Blender camera and with Blender's own ``world_to_camera_view``;
write the largest pixel difference per camera setting as JSON (run by tests/test_scene_mode.py).

Works as ``python camera_intrinsics.py OUT.json`` (bpy module) and ``blender -b -P … -- OUT.json``.
"""
import itertools
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
for site in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")):
    sys.path.append(str(site))

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from bpy_extras.object_utils import world_to_camera_view  # noqa: E402
from mathutils import Vector  # noqa: E402

from fogsim.render.blender.scene_mode import camera_record  # noqa: E402

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else sys.argv[1]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
scene.collection.objects.link(cam)
scene.camera = cam
cam.location, cam.rotation_euler = (1.0, -9.0, 2.0), (math.radians(80), math.radians(3), math.radians(10))
rng = np.random.default_rng(0)
points = [cam.matrix_world @ Vector((x, y, -z)) for x, y, z in zip(rng.uniform(-3, 3, 50), rng.uniform(-2, 2, 50),
                                                                    rng.uniform(4, 30, 50))]
results = []
for fit, (w, h), (ax, ay), shift in itertools.product(("AUTO", "HORIZONTAL", "VERTICAL"), ((96, 64), (60, 90)),
                                                      ((1, 1), (1, 2), (3, 2)), ((0, 0), (0.07, -0.11))):
    cam.data.sensor_fit, cam.data.lens, cam.data.sensor_width, cam.data.sensor_height = fit, 28.0, 36.0, 20.0
    cam.data.shift_x, cam.data.shift_y = shift
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage, r.pixel_aspect_x, r.pixel_aspect_y = w, h, 100, ax, ay
    bpy.context.view_layer.update()
    rec = camera_record(scene, cam, (w, h), "test scene")
    K, M = np.array(rec["intrinsics"]["K"]), np.array(rec["world_to_camera"])
    err = 0.0
    for p in points:
        c = M[:3, :3] @ np.array(p) + M[:3, 3]
        u, v = (K @ (c / c[2]))[:2]
        x, y, _ = world_to_camera_view(scene, cam, p)
        err = max(err, abs(u - (x * w - 0.5)), abs(v - ((1 - y) * h - 0.5)))
    results.append({"fit": fit, "size": [w, h], "aspect": [ax, ay], "shift": list(shift), "max_err_px": err})
Path(out).write_text(json.dumps(results))
