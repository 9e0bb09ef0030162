"""The user's models in Blender: each file imported once per run, instanced per frame.

:func:`load_library` imports every file of a run's asset library (``RenderConfig.assets``, see
:func:`fogsim.render.preset.resolve_assets`) with Blender's own importer — glTF/GLB, OBJ (+MTL),
FBX, and ``.blend`` (appended) — so materials and textures come along. Of what a file brings,
only the renderable geometry is kept: every visible mesh-like object becomes one mesh with its
modifiers, shape keys and pose applied (``meshes.new_from_object``) plus its matrix in the
file's frame; everything else it created (objects, cameras, lights, armatures, the original
meshes) is removed at once. The triangles go to the pure side
(:mod:`fogsim.scene.library`: normalised to the asset frame, size-checked, sampled by the
layout, and used for silhouettes). A frame then instances a model as one Blender object per
part sharing those meshes and materials, all with the scene object's pass index (one instance
in the mask); :func:`fogsim.render.blender.scratch.clear` removes the objects, never the meshes,
so memory stays flat however many frames a run renders.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import bpy
import mathutils
import numpy as np

from fogsim.console import captured_fds
from fogsim.errors import InputError
from fogsim.render.blender.compat import enable_importers
from fogsim.render.blender.output import show
from fogsim.scene.library import FORMATS, AssetLibrary, LibraryModel, extent, fit_size, normalise

#: the custom property on a material (or, in scene mode, an object) that sets its LiDAR reflectivity (0–100)
REFLECTIVITY = "fogsim_reflectivity"
#: bpy.data collections an import may add to; all but the kept ones are emptied again afterwards
_KINDS = ("objects", "meshes", "armatures", "cameras", "lights", "curves", "collections", "actions", "lattices")
_MESHLIKE = {"MESH", "CURVE", "SURFACE", "META", "FONT"}


@dataclass
class BlenderLibrary:
    """A run's imported models: the pure ``library`` (for the layout and the ground truth) and,
    per file, its parts in Blender: (mesh, 4×4 part → asset frame) pairs."""

    library: AssetLibrary
    parts: dict[str, list[tuple[object, np.ndarray]]] = field(default_factory=dict)

    def instance(self, built, obj: dict) -> None:
        """Place scene object ``obj`` (``asset.type == "library"``) in ``built``: one object per part."""
        T = np.asarray(obj["transform"], dtype=np.float64)
        for i, (mesh, local) in enumerate(self.parts[obj["asset"]["params"]["file"]]):
            bobj = bpy.data.objects.new(f"fogsim_{obj['class']}_{obj['id']}_{i}", mesh)
            bobj.matrix_world = mathutils.Matrix((T @ local).tolist())
            bobj.pass_index = int(obj["id"])
            built.collection.objects.link(bobj)
            built.objects.append(bobj)

    def remove(self) -> None:
        """Delete the imported meshes (their materials and images stay with Blender's data)."""
        for parts in self.parts.values():
            for mesh, _ in parts:
                if mesh.name in bpy.data.meshes:
                    bpy.data.meshes.remove(mesh)
        self.parts.clear()


def load_library(assets: dict, quiet: bool = False) -> BlenderLibrary:
    """Import every file of ``assets`` (``{"files": {class: [paths]}, "mix", "units", "forward",
    "out_of_range"}``); a file that does not import, holds no geometry or has the wrong size is
    an InputError naming it (nothing imported is left behind). The importers' own output is
    captured: shown as :func:`fogsim.render.blender.output.show` does (``quiet``: errors only)
    for a file imported, dropped for a file refused (its InputError says why)."""
    enable_importers()
    out = BlenderLibrary(AssetLibrary(mix=dict(assets["mix"])))
    try:
        for cls, files in assets["files"].items():
            models = out.library.models.setdefault(cls, [])
            for file in files:
                with captured_fds() as lines:  # a file refused is one line (its InputError) …
                    parts = import_parts(file)
                show(lines, quiet)  # … one imported shows the importer's warnings (quiet: errors only)
                out.parts[file] = parts  # before the checks, so remove() cleans up a refused model
                models.append(_model(file, cls, parts, assets))
    except BaseException:
        out.remove()
        raise
    return out


def _model(file: str, cls: str, parts: list, assets: dict) -> LibraryModel:
    """Normalise ``parts`` in place (their matrices become part → asset frame) and size-check them."""
    tris = [mesh_triangles(mesh) for mesh, _ in parts]
    world = np.concatenate([v @ M[:3, :3].T + M[:3, 3] for (v, _), (_, M) in zip(tris, parts)])
    N = normalise(world, assets["forward"], assets["units"])
    local = world @ N[:3, :3].T + N[:3, 3]
    scale = fit_size(file, cls, extent(local), assets["out_of_range"])
    N = np.diag([scale, scale, scale, 1.0]) @ N
    for i, (mesh, M) in enumerate(parts):
        parts[i] = (mesh, N @ M)
    offsets = np.cumsum([0] + [len(v) for v, _ in tris[:-1]])
    faces = np.concatenate([f + o for (_, f), o in zip(tris, offsets)])
    vertices = local * scale
    materials, face_material = _materials(file, [mesh for mesh, _ in parts])
    return LibraryModel(file, cls, vertices, faces, extent(vertices), scale, materials, face_material)


def material_info(material) -> dict:
    """What the LiDAR needs of a Blender material (:func:`fogsim.scene.reflectivity.material_entry`):
    ``name``; ``color`` (its Principled BSDF's base colour, linear RGB) and ``transmission`` (0–1), None
    and 0 without one; ``reflectivity``, its ``fogsim_reflectivity`` custom property (0–100) or None — a
    value out of range is an InputError naming the material."""
    from fogsim.render.blender.compat import node_tree_in_use, principled_inputs

    info = {"name": material.name, "color": None, "transmission": 0.0, "reflectivity": None}
    if REFLECTIVITY in material:
        where = f"{type(material).__name__} {material.name!r}"
        info["reflectivity"] = checked_reflectivity(material[REFLECTIVITY], where)
    tree = node_tree_in_use(material)
    nodes = tree.nodes if tree is not None else ()
    bsdf = next((n for n in nodes if n.type == "BSDF_PRINCIPLED"), None)
    if bsdf is not None:
        sockets = principled_inputs(bsdf)
        if sockets["base"] is not None:
            info["color"] = [round(float(c), 6) for c in sockets["base"].default_value[:3]]
        if sockets["transmission"] is not None:
            info["transmission"] = float(sockets["transmission"].default_value)
    return info


def checked_reflectivity(value, where: str) -> float:
    """A ``fogsim_reflectivity`` value: a number in [0, 100], else an InputError naming ``where``."""
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not 0 <= float(value) <= 100:
        raise InputError(where, f"{REFLECTIVITY} must be a number in [0, 100], got {value!r}")
    return float(value)


def _materials(file: str, meshes: list) -> tuple[tuple[dict, ...], np.ndarray | None]:
    """The model's materials (:func:`material_info`, one per distinct material of its meshes' slots; an
    empty slot: an unnamed one) and each triangle's index into them (the meshes' triangles in order)."""
    infos, index, per_face = [], {}, []
    for mesh in meshes:
        slots = [m for m in mesh.materials] or [None]
        local = []
        for m in slots:
            key = None if m is None else m.name
            if key not in index:
                index[key] = len(infos)
                infos.append({"name": None} if m is None else material_info(m))
            local.append(index[key])
        mats = mesh_triangle_materials(mesh)
        per_face.append(np.asarray(local, np.int32)[np.clip(mats, 0, len(local) - 1)])
    if all(i.get("name") is None for i in infos):
        return (), None
    return tuple(infos), np.concatenate(per_face)


def mesh_triangles(mesh) -> tuple[np.ndarray, np.ndarray]:
    """A mesh's vertices (N×3 float64, its own frame) and triangles (F×3 int64)."""
    mesh.calc_loop_triangles()
    v = np.empty(len(mesh.vertices) * 3, np.float64)
    mesh.vertices.foreach_get("co", v)
    f = np.empty(len(mesh.loop_triangles) * 3, np.int64)
    mesh.loop_triangles.foreach_get("vertices", f)
    return v.reshape(-1, 3), f.reshape(-1, 3)


def mesh_triangle_materials(mesh) -> np.ndarray:
    """The material slot index of each of a mesh's triangles (:func:`mesh_triangles`' order), int64."""
    m = np.empty(len(mesh.loop_triangles), np.int32)
    mesh.loop_triangles.foreach_get("material_index", m)
    return m.astype(np.int64)


def import_parts(file: str) -> list[tuple[object, np.ndarray]]:
    """Import ``file`` into the current scene, keep its visible geometry as (mesh, matrix) parts
    and remove everything else the import created."""
    before = {k: set(getattr(bpy.data, k)) for k in _KINDS}
    try:
        _import(file)
    except InputError:
        raise
    except Exception as exc:  # the importer's own complaint about the file
        _remove_new(before, keep=())
        raise InputError(file, f"Blender's {FORMATS[Path(file).suffix.lower()]} importer failed: "
                               f"{str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__}") \
            from None
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    parts = []
    for obj in sorted(set(bpy.data.objects) - before["objects"], key=lambda o: o.name):
        if obj.type not in _MESHLIKE or obj.hide_render:
            continue
        mesh = bpy.data.meshes.new_from_object(obj.evaluated_get(depsgraph), preserve_all_data_layers=True,
                                               depsgraph=depsgraph)
        if len(mesh.polygons) == 0:
            bpy.data.meshes.remove(mesh)
            continue
        mesh.name = f"fogsim_asset_{Path(file).stem}_{len(parts)}"
        parts.append((mesh, np.array(obj.matrix_world, dtype=np.float64)))
    _remove_new(before, keep={m for m, _ in parts})
    if not parts:
        raise InputError(file, "no visible mesh in this model file")
    return parts


def _import(file: str) -> None:
    kind = FORMATS[Path(file).suffix.lower()]
    if kind == "gltf":
        bpy.ops.import_scene.gltf(filepath=file)
    elif kind == "obj":
        bpy.ops.wm.obj_import(filepath=file)
    elif kind == "fbx":
        bpy.ops.import_scene.fbx(filepath=file)
    else:  # .blend: append its objects and link them to the scene (to evaluate them)
        with bpy.data.libraries.load(file, link=False) as (src, dst):
            dst.objects = list(src.objects)
        for obj in dst.objects:
            if obj is not None and not obj.users_collection:
                bpy.context.scene.collection.objects.link(obj)


def _remove_new(before: dict, keep) -> None:
    """Delete what an import added to :data:`_KINDS` (objects first), except ``keep``."""
    for kind in _KINDS:
        data = getattr(bpy.data, kind)
        new = [b for b in set(data) - before[kind] if b not in keep]
        if new:
            bpy.data.batch_remove(new)
    for lib in list(bpy.data.libraries):  # an appended .blend leaves its library entry
        if not lib.users:
            bpy.data.libraries.remove(lib)
