"""Import a test-made asset library with Blender's own importers, as a render run does.

Run by tests/test_asset_render.py: ``python asset_import.py LIB OUT.json`` (bpy module) or
``blender -b -P asset_import.py -- LIB OUT.json``. LIB holds trimesh's GLB and OBJ files
(tests/asset_models.py); this script adds an FBX and a .blend of the hatchback made by
Blender's own exporters, loads them all with :func:`fogsim.render.blender.library.load_library`
and writes per model: its size, part count, where the cabin (the highest vertices) lies along
the front axis, the lowest z, and how many datablocks the import left behind before and after
:meth:`BlenderLibrary.remove`.
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

from fogsim.render.blender.compat import enable_importers  # noqa: E402
from fogsim.render.blender.library import load_library  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
lib, out = Path(args[0]), Path(args[1])


def export_other_formats() -> None:
    """lib/car/fbx/hatch.fbx and lib/car/blend/hatch.blend from the hatchback, then clear the scene."""
    enable_importers()
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=str(lib / "car" / "hatch.glb"))
    new = list(set(bpy.data.objects) - before)
    for d in ("fbx", "blend"):
        (lib / "car" / d).mkdir(parents=True, exist_ok=True)
    for o in bpy.data.objects:
        o.select_set(o in new)
    bpy.ops.export_scene.fbx(filepath=str(lib / "car" / "fbx" / "hatch.fbx"), use_selection=True)
    bpy.data.libraries.write(str(lib / "car" / "blend" / "hatch.blend"), set(new))
    bpy.data.batch_remove(new)


def counts() -> dict:
    return {k: len(getattr(bpy.data, k)) for k in ("objects", "meshes", "cameras", "lights", "armatures")}


for o in list(bpy.data.objects):  # the factory scene's cube, camera and light
    bpy.data.objects.remove(o)
export_other_formats()
start = counts()
files = {"car": sorted(str(p) for p in (lib / "car").rglob("*") if p.suffix in (".glb", ".fbx", ".blend")),
         "pedestrian": [str(p) for p in (lib / "pedestrian").rglob("*.obj")]}
loaded = load_library({"files": files, "mix": {"car": 1.0, "pedestrian": 1.0}, "units": "m", "forward": "-y",
                       "out_of_range": "refuse"})
models = {}
for cls, ms in loaded.library.models.items():
    for m in ms:
        v = m.vertices
        top = v[:, 2] > v[:, 2].max() - 0.05
        parts = loaded.parts[m.file]
        # the part matrices put the Blender meshes where the pure side's vertices are
        placed = np.concatenate([np.array([(mat[:3, :3] @ np.array(x.co)) + mat[:3, 3] for x in mesh.vertices])
                                 for mesh, mat in parts])
        models[Path(m.file).relative_to(lib).as_posix()] = {
            "class": cls, "extent": list(m.extent), "parts": len(parts), "scale": m.scale,
            "cabin_y": float(v[top, 1].mean()), "min_z": float(v[:, 2].min()),
            "centre_xy": [float((v[:, i].max() + v[:, i].min()) / 2) for i in (0, 1)],
            "faces": int(len(m.faces)), "materials": sorted({s.name for mesh, _ in parts for s in mesh.materials
                                                            if s is not None}),
            "blender_matches": bool(np.allclose(np.sort(placed, axis=0), np.sort(v, axis=0), atol=1e-4))}
after_load = counts()
loaded.remove()
out.write_text(json.dumps({"blender": bpy.app.version_string, "models": models, "start": start,
                           "after_load": after_load, "after_remove": counts()}, indent=1))
