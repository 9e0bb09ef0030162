"""A small asset library made by trimesh, for the asset tests and the library contact sheet.

Models follow their format's convention: glTF is y up with the front toward +z (its spec);
the OBJ files too (y up, front +z: what Blender's exporter writes for a model facing Blender's
−y). Blender's importers turn both into z up with the front toward −y, the ``assets.forward``
default. Every car has its cabin behind the middle and its bonnet in front, so where the front
went after normalisation can be checked (the highest vertices lie at local y < 0).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

#: (file under the library root, class, length or height in metres)
MODELS = (("car/hatch.glb", "car", 3.9), ("car/estate/estate.glb", "car", 4.7),
          ("pedestrian/walker/walker.obj", "pedestrian", 1.78))


def _box(size, centre, colour) -> trimesh.Trimesh:
    m = trimesh.creation.box(extents=size)
    m.apply_translation(centre)
    m.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
        baseColorFactor=np.array([*colour, 255], np.uint8), roughnessFactor=0.5, metallicFactor=0.0))
    return m


def car(length: float, colour) -> trimesh.Scene:
    """A car in glTF's frame (x right, y up, z front): body, a cabin toward the back, four wheels."""
    w, r = 1.8 * length / 4.3, 0.33
    scene = trimesh.Scene()
    scene.add_geometry(_box([w, 0.75, length], [0, r + 0.37, 0], colour), geom_name="body")
    scene.add_geometry(_box([w * 0.9, 0.6, length * 0.45], [0, r + 1.04, -length * 0.15], (40, 50, 60)),
                       geom_name="cabin")
    for i, (sx, sz) in enumerate(((-1, -1), (-1, 1), (1, -1), (1, 1))):
        wheel = trimesh.creation.cylinder(radius=r, height=0.25, sections=16)
        wheel.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
        wheel.apply_translation([sx * (w / 2 - 0.02), r, sz * length * 0.33])
        wheel.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
            baseColorFactor=np.array([20, 20, 20, 255], np.uint8)))
        scene.add_geometry(wheel, geom_name=f"wheel{i}")
    return scene


def pedestrian(height: float) -> trimesh.Trimesh:
    """A person in OBJ's usual frame (y up, front +z): legs, torso, head, with an MTL colour."""
    legs = _box([0.36, height * 0.47, 0.22], [0, height * 0.235, 0], (30, 30, 80))
    torso = _box([0.46, height * 0.35, 0.26], [0, height * 0.645, 0], (180, 120, 40))
    head = trimesh.creation.icosphere(subdivisions=2, radius=height * 0.09)
    head.apply_translation([0, height * 0.91, 0])
    m = trimesh.util.concatenate([legs, torso, head])
    m.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.SimpleMaterial(
        diffuse=[200, 160, 130, 255], name="skin"))
    return m


def make_library(root: Path, giant: bool = False) -> dict[str, Path]:
    """Write the library under ``root`` (``car/``, ``pedestrian/``); ``giant`` adds a car 45 m long
    (a model in centimetres read as metres would be 100× too big; this one is refused by size).
    Returns file name → path."""
    paths = {}
    colours = iter([(170, 25, 30), (30, 90, 170)])
    for rel, cls, size in MODELS + ((("car/giant.glb", "car", 45.0),) if giant else ()):
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        model = car(size, next(colours, (90, 90, 90))) if cls == "car" else pedestrian(size)
        model.export(path)
        paths[path.name] = path
    return paths
