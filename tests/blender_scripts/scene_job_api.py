"""The add-on's entry (scene_mode.scene_job) on the open scene: render it (volumetric fog), then
report what of the user's data changed, as JSON (run by tests/test_scene_mode.py).

    python scene_job_api.py FILE.blend OUT_DIR RESULT.json           # bpy module
"""
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import bpy  # noqa: E402

from fogsim.render.blender.scene_mode import open_blend, scene_job  # noqa: E402
from fogsim.render.job_options import RunOptions, SceneOptions  # noqa: E402
from fogsim.render.loop import FrameLoop  # noqa: E402

blend, out, result = sys.argv[1:4]
scene = open_blend(blend, quiet=True)
scene.frame_set(2)
layer = bpy.context.view_layer


def state() -> dict:
    """What the user could see change: data-block counts, visibility flags, pass indices, the frame."""
    return {"counts": {k: len(getattr(bpy.data, k)) for k in ("objects", "meshes", "collections", "scenes",
                                                                "cameras", "lights", "materials")},
            "objects": {o.name: [o.hide_render, o.hide_viewport, o.hide_get(view_layer=layer)
                                 if o.name in layer.objects else None, o.pass_index, list(o.location)]
                        for o in bpy.data.objects},
            "cameras": {c.name: [c.lens, c.clip_start, c.clip_end, c.shift_x, c.shift_y] for c in bpy.data.cameras},
            "frame": scene.frame_current, "engine": scene.render.engine, "samples": scene.cycles.samples,
            "is_dirty_before": bpy.data.is_dirty}


before = state()
job = scene_job(scene, out, SceneOptions(frame_range="1:3:2", levels="clear,0.06", samples=1, fog="volumetric"),
                RunOptions(quiet=True))
try:
    loop = FrameLoop(job)
    loop.run()
    loop.finish(sharded=False)
finally:
    job.close()
after = state()
Path(result).write_text(json.dumps({"before": before, "after": after, "done": loop.done, "failed": loop.failed,
                                    "summary": job.summary}))
