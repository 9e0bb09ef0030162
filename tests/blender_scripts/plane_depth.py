"""Render a wall 10 m ahead and the ground; print depth facts as JSON (run by tests/test_blender.py).

Works as ``python plane_depth.py OUT.json`` (bpy module) and ``blender -b -P plane_depth.py -- OUT.json``.
"""
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
for site in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")):
    sys.path.insert(1, str(site))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

from fogsim.camera import Intrinsics, planar_to_ray  # noqa: E402
from fogsim.render.blender import build  # noqa: E402
from fogsim.render.blender import cycles as render  # noqa: E402
from fogsim.render.blender.scratch import clear  # noqa: E402
from fogsim.scene.pose import camera_to_world, transform, world_to_camera  # noqa: E402

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else sys.argv[1]
K = Intrinsics.from_hfov(60.0, 96, 64)
box = lambda size, mat: {"type": "box", "params": {"size": size, "material": mat}}  # noqa: E731
desc = {"camera": {"intrinsics": K.to_dict(),
                   "world_to_camera": world_to_camera(camera_to_world([0, 0, 1.5])).tolist()},
        "lighting": {"sun_elevation_deg": 40, "sun_azimuth_deg": 30, "sun_strength": 4.0, "sky_strength": 0.3},
        "objects": [{"id": 1, "class": "road", "asset": box([200, 400, 0.1], "asphalt"),
                     "transform": transform([0, 0, -0.1]).tolist()},
                    {"id": 7, "class": "building", "asset": box([40, 1, 3], "facade_brick"),
                     "transform": transform([0, 10.5, 0]).tolist()}]}
counts = lambda: [len(bpy.data.meshes), len(bpy.data.materials), len(bpy.data.objects)]  # noqa: E731
before = counts()
scene = bpy.data.scenes.new("plane_test")
render.configure(scene, {"samples": 2, "denoise": False}, seed=1)
built = build.build(desc, scene)
p = render.render(scene)
clear(built)
ray = planar_to_ray(p.depth, K)
wall = p.mask == 7
v, u = np.nonzero(wall)
expect_ray = 10.0 * np.sqrt(1 + ((u - K.cx) / K.fx) ** 2 + ((v - K.cy) / K.fy) ** 2)
rows = np.arange(64)[:, None] * np.ones((1, 96))
ground = p.mask == 1
expect_ground = 1.5 * K.fy / (rows - K.cy)
json.dump({"blender": bpy.app.version_string, "wall_pixels": int(wall.sum()),
           "wall_depth_min": float(p.depth[wall].min()), "wall_depth_max": float(p.depth[wall].max()),
           "wall_ray_max_abs_err": float(np.abs(ray[wall] - expect_ray).max()),
           "ground_depth_max_rel_err": float(np.abs(p.depth[ground] / expect_ground[ground] - 1).max()),
           "sky_rows_inf": bool(np.isinf(p.depth[:5]).all()),
           "leftover": [a - b for a, b in zip(counts(), before)]},
          open(out, "w"))
