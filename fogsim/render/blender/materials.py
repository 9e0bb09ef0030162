"""Procedural Cycles materials from fogsim's material catalogue (no image textures).

Every surface except glass, lights and paint gets texture from a noise or brick pattern in
object coordinates (metres), so a stereo matcher has something to match and nothing looks
like flat CG colour.
"""
from __future__ import annotations

import bpy

from fogsim.render.blender.compat import node_tree, principled_inputs
from fogsim.scene.materials import material as catalogue_material

_NOISE_DETAIL = {"asphalt": (14.0, 0.35), "concrete": (6.0, 0.25), "noise": (4.0, 0.2),
                 "bark": (10.0, 0.45), "foliage": (6.0, 0.5), "fabric": (12.0, 0.25),
                 "windows": (3.0, 0.15)}


def _scaled(rgb, k):
    return (min(1.0, rgb[0] * k), min(1.0, rgb[1] * k), min(1.0, rgb[2] * k), 1.0)


def make_material(name: str, slot: str, overrides: dict) -> bpy.types.Material:
    """A new material for catalogue entry ``slot`` with instance ``overrides`` (e.g. colour)."""
    spec = catalogue_material(slot, **overrides)
    mat = bpy.data.materials.new(name)
    nt = node_tree(mat)
    bsdf = next(n for n in nt.nodes if n.type == "BSDF_PRINCIPLED")
    sockets = principled_inputs(bsdf)
    color = tuple(spec["color"])
    sockets["roughness"].default_value = spec.get("roughness", 0.5)
    sockets["metallic"].default_value = spec.get("metallic", 0.0)
    sockets["base"].default_value = (*color, 1.0)
    mat.diffuse_color = (*color, 1.0)  # the viewport's solid-mode colour
    if spec.get("emission", 0.0) > 0 and sockets["emission"] is not None:
        sockets["emission"].default_value = (*color, 1.0)
        if sockets["emission_strength"] is not None:
            sockets["emission_strength"].default_value = spec["emission"]
    kind = spec.get("texture", "none")
    if kind == "none":
        return mat
    coords = nt.nodes.new("ShaderNodeTexCoord")
    scale = 1.0 / max(spec.get("texture_scale", 0.5), 1e-3)
    if kind == "brick":
        tex = nt.nodes.new("ShaderNodeTexBrick")
        tex.inputs["Scale"].default_value = scale
        tex.inputs["Color1"].default_value = _scaled(color, 1.0)
        tex.inputs["Color2"].default_value = _scaled(color, 0.8)
        tex.inputs["Mortar"].default_value = (0.35, 0.33, 0.3, 1.0)
        nt.links.new(coords.outputs["Object"], tex.inputs["Vector"])
        nt.links.new(tex.outputs["Color"], sockets["base"])
        return mat
    detail, contrast = _NOISE_DETAIL.get(kind, (4.0, 0.2))
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = scale
    noise.inputs["Detail"].default_value = detail
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = _scaled(color, 1.0 - contrast)
    ramp.color_ramp.elements[1].color = _scaled(color, 1.0 + contrast)
    nt.links.new(coords.outputs["Object"], noise.inputs["Vector"])
    nt.links.new(noise.outputs["Fac"], ramp.inputs["Fac"])
    nt.links.new(ramp.outputs["Color"], sockets["base"])
    bump = nt.nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = 0.15
    nt.links.new(noise.outputs["Fac"], bump.inputs["Height"])
    nt.links.new(bump.outputs["Normal"], sockets["normal"])
    return mat
