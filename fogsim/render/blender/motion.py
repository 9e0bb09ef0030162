"""Cycles motion blur of a built frame: keyframes around the current frame, then undone.

:func:`motion_blur` moves the camera and the moving objects (:func:`fogsim.scene.motion.frame_motion`)
linearly through their positions at −s/2 and +s/2 (s = shutter in seconds, at ``FPS`` frames per
second: keyframes one frame before and after, shutter = s·FPS frames), turns Cycles motion
blur on and the Depth / Object Index passes off (labels come from the sharp render), and on exit
removes the animation (and its actions) and restores the scene. Objects are built in world
coordinates with their origin at 0, so moving an object's location moves its geometry.
"""
from __future__ import annotations

from contextlib import contextmanager

import bpy
import mathutils

FPS = 24
FRAME = 1  # the frame's instant; keyframes at FRAME ± 1


def _animate(obj, velocity, actions: list) -> None:
    base = obj.location.copy()
    step = mathutils.Vector(velocity) / FPS
    for frame, pos in ((FRAME - 1, base - step), (FRAME + 1, base + step)):
        obj.location = pos
        obj.keyframe_insert("location", frame=frame)
    obj.location = base
    action = obj.animation_data.action
    actions.append(action)
    for curve in _fcurves(action):
        for key in curve.keyframe_points:
            key.interpolation = "LINEAR"


def _fcurves(action):
    """An action's F-curves (Blender 5.0 keeps them in layers / strips / channel bags)."""
    if hasattr(action, "fcurves") and len(getattr(action, "fcurves", ())):
        return list(action.fcurves)
    curves = []
    for layer in getattr(action, "layers", ()):
        for strip in layer.strips:
            for bag in getattr(strip, "channelbags", ()):
                curves += list(bag.fcurves)
    return curves


@contextmanager
def motion_blur(built, scene, motion: dict):
    """Inside: the scene renders with motion blur (Combined only). ``motion``: frame_motion's record."""
    by_id = {o.pass_index: o for o in built.objects if o.type == "MESH" and o.pass_index}
    moving = [(scene.camera, motion["camera_velocity_mps"])]
    moving += [(by_id[int(i)], v) for i, v in motion["object_velocity_mps"].items() if int(i) in by_id]
    saved = {"frame": scene.frame_current, "fps": scene.render.fps, "fps_base": scene.render.fps_base,
             "blur": scene.render.use_motion_blur, "shutter": scene.render.motion_blur_shutter}
    layer = scene.view_layers[0]
    passes = (layer.use_pass_z, layer.use_pass_object_index)
    matrices = [(obj, obj.matrix_world.copy()) for obj, _ in moving]
    actions: list = []
    try:
        scene.render.fps, scene.render.fps_base = FPS, 1.0
        for obj, velocity in moving:
            _animate(obj, velocity, actions)
        scene.frame_set(FRAME)
        scene.render.use_motion_blur = True
        scene.render.motion_blur_shutter = motion["shutter_s"] * FPS
        layer.use_pass_z = layer.use_pass_object_index = False
        yield
    finally:
        for obj, matrix in matrices:
            obj.animation_data_clear()
            obj.matrix_world = matrix
        for action in actions:
            if action.name in bpy.data.actions:
                bpy.data.actions.remove(action)
        scene.render.fps, scene.render.fps_base = saved["fps"], saved["fps_base"]
        scene.render.use_motion_blur, scene.render.motion_blur_shutter = saved["blur"], saved["shutter"]
        layer.use_pass_z, layer.use_pass_object_index = passes
        scene.frame_set(saved["frame"])
