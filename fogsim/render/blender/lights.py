"""Light objects for a scene description's ``lighting.sources`` (street lamps, vehicle lights).

The sources are described, seeded and placed in pure Python (:mod:`fogsim.scene.lights`); this
module only makes the Blender datablocks. Lights have no geometry and are hidden from camera
rays, so the Depth and Object Index passes — hence depth, masks and labels — are exactly those
of the same scene by day; the lenses the camera sees are emissive faces of the pole or vehicle
they belong to (same pass index). Everything made is recorded in the :class:`Built` so
:func:`fogsim.render.blender.scratch.clear` removes it.
"""
from __future__ import annotations

import math

import bpy
import mathutils


def add_lights(built, sources) -> int:
    """Create one Blender light per source record in ``built.collection``; returns how many.

    Record fields (world metres, Cycles watts): ``type`` POINT or SPOT, ``position``,
    ``direction`` (SPOT: the beam axis; a Blender light shines along its local −z),
    ``spot_angle_deg`` (full cone), ``spot_blend``, ``radius_m``, ``power_w``, ``color``.
    """
    for i, src in enumerate(sources or ()):
        kind = src["type"]
        data = bpy.data.lights.new(f"fogsim_{src.get('kind', 'light')}_{i}", kind)
        data.energy = float(src["power_w"])
        data.color = tuple(src["color"])
        data.shadow_soft_size = float(src.get("radius_m", 0.05))
        if kind == "SPOT":
            data.spot_size = math.radians(float(src["spot_angle_deg"]))
            data.spot_blend = float(src.get("spot_blend", 0.15))
        obj = bpy.data.objects.new(data.name, data)
        obj.location = tuple(src["position"])
        if kind == "SPOT":
            axis = mathutils.Vector(src["direction"]).normalized()
            obj.rotation_mode = "QUATERNION"  # local −z along the beam (the up axis must differ from it)
            obj.rotation_quaternion = axis.to_track_quat("-Z", "Y")
        if hasattr(obj, "visible_camera"):  # 3.0+: never seen directly, never in Depth/Index passes
            obj.visible_camera = False
        built.collection.objects.link(obj)
        built.objects.append(obj)
        built.others.append(("lights", data))
    return len(sources or ())
