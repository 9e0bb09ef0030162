"""``--lidar-model hahner2021``: the LiDAR fog of Hahner et al. (ICCV 2021) as their released code fogs
datasets (its batch path), on fogsim's scans and outcomes.

Written from the paper and a description of the released code's behaviour (``docs/lidar-fog.md``), not
from the code (CC BY-NC 4.0); the soft-target integrals are :mod:`fogsim.lidar.hahner`'s. Their α is the
level's β at 905 nm (α = ``extinction_ratio``·β); β_b the backscatter coefficient. Per input point with
range R₀ and fed intensity i:

* **fed intensity** (integers 0–255, as the released code expects): a ``0-255`` scan (nuScenes, STF) as
  stored; a ``0-1`` scan (KITTI) × 255 and rounded, as the authors' documentation and KITTI viewer feed it;
  a ``tanh`` scan (Waymo) its normalised value × 255, rounded. Intensities written back are in the scan's
  own scale (fed value / 255 normalised).
* **hard return**: i_h = round(i·e^(−2αR₀)) (numpy's round half to even), always reported.
* **fog response**: i_s = min(i·R₀²·(β_b/β₀)·I_max(R₀), 255) with β₀ = Γ/π (Γ = 10⁻⁶) and I_max(R₀) the
  peak of the soft-target integral I(R) over R ≤ R₀, at R_f(R₀) — as the released tables hold it: for
  R₀ beyond the fog's own peak (≈ 4.6 m) that peak (:func:`fogsim.lidar.hahner.fog_peak`), for a nearer
  target I(R₀) at R_f = R₀ (:func:`fogsim.lidar.hahner.open_fog_response`), computed at the exact α. A
  dark near point whose hard return rounds to 0 is therefore scattered too. The batch path computes
  β_b = 0.046/MOR at the released parameter set's default α = 0.06 *before* setting α, so
  β_b = 0.046·0.06/ln 20 at **every** α (``hahner_variant`` ``batch``, the default); its viewer recomputes
  β_b = 0.046·α/ln 20 (``hahner_variant`` ``viewer``; the viewer's other defaults — 'v4' noise, an
  intensity gain — are not reproduced).
* **scattered** when i_s > i_h: the point moves along its ray to R_f(R₀)·R₀/u, u ~ U(R₀ − 10, R₀ + 10) m
  (the released default range noise, 'v1': multiplicative, so a far point's clutter never lands behind
  the sensor; a point nearer than 10 m could, and is left where the formula puts it), intensity i_s
  (capped at 255, not rounded): ``clutter``. A zero-intensity point (fed 0) is never scattered.
* otherwise it stays where it is with intensity i_h: ``kept`` when i_h = i (written bit for bit),
  ``attenuated`` otherwise. No point is ever lost and none is added; the sweep's empty rays are counted,
  never fogged.
* a **no-return row** (nearer than the sensor's minimum range: :func:`fogsim.lidar.rays.no_returns`; a nuScenes
  sweep's firing without an echo, stored at ≈ 0 m) is no point: the released code is run on returns (the
  nuScenes devkit's ``remove_close`` drops such rows first), so it is neither fed nor scattered, and stays the
  row it was, bit for bit — ``no-return``. Rows out = rows in.

Differences from the released code, deliberate: the integral is computed at the level's own α — the
released code reads tables for nine α and takes the nearest (0.09 runs as 0.10; ``scripts/
check_hahner_released.py`` measures the effect) — and at the exact R₀ (its tables: every 0.1 m to 200 m).
One β per scan (the released code fogs a scan at one α): a per-point β (patchy fog) is refused.

Random draws from the caller's Generator, in this order: one ``integers(1, 20)`` (the released code draws it for a
noise variant it does not use, and discards it), then one ``uniform(R₀ − 10, R₀ + 10)`` per scattered point
(no-return rows are never scattered), in input order — what the released code draws from its module-level
Generator, in the same order, so the same Generator state gives the same clutter ranges.
"""
from __future__ import annotations

import math
import weakref

import numpy as np

from fogsim.lidar.fogged_scan import assemble
from fogsim.lidar.hahner import HahnerParameters, fog_peak, open_fog_response
from fogsim.lidar.outcomes import ATTENUATED, CLUTTER, KEPT, NO_RETURN

__all__ = ["BATCH_ALPHA", "FED_TOP", "Model", "backscatter", "fed_intensity"]

#: the released parameter set's default α (1/m): the batch path's backscatter is computed at it
BATCH_ALPHA = 0.06
#: the fed intensities' top (8-bit), and the cap of the fog response
FED_TOP = 255.0


def fed_intensity(scan) -> np.ndarray:
    """The intensities the released code is fed (float64, module docstring): 0–255 as stored, others
    normalised × 255 and rounded."""
    if scan.scale == "0-255":
        return np.asarray(scan.raw_intensity, np.float64)
    return np.round(np.asarray(scan.intensity, np.float64) * FED_TOP)


def backscatter(alpha: float, variant: str = "batch", p: HahnerParameters = HahnerParameters()) -> float:
    """β_b (1/(m·sr)): frozen at α 0.06 (``batch``) or at ``alpha`` (``viewer``)."""
    return p.backscatter(BATCH_ALPHA if variant == "batch" else alpha)


class Model:
    """hahner2021 on a :class:`~fogsim.lidar.fog.LidarFogger`'s scan (``owner``: its scan, spec, scale and no-return
    rows; the level assembled by :func:`fogsim.lidar.fogged_scan.assemble`); ``model(β, rng)`` one level (β > 0,
    one per scan)."""

    def __init__(self, owner):
        self.owner = weakref.proxy(owner)  # (no reference cycle: a fogger's arrays go when the fogger goes)
        self.params = HahnerParameters()
        self.variant = owner.spec.hahner_variant
        self.fed = fed_intensity(owner.scan)
        self.r0 = owner.scan.range_m

    def check(self, beta) -> None:
        if np.ndim(beta) != 0:
            raise ValueError("lidar_fog.model hahner2021 fogs a scan at one β (the released code's one α): a "
                             "per-point β (patchy fog, --heterogeneity) needs soft-target, attenuation or stf2020")

    def alpha(self, beta: float) -> float:
        return self.owner.spec.extinction_ratio * float(beta)

    def parameters(self, beta) -> dict:
        a = self.alpha(beta)
        out = {"hahner_variant": self.variant, "alpha": a,
               "backscatter_per_m_sr": backscatter(a, self.variant, self.params),
               "scatter_noise": f"v1: R_f·R0/U(R0 ± {self.params.scatter_noise_m:g} m)"}
        if a > 0:
            peak, rf = fog_peak(a, self.params)
            out |= {"fog_peak_range_m": rf, "fog_peak_integral_s_per_m2": peak}
        return out

    def __call__(self, beta, rng: np.random.Generator):
        owner, p, a = self.owner, self.params, self.alpha(beta)
        i, r0 = self.fed, self.r0
        i_hard = np.round(i * np.exp(-2.0 * a * r0))
        peak, rf_far = fog_peak(a, p)
        nodes, curve = open_fog_response(p.integral_alpha(a), p)
        near = r0 < rf_far
        imax = np.where(near, np.interp(r0, nodes, curve, left=0.0), peak)
        rf = np.where(near, r0, rf_far)
        gain = backscatter(a, self.variant, p) / (p.target_reflectivity / math.pi)
        i_soft = np.minimum(i * (r0 * r0) * gain * imax, FED_TOP)
        scattered = i_soft > i_hard
        if owner.blank_mask is not None:
            scattered &= ~owner.blank_mask  # a no-return row is no point: never fed, never scattered
        sc = np.flatnonzero(scattered)
        rng.integers(1, 20)  # drawn and discarded, as the released code does
        u = rng.uniform(r0[sc] - p.scatter_noise_m, r0[sc] + p.scatter_noise_m)  # the draws: one per scattered point
        new_r = owner.range_m.copy()
        new_r[sc] = rf[sc] * r0[sc] / u
        fed_out = np.where(scattered, i_soft, i_hard)
        norm, raw = owner.scale.from_linear(owner.scale.to_linear(fed_out / FED_TOP))
        if owner.scan.scale == "0-255":
            raw = fed_out.astype(np.float32)  # the fed values themselves (no round trip through /255)
        outcome = np.where(scattered, CLUTTER, np.where(i_hard == i, KEPT, ATTENUATED)).astype(np.int8)
        if owner.blank_mask is not None:
            outcome[owner.blank_mask] = NO_RETURN  # written as it was
        n = len(outcome)
        return assemble(owner, np.arange(n), slice(None), outcome, new_r, norm, raw, outcome.copy(),
                        owner.parameters(beta))
