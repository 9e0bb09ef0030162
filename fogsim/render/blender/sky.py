"""The world of a frame: procedural sky texture, an HDRI environment, or a CIE overcast sky.

The frame's record ``desc["lighting"]`` (:mod:`fogsim.scene.sky`) says which; this module makes
the world datablock (and, for an HDRI, loads the image) and nothing else. The world is what the
camera sees where nothing is hit (depth +inf, mask 0) and what lights the scene and any fog
volume (Cycles path-traces both with the same world), so a foggy HDRI frame is lit by that HDRI.

* procedural: Blender's physical sky texture (Nishita in 3.4 … 5.0), sun disc off (the sun
  lamp lights the scene), strength ``sky_strength``;
* hdri: Environment Texture of the file (``hdri_file``: a Blender world HDRI name → this
  Blender's ``datafiles/studiolights/world/<name>.exr``), turned ``hdri_rotation_deg`` about
  the vertical axis, strength ``sky_strength``; its sun is in the image (no sun lamp);
* overcast: L(d) = ``sky_strength`` · colour · (1 + 2·max(d_z, 0))/3 for the view direction d
  (the CIE standard overcast sky; below the horizon the horizon's third), no sun.
"""
from __future__ import annotations

import math
from pathlib import Path

import bpy

from fogsim.errors import InputError
from fogsim.render.blender.compat import node_tree, sky_type_physical
from fogsim.scene.sky import OVERCAST_COLOR, hdri_file, sky_of

#: the world importance map's side: small for smooth skies (Cycles' default 1024² costs ~0.7 s a
#: frame), larger for an HDRI, whose sun is a few pixels of a 1024 × 512 image
MAP_RESOLUTION = {"procedural": 64, "overcast": 64, "hdri": 256}


def blender_hdri(spec: str) -> Path:
    """The HDRI file of a lighting record's ``hdri`` in the running Blender."""
    return hdri_file(spec, bpy.utils.system_resource("DATAFILES"))


def _procedural(nt, bg, light: dict) -> None:
    elev, azim = math.radians(light["sun_elevation_deg"]), math.radians(light["sun_azimuth_deg"])
    sky = nt.nodes.new("ShaderNodeTexSky")
    chosen = sky_type_physical(sky)
    if chosen in ("NISHITA", "SINGLE_SCATTERING", "MULTIPLE_SCATTERING"):
        sky.sun_disc = False  # the sun lamp lights the scene; the sky gives ambient light
        sky.sun_elevation, sky.sun_rotation = elev, azim
        sky.altitude = 100.0
    else:
        sky.sun_direction = (math.cos(elev) * math.sin(azim), math.cos(elev) * math.cos(azim), math.sin(elev))
    nt.links.new(sky.outputs["Color"], bg.inputs["Color"])


def _hdri(nt, bg, light: dict, built) -> None:
    path = blender_hdri(light["hdri"])
    if not path.is_file():
        raise InputError(path, "HDRI not found (lighting.hdri)")
    image = bpy.data.images.load(str(path), check_existing=False)
    built.others.append(("images", image))
    if image.size[0] == 0 or image.size[1] == 0:
        raise InputError(path, "Blender cannot read this HDRI")
    coords = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(light.get("hdri_rotation_deg", 0.0)))
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    nt.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    nt.links.new(env.outputs["Color"], bg.inputs["Color"])


def _overcast(nt, bg, strength: float) -> None:
    """Colour constant, strength = sky_strength · (max(d_z, 0)·2/3 + 1/3) for view direction d."""
    coords = nt.nodes.new("ShaderNodeTexCoord")
    xyz = nt.nodes.new("ShaderNodeSeparateXYZ")
    up = nt.nodes.new("ShaderNodeMath")
    up.operation = "MAXIMUM"
    up.inputs[1].default_value = 0.0
    gradient = nt.nodes.new("ShaderNodeMath")
    gradient.operation = "MULTIPLY_ADD"
    gradient.inputs[1].default_value, gradient.inputs[2].default_value = 2.0 / 3.0, 1.0 / 3.0
    scaled = nt.nodes.new("ShaderNodeMath")
    scaled.operation = "MULTIPLY"
    scaled.inputs[1].default_value = strength
    nt.links.new(coords.outputs["Generated"], xyz.inputs[0])
    nt.links.new(xyz.outputs["Z"], up.inputs[0])
    nt.links.new(up.outputs[0], gradient.inputs[0])
    nt.links.new(gradient.outputs[0], scaled.inputs[0])
    nt.links.new(scaled.outputs[0], bg.inputs["Strength"])
    bg.inputs["Color"].default_value = (*OVERCAST_COLOR, 1.0)


def make_world(built, light: dict):
    """The world of a frame's lighting record (:mod:`fogsim.scene.sky`; recorded in ``built`` for removal)."""
    kind = sky_of(light)
    world = bpy.data.worlds.new("fogsim_world")
    built.others.append(("worlds", world))
    nt = node_tree(world)
    bg = nt.nodes["Background"]
    bg.inputs["Strength"].default_value = light["sky_strength"]
    if kind == "hdri":
        _hdri(nt, bg, light, built)
    elif kind == "overcast":
        _overcast(nt, bg, light["sky_strength"])
    else:
        _procedural(nt, bg, light)
    world.cycles.sampling_method = "MANUAL"
    world.cycles.sample_map_resolution = MAP_RESOLUTION[kind]
    return world
