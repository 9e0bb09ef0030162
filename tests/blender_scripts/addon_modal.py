"""*Source: current scene* through the add-on's modal operator in a real Blender window (Xvfb).

    blender --factory-startup -noaudio SCENE.blend -P addon_modal.py -- OUT_DIR RESULT.json

Invokes ``fogsim.render_dataset`` as a click would (``INVOKE_DEFAULT``, window context): the
render runs on the window manager's timer, one frame per event, with the progress bar. A
watcher timer records the panel's status and progress as they change, then writes RESULT.json
(with whether the user's scene is as it was) and quits Blender.
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
from fogsim.render.blender import addon  # noqa: E402

out, result = sys.argv[sys.argv.index("--") + 1:][:2]
blender_addon.register()
seen = {"status": [], "progress": [], "modal": False}


def state() -> list:
    scene = bpy.context.scene
    return [len(bpy.data.objects), len(bpy.data.meshes), len(bpy.data.scenes), scene.frame_current,
            scene.render.engine, scene.cycles.samples, scene.render.resolution_x,
            {o.name: [list(o.location), o.pass_index, o.hide_render] for o in bpy.data.objects}]


def start():
    s = bpy.context.scene.fogsim
    s.source, s.frame_range, s.resolution, s.samples = "SCENE", "1:3:2", "96x64", 2
    s.levels_kind, s.levels, s.output = "beta", "clear,0.06", out
    seen["before"] = state()
    window = bpy.context.window_manager.windows[0]
    area = next(a for a in window.screen.areas if a.type == "VIEW_3D")
    region = next(r for r in area.regions if r.type == "WINDOW")
    with bpy.context.temp_override(window=window, area=area, region=region):
        try:
            seen["invoke"] = list(bpy.ops.fogsim.render_dataset("INVOKE_DEFAULT"))
        except RuntimeError as exc:  # a refusal: report it and stop, no render to watch
            seen["invoke"] = str(exc)
    seen["modal"] = addon._state["timer"] is not None  # the window manager's timer drives the frames
    bpy.app.timers.register(watch, first_interval=0.05)
    return None


def watch():
    s = bpy.context.scene.fogsim
    if not seen["status"] or seen["status"][-1] != s.status:
        seen["status"].append(s.status)
        seen["progress"].append(s.progress)
    if addon._state["job"] is not None:
        return 0.05
    seen["same_state"] = state() == seen["before"]
    seen.pop("before")
    Path(result).write_text(json.dumps(seen))
    bpy.ops.wm.quit_blender()
    return None


bpy.app.timers.register(start, first_interval=1.0)
