"""Full-resolution fog images from low-resolution fog renders and the full-resolution clear render.

Cheap volumetric fog (``fog_model.volumetric.resolution_scale`` < 1): Cycles renders each fog
level at a fraction ``s`` of the width and height (s² of the pixels, so about s² of the cost),
and this module rebuilds the full-resolution image from what is exact at full resolution — the
clear render C and the ray distance ℓ of every pixel — and what varies slowly in fog, fitted on
the low-resolution render F_low. Everything is scene-linear radiance; ℓ in metres, β in 1/m.

The model, per pixel and channel, with t = e^(−βℓ) (0 for the sky)::

    F = α · C · t + A · (1 − t)

α is the forward-scatter gain (light scattered forward still arrives, α ≥ 1 in path-traced fog;
α = 1 is Koschmieder) and A the local airlight (in-scattered light per unit of 1 − t; it varies
with elevation and near lamps, but slowly). Both are fitted by ridge-regularised least squares in
every (2r+1)² window of the low-resolution render (C and t reduced to that size by area averaging,
as Cycles' pixel filter averages), smoothed, upsampled bilinearly and applied to the full-resolution
C and t: the edges of objects and the depth discontinuities come from the exact full-resolution
passes, the fog's slowly varying light from the render. For Koschmieder-like media (the ``ea``
medium: α = 1 and A constant) the rebuild is exact up to the render's noise.
"""
from __future__ import annotations

import cv2
import numpy as np

from fogsim.fog.model import transmission

#: half-width r of the fitting window, in low-resolution pixels
WINDOW_RADIUS = 2
#: ridge weight pulling α towards 1, relative to the window's mean (C·t)² (keeps α finite where
#: the window holds one colour, so C·t and 1 − t cannot be told apart)
ALPHA_RIDGE = 0.01
RULE = "F = α·C·t + A·(1 − t), t = e^(−βℓ); α, A fitted per 5×5 low-res window (ridge α → 1), bilinear up"


def low_size(width: int, height: int, scale: float) -> tuple[int, int]:
    """The (width, height) Blender renders at ``resolution_percentage = round(100·scale)``."""
    pct = max(1, round(100 * float(scale)))
    return max(1, int(width * pct / 100)), max(1, int(height * pct / 100))


def _box(x: np.ndarray, r: int) -> np.ndarray:
    return cv2.boxFilter(x, -1, (2 * r + 1, 2 * r + 1), normalize=True, borderType=cv2.BORDER_REFLECT)


def fit_fog_terms(clear_low: np.ndarray, t_low: np.ndarray, fog_low: np.ndarray,
                  r: int = WINDOW_RADIUS) -> tuple[np.ndarray, np.ndarray]:
    """α and A (h×w×3 float32, low resolution) fitted to ``fog_low`` ≈ α·C·t + A·(1 − t).

    ``clear_low``, ``fog_low``: h×w×3 scene-linear; ``t_low``: h×w transmittance.
    """
    t = t_low.astype(np.float64)[..., None]
    x1 = clear_low.astype(np.float64) * t  # C·t
    x2 = np.broadcast_to(1.0 - t, x1.shape)  # 1 − t
    y = fog_low.astype(np.float64)
    m = {k: _box(np.ascontiguousarray(v), r) for k, v in
         (("11", x1 * x1), ("12", x1 * x2), ("22", x2 * x2), ("1y", x1 * y), ("2y", x2 * y))}
    lam = ALPHA_RIDGE * m["11"] + 1e-12
    a11, a12, a22 = m["11"] + lam, m["12"], m["22"] + 1e-9
    b1, b2 = m["1y"] + lam * 1.0, m["2y"]  # ridge: α → 1
    det = a11 * a22 - a12 * a12
    alpha = (b1 * a22 - b2 * a12) / det
    airlight = (a11 * b2 - a12 * b1) / det
    return alpha.astype(np.float32), airlight.astype(np.float32)


def rebuild(clear: np.ndarray, fog_low: np.ndarray, ray: np.ndarray, beta: float) -> np.ndarray:
    """The full-resolution fog image (H×W×3 float32, scene-linear) from the clear render
    ``clear`` (H×W×3), a low-resolution fog render ``fog_low`` (h×w×3, same scene and camera)
    and the full-resolution ray distance ``ray`` (H×W, metres, inf = sky) at extinction β (1/m)."""
    H, W = clear.shape[:2]
    h, w = fog_low.shape[:2]
    if (h, w) == (H, W):
        return fog_low.astype(np.float32)
    t = transmission(ray, beta)
    clear_low = cv2.resize(clear.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    t_low = cv2.resize(t, (w, h), interpolation=cv2.INTER_AREA)
    alpha, airlight = fit_fog_terms(clear_low, t_low, fog_low)
    alpha = cv2.resize(_box(alpha, 1), (W, H), interpolation=cv2.INTER_LINEAR)
    airlight = cv2.resize(_box(airlight, 1), (W, H), interpolation=cv2.INTER_LINEAR)
    out = alpha * clear.astype(np.float32) * t[..., None] + airlight * (1.0 - t[..., None])
    return np.maximum(out, 0.0).astype(np.float32)
