"""Register the add-on, set the new panel properties and run its operators, headless.

``python addon_preview.py OUT_DIR`` (bpy module) or ``blender -b -P addon_preview.py -- OUT_DIR``.
Writes OUT_DIR/clear.png, depth.npy (planar Z), intrinsics.json, preview.png (the Blender image's pixels read back) and
prints one JSON line with what happened; the test checks the fog against the formula.
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

import blender_addon  # noqa: E402
from fogsim.io.images import write_image  # noqa: E402
from fogsim.render.blender import addon  # noqa: E402
from fogsim.render.blender.preview import IMAGE_NAME, image_pixels  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
out = Path(args[0])
out.mkdir(parents=True, exist_ok=True)
blender_addon.register()
s = bpy.context.scene.fogsim
s.preset, s.seed, s.frame, s.frames = "default", 3, 0, 1
s.resolution, s.samples, s.output = "96x64", 2, str(out / "ds")
r = {"scenes_before": len(bpy.data.scenes), "objects_before": len(bpy.data.objects)}


def call(op):
    """An operator's result and the error Blender raises for its ERROR report (None when none)."""
    try:
        return list(op()), None
    except RuntimeError as exc:
        return None, str(exc)


# class assignment on the selection
for name in ("a", "b", "c"):
    obj = bpy.data.objects.new(name, None)
    bpy.context.scene.collection.objects.link(obj)
bpy.context.view_layer.update()
for obj in bpy.context.scene.collection.objects:
    obj.select_set(obj.name in ("a", "b"))
s.assign_class = "pedestrian"
r["assign"] = call(bpy.ops.fogsim.assign_class)
r["classes"] = {o.name: o.get("fogsim_class") for o in bpy.data.objects if o.name in ("a", "b", "c")}
s.assign_class = "NONE"
bpy.data.objects["a"].select_set(False)
r["unassign"] = call(bpy.ops.fogsim.assign_class)
r["classes_after_unassign"] = {o.name: o.get("fogsim_class") for o in bpy.data.objects if o.name in ("a", "b")}
for obj in list(bpy.data.objects):
    obj.select_set(False)
r["assign_none_selected"] = call(bpy.ops.fogsim.assign_class)
r["status_none_selected"] = s.status
for name in ("a", "b", "c"):
    bpy.data.objects.remove(bpy.data.objects[name])

# a bad β list: reported (Blender raises its report for a script caller), the panel says why
s.levels_kind, s.levels = "beta", "0.06,fog"
r["bad_levels_render"] = call(bpy.ops.fogsim.render_dataset)
r["bad_levels_status"] = s.status
r["bad_levels_preview"] = call(bpy.ops.fogsim.preview_fog)
r["bad_output_written"] = (out / "ds").exists()
s.levels_kind, s.levels = "visibility", "100,0"
r["bad_visibility"] = call(bpy.ops.fogsim.preview_fog)

# the preview at one β, with visibility levels and night set (both must reach the config)
s.levels_kind, s.levels, s.time_of_day = "visibility", "50,100", "day"
config = addon._config(s)
r["config_levels"] = [lv.key for lv in config.levels]
s.time_of_day = "night"
r["config_night"] = addon._config(s).lighting.get("time_of_day")
s.time_of_day = "PRESET"
s.preview_beta = 0.06
r["preview"] = call(bpy.ops.fogsim.preview_fog)
r["status"] = s.status
img = bpy.data.images.get(IMAGE_NAME)
r["image"] = None if img is None else list(img.size)
preview = addon._state["preview"]
write_image(out / "clear.png", preview.clear)
np.save(out / "depth.npy", preview.depth)
(out / "intrinsics.json").write_text(json.dumps(preview.meta["camera"]["intrinsics"]))
write_image(out / "preview.png", image_pixels(img))
r["records"] = [{"bbox": rec["bbox"], "class": rec["class"]} for rec in preview.records]

# the volumetric preview: a second, Combined-only render with the fog layer at the preview β
s.fog_model, s.fog_medium, s.preview_boxes = "volumetric", "ea", False
r["volumetric"] = call(bpy.ops.fogsim.preview_fog)
r["volumetric_status"] = s.status
vol = addon._state["preview"]
write_image(out / "volumetric.png", image_pixels(bpy.data.images[IMAGE_NAME]))
write_image(out / "volumetric_clear.png", vol.clear)
r["scenes_after"] = len(bpy.data.scenes)
r["objects_after"] = len(bpy.data.objects)
blender_addon.unregister()
r["unregistered"] = not hasattr(bpy.types.Scene, "fogsim")
print("RESULT " + json.dumps(r))
