"""The add-on's Source / Sky / Assets controls through its operators, headless (run by tests/test_addon_sources.py).

    python addon_sources.py OUT_DIR SCENE.blend UNLABELLED.blend ASSET_LIBRARY     # bpy module

Sets the panel's properties and reads back the RenderConfig / scene job they make, renders the
open scene (*Source: current scene*) with ``bpy.ops.fogsim.render_dataset`` and compares the
user's data before and after, and collects the panel messages of the refusals. Prints one JSON
line (``RESULT {...}``).
"""
import hashlib
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
for site in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")):
    sys.path.insert(1, str(site))

import bpy  # noqa: E402

import blender_addon  # noqa: E402
from fogsim.render.blender import addon, panel_options  # noqa: E402
from fogsim.render.blender.scene_mode import open_blend  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
out, blend, unlabelled, library = Path(args[0]), Path(args[1]), Path(args[2]), Path(args[3])
out.mkdir(parents=True, exist_ok=True)
blender_addon.register()
r = {}


def call(op):
    """An operator's result and the error Blender raises for its ERROR report (None when none)."""
    try:
        return list(op()), None
    except RuntimeError as exc:
        return None, str(exc)


def config_error(s) -> str | None:
    try:
        panel_options.config(s)
    except Exception as exc:  # what the operators turn into a panel message
        return addon._problem(exc)
    return None


def settings(**values):
    s = bpy.context.scene.fogsim
    s.preset, s.seed, s.frame, s.frames, s.resolution, s.samples = "default", 1, 0, 1, "96x64", 2
    for k, v in values.items():
        setattr(s, k, v)
    return s


# ---- preset source: Sky and Assets reach the RenderConfig
s = settings(sky="hdri", hdri="sunset")
r["hdri_name"] = panel_options.config(s).lighting
# a 2×1 Radiance HDR of white (the preset loader decodes it once, refusing NaN or garbage)
(out / "sky.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n" + bytes([128, 128, 128, 129]) * 2)
s.hdri, s.hdri_file = "FILE", str(out / "sky.hdr")
r["hdri_file"] = panel_options.config(s).lighting
s.sky = "overcast"
r["overcast"] = panel_options.config(s).lighting
s.preset, s.sky = "hdri", "procedural"
r["procedural_over_hdri_preset"] = panel_options.config(s).lighting
s.sky = "PRESET"
r["hdri_preset"] = panel_options.config(s).lighting.get("sky")
s = settings(lidar="hdl64e")  # the LiDAR choice reaches the RenderConfig (and NONE turns one off)
r["lidar"] = panel_options.config(s).lidar_sensor.beams, [i.identifier for i in s.bl_rna.properties["lidar"].enum_items]
s.lidar = "NONE"
r["no_lidar"] = panel_options.config(s).lidar
s = settings(radar="ars408-lr")  # the radar choice likewise
r["radar"] = panel_options.config(s).radar_sensor.name, [i.identifier for i in s.bl_rna.properties["radar"].enum_items]
s.radar = "NONE"
r["no_radar"] = panel_options.config(s).radar
s = settings()
s.preset, s.assets = "default", str(library)
r["assets"] = {k: sorted(Path(p).name for p in v) for k, v in panel_options.config(s).assets["files"].items()}

# ---- preset source: refusals become panel messages
s = settings(sky="hdri", hdri="FILE", hdri_file=str(out / "missing.exr"))
r["missing_hdri"] = call(bpy.ops.fogsim.render_dataset), s.status
s = settings(sky="hdri", hdri="FILE", hdri_file=str(out / "sky.png"))
r["hdri_not_exr"] = config_error(s)
s = settings(sky="overcast", time_of_day="night")
r["night_sky"] = call(bpy.ops.fogsim.render_dataset), s.status
s = settings(assets=str(out / "no_such_folder"), output=str(out / "bad_assets"))
r["bad_assets"] = call(bpy.ops.fogsim.render_dataset), s.status
(out / "odd" / "spaceship").mkdir(parents=True)
s.assets = str(out / "odd")
r["odd_assets"] = call(bpy.ops.fogsim.render_dataset)
r["bad_assets_written"] = (out / "bad_assets").exists()


# ---- current scene: options reach the scene job; a render leaves the user's scene as it was
def state() -> dict:
    """What the user could see change: data-blocks, object flags and matrices, render settings, the frame."""
    scene, layer = bpy.context.scene, bpy.context.view_layer
    rd = scene.render
    return {"counts": {k: len(getattr(bpy.data, k)) for k in ("objects", "meshes", "collections", "scenes", "cameras",
                                                                "lights", "materials", "worlds", "node_groups")},
            # Blender's "Render Result" (as after F12) is not the user's data and is never saved
            "images": sorted(i.name for i in bpy.data.images if i.type != "RENDER_RESULT"),
            "scenes": sorted(sc.name for sc in bpy.data.scenes),
            "objects": {o.name: [o.hide_render, o.hide_viewport, o.hide_get(view_layer=layer), o.pass_index,
                                 [list(row) for row in o.matrix_world], o.get("fogsim_class"), len(o.modifiers)]
                        for o in bpy.data.objects},
            "render": [scene.frame_current, scene.frame_start, scene.frame_end, rd.engine, rd.resolution_x,
                       rd.resolution_y, rd.resolution_percentage, rd.filepath, rd.image_settings.file_format,
                       rd.use_motion_blur, rd.use_compositing, scene.cycles.samples, scene.cycles.seed,
                       scene.camera.name if scene.camera else None, scene.world.name if scene.world else None],
            "passes": [layer.use_pass_z, layer.use_pass_object_index, layer.name]}


def digest(path: Path) -> list:
    return [hashlib.sha256(path.read_bytes()).hexdigest(), path.stat().st_mtime_ns]


scene = open_blend(blend, quiet=True)
scene.frame_set(2)
blend_before = digest(blend)
before = state()
s = settings(source="SCENE", camera="Camera", frame_range="1:3:2", levels_kind="visibility", levels="100,50",
             fog_model="koschmieder", output=str(out / "probe"))
job = panel_options.scene_job(s, scene)
try:
    r["job"] = {"frames": list(job.frames), "levels": [lv.key for lv in job.config.levels],
                "camera": job.camera.name, "resolution": list(job.config.resolution), "seed": job.config.seed,
                "fog": job.config.fog_model.get("kind"), "summary": job.summary}
finally:
    job.close()
s.levels_kind, s.levels, s.output = "beta", "clear,0.06", str(out / "scene_ds")
r["render"] = call(bpy.ops.fogsim.render_dataset)
r["render_status"] = s.status
s.status = ""
r["same_state"] = state() == before
r["diff"] = {k: [before[k], v] for k, v in state().items() if v != before[k]}
r["blend_untouched"] = digest(blend) == blend_before
r["is_dirty"] = bpy.data.is_dirty
s = settings(source="SCENE", camera="NoSuchCamera", output=str(out / "no_camera"))
r["no_camera"] = call(bpy.ops.fogsim.render_dataset), s.status
s = settings(source="PRESET", frame=0)
bpy.ops.fogsim.build_scene()  # a procedural street in the user's scene, then Source: current scene
s = settings(source="SCENE", camera="Camera", output=str(out / "built_ds"))
r["built_street"] = call(bpy.ops.fogsim.render_dataset), s.status
bpy.ops.fogsim.clear_scene()

scene = open_blend(unlabelled, quiet=True)
s = settings(source="SCENE", output=str(out / "unlabelled_ds"))
r["unlabelled"] = call(bpy.ops.fogsim.render_dataset), s.status
r["unlabelled_written"] = (out / "unlabelled_ds").exists()
blender_addon.unregister()
print("RESULT " + json.dumps(r))
