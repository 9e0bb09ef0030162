"""Pure numpy helpers of the volumetric fog model (no bpy): exposure, horizon radiance, the EA check.

The Blender side (:mod:`fogsim.render.blender.fog_volume`) renders, per fog level with β > 0, a
scene-linear Combined image of the same scene with a participating medium around camera and
scene. These functions turn such renders into the numbers recorded in ``meta["fog"]``:

* :func:`auto_exposure`: the scale a camera's auto-exposure would apply. fogsim's rule (one
  rule, documented here): **match the median luminance** (Rec. 709 weights, scene-linear) of the
  foggy render to that of the clear render of the same frame, factor = median_clear /
  median_fog, clipped to [1/64, 64]. A median is robust to the sun-lit sky and to black pixels,
  and a fog layer lit only from above makes the path-traced frame 2.5–4× darker than the clear
  one (notes/path-traced-fog.md §3), which this undoes the way average metering would.
* :func:`horizon_radiance`: the fog's airlight as seen in the render: the median luminance of the
  pixels farther than the meteorological visibility ln(20)/β along the ray (sky included, where
  e^(−βℓ) < 5 %), None when no pixel is that far.
* :func:`koschmieder_linear`: I·t + A·(1 − t) in linear light, the law the camera-only
  emission–absorption medium must reproduce (through :func:`fogsim.fog.model.koschmieder`).

The interior mask (mixed edge pixels masked) is :func:`fogsim.fog.physics.interior_mask`.
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.colour import luminance

EXPOSURE_LIMITS = (1.0 / 64.0, 64.0)
VISIBILITY_CONTRAST = 0.05  # t at the meteorological visibility: V = ln(20)/β


def auto_exposure(clear_linear: np.ndarray, fog_linear: np.ndarray) -> float:
    """Scale for the fog render so its median luminance equals the clear render's (see module doc)."""
    ref, got = float(np.median(luminance(clear_linear))), float(np.median(luminance(fog_linear)))
    if not (math.isfinite(ref) and math.isfinite(got)) or ref <= 0 or got <= 0:
        return 1.0
    return float(np.clip(ref / got, *EXPOSURE_LIMITS))


def horizon_radiance(fog_linear: np.ndarray, ray: np.ndarray, beta: float) -> float | None:
    """Median scene-linear luminance of pixels beyond the visibility ln(20)/β (ray distance, m)."""
    far = ray >= math.log(1.0 / VISIBILITY_CONTRAST) / beta
    if not far.any():
        return None
    return float(np.median(luminance(fog_linear)[far]))


def koschmieder_linear(clear_linear: np.ndarray, ray: np.ndarray, beta: float, airlight: float) -> np.ndarray:
    """Koschmieder's law on a scene-linear image: I·t + A·(1 − t), t = e^(−βℓ) (ℓ: ray distance, m;
    +inf = sky, t = 0). ``airlight`` A is scene-linear (1.0 = white), at most 1."""
    from fogsim.fog.model import koschmieder

    # a float image blended in its own values ("srgb" = no transfer applied): linear light here
    return koschmieder(np.asarray(clear_linear, dtype=np.float32), ray, beta, airlight=255.0 * airlight,
                       space="srgb")


def bin_bias(diff: np.ndarray, ray: np.ndarray, mask: np.ndarray,
             edges=(0.0, 10.0, 20.0, 40.0, 80.0, 160.0, math.inf)) -> list[dict]:
    """Mean of ``diff`` (H×W or H×W×3) per ray-distance bin over ``mask``; sky (+inf) is its own bin."""
    d = diff.mean(axis=-1) if diff.ndim == 3 else diff
    out = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = mask & (ray >= lo) & (ray < hi)
        if sel.any():
            out.append({"from_m": lo, "to_m": hi, "pixels": int(sel.sum()), "bias": float(d[sel].mean())})
    sky = mask & np.isinf(ray)
    if sky.any():
        out.append({"from_m": math.inf, "to_m": math.inf, "pixels": int(sky.sum()), "bias": float(d[sky].mean())})
    return out
