"""Render one frame of a volumetric-fog preset with RenderJob; print what Cycles held after it.

``python volumetric_job.py OUT PRESET.json`` (bpy module) or ``blender -b -P volumetric_job.py -- OUT PRESET.json``.
Prints one ``RESULT {json}`` line: the scene's Cycles settings before and after the frame
(the fog renders must not leak their settings into the next clear render) and the Blender version.
"""
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
for site in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")):
    sys.path.insert(1, str(site))

import bpy  # noqa: E402

from fogsim.render.blender.job import RenderJob  # noqa: E402
from fogsim.render.job_options import RunOptions  # noqa: E402
from fogsim.render.preset import load_render_preset  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
out, preset = args[0], args[1]
config = load_render_preset(preset, frames=1)
job = RenderJob(config, out, RunOptions(resume=False))


def settings():
    cy, layer = job.scene.cycles, job.scene.view_layers[0]
    return {"volume_bounces": cy.volume_bounces, "max_bounces": cy.max_bounces,
            "sample_clamp_indirect": cy.sample_clamp_indirect, "z": layer.use_pass_z,
            "index": layer.use_pass_object_index, "persistent": job.scene.render.use_persistent_data}


meta = job.step()
after = settings()
job.finish()
job.close()
print("RESULT " + json.dumps({"blender": bpy.app.version_string, "after": after,
                              "fog_cycles": meta["fog"].get("cycles")}))
sys.stdout.flush()
