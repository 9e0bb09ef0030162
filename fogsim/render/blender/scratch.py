"""What a frame adds to Blender and removes again: :class:`Scratch` and its one :func:`clear`.

A procedural frame (:mod:`fogsim.render.blender.build`) and a realised frame of a user's scene
(:mod:`fogsim.render.blender.realise`) both create objects, meshes, materials and other datablocks
(worlds, lights, the fog domain's mesh and material) in a collection of their own; everything is
recorded here and removed after the frame, so a long run does not grow Blender's memory.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import bpy


@dataclass
class Scratch:
    """The datablocks one frame created: ``collection`` (removed last), ``objects``, ``meshes``,
    ``materials`` (key → material, shared by the frame's objects) and ``others`` ((``bpy.data``
    collection name, datablock) pairs)."""

    collection: object = None
    objects: list = field(default_factory=list)
    meshes: list = field(default_factory=list)
    materials: dict = field(default_factory=dict)
    others: list = field(default_factory=list)


def clear(scratch: Scratch) -> None:
    """Delete everything ``scratch`` records (objects first: they hold the meshes and materials)."""
    for obj in scratch.objects:
        bpy.data.objects.remove(obj, do_unlink=True)
    for mesh in scratch.meshes:
        bpy.data.meshes.remove(mesh)
    for mat in scratch.materials.values():
        bpy.data.materials.remove(mat)
    for kind, block in scratch.others:
        getattr(bpy.data, kind).remove(block)
    if scratch.collection is not None:
        bpy.data.collections.remove(scratch.collection)
    scratch.objects, scratch.meshes, scratch.materials, scratch.others = [], [], {}, []
    scratch.collection = None
