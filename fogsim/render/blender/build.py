"""Turn a fogsim scene description into Blender objects, and remove them again.

Everything created is recorded in a :class:`Built` (a :class:`~fogsim.render.blender.scratch.Scratch`)
so :func:`fogsim.render.blender.scratch.clear` can delete exactly it (meshes, materials, objects,
lights, camera, world): long batch runs keep flat memory.
"""
from __future__ import annotations

import math

import bpy
import mathutils
import numpy as np

from fogsim.camera import Intrinsics
from fogsim.render.blender.compat import set_mesh_polygons
from fogsim.render.blender.lights import add_lights
from fogsim.render.blender.materials import make_material
from fogsim.render.blender.scratch import Scratch
from fogsim.render.blender.sky import make_world
from fogsim.scene.geometry import material_key, world_parts
from fogsim.scene.pose import blender_camera_matrix, blender_lens

COLLECTION = "fogsim_scene"


class Built(Scratch):
    """What :func:`build` created for one frame (removed by :func:`fogsim.render.blender.scratch.clear`)."""


def _mesh(name: str, parts, slots: list[str]) -> bpy.types.Mesh:
    """One mesh from (vertices, faces, slot) parts: arrays set in bulk, material index per face."""
    verts = np.concatenate([v for v, _, _ in parts]).astype(np.float32)
    offsets = np.cumsum([0] + [len(v) for v, _, _ in parts[:-1]])
    faces = np.concatenate([f + o for (_, f, _), o in zip(parts, offsets)]).astype(np.int32)
    mat_index = np.concatenate([np.full(len(f), slots.index(s), np.int32) for _, f, s in parts])
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set("co", verts.ravel())
    mesh.loops.add(faces.size)
    mesh.loops.foreach_set("vertex_index", faces.ravel())
    mesh.polygons.add(len(faces))
    set_mesh_polygons(mesh, np.arange(0, faces.size, 3, dtype=np.int32), np.full(len(faces), 3, np.int32))
    mesh.polygons.foreach_set("material_index", mat_index)
    # flat shading: Blender ≥ 4.1 makes added polygons smooth (no "sharp_face" attribute), which
    # averages normals across every box edge (boxes share their 8 corners) and darkens whole faces
    mesh.polygons.foreach_set("use_smooth", np.zeros(len(faces), bool))
    mesh.update()
    return mesh


def _material(built: Built, obj: dict, slot: str):
    key = material_key(obj, slot)
    if key not in built.materials:
        overrides = obj["asset"].get("materials", {}).get(slot, {})
        built.materials[key] = make_material(f"fogsim_{slot}_{len(built.materials)}", slot, overrides)
    return built.materials[key]


def _camera(built: Built, cam: dict, scene) -> None:
    K = Intrinsics.from_dict(cam["intrinsics"])
    data = bpy.data.cameras.new("fogsim_camera")
    for key, value in blender_lens(K.fx, K.fy, K.cx, K.cy, K.width, K.height).items():
        setattr(data, key, value)
    data.clip_start, data.clip_end = 0.1, 2000.0
    obj = bpy.data.objects.new("fogsim_camera", data)
    built.collection.objects.link(obj)
    built.others += [("cameras", data)]
    built.objects.append(obj)
    scene.camera = obj
    set_camera_pose(scene, cam["world_to_camera"])
    scene.render.resolution_x, scene.render.resolution_y = K.width, K.height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0


#: the sun lamp: its angular diameter (soft shadows) and its colour by day (linear RGB)
SUN_ANGLE_DEG, SUN_COLOR = 0.6, (1.0, 0.97, 0.92)


def set_camera_pose(scene, world_to_camera) -> None:
    """Place the scene camera from an OpenCV world→camera matrix (4×4)."""
    M = blender_camera_matrix(np.asarray(world_to_camera, dtype=np.float64))
    scene.camera.matrix_world = mathutils.Matrix(M.tolist())


def _lighting(built: Built, light: dict, scene) -> None:
    """The world (procedural sky, HDRI or overcast: :mod:`fogsim.render.blender.sky`) and the sun lamp."""
    elev, azim = math.radians(light["sun_elevation_deg"]), math.radians(light["sun_azimuth_deg"])
    scene.world = make_world(built, light)
    sun = bpy.data.lights.new("fogsim_sun", "SUN")
    sun.energy = light["sun_strength"]
    sun.angle = math.radians(SUN_ANGLE_DEG)
    sun.color = light.get("sun_color", SUN_COLOR)  # the night's moon has its own colour
    sun_obj = bpy.data.objects.new("fogsim_sun", sun)
    # a sun lamp shines along its −z: point −z from the sun toward the scene
    sun_obj.rotation_euler = (math.pi / 2 - elev, 0.0, azim + math.pi)
    built.collection.objects.link(sun_obj)
    built.objects.append(sun_obj)
    built.others += [("lights", sun)]


def build(desc: dict, scene=None, meshes: dict | None = None, library=None) -> Built:
    """Create camera, lighting and every object of ``desc`` in ``scene`` (pass index = id).

    ``meshes`` (id → world parts, from :func:`fogsim.render.frame.scene_meshes`) avoids building
    the trimesh geometry twice when the caller already has it. ``library``: the run's
    :class:`fogsim.render.blender.library.BlenderLibrary`, which instances library models.
    """
    scene = scene or bpy.context.scene
    built = Built()
    built.collection = bpy.data.collections.new(COLLECTION)
    scene.collection.children.link(built.collection)
    _camera(built, desc["camera"], scene)
    _lighting(built, desc["lighting"], scene)
    add_lights(built, desc["lighting"].get("sources", ()))  # night: lamps, vehicle lights (fogsim.scene.lights)
    for obj in desc["objects"]:
        if obj["asset"]["type"] == "library":
            library.instance(built, obj)  # the imported model's meshes, shared by every frame
            continue
        parts = meshes[obj["id"]] if meshes is not None else world_parts(obj)
        slots = sorted({s for _, _, s in parts})
        mesh = _mesh(f"fogsim_{obj['class']}_{obj['id']}", parts, slots)
        for slot in slots:
            mesh.materials.append(_material(built, obj, slot))
        bobj = bpy.data.objects.new(mesh.name, mesh)
        bobj.pass_index = int(obj["id"])
        built.collection.objects.link(bobj)
        built.objects.append(bobj)
        built.meshes.append(mesh)
    return built
