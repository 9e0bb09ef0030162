"""Outdoor light of a day frame: procedural sky, HDRI or overcast, chosen per frame (pure Python).

A day preset's ``lighting`` (:class:`fogsim.schema.presets.Lighting`) may pick the sky. Without
sky keys the description is exactly what the layout made (procedural sky + sun lamp), so old
datasets resume unchanged. With them, :func:`apply_sky` rewrites ``desc["lighting"]`` after every
object is placed, drawing from the layout's generator *after* the layout is done (same objects,
depth and masks as the default day frame of that seed), in this order: sun elevation and sun
azimuth (when the preset gives their ranges; else the layout's), overcast or not, then the
sky's own draws. The record (also in ``meta["scene"]``)::

    {"sky": "procedural" | "hdri" | "overcast",
     "sun_elevation_deg", "sun_azimuth_deg" (degrees; azimuth from +y toward +x),
     "sun_strength" (W/m², 0 for HDRI and overcast: an HDRI carries its own sun),
     "sky_strength" (world background strength; fog_model.volumetric emission "sky" reads it),
     "hdri": name or absolute path, "hdri_rotation_deg" (HDRI only),
     "overcast": bool}

Overcast is the CIE standard overcast sky, radiance L(θ) = L_z·(1 + 2 sin θ)/3 at elevation θ
(a third of the zenith at the horizon), grey-white, and no sun: soft shadows only.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fogsim.schema.base import check
from fogsim.schema.presets import DAY_SKY_STRENGTH, SKY_KEYS, WORLD_HDRIS, Lighting

__all__ = ["OVERCAST_COLOR", "apply_sky", "hdri_file", "has_sky_keys", "sky_of"]

#: linear RGB of the overcast sky (a slightly cool grey-white) and of the ground under it
OVERCAST_COLOR = [0.92, 0.95, 1.0]
#: the default world strength ranges by sky (procedural: the layout's 0.3)
DEFAULT_STRENGTH = {"procedural": [DAY_SKY_STRENGTH] * 2, "hdri": [1.0, 1.0], "overcast": [1.0, 1.6]}
#: where a Blender keeps its world HDRIs, under its DATAFILES folder
WORLD_DIR = Path("studiolights") / "world"


def has_sky_keys(lighting: dict | None) -> bool:
    """Whether a (checked) lighting object asks for more than the default day sky."""
    return bool(set(lighting or {}) & set(SKY_KEYS))


def hdri_file(spec: str, datafiles: str | Path) -> Path:
    """The HDRI file of ``spec``: a Blender world HDRI name → ``DATAFILES/studiolights/world/<name>.exr``
    of the Blender whose DATAFILES folder is ``datafiles``; anything else is a path (the preset
    loader made it absolute). The one place a name becomes a file."""
    if spec in WORLD_HDRIS:
        return Path(datafiles) / WORLD_DIR / f"{spec}.exr"
    return Path(spec)


def sky_of(light: dict) -> str:
    """The sky of a frame's lighting record: its ``sky``; a record without one is the layout's
    procedural day (the default day frame is written without sky keys, so old datasets resume)."""
    return light["sky"] if "sky" in light else "procedural"


#: the largest HDRI read (24576 × 12288, the largest equirectangular maps published, ≈ 3.6 GB as float RGB)
MAX_HDRI_PIXELS = 24576 * 12288


def hdri_problem(path: str | Path) -> str | None:
    """Why the user's HDRI file ``path`` would light a frame with garbage, or None: it does not
    decode as an image, or it holds NaN or ±inf (Cycles renders a black frame from it). One decode
    per file, at set-up (OpenCV; the OpenEXR package where this OpenCV build reads no EXR)."""
    import cv2

    from fogsim.errors import InputError
    from fogsim.io.exr import read_exr_channels
    from fogsim.io.images import read_image
    from fogsim.io.pixel_bound import pixel_bound

    path = Path(path)
    try:
        with pixel_bound(MAX_HDRI_PIXELS):  # refused by its header above this, before it is decoded
            if path.suffix.lower() == ".exr" and not cv2.haveImageWriter(".exr"):  # an OpenCV without EXR
                pixels = np.stack(list(read_exr_channels(path).values()))
            else:
                pixels = read_image(path)
    except InputError as exc:
        return f"not a readable HDRI ({exc.problem})"
    if pixels.dtype.kind == "f" and not np.isfinite(pixels).all():
        bad = int((~np.isfinite(pixels)).sum())
        return f"holds {bad} NaN or infinite values (of {pixels.size}): Cycles would render black frames from it"
    return None


def _uniform(rng: np.random.Generator, lo_hi) -> float:
    lo, hi = (float(v) for v in lo_hi)
    return lo if lo == hi else float(rng.uniform(lo, hi))


def apply_sky(desc: dict, lighting: dict | None, rng: np.random.Generator) -> dict:
    """Set the frame's outdoor light in ``desc["lighting"]`` (in place; returns ``desc``).

    ``lighting``: the preset's checked day lighting; ``rng``: the layout's generator after the
    layout. A lighting without sky keys leaves ``desc`` untouched (and draws nothing).
    """
    if not has_sky_keys(lighting):
        return desc
    spec = check(lighting, Lighting, prefix="lighting")  # every default from the schema
    light = desc["lighting"]
    if spec.sun_elevation_deg is not None:
        light["sun_elevation_deg"] = _uniform(rng, spec.sun_elevation_deg)
    if "sun_azimuth_deg" in spec.model_fields_set:
        light["sun_azimuth_deg"] = _uniform(rng, spec.sun_azimuth_deg) % 360.0
    p = float(spec.overcast) if not isinstance(spec.overcast, bool) else (1.0 if spec.overcast else 0.0)
    overcast = bool(rng.random() < p)
    kind = "overcast" if overcast else spec.sky
    strength = _uniform(rng, spec.strength or DEFAULT_STRENGTH[kind])
    elevation = math.radians(light["sun_elevation_deg"])
    light.update(sky=kind, overcast=overcast, sky_strength=strength,
                 sun_strength=3.0 + 2.0 * math.sin(elevation) if kind == "procedural" else 0.0)
    if kind == "hdri":
        choices = [spec.hdri] if isinstance(spec.hdri, str) else list(spec.hdri)
        light["hdri"] = choices[int(rng.integers(0, len(choices)))] if len(choices) > 1 else choices[0]
        light["hdri_rotation_deg"] = _uniform(rng, spec.rotation_deg) % 360.0
    return desc
