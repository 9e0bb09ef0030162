"""Motion during the shutter, for Cycles motion blur (``sensor.motion_blur``; pure Python).

A frame is still one instant for the labels: depth, masks and boxes come from the sharp render.
Motion blur only blurs the image: the renderer renders the Combined pass a second time with the
camera moving forward (its optical axis flattened to the ground) at the ego speed and every
*driving* vehicle (:func:`fogsim.scene.lights.is_driving`) along its heading (local +y) at a
traffic speed, for ``shutter_s`` centred on the frame's instant. Speeds are uniform in the
preset's ranges, drawn from ``default_rng([frame seed, MOTION_STREAM])`` (the layout's draws
are untouched). Record (into ``meta["render"]["motion_blur"]``)::

    {"shutter_s": s, "camera_velocity_mps": [vx, vy, vz], "object_velocity_mps": {id: [vx, vy, vz]}}
"""
from __future__ import annotations

import numpy as np

from fogsim.scene.lights import VEHICLE_CLASSES, is_driving

MOTION_STREAM = 0x30710


def _speed(rng: np.random.Generator, lo_hi) -> float:
    lo, hi = (float(v) for v in lo_hi)
    return lo if lo == hi else float(rng.uniform(lo, hi))


def _flat(v: np.ndarray) -> np.ndarray:
    v = np.array([v[0], v[1], 0.0])
    n = np.linalg.norm(v)
    return v / n if n > 0 else v


def frame_motion(motion_blur: dict | None, desc: dict, seed: int) -> dict | None:
    """The velocities of frame ``desc`` (world m/s, z up) for a checked ``sensor.motion_blur``
    (None: no motion blur → None)."""
    if motion_blur is None:
        return None
    from fogsim.schema.presets import MotionBlur

    mb = MotionBlur.model_validate(motion_blur)
    rng = np.random.default_rng([int(seed), MOTION_STREAM])
    w2c = np.asarray(desc["camera"]["world_to_camera"], float)
    forward = _flat(w2c[:3, :3].T @ np.array([0.0, 0.0, 1.0]))  # the optical axis (OpenCV +z) in the world
    camera = forward * _speed(rng, mb.ego_speed_mps)
    objects = {}
    for obj in desc["objects"]:
        if obj["class"] in VEHICLE_CLASSES and is_driving(obj, desc["street"]):
            heading = _flat(np.asarray(obj["transform"], float)[:3, :3] @ np.array([0.0, 1.0, 0.0]))
            objects[int(obj["id"])] = [float(x) for x in heading * _speed(rng, mb.traffic_speed_mps)]
    return {"shutter_s": float(mb.shutter_s), "camera_velocity_mps": [float(x) for x in camera],
            "object_velocity_mps": objects}
