"""One frame of a user's scene made renderable and labelled (scene mode, :mod:`fogsim.render.blender.scene_mode`).

:class:`SceneClasses` answers an object's class (its own ``fogsim_class``, the class map, its
parents, its collections) and its render visibility; :func:`render_visibility` makes the viewport
depsgraph see what a render sees; :func:`realise` turns every visible geometry instance at the
current frame into a realised mesh object in the render scene (pass index = fogsim id), with
:func:`fogsim.render.blender.scratch.clear` to remove them. The rules are in
:mod:`fogsim.render.blender.scene_mode`'s docstring.
"""
from __future__ import annotations

from collections import Counter
from contextlib import contextmanager
from dataclasses import dataclass, field

import bpy
import mathutils
import numpy as np

from fogsim.errors import InputError
from fogsim.render.blender.library import (
    REFLECTIVITY,
    checked_reflectivity,
    material_info,
    mesh_triangle_materials,
    mesh_triangles,
)
from fogsim.render.blender.scratch import Scratch
from fogsim.render.lidar_scan import surface_reflectivity
from fogsim.render.scene_classes import PROPERTY, ClassMap
from fogsim.scene.classes import is_labelled

GEOMETRY = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
#: object types Blender renders that scene mode does not (counted in the run's summary)
NOT_RENDERED = {"VOLUME", "POINTCLOUD", "CURVES", "GPENCIL", "GREASEPENCIL"}
#: what a visible labelled object's ``kind`` says: one object, or one instance
KINDS = ("object", "instance")


# ----------------------------------------------------------------------------- classes
@dataclass
class SceneClasses:
    """Class lookups over one scene: objects, parents and collections (render visibility too)."""

    scene: object
    class_map: ClassMap
    parents: dict = field(default_factory=dict)  # collection name → parent collections
    in_scene: set = field(default_factory=set)   # names of the collections of this view layer
    hidden: set = field(default_factory=set)     # names of render-hidden collections of this view layer
    holdout: set = field(default_factory=set)    # names of holdout collections

    def __post_init__(self):
        for coll in [self.scene.collection, *bpy.data.collections]:
            for child in coll.children:
                self.parents.setdefault(child.name, []).append(coll)
        self._walk(bpy.context.view_layer.layer_collection, False, False)

    def _walk(self, lc, hidden: bool, holdout: bool) -> None:
        hidden = hidden or lc.exclude or lc.collection.hide_render
        holdout = holdout or lc.holdout
        self.in_scene.add(lc.collection.name)
        if hidden:
            self.hidden.add(lc.collection.name)
        if holdout:
            self.holdout.add(lc.collection.name)
        for child in lc.children:
            self._walk(child, hidden, holdout)

    def direct(self, idblock) -> str | None:
        return self.class_map.direct(idblock.name, idblock.get(PROPERTY), f"{type(idblock).__name__} "
                                     f"{idblock.name!r} ({PROPERTY})")

    def own_chain(self, obj) -> tuple[object, str] | tuple[None, None]:
        """The nearest of ``obj`` and its parents that carries a class itself, and that class."""
        while obj is not None:
            cls = self.direct(obj)
            if cls is not None:
                return obj, cls
            obj = obj.parent
        return None, None

    def of_collections(self, collections) -> str | None:
        """The class of the nearest labelled collection among ``collections`` and their parents."""
        todo, seen = list(collections), set()
        while todo:
            coll = todo.pop(0)
            if coll.name in seen:
                continue
            seen.add(coll.name)
            cls = self.direct(coll)
            if cls is not None:
                return cls
            todo += self.parents.get(coll.name, [])
        return None

    def render_hidden(self, obj) -> bool:
        if obj.hide_render:
            return True
        colls = [c.name for c in obj.users_collection if c.name in self.in_scene]
        return bool(colls) and all(c in self.hidden for c in colls)

    def in_holdout(self, obj) -> bool:
        return any(c.name in self.holdout for c in obj.users_collection)


def _identity(inst, classes: SceneClasses) -> tuple[tuple, str | None]:
    """(object key, class) of one depsgraph instance: who it belongs to, and its class (None:
    background). See the module docstring for the rules."""
    obj = inst.object.original
    if not inst.is_instance:
        owner, cls = classes.own_chain(obj)
        if owner is not None:
            return ("object", owner.name), cls
        return ("object", obj.name), classes.of_collections(obj.users_collection)
    parent = inst.parent.original
    if parent.instance_type == "COLLECTION" and parent.instance_collection is not None:
        group = ("instance", parent.name)
        inner = [parent.instance_collection]
    else:  # particles, geometry nodes: every instance its own object
        pid = list(inst.persistent_id)
        while pid and pid[-1] == 2**31 - 1:  # the unused levels
            pid.pop()
        group = ("instance", parent.name, *pid)
        inner = []
    owner, cls = classes.own_chain(obj) if obj != parent else (None, None)
    if owner is not None:
        return (*group, owner.name), cls
    cls = classes.of_collections(inner) if inner else None
    if cls is None:
        cls = classes.own_chain(parent)[1] or classes.of_collections(parent.users_collection)
    if cls is None and obj != parent:
        cls = classes.of_collections(obj.users_collection)
    return group, cls


# ----------------------------------------------------------------------------- what a render sees
@contextmanager
def render_visibility(scene):
    """Blender's viewport evaluation made to see what a render sees, for the ``with`` block:
    objects and collections disabled in viewports (monitor) or hidden with the eye, but not
    hidden from renders, are shown, and every modifier is shown as in renders. Restored after."""
    undo, eye = [], []

    def put(block, attr, value):
        if getattr(block, attr) != value:
            try:
                old = getattr(block, attr)
                setattr(block, attr, value)
                undo.append((block, attr, old))
            except (AttributeError, TypeError, RuntimeError):  # linked (library) data is read only
                pass

    layer = bpy.context.view_layer
    try:
        for obj in bpy.data.objects:
            if not obj.hide_render:
                put(obj, "hide_viewport", False)
            for mod in obj.modifiers:
                put(mod, "show_viewport", mod.show_render)
        for coll in bpy.data.collections:
            if not coll.hide_render:
                put(coll, "hide_viewport", False)
        todo = [layer.layer_collection]
        while todo:
            lc = todo.pop()
            if not lc.collection.hide_render:
                put(lc, "hide_viewport", False)
            todo += list(lc.children)
        for obj in scene.objects:
            try:
                if not obj.hide_render and obj.hide_get(view_layer=layer):
                    obj.hide_set(False, view_layer=layer)
                    eye.append(obj)
            except RuntimeError:  # not in this view layer (an excluded collection)
                pass
        layer.update()
        yield
    finally:
        for obj in eye:
            obj.hide_set(True, view_layer=layer)
        for block, attr, old in reversed(undo):
            setattr(block, attr, old)
        layer.update()


# ----------------------------------------------------------------------------- one frame
@dataclass
class Realised(Scratch):
    """One frame's render scene content: what to remove afterwards (the :class:`Scratch` fields: the
    realised objects, their meshes, the fog domain's datablocks in ``others``), and the ground truth."""

    labelled: dict = field(default_factory=dict)   # id → {"class", "key", "kind", "blender_objects"}
    parts: dict = field(default_factory=dict)      # id → [(world vertices, triangles, "")]
    lidar_parts: list = field(default_factory=list)  # (world vertices, triangles, id or 0, ρ per triangle): lidar=True
    background: int = 0                            # unlabelled geometry instances rendered
    skipped: Counter = field(default_factory=Counter)  # object types not rendered


def _copy_visibility(src, dst, holdout: bool) -> None:
    for attr in ("visible_camera", "visible_diffuse", "visible_glossy", "visible_transmission",
                 "visible_volume_scatter", "visible_shadow", "is_shadow_catcher", "is_holdout"):
        if hasattr(src, attr):
            setattr(dst, attr, getattr(src, attr))
    dst.is_holdout = dst.is_holdout or holdout


def _reflectivity(material, obj) -> float:
    """The LiDAR reflectivity (905 nm) of a surface: ``fogsim_reflectivity`` on the object, else on the material,
    else a transmissive Principled BSDF's glass, else the material's name mapped by the 905 nm table, a paint
    by the colour word of its name or its base colour (:func:`fogsim.render.lidar_scan.surface_reflectivity`:
    keywords such as "glass", "tyre", "paint", "foliage"; no match or no material: the stated fallback, a
    mid-grey painted surface)."""
    if obj is not None and REFLECTIVITY in obj:
        return checked_reflectivity(obj[REFLECTIVITY], f"{type(obj).__name__} {obj.name!r}")
    if material is None:
        return surface_reflectivity(None)[0]
    info = material_info(material)
    if info["reflectivity"] is not None:
        return info["reflectivity"]
    return surface_reflectivity(material.name, info["transmission"], info["color"])[0]


def _face_reflectivity(src, obj, material_index: np.ndarray) -> np.ndarray:
    """ρ per triangle of a realised object from the materials of its slots (``obj``'s, linked as rendered)."""
    rho = np.array([_reflectivity(slot.material, src.original) for slot in obj.material_slots] or
                   [_reflectivity(None, src.original)], np.float32)
    return rho[np.clip(material_index, 0, len(rho) - 1)]


def _box_frame(inst, key: tuple, depsgraph) -> list:
    """The world matrix a labelled object's 3D box is oriented by: the labelled object's (a plain object,
    a labelled parent) or the instancer's (a collection instance), else the instance's own."""
    obj = bpy.data.objects.get(key[1]) if key[0] == "object" or len(key) == 2 else None
    matrix = obj.evaluated_get(depsgraph).matrix_world if obj is not None else inst.matrix_world
    return np.array(matrix, dtype=np.float64).tolist()


def realise(user_scene, render_scene, classes: SceneClasses, camera, lidar: bool = False) -> Realised:
    """Every visible geometry instance of ``user_scene`` at its current frame as a realised
    object (pass index = fogsim id of a labelled object, 0 for background), lights as lights,
    and ``camera`` placed, all in a fresh collection of ``render_scene``. ``lidar``: also collect every
    camera-visible triangle with its object's id and reflectivity (``lidar_parts``): what the LiDAR sees
    is what the masks come from (hidden and camera-invisible objects are left out, holdouts occlude)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = Realised(collection=bpy.data.collections.new("fogsim_realised"))
    render_scene.collection.children.link(out.collection)
    ids: dict[tuple, int] = {}
    meshes: dict[tuple, tuple] = {}
    for inst in depsgraph.object_instances:
        src, orig = inst.object, inst.object.original
        if orig.type == "CAMERA" or classes.render_hidden(orig) or (
                inst.is_instance and classes.render_hidden(inst.parent.original)):
            continue
        matrix = mathutils.Matrix(inst.matrix_world)
        if src.type == "LIGHT":
            obj = bpy.data.objects.new(f"fogsim_{orig.name}", orig.data)
        elif src.type in GEOMETRY:
            mkey = (src.name, src.data.name if src.data is not None else "", src.type)
            if mkey not in meshes:
                mesh = bpy.data.meshes.new_from_object(src, preserve_all_data_layers=True, depsgraph=depsgraph)
                out.meshes.append(mesh)
                meshes[mkey] = (mesh, None, None)
            mesh = meshes[mkey][0]
            if not len(mesh.polygons):
                continue
            obj = bpy.data.objects.new(f"fogsim_{orig.name}", mesh)
            for i, slot in enumerate(src.material_slots):
                if i < len(obj.material_slots) and slot.material is not None:
                    obj.material_slots[i].link = "OBJECT"
                    obj.material_slots[i].material = slot.material.original
            holdout = classes.in_holdout(orig) or (inst.is_instance and classes.in_holdout(inst.parent.original))
            _copy_visibility(orig, obj, holdout)
            key, cls = _identity(inst, classes)
            labelled = cls is not None and is_labelled(cls) and obj.visible_camera and not obj.is_holdout
            if (labelled or (lidar and obj.visible_camera)) and meshes[mkey][1] is None:
                meshes[mkey] = (mesh, mesh_triangles(mesh), mesh_triangle_materials(mesh))
            M = np.array(matrix, dtype=np.float64)
            oid = 0
            if labelled:
                oid = ids.setdefault(key, len(ids) + 1)
                if oid > 65535:
                    raise InputError(user_scene.name, "more than 65535 labelled objects (uint16 instance ids)")
                rec = out.labelled.setdefault(oid, {"class": cls, "key": "/".join(map(str, key)),
                                                    "kind": KINDS[inst.is_instance], "blender_objects": [],
                                                    "transform": _box_frame(inst, key, depsgraph), "forward": "auto"})
                rec["blender_objects"].append(orig.name)
                v, f = meshes[mkey][1]
                out.parts.setdefault(oid, []).append((v @ M[:3, :3].T + M[:3, 3], f, ""))
                obj.pass_index = oid
            else:
                out.background += 1
            if lidar and obj.visible_camera:
                (v, f), mats = meshes[mkey][1], meshes[mkey][2]
                out.lidar_parts.append((v @ M[:3, :3].T + M[:3, 3], f, oid, _face_reflectivity(src, obj, mats)))
        else:
            if src.type in NOT_RENDERED:
                out.skipped[src.type] += 1
            continue
        obj.matrix_world = matrix
        out.collection.objects.link(obj)
        out.objects.append(obj)
    cam = bpy.data.objects.new("fogsim_camera", camera.data)
    loc, rot, _ = camera.evaluated_get(depsgraph).matrix_world.decompose()
    cam.matrix_world = mathutils.Matrix.Translation(loc) @ rot.to_matrix().to_4x4()
    out.collection.objects.link(cam)
    out.objects.append(cam)
    render_scene.camera = cam
    return out
