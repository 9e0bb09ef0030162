"""Intensity scales: how each point-cloud format stores intensity, and the one conversion of each.

A scale maps the intensity a file stores (*raw*) to three things:

* the **normalised** intensity in [0, 1] that :class:`fogsim.lidar.points.PointCloud` offers
  (``intensity``), the same numbers whatever the storage, so one scan stored 0–1 or 0–255 gives the
  same fog outcomes;
* the **linear** intensity the physics works with: proportional to the received power after the
  sensor's own range compensation (what fog attenuates by e^(−2βR));
* the check of what the scale admits (a "0–1" file holding 200 is refused, naming the file).

=========  ==========================  =====================  ============================================
scale      stored (raw)                normalised             linear (physics)
=========  ==========================  =====================  ============================================
``0-1``    KITTI reflectance, [0, 1]   raw                    normalised
``0-255``  nuScenes / STF, [0, 255]    raw / 255              normalised
``tanh``   Waymo, float ≥ 0, unbound   tanh(raw)              raw (= artanh(normalised))
=========  ==========================  =====================  ============================================

Why ``tanh`` for Waymo: its intensities are floats that exceed 1 on retro-reflectors (plates, signs)
and have no published upper bound; tanh maps [0, ∞) onto [0, 1) monotonically, is ≈ the identity
below 0.5 (ordinary surfaces keep their value) and compresses only the bright tail. It is the common
practice of the detection code bases (e.g. ``np.tanh(intensity)`` in OpenPCDet's Waymo loader). The
physics never works on the tanh value: it uses the raw (linear) intensity.

Raw values are kept beside the normalised ones (:attr:`PointCloud.raw_intensity`), so a scan written
back in its own format is bit-identical: no scale is ever inverted for a point fog did not change.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fogsim.schema.lidar import SCALES  # the scale names, declared once with the sensor schema

#: a 0–255 scan whose intensities are all ≤ 1 and not all whole numbers is 0–1 data (when it has this
#: many points with intensity > 0): nuScenes and STF store whole numbers 0–255
SMALL_SCAN = 100


@dataclass(frozen=True)
class Scale:
    """One intensity scale (the module docstring's table)."""

    name: str
    top: float | None  # the largest raw value admitted (None: unbounded)

    def normalise(self, raw: np.ndarray) -> np.ndarray:
        """Raw → normalised [0, 1] float32."""
        raw = np.asarray(raw, np.float32)
        if self.name == "0-1":
            return raw.copy()
        if self.name == "0-255":
            return (raw.astype(np.float64) / 255.0).astype(np.float32)
        return np.tanh(raw.astype(np.float64)).astype(np.float32)

    def to_linear(self, normalised: np.ndarray, raw: np.ndarray | None = None) -> np.ndarray:
        """Normalised → linear intensity (float64); for ``tanh`` the raw values are used when given
        (exact), else artanh of the normalised ones."""
        if self.name != "tanh":
            return np.asarray(normalised, np.float64)
        if raw is not None:
            return np.asarray(raw, np.float64)
        return np.arctanh(np.clip(np.asarray(normalised, np.float64), 0.0, np.nextafter(1.0, 0.0)))

    def from_linear(self, linear: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Linear intensity (≥ 0) → (normalised float32, raw float32), clipped to the scale's top."""
        lin = np.clip(np.asarray(linear, np.float64), 0.0, np.inf if self.name == "tanh" else 1.0)
        if self.name == "0-1":
            norm = lin.astype(np.float32)
            return norm, norm.copy()
        if self.name == "0-255":
            return lin.astype(np.float32), (lin * 255.0).astype(np.float32)
        return np.tanh(lin).astype(np.float32), lin.astype(np.float32)

    def problem(self, raw: np.ndarray) -> str | None:
        """Why ``raw`` cannot be intensities of this scale (None when they can)."""
        raw = np.asarray(raw)
        if not raw.size:
            return None
        finite = np.isfinite(raw)
        if not finite.all():
            return f"{int((~finite).sum())} intensities are NaN or infinite"
        lo, hi = float(raw.min()), float(raw.max())
        if lo < 0 or (self.top is not None and hi > self.top):
            span = f"[0, {self.top:g}]" if self.top is not None else "≥ 0"
            return (f"intensities span {lo:g} … {hi:g}, outside the declared {self.name} scale ({span})"
                    + ("; is it 0–255 data?" if self.name == "0-1" and hi > 1 else ""))
        if self.name == "0-255" and hi <= 1.0 and int((raw > 0).sum()) >= SMALL_SCAN \
                and not np.all(raw == np.round(raw)):
            return (f"intensities are all ≤ {hi:g} and fractional: this is 0–1 data (KITTI-like), not the "
                    "declared 0-255 scale (whole numbers 0–255)")
        return None


_SCALES = {"0-1": Scale("0-1", 1.0), "0-255": Scale("0-255", 255.0), "tanh": Scale("tanh", None)}


def scale(name: str) -> Scale:
    """The :class:`Scale` named ``name`` (one of :data:`SCALES`); another name is a ValueError."""
    try:
        return _SCALES[name]
    except KeyError:
        raise ValueError(f"unknown intensity scale {name!r} (known: {', '.join(SCALES)})") from None
