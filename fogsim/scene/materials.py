"""The material catalogue: named base materials the renderer turns into procedural shaders.

Every entry has ``color`` (linear RGB, 0..1), ``roughness``, ``metallic``, ``texture`` (one of
:data:`TEXTURES`) and ``texture_scale`` (metres per texture feature); ``emission`` (strength,
0 = not a light) is optional. Asset specs override entries per instance (usually ``color``,
and ``emission`` for lit lamps) through :func:`material`. Only glass, lights and paint are
untextured: a stereo matcher needs texture on every real surface.
"""
from __future__ import annotations

TEXTURES = ("none", "noise", "asphalt", "brick", "concrete", "windows", "bark", "foliage", "fabric")


def _m(color, roughness, metallic=0.0, texture="noise", texture_scale=0.5, **extra) -> dict:
    return {"color": list(color), "roughness": roughness, "metallic": metallic,
            "texture": texture, "texture_scale": texture_scale, **extra}


MATERIALS: dict[str, dict] = {
    # vehicles
    "body_paint": _m((0.35, 0.35, 0.36), 0.3, 0.4, "noise", 0.8),
    "cargo_box": _m((0.75, 0.75, 0.73), 0.5, 0.2, "noise", 0.6),
    "glass": _m((0.015, 0.02, 0.025), 0.05, 0.0, "none", 1.0, transmission=0.0, alpha=1.0),
    "tyre": _m((0.02, 0.02, 0.02), 0.9, 0.0, "noise", 0.05),
    "rim": _m((0.55, 0.56, 0.58), 0.25, 1.0, "noise", 0.1),
    "headlight": _m((0.9, 0.9, 0.85), 0.1, 0.0, "none", 1.0, emission=0.0),
    "taillight": _m((0.35, 0.01, 0.01), 0.15, 0.0, "none", 1.0, emission=0.0),
    "plastic_black": _m((0.025, 0.025, 0.025), 0.6, 0.0, "noise", 0.2),
    "license_plate": _m((0.8, 0.8, 0.75), 0.4, 0.0, "noise", 0.05),
    # people and bicycles
    "skin": _m((0.6, 0.4, 0.3), 0.55, 0.0, "noise", 0.05),
    "hair": _m((0.05, 0.03, 0.02), 0.7, 0.0, "fabric", 0.02),
    "cloth_top": _m((0.2, 0.2, 0.25), 0.85, 0.0, "fabric", 0.03),
    "cloth_bottom": _m((0.05, 0.07, 0.15), 0.85, 0.0, "fabric", 0.03),
    "shoe": _m((0.03, 0.03, 0.03), 0.6, 0.0, "noise", 0.03),
    "bike_frame": _m((0.3, 0.02, 0.02), 0.35, 0.3, "noise", 0.1),
    # street surfaces
    "asphalt": _m((0.05, 0.05, 0.05), 0.9, 0.0, "asphalt", 0.05),
    "lane_paint": _m((0.75, 0.75, 0.72), 0.6, 0.0, "none", 1.0),
    "sidewalk": _m((0.3, 0.29, 0.27), 0.85, 0.0, "concrete", 0.3),
    "curb": _m((0.4, 0.4, 0.38), 0.8, 0.0, "concrete", 0.15),
    # buildings
    "facade_brick": _m((0.35, 0.12, 0.07), 0.85, 0.0, "brick", 0.5),
    "facade_concrete": _m((0.4, 0.39, 0.36), 0.85, 0.0, "concrete", 0.6),
    "facade_plaster": _m((0.6, 0.55, 0.45), 0.8, 0.0, "noise", 0.4),
    "window": _m((0.03, 0.04, 0.05), 0.08, 0.0, "windows", 1.5),
    "window_lit": _m((1.0, 0.62, 0.3), 0.08, 0.0, "windows", 1.5, emission=0.8),  # a lit room at night
    "window_frame": _m((0.7, 0.7, 0.68), 0.5, 0.0, "noise", 0.2),
    "door": _m((0.12, 0.07, 0.04), 0.6, 0.0, "noise", 0.15),
    "roof": _m((0.12, 0.11, 0.1), 0.9, 0.0, "concrete", 0.4),
    # street furniture and vegetation
    "pole_metal": _m((0.2, 0.21, 0.22), 0.45, 0.8, "noise", 0.2),
    "street_lamp": _m((0.9, 0.85, 0.7), 0.2, 0.0, "none", 1.0, emission=0.0),
    "signal_housing": _m((0.03, 0.03, 0.03), 0.5, 0.0, "noise", 0.1),
    "signal_red": _m((0.12, 0.01, 0.01), 0.1, 0.0, "none", 1.0, emission=0.0),
    "signal_amber": _m((0.12, 0.06, 0.0), 0.1, 0.0, "none", 1.0, emission=0.0),
    "signal_green": _m((0.0, 0.1, 0.05), 0.1, 0.0, "none", 1.0, emission=0.0),
    "sign_face": _m((0.8, 0.8, 0.78), 0.4, 0.0, "noise", 0.1),
    "sign_border": _m((0.6, 0.02, 0.02), 0.4, 0.0, "noise", 0.1),
    "sign_back": _m((0.35, 0.36, 0.37), 0.5, 0.6, "noise", 0.1),
    "bark": _m((0.07, 0.05, 0.035), 0.9, 0.0, "bark", 0.08),
    "foliage": _m((0.04, 0.09, 0.02), 0.8, 0.0, "foliage", 0.25),
}


def material(name: str, **overrides) -> dict:
    """A copy of catalogue entry ``name`` with ``overrides`` (e.g. ``color=[r, g, b]``) merged in."""
    try:
        base = MATERIALS[name]
    except KeyError:
        raise KeyError(f"unknown material {name!r}; known: {', '.join(sorted(MATERIALS))}") from None
    out = {k: (list(v) if isinstance(v, list) else v) for k, v in base.items()}
    out.update({k: (list(v) if isinstance(v, (list, tuple)) else v) for k, v in overrides.items()})
    return out
