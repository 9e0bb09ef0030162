"""Pure numpy helper of the volumetric fog model (no bpy): the exposure of a fog render.

The Blender side (:mod:`fogsim.render.blender.fog_volume`) renders, per fog level with β > 0, a
scene-linear Combined image of the same scene with a participating medium around camera and
scene. What turns such renders into the numbers recorded in ``meta["fog"]``:

* :func:`auto_exposure`: the scale a camera's auto-exposure would apply. fogsim's rule (one
  rule, documented here): **match the median luminance** (Rec. 709 weights, scene-linear) of the
  foggy render to that of the clear render of the same frame, factor = median_clear /
  median_fog, clipped to [1/64, 64]. A median is robust to the sun-lit sky and to black pixels,
  and a fog layer lit only from above makes the path-traced frame 2.5–4× darker than the clear
  one (``docs/fog-physics.md``), which this undoes the way average metering would.
* the horizon radiance, the fog's airlight as seen in the render: :func:`fogsim.fog.physics.far_luminance`,
  the median luminance of the pixels farther than the meteorological visibility ln(20)/β along the
  ray (sky included, where e^(−βℓ) < 5 %), None when no pixel is that far.

The interior mask (mixed edge pixels masked) is :func:`fogsim.fog.physics.interior_mask`.
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.colour import luminance

EXPOSURE_LIMITS = (1.0 / 64.0, 64.0)


def auto_exposure(clear_linear: np.ndarray, fog_linear: np.ndarray) -> float:
    """Scale for the fog render so its median luminance equals the clear render's (see module doc)."""
    ref, got = float(np.median(luminance(clear_linear))), float(np.median(luminance(fog_linear)))
    if not (math.isfinite(ref) and math.isfinite(got)) or ref <= 0 or got <= 0:
        return 1.0
    return float(np.clip(ref / got, *EXPOSURE_LIMITS))
