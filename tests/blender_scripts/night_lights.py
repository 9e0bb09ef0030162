"""A street lamp, a car driving away and a wall: by day, at night, and at night without Light objects.

Run by tests/test_night.py: ``python night_lights.py OUT.json`` (bpy module) or
``blender -b -P night_lights.py -- OUT.json``. Writes what the test checks as JSON: whether the
passes are identical, mean brightness, and the brightness the lights add (night − night without
Light objects, i.e. only the emissive lenses and windows) in the lamp's pool on the road, in the
headlights' beam on the wall ahead of the car and on a patch of that wall outside the beam, and
how many faces Blender would shade smooth (none: Blender ≥ 4.1 makes added polygons smooth, and
a smooth road box left the road black under grazing light).
"""
import copy
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
for site in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")):
    sys.path.insert(1, str(site))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

from fogsim.camera import Intrinsics  # noqa: E402
from fogsim.render.blender import build, cycles  # noqa: E402
from fogsim.render.blender.scratch import clear  # noqa: E402
from fogsim.scene.assets import sample_asset  # noqa: E402
from fogsim.scene.lights import apply_night  # noqa: E402
from fogsim.scene.pose import camera_to_world, transform, world_to_camera  # noqa: E402

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else sys.argv[1]
K = Intrinsics.from_hfov(60.0, 96, 64)
w2c = world_to_camera(camera_to_world([0.0, 0.0, 1.5], pitch_deg=-5.0))
rng = np.random.default_rng(4)
pole = sample_asset("pole", rng, height=7.0, arm=1.5, double=False)
car = sample_asset("car", rng, lights_on=False)
LAMP_XY = (5.0 - 1.5 + 0.125, 14.0)  # the pole at x = 5 turned 90° puts its lamp head 1.5 m toward −x
CAR = (-2.2, 10.0)  # driving away from the camera (heading +y), toward the wall
WALL_Y = 25.0
ROAD = (-5.0, 9.0)  # road 55° off the lamp's nadir (~1/6 of the pool's irradiance), beside the car
BEAM, OUTSIDE = (-2.2, WALL_Y, 0.8), (-12.0, WALL_Y, 0.8)  # on the wall: in the beam, 33° off its axis
day = {"seed": 0, "street": {"lanes": 2, "lane_width": 3.4},
       "camera": {"intrinsics": K.to_dict(), "world_to_camera": w2c.tolist()},
       "lighting": {"sun_elevation_deg": 40.0, "sun_azimuth_deg": 30.0, "sun_strength": 4.0, "sky_strength": 0.3},
       "objects": [{"id": 1, "class": "road", "asset": {"type": "box", "params": {"size": [60, 200, 0.1],
                                                                                    "material": "asphalt"}},
                    "transform": transform([0, 60, -0.1]).tolist()},
                   {"id": 2, "class": "pole", "asset": pole, "transform": transform([5.0, 14.0, 0.0], 90.0).tolist()},
                   {"id": 3, "class": "car", "asset": car, "transform": transform([*CAR, 0.0], 0.0).tolist()},
                   {"id": 4, "class": "building", "asset": {"type": "box", "params": {"size": [60, 1, 12],
                                                                                        "material": "facade_plaster"}},
                    "transform": transform([0, WALL_Y + 0.5, 0]).tolist()}]}
night = apply_night(copy.deepcopy(day), {"time_of_day": "night"}, np.random.default_rng(0))
dark = copy.deepcopy(night)
dark["lighting"]["sources"] = []

scene = bpy.data.scenes.new("night_test")
cycles.configure(scene, {"samples": 16, "denoise": False}, seed=1)
passes = {}
before = [len(bpy.data.lights), len(bpy.data.objects)]
for name, desc in (("day", day), ("night", night), ("dark", dark)):
    built = build.build(desc, scene)
    n_lights = sum(o.type == "LIGHT" for o in built.objects)
    smooth = sum(sum(p.use_smooth for p in m.polygons) for m in built.meshes)
    passes[name] = (cycles.render(scene), n_lights)
    clear(built)


def pixel(x, y, z=0.0):
    c = w2c[:3, :3] @ np.array([x, y, z]) + w2c[:3, 3]
    return int(round(K.fx * c[0] / c[2] + K.cx)), int(round(K.fy * c[1] / c[2] + K.cy))


def patch(img, x, y, z=0.0, r=1):
    u, v = pixel(x, y, z)
    return float(np.median(img[max(v - r, 0):v + r + 1, max(u - r, 0):u + r + 1]))  # median: no fireflies


luma = {k: p.rgb_linear @ np.array([0.2126, 0.7152, 0.0722]) for k, (p, _) in passes.items()}
added = luma["night"] - luma["dark"]  # what the Light objects add
d, n = passes["day"][0], passes["night"][0]
json.dump({"blender": bpy.app.version_string,
           "lights": {k: v for k, (_, v) in passes.items()}, "sources": len(night["lighting"]["sources"]),
           "smooth_faces": smooth,
           "leftover": [len(bpy.data.lights) - before[0], len(bpy.data.objects) - before[1]],
           "index_equal": bool(np.array_equal(d.mask, n.mask)),
           "depth_equal": bool(np.array_equal(d.depth, n.depth)),
           "car_pixels": int((d.mask == 3).sum()), "pole_pixels": int((d.mask == 2).sum()),
           "mean_day": float(luma["day"].mean()), "mean_night": float(luma["night"].mean()),
           "patch_ids": [int(d.mask[pixel(*q)[1], pixel(*q)[0]]) for q in (LAMP_XY, ROAD, BEAM, OUTSIDE)],
           "pool": patch(added, *LAMP_XY), "road": patch(added, *ROAD),
           "beam": patch(added, *BEAM), "outside": patch(added, *OUTSIDE)},
          open(out, "w"))
