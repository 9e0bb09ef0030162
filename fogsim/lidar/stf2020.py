"""``--lidar-model stf2020``: the LiDAR fog rule of the Seeing Through Fog authors (Bijelic et al., CVPR 2020;
their dataset tools' foggification, parameters "found empirically" in a fog chamber), on fogsim's scans.

Written from a description of the rule (``docs/lidar-fog.md``), not from the authors' code (no licence).
β is the level's β at 905 nm (``extinction_ratio``·β), one for every ray by default (``stf_beta_field``
``homogeneous``: one fog for every sensor); ``random`` adds the authors' random β field (below). Per sensor
a noise level n and a gain g (``stf_noise_level``, ``stf_gain``: the HDL-64 S3D n 0.04, g 0.45; the
HDL-64 S2 n 0.05, g 0.35); a sensor without them is refused unless a calibration file gives them. Per input
point at range d with intensity I normalised to 0–1 (0–255 scans ÷ 255):

* d ≤ d_min = 2 m: below the rule's minimal detectable distance — ``lost`` (returns only: a **no-return row**,
  nearer than the sensor's minimum range — :func:`fogsim.lidar.rays.no_returns`, a nuScenes firing without an
  echo — is no point, never fogged: ``no-return``, written as it was);
* d_max = ln((I + g)/n)/(2β); d < d_max: reported where it is with intensity I·e^(−βd) (one-way, as the
  rule writes it) — ``kept`` when that falls by less than ``kept_tolerance`` (written bit for bit), else
  ``attenuated``;
* d ≥ d_max: lost with probability p = 1 − e^(−β·d_max) (= 1 − √(n/(I + g)): β cancels); if not lost and
  d > d_new = ln 2/β, moved along its ray to d_new with intensity I·e^(−β·d_new) = I/2 (*cloud scatter*) —
  ``clutter``; if not lost and d ≤ d_new, not reported either — ``lost``;
* **random scatter** (added points, ``FoggedScan.added_points``): the points beyond d_min whose loss draw
  spared them and with d ≤ d_new (reported or not) are candidates; each draws a range u ~ U(0, min(d_max, d));
  of those with u > d_min a random 5 % (⌊0.05·count⌋, without replacement) gain an extra point on their ray
  at u with intensity I·e^(−βu), appended after the input's reported points (index −1, the source point's
  ring and return index).

**A scan that stores every firing** (rings and placeholder rows at ≈ 0 m: nuScenes; ``LidarFogger.keeps_firings``)
keeps one row per firing: a lost return becomes a placeholder row (x y z 0, intensity 0, ``output_index``
naming it); a random-scatter point whose source return is lost becomes that firing's row (``clutter``: the
one echo its firing reports), one whose source is reported is a second return of that firing, which the
format does not hold — not written, counted as ``random_scatter_unstored`` in the level's parameters (the
draws are the same). Rows out = firings in.

The random β field (``stf_beta_field`` ``random``): β(x, y, z) = β + Σ_k |A_k·sin(a + o_k) +
B_k·sin(a + f_k·z + p_k)| with a = tan(y/x) (x = 0 taken as 10⁻⁴; the authors' code takes the tangent where
an azimuth was presumably meant — kept as released), K ∈ {6 … 9} components, f_k ∈ {0 … 4}, o_k, p_k ~
U(0, 2π), A_k, B_k ~ U(0, 0.05/K), the phases then advanced once by their time step (o_k + 1, p_k + f_k):
β rises by 0 … 0.1 1/m, a new field per scan. The sweep's empty rays are counted, never fogged.

β → 0 keeps every point (d_max → ∞) but the random scatter does not vanish: at any β > 0 about 5 % of the
spared points gain a point (β = 0 itself is the clear scan, bit for bit, as for every model).

Random draws from the caller's Generator, in this order: with the random field its K (``integers(6, 10)``), f (K
``integers(0, 5)``), o, p (K ``uniform(0, 2π)`` each), A, B (K ``uniform(0, 0.05/K)`` each); then one ``random()``
per input row (the loss draw, input order; drawn for no-return rows too, unused); one ``uniform(0, min(d_max,
d))`` per candidate (input order); ``choice(count, ⌊0.05·count⌋, replace=False)`` of the eligible ones (the added
points in that order).
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

from fogsim.lidar.fogged_scan import assemble
from fogsim.lidar.outcomes import ATTENUATED, CLUTTER, KEPT, LOST, NO_RETURN

__all__ = ["D_MIN_M", "RANDOM_SCATTER", "S2_ASSUMED", "Model", "RandomBetaField", "constants"]

#: the rule's minimal detectable distance (metres)
D_MIN_M = 2.0
#: the share of the eligible candidates that gain a random-scatter point
RANDOM_SCATTER = 0.05
_S2_SOURCE = ("assumption: the STF authors' HDL-64 S2 constants (Bijelic et al. 2020, SeeingThroughFog "
              "tools/DatasetFoggification/lidar_foggification.py, sensor VelodyneHDLS2: n = 0.05, g = 0.35, found "
              "empirically in their fog chamber) for a sensor they published none for (nuScenes' HDL-32E)")
#: a calibration block (``--lidar-calibration``) giving a sensor without published n and g the HDL-64 S2's, as
#: the lidar-realism notes' measurement on a nuScenes sweep did — an assumption, and named as one
S2_ASSUMED = {"name": "stf-s2-assumed", "stf_noise_level": 0.05, "stf_gain": 0.35,
              "sources": {"stf_noise_level": _S2_SOURCE, "stf_gain": _S2_SOURCE}}


def constants(sensor) -> tuple[float, float]:
    """(n, g) of ``sensor`` (a :class:`~fogsim.lidar.sensors.LidarSensor`); a ValueError naming it when it
    has none."""
    n, g = sensor.stf_noise_level, sensor.stf_gain
    if n is None or g is None:
        raise ValueError(f"lidar_fog.model stf2020 needs the sensor's noise level and gain, which the STF authors "
                         f"published for the HDL-64 S3D and S2 only: {sensor.name} has none (give stf_noise_level "
                         "and stf_gain in a calibration file: --lidar-calibration FILE)")
    return float(n), float(g)


@dataclass(frozen=True)
class RandomBetaField:
    """The authors' random β field (module docstring): per component its vertical frequency ``f``, phases
    ``o`` and ``p`` (after the time step) and amplitudes ``a`` and ``b`` (1/m)."""

    f: np.ndarray
    o: np.ndarray
    p: np.ndarray
    a: np.ndarray
    b: np.ndarray

    @classmethod
    def draw(cls, rng: np.random.Generator) -> "RandomBetaField":
        k = int(rng.integers(6, 10))
        f = rng.integers(0, 5, k)
        o, p = rng.uniform(0.0, 2 * math.pi, k), rng.uniform(0.0, 2 * math.pi, k)
        a, b = rng.uniform(0.0, 0.05 / k, k), rng.uniform(0.0, 0.05 / k, k)
        return cls(f.astype(np.float64), o + 1.0, p + f, a, b)

    def __call__(self, xyz: np.ndarray) -> np.ndarray:
        """The field's addition to β (1/m) at points ``xyz`` (N×3, sensor frame)."""
        x = np.where(xyz[:, 0] == 0, 1e-4, xyz[:, 0])
        ang, z = np.tan(xyz[:, 1] / x), xyz[:, 2]
        out = np.zeros(len(xyz))
        for f, o, p, a, b in zip(self.f, self.o, self.p, self.a, self.b):
            out += np.abs(a * np.sin(ang + o) + b * np.sin(ang + f * z + p))
        return out

    def record(self) -> dict:
        return {"components": len(self.f), "f": self.f.tolist(), "o": self.o.tolist(), "p": self.p.tolist(),
                "a": self.a.tolist(), "b": self.b.tolist()}


class Model:
    """stf2020 on a :class:`~fogsim.lidar.fog.LidarFogger`'s scan (``owner``: its scan, sensor, spec, scale
    and no-return rows; the level assembled by :func:`fogsim.lidar.fogged_scan.assemble`); ``model(β, rng)`` one
    level (β > 0: a number, or one per point)."""

    def __init__(self, owner):
        self.owner = weakref.proxy(owner)  # (no reference cycle: a fogger's arrays go when the fogger goes)
        self.n, self.g = constants(owner.sensor)
        self.field = owner.spec.stf_beta_field
        self.d = owner.range_m
        self.i = owner.normalised

    def check(self, beta) -> None:
        pass

    def parameters(self, beta) -> dict:
        out = {"stf_noise_level": self.n, "stf_gain": self.g, "d_min_m": D_MIN_M, "random_scatter": RANDOM_SCATTER,
               "stf_beta_field": self.field, "backscatter_per_m_sr": None}
        if np.ndim(beta) == 0 and beta > 0 and self.field == "homogeneous":
            out["d_new_m"] = math.log(2.0) / (self.owner.spec.extinction_ratio * float(beta))
        return out

    def _converted(self, norm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        sc = self.owner.scale
        return sc.from_linear(sc.to_linear(norm))

    def __call__(self, beta, rng: np.random.Generator):
        owner, d, i = self.owner, self.d, self.i
        n = len(d)
        b = owner.spec.extinction_ratio * (beta if np.ndim(beta) == 0 else np.asarray(beta, np.float64))
        field = RandomBetaField.draw(rng) if self.field == "random" else None
        if field is not None:
            b = b + field(owner.scan.xyz.astype(np.float64))
        b = np.broadcast_to(np.asarray(b, np.float64), d.shape)
        foggy = b > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            d_max = np.log((i + self.g) / self.n) / (2.0 * b)
            d_new = math.log(2.0) / b
            p_lost = 1.0 - np.exp(-b * d_max)
        drawn_lost = rng.random(n) < p_lost  # the draws: one per input row
        real = np.ones(n, bool) if owner.blank_mask is None else ~owner.blank_mask  # returns, not no-return rows
        near = real & (d <= D_MIN_M)
        stable = real & ~near & (d < d_max)
        beyond = real & ~near & ~stable
        cloud = beyond & ~drawn_lost & (d > d_new)
        lost = near | (beyond & ~cloud)
        cand = np.flatnonzero(real & ~near & ~drawn_lost & ~(d > d_new) & foggy)
        u = rng.uniform(0.0, np.minimum(d_max[cand], d[cand]))  # one per candidate
        eligible = u > D_MIN_M
        cand, u = cand[eligible], u[eligible]
        pick = rng.choice(len(cand), int(RANDOM_SCATTER * len(cand)), replace=False)
        src, u = cand[pick], u[pick]
        # every input row: its outcome, range along its ray and intensity
        with np.errstate(invalid="ignore"):  # β = 0 rows (a per-point β): d_new = inf, never cloud scatter
            new_i = np.where(cloud, i * np.exp(-b * d_new), i * np.exp(-b * d))
        outcome = np.where(cloud, CLUTTER, np.where(i - new_i < owner.spec.kept_tolerance, KEPT, ATTENUATED))
        outcome = outcome.astype(np.int8)
        outcome[lost] = LOST
        outcome[~real] = NO_RETURN  # written as it was
        new_r = np.where(cloud, d_new, d)
        norm, raw = self._converted(new_i)
        a_norm, a_raw = self._converted(i[src] * np.exp(-b[src] * u))
        params = owner.parameters(beta) | {"within_d_min": int(near.sum()), "random_scatter_points": int(len(src))}
        if field is not None:
            params["beta_field"] = field.record()
        placed = None
        if owner.keeps_firings:  # one row per firing (nuScenes): module docstring
            fill = outcome[src] == LOST  # its firing reports nothing else: the scatter point is its return
            rows = src[fill]
            outcome[rows], new_r[rows], norm[rows], raw[rows] = CLUTTER, u[fill], a_norm[fill], a_raw[fill]
            params["random_scatter_unstored"] = int((~fill).sum())
            src, u, a_norm, a_raw = src[:0], u[:0], a_norm[:0], a_raw[:0]
            gone = np.flatnonzero(outcome == LOST)  # a lost return keeps its row: a placeholder
            norm[gone], raw[gone] = 0.0, 0.0
            placed = [(gone, np.zeros((len(gone), 3)))]
            idx = np.arange(n)
        else:
            idx = np.flatnonzero(outcome != LOST)
        # the random-scatter points: on their source point's ray at u
        axyz = (owner.scan.xyz[src].astype(np.float64) * (u / d[src])[:, None]).astype(np.float32)
        pick_rows = slice(None) if len(idx) == n else idx
        return assemble(owner, idx, pick_rows, outcome[idx], new_r[idx], norm[idx], raw[idx], outcome, params,
                        placed=placed, added=(axyz, a_norm, a_raw, src))
