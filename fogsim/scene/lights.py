"""Time of day and the light sources of a night street (pure Python, no bpy).

A preset's ``lighting`` (:class:`fogsim.schema.presets.Lighting`, checked when the preset is read) picks the time
of day. ``"day"`` (the default) leaves the scene description exactly as the layout made it: sun
and sky, no light sources. ``"night"`` turns it into a night street by :func:`apply_night`, after
every object is placed, so a night frame has the very same objects, poses and geometry as the
day frame of the same seed (identical depth, masks and labels) and differs only in light:

* ``lighting.sky_strength`` → :data:`NIGHT` ``sky_strength`` (0.01), the sun → ``moon_strength``
  (a faint bluish "moon"; 0 = none); ``lighting.time_of_day = "night"``;
* ``lighting.sources``: a list of light records (below) — a warm spot light under every lamp
  head of every street-lamp pole, two white spot headlights and two red tail lights on every
  *driving* vehicle (parked ones stay dark);
* emissive parts that belong to the object they sit on (same pass index, so the instance
  mask is unchanged): the lamp lenses of the poles, the headlight and tail-light lenses of the
  driving vehicles (parked vehicles' lenses are switched off), and a seeded fraction of every
  building's windows (``params.lit_windows``, see :mod:`fogsim.scene.assets_buildings`).

Light record (world frame: metres, z up; powers in Cycles watts, Blender's point-light
convention — a spot of P W is as bright inside its cone as a P W point light)::

    {"kind": "street_lamp" | "headlight" | "taillight", "object_id": id of the pole / vehicle,
     "type": "SPOT" | "POINT", "position": [x, y, z], "direction": [dx, dy, dz] (unit; SPOT only),
     "spot_angle_deg": full cone angle (SPOT only), "spot_blend": 0..1 (SPOT only),
     "radius_m": emitter radius (soft shadows), "power_w": P, "color": linear RGB (max 1)}

Everything random comes from the layout's generator *after* the layout has drawn all it needs,
so the night description is a function of the frame seed, and the day one is untouched.
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.schema.base import check
from fogsim.schema.presets import NIGHT_KEYS, Lighting

__all__ = ["NIGHT", "apply_night", "night_settings", "street_lamps", "vehicle_lights"]
VEHICLE_CLASSES = ("car", "van", "truck", "bus")

#: night defaults (declared in :class:`fogsim.schema.presets.Lighting`): sky and moon strength,
#: lamp / headlight / tail-light powers (Cycles watts), each building's lit window fraction
NIGHT = Lighting.night_defaults()
#: colours, linear RGB: ≈ 3000 K street lamps, ≈ 5500 K LED headlights, red tail lights, ≈ 2700 K rooms
LAMP_COLOR = [1.0, 0.71, 0.42]
HEADLIGHT_COLOR = [1.0, 0.95, 0.88]
TAILLIGHT_COLOR = [1.0, 0.02, 0.01]
MOON_COLOR = [0.75, 0.85, 1.0]
#: emission strengths of the lit lenses (they show the source; the Light objects light the scene)
LAMP_LENS = {"color": LAMP_COLOR, "emission": 40.0}
HEADLIGHT_LENS = {"color": HEADLIGHT_COLOR, "emission": 30.0}
TAILLIGHT_LENS = {"color": [0.8, 0.01, 0.005], "emission": 8.0}
#: street lamps: spot straight down, 150° cone (a cut-off luminaire lights nothing above 75° from nadir)
LAMP_CONE_DEG, LAMP_BLEND = 150.0, 0.4
#: headlights: 35° cone, aimed 2° below the vehicle's heading
HEADLIGHT_CONE_DEG, HEADLIGHT_BLEND, HEADLIGHT_TILT_DEG = 35.0, 0.35, 2.0
#: how far a light's emitter (a sphere or disk of radius_m) stays clear of its lens (m): an
#: emitter reaching into the lens or lamp-head box would be partly shadowed by it
LENS_GAP = 0.04
LAMP_RADIUS, CAR_LIGHT_RADIUS = 0.08, 0.03


def night_settings(lighting: dict | None) -> dict | None:
    """The night settings of a preset's checked ``lighting`` (every default from the schema), or
    None for a day preset."""
    if not lighting:
        return None
    spec = check(lighting, Lighting, prefix="lighting")
    if spec.time_of_day != "night":
        return None
    return {k: getattr(spec, k) for k in NIGHT_KEYS}


def _slot_boxes(asset: dict, slot: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """(lo, hi) local bounding boxes of the asset's primitives of material ``slot``."""
    from fogsim.scene.assets import asset_parts

    if asset["type"] == "library":  # the user's model: where its lamps are is not known
        return []

    return [(p.lo, p.hi) for p in asset_parts(asset) if p.slot == slot]


def _world(M: np.ndarray, p) -> list[float]:
    return [float(v) for v in M[:3, :3] @ np.asarray(p, float) + M[:3, 3]]


def _unit(v) -> list[float]:
    v = np.asarray(v, float)
    return [float(x) for x in v / np.linalg.norm(v)]


def street_lamps(pole: dict, power_w: float) -> list[dict]:
    """One spot light just under each lamp head's lens of a ``pole`` object, pointing down."""
    M = np.asarray(pole["transform"], float)
    out = []
    for lo, hi in _slot_boxes(pole["asset"], "street_lamp"):
        centre = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2] - LENS_GAP - LAMP_RADIUS]
        out.append({"kind": "street_lamp", "object_id": pole["id"], "type": "SPOT",
                    "position": _world(M, centre), "direction": [0.0, 0.0, -1.0],
                    "spot_angle_deg": LAMP_CONE_DEG, "spot_blend": LAMP_BLEND, "radius_m": LAMP_RADIUS,
                    "power_w": float(power_w), "color": list(LAMP_COLOR)})
    return out


def vehicle_lights(vehicle: dict, headlight_w: float, taillight_w: float) -> list[dict]:
    """Spot headlights in front of the headlight lenses, along the heading tilted slightly down,
    and point tail lights behind the tail-light lenses (local +y is the vehicle's front)."""
    M = np.asarray(vehicle["transform"], float)
    heading = M[:3, :3] @ np.array([0.0, 1.0, 0.0])
    heading[2] = 0.0
    heading /= np.linalg.norm(heading)
    t = math.radians(HEADLIGHT_TILT_DEG)
    beam = _unit(heading * math.cos(t) - np.array([0.0, 0.0, math.sin(t)]))
    out = []
    for lo, hi in _slot_boxes(vehicle["asset"], "headlight"):
        p = [(lo[0] + hi[0]) / 2, hi[1] + LENS_GAP + CAR_LIGHT_RADIUS, (lo[2] + hi[2]) / 2]
        out.append({"kind": "headlight", "object_id": vehicle["id"], "type": "SPOT", "position": _world(M, p),
                    "direction": beam, "spot_angle_deg": HEADLIGHT_CONE_DEG, "spot_blend": HEADLIGHT_BLEND,
                    "radius_m": CAR_LIGHT_RADIUS, "power_w": float(headlight_w), "color": list(HEADLIGHT_COLOR)})
    for lo, hi in _slot_boxes(vehicle["asset"], "taillight"):
        p = [(lo[0] + hi[0]) / 2, lo[1] - LENS_GAP - CAR_LIGHT_RADIUS, (lo[2] + hi[2]) / 2]
        out.append({"kind": "taillight", "object_id": vehicle["id"], "type": "POINT", "position": _world(M, p),
                    "radius_m": CAR_LIGHT_RADIUS, "power_w": float(taillight_w), "color": list(TAILLIGHT_COLOR)})
    return out


def is_driving(vehicle: dict, street: dict) -> bool:
    """A vehicle in a traffic lane (not in a parking lane): |x| inside the lanes."""
    x = float(np.asarray(vehicle["transform"], float)[0, 3])
    return abs(x) < street["lanes"] * street["lane_width"]


def apply_night(desc: dict, lighting: dict, rng: np.random.Generator) -> dict:
    """Turn the day description ``desc`` into the night one, in place (and return it).

    ``lighting``: the preset's lighting object (``time_of_day`` = ``"night"``); ``rng``: the
    layout's generator, after the layout is done with it.
    """
    s = night_settings(lighting)
    if s is None:
        return desc
    sources: list[dict] = []
    lo, hi = s["lit_window_fraction"]
    for obj in desc["objects"]:
        asset = obj["asset"]
        if obj["class"] == "pole":
            asset["materials"] = {**asset.get("materials", {}), "street_lamp": dict(LAMP_LENS)}
            sources += street_lamps(obj, s["street_lamp_power_w"])
        elif obj["class"] in VEHICLE_CLASSES:
            mats = {k: v for k, v in asset.get("materials", {}).items() if k not in ("headlight", "taillight")}
            if is_driving(obj, desc["street"]):
                mats.update(headlight=dict(HEADLIGHT_LENS), taillight=dict(TAILLIGHT_LENS))
                sources += vehicle_lights(obj, s["headlight_power_w"], s["taillight_power_w"])
            asset["materials"] = mats
        elif obj["class"] == "building" and asset.get("type") == "building":
            asset["params"]["lit_windows"] = {"fraction": float(rng.uniform(lo, hi)),
                                              "seed": int(rng.integers(0, 2 ** 31))}
    light = desc["lighting"]
    light.update(time_of_day="night", sky_strength=float(s["sky_strength"]),
                 sun_strength=float(s["moon_strength"]), sun_color=list(MOON_COLOR), sources=sources)
    return desc
