"""The fog's own echo: fog as a *soft target* of the LiDAR equation, computed for any β.

A slab of fog dR thick at range R backscatters like a target of reflectance-per-steradian β_b·dR
(β_b the backscatter coefficient, 1/(m·sr)), attenuated two ways and seen through the overlap ξ. The
transmitted pulse is P(t) = P₀·sin²(πt / 2τ_H) for 0 ≤ t ≤ 2τ_H (τ_H the half-power width), so the echo
received when the pulse's front has reached R_t = c·t/2 is

    J(R_t) = ∫_{R_t − L}^{R_t} sin²(π (R_t − R) / L) · ξ(R) · e^(−2β R) / R²  dR,      L = c·τ_H,

and, over the detection threshold (the clear-air return of the reference target ρ_ref at R_max, whose
peak is P₀·(ρ_ref/π)/R_max²), the fog's signal is

    q_fog(R_t) = s_f · π · β_b · J(R_t) · R_max² / ρ_ref,

s_f the sensor's ``fog_echo_scale`` (1 = the LiDAR equation with the backscatter rule as it is; a calibration
fitted to real foggy scans, :mod:`fogsim.lidar.fit`, sets it: the backscatter rule's uncertainty and a receiver
that answers a wide soft-target echo less than a pulse-shaped hard one both scale the echo alone).

Its **peak** (value q_f, range r_f, full width at half maximum w_f) is the fog echo a sensor may report:
it lies a few metres from the sensor (ξ rises as R², so ξ/R² is flat up to R_o and the pulse's window
fills there). β is the LiDAR's extinction (β_905 = ``extinction_ratio`` · β); the backscatter β_b
follows :func:`backscatter_coefficient`.

Numerics, exact for any β (no table of densities): J is the midpoint rule on a grid of step L/400
(≤ 7.5 mm for a 10 ns pulse) out to 4·(L + R_o), evaluated for every R_t on the grid at once in O(n)
from two running sums (sin² = (1 − cos)/2, the cosine through a complex exponential); the peak is
refined by a parabola through its three grid samples. Against adaptive quadrature the peak value is
within 1e-5 relative (tests/test_lidar_fog.py). A per-point β (:func:`echo_per_point`) is exact for up
to :data:`EXACT_UNIQUE` distinct values; beyond, log J, r_f and w_f are interpolated linearly between
β nodes at most :data:`NODE_STEP` apart: relative error of q_f ≤ 1e-4 and of r_f ≤ 1 mm (tested).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from fogsim.lidar.sensors import LidarSensor
from fogsim.schema.lidar import LidarFogSpec

__all__ = ["EXACT_UNIQUE", "FogEcho", "NODE_STEP", "backscatter_coefficient", "echo_per_point", "fog_echo",
           "fog_waveform"]

#: grid points per pulse length L
STEPS_PER_PULSE = 400
#: a per-point β with at most this many distinct values is computed exactly, value by value
EXACT_UNIQUE = 64
#: the largest β step (1/m, LiDAR extinction) between interpolation nodes of a per-point β
NODE_STEP = 2e-3
MAX_NODES = 2048
LN20 = math.log(20.0)


def backscatter_coefficient(beta, spec: LidarFogSpec):
    """β_b (1/(m·sr)) of fog whose *visible* extinction is ``beta`` (1/m; scalar or array):
    ``visibility`` rule β_b = c_b / V = c_b·β / ln 20; ``lidar-ratio`` rule β_b = β_905 / S."""
    beta = np.asarray(beta, np.float64)
    if spec.backscatter_rule == "visibility":
        return spec.backscatter_coefficient * beta / LN20
    return spec.extinction_ratio * beta / spec.lidar_ratio_sr


def _grid(sensor: LidarSensor) -> tuple[float, int, int, float]:
    """(step, points per pulse m, grid size n, integration start)."""
    length = sensor.pulse_length_m
    if sensor.overlap_full_m <= 0 and sensor.min_range_m <= 0:
        raise ValueError(f"{sensor.name}: the fog echo needs overlap_full_m > 0 or min_range_m > 0 "
                         "(with full overlap from R = 0 the 1/R² echo diverges)")
    step = length / STEPS_PER_PULSE
    n = int(math.ceil(4.0 * (length + sensor.overlap_full_m + sensor.min_range_m) / step)) + STEPS_PER_PULSE
    start = 0.0 if sensor.overlap_full_m > 0 else sensor.min_range_m
    return step, STEPS_PER_PULSE, n, start


def fog_waveform(sensor: LidarSensor, beta_ext: float) -> tuple[np.ndarray, np.ndarray]:
    """(R_t grid, J(R_t)) in metres and 1/m for the LiDAR extinction ``beta_ext`` (the module docstring)."""
    step, m, n, _ = _grid(sensor)
    r, base, down, up = _terms(sensor)
    w = base * np.exp(-2.0 * beta_ext * r)
    c0 = np.concatenate([[0.0], np.cumsum(w)])
    c1 = np.concatenate([[0.0], np.cumsum(w * down)])
    k = np.arange(n + 1)
    lo = np.maximum(k - m, 0)
    s0, s1 = c0[k] - c0[lo], c1[k] - c1[lo]
    j = 0.5 * step * (s0 - (up * s1).real)
    return k * step, np.maximum(j, 0.0)


@lru_cache(maxsize=16)
def _terms(sensor: LidarSensor):
    """What J's grid for ``sensor`` needs that does not depend on β (read-only): the midpoints r, ξ(r)/r² (0
    before the integration's start), and the phasors e^(−2πik/m) (k < n) and e^(2πi(k − ½)/m) (k ≤ n)."""
    step, m, n, start = _grid(sensor)
    r = (np.arange(n) + 0.5) * step
    base = sensor.overlap(r) / (r * r)
    base[r < start] = 0.0
    down = np.exp(-2j * np.pi * np.arange(n) / m)
    up = np.exp(2j * np.pi * (np.arange(n + 1) - 0.5) / m)
    for a in (r, base, down, up):
        a.flags.writeable = False
    return r, base, down, up


@dataclass(frozen=True)
class FogEcho:
    """The fog echo's peak for one β: ``signal`` q_f over the threshold, ``range_m`` r_f, ``width_m``
    w_f (FWHM in range), and J at the peak (``integral``, 1/m); ``backscatter`` β_b, ``beta_ext`` β_905."""

    beta_ext: float
    backscatter: float
    integral: float
    signal: float
    range_m: float
    width_m: float


def _peak(rt: np.ndarray, j: np.ndarray) -> tuple[float, float, float]:
    """(value, position, FWHM) of a sampled unimodal curve, the peak refined by a parabola."""
    k = int(np.argmax(j))
    step = rt[1] - rt[0]
    value, pos = float(j[k]), float(rt[k])
    if 0 < k < len(j) - 1:
        a, b, c = j[k - 1], j[k], j[k + 1]
        den = a - 2 * b + c
        if den < 0:
            d = 0.5 * (a - c) / den
            value, pos = float(b - 0.25 * (a - c) * d), float(rt[k] + d * step)
    half = 0.5 * value
    left = np.flatnonzero(j[:k] < half)
    right = np.flatnonzero(j[k:] < half)
    def cross(i0, i1):  # linear interpolation of the half-level crossing between samples i0, i1
        y0, y1 = j[i0], j[i1]
        return float(rt[i0] + (half - y0) / (y1 - y0) * (rt[i1] - rt[i0])) if y1 != y0 else float(rt[i0])
    x0 = cross(left[-1], left[-1] + 1) if left.size else float(rt[0])
    x1 = cross(k + right[0] - 1, k + right[0]) if right.size else float(rt[-1])
    return value, pos, x1 - x0


def _echo(sensor: LidarSensor, beta_ext: float, backscatter: float) -> FogEcho:
    rt, j = fog_waveform(sensor, beta_ext)
    integral, pos, width = _peak(rt, j)
    signal = (sensor.fog_echo_scale * math.pi * backscatter * integral * sensor.max_range_m ** 2
              / sensor.reference_reflectivity)
    return FogEcho(float(beta_ext), float(backscatter), integral, signal, pos, width)


def fog_echo(sensor: LidarSensor, beta: float, spec: LidarFogSpec = LidarFogSpec()) -> FogEcho:
    """The fog echo of fog with visible extinction ``beta`` (1/m) for ``sensor`` and ``spec``."""
    return _echo(sensor, spec.extinction_ratio * float(beta), float(backscatter_coefficient(beta, spec)))


def echo_per_point(sensor: LidarSensor, beta: np.ndarray, spec: LidarFogSpec = LidarFogSpec()
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q_f, r_f, w_f) per point for a per-point visible β (N): exact for ≤ :data:`EXACT_UNIQUE` distinct
    values, else interpolated between β nodes (the module docstring's bound)."""
    beta = np.asarray(beta, np.float64).reshape(-1)
    bb = backscatter_coefficient(beta, spec)
    values, inverse = np.unique(beta, return_inverse=True)
    if len(values) <= EXACT_UNIQUE:
        echoes = [fog_echo(sensor, b, spec) for b in values]
        q = np.array([e.signal for e in echoes])[inverse]
        r = np.array([e.range_m for e in echoes])[inverse]
        w = np.array([e.width_m for e in echoes])[inverse]
        return q, r, w
    ext = spec.extinction_ratio * beta
    lo, hi = float(ext.min()), float(ext.max())
    count = min(MAX_NODES, int(math.ceil((hi - lo) / NODE_STEP)) + 1)
    nodes = np.linspace(lo, hi, max(count, 2))
    table = [_echo(sensor, b, 1.0) for b in nodes]
    log_j = np.interp(ext, nodes, np.log([e.integral for e in table]))
    r = np.interp(ext, nodes, [e.range_m for e in table])
    w = np.interp(ext, nodes, [e.width_m for e in table])
    q = sensor.fog_echo_scale * math.pi * bb * np.exp(log_j) * sensor.max_range_m ** 2 / sensor.reference_reflectivity
    return q, r, w
