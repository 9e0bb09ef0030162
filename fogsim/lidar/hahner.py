"""The LiDAR fog simulation of Hahner et al. (ICCV 2021, "Fog Simulation on Real LiDAR Point Clouds for 3D
Object Detection in Adverse Weather"), re-implemented here from the paper's equations — the reference
fogsim's own model (:mod:`fogsim.lidar.fog`) is compared with (``scripts/lidar_side_by_side.py``).

Written from the published equations and the measured facts in ``docs/lidar-fog.md``, not from the
authors' code (CC BY-NC 4.0: non-commercial). Their α is fogsim's β (extinction, 1/m); their β is the
backscatter coefficient β_b = 0.046 / MOR (MOR = ln 20 / α, 1/(m·sr)).

The LiDAR equation (time domain, their §3.1): P_R(R) = C_A ∫₀^{2R/c} P₀(t) H(R − ct/2) dt with the pulse
P₀(t) = P₀ sin²(πt / 2τ_H) for 0 ≤ t ≤ 2τ_H (τ_H = 20 ns, its half-power width), the channel
H_C(R) = e^(−2αR) ξ(R) / R² and the overlap ξ(R) = 0 up to R₁ = 0.9 m, rising linearly to 1 at R₂ = 1 m.
A hard target at R₀ (H_T = β₀ δ(R − R₀), β₀ = Γ/π, Γ = 10⁻⁶ for every target) peaks at
C_A P₀ β₀ e^(−2αR₀) / R₀²; fog in front of it (H_T = β_b for R < R₀) gives

    I(R; R₀) = ∫₀^{2τ_H} sin²(πt / 2τ_H) · ξ(r) e^(−2αr) / r² · [R₁ < r < R₀] dt,   r = R − ct/2   (s/m²)

and a received fog power C_A P₀ β_b I(R; R₀) — I kept in s/m² (a time integral) against the hard peak's
1/R₀², as the paper writes them: the units in which Γ = 10⁻⁶ gives the reference's thresholds (below).
Per point (their §3.2) with fed intensity i and range R₀:
the clear intensity fixes the point's own system constant, C_A P₀ = i R₀² / β₀, so

* the attenuated hard return is i_hard = round(i · e^(−2αR₀)) (an integer: the reference rounds);
* the fog's return peaks at i_soft = i R₀² (β_b / β₀) · max_R I(R; R₀), at R_f = argmax (≈ 4.6 m beyond
  a few metres: 4.67 m at α 0.03, 4.58 m at 0.12);
* if i_soft > i_hard the point is **scattered**: moved along its ray to R_f + δ, δ uniform in ±10 m
  (the training default; R_f + δ < 0, which the paper leaves open, puts it at that signed distance on
  its ray's line, behind the sensor), intensity round(i_soft) (rounded here like i_hard); else it stays
  where it is with intensity i_hard.
  No point is added or removed. The echo scales with the point's own intensity, so a zero-intensity
  point is never scattered; and the decision does not otherwise depend on i — every return beyond
  r_thr(α) (62 / 36 / 24 / 20 m at α 0.03 / 0.06 / 0.10 / 0.12) becomes a scattered point — except
  through the rounding of i_hard: fed KITTI's unscaled 0–1 reflectances, i_hard rounds to 0 and every
  non-zero point is scattered at any α (the "0–1 trap"); fed ×255 (as their KITTI viewer does) it is not.

Outcomes in fogsim's vocabulary (:data:`fogsim.lidar.fog.OUTCOMES`): scattered → ``clutter``; a hard
return whose integer intensity is unchanged → ``kept``; otherwise ``attenuated``; ``lost`` never occurs.

Numerics (here, not theirs): I is computed for any α on a grid of L/2400 (L = cτ_H, 2.5 mm at 20 ns) from
running sums (sin² = (1 − cos)/2), the peak refined by a parabola: within 10⁻⁴ of adaptive quadrature
from 1.5 m (tests/test_lidar_hahner.py); targets nearer than R_f take their peak from a table every 1 cm
of R₀ (within 2·10⁻³). The reference code instead reads tables of I for nine α (0.005, 0.01, 0.02,
0.03, 0.06, 0.1, 0.12, 0.15, 0.2) at 0.1 m steps of R₀ and takes the **nearest** α (α = 0.09 runs as
0.1): ``HahnerParameters(table_lookup=True)`` does that for the integral.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from functools import lru_cache

import numpy as np

from fogsim.lidar.outcomes import ATTENUATED, CLUTTER, KEPT
from fogsim.lidar.points import PointCloud
from fogsim.lidar.sensors import LIGHT_SPEED

__all__ = ["FEEDS", "HahnerFog", "HahnerParameters", "TABLE_ALPHAS", "clear_cache", "fed_intensity", "fog_peak",
           "hahner_fog", "open_fog_response", "overlap", "soft_target_integral", "soft_target_peaks"]

#: the α of the reference code's precomputed integral tables (it uses the nearest one)
TABLE_ALPHAS = (0.005, 0.01, 0.02, 0.03, 0.06, 0.1, 0.12, 0.15, 0.2)
#: how intensities are fed: ``viewer`` as the reference's own viewer feeds KITTI (0–1 × 255, rounded;
#: 0–255 sources as stored), ``raw`` the stored values as they are (KITTI 0–1 unscaled: the trap)
FEEDS = ("viewer", "raw")
LN20 = math.log(20.0)
#: the R₀ step of the table of peaks for targets closer than the fog peak (metres), and the R samples of each
PEAK_TABLE_STEP_M, PEAK_SAMPLES = 0.01, 200


@dataclass(frozen=True)
class HahnerParameters:
    """The reference's constants (units in the names): pulse τ_H, overlap ξ from R₁ to R₂, the targets'
    Γ (β₀ = Γ/π), β_b = ``backscatter_per_visibility`` / MOR, the scattered points' uniform range noise
    (± metres), ``table_lookup`` (the integral at the nearest :data:`TABLE_ALPHAS`, as their code),
    ``steps_per_pulse`` (the integration grid: L / this)."""

    pulse_half_power_ns: float = 20.0
    overlap_start_m: float = 0.9
    overlap_full_m: float = 1.0
    target_reflectivity: float = 1e-6
    backscatter_per_visibility: float = 0.046
    scatter_noise_m: float = 10.0
    table_lookup: bool = False
    steps_per_pulse: int = 2400

    @property
    def pulse_length_m(self) -> float:
        """L = c·τ_H: the range the 2τ_H-long sin² pulse spans (c·2τ_H / 2)."""
        return LIGHT_SPEED * self.pulse_half_power_ns * 1e-9

    def backscatter(self, alpha: float) -> float:
        """β_b = c_b / MOR = c_b·α / ln 20 (1/(m·sr))."""
        return self.backscatter_per_visibility * alpha / LN20

    def integral_alpha(self, alpha: float) -> float:
        """The α the soft-target integral is computed at: α, or the nearest table's (``table_lookup``)."""
        if not self.table_lookup:
            return float(alpha)
        return float(min(TABLE_ALPHAS, key=lambda a: abs(a - alpha)))


def overlap(r, p: HahnerParameters = HahnerParameters()) -> np.ndarray:
    """ξ(R): 0 up to R₁, linear to 1 at R₂, 1 beyond (float64)."""
    r = np.asarray(r, np.float64)
    span = p.overlap_full_m - p.overlap_start_m
    if span <= 0:
        return (r >= p.overlap_full_m).astype(np.float64)
    return np.clip((r - p.overlap_start_m) / span, 0.0, 1.0)


def _cumulative(alpha: float, p: HahnerParameters, reach_m: float):
    """Running sums (midpoint rule, step h ≈ L / ``steps_per_pulse`` from R₁, R₂ a node) of w = ξ e^(−2αr)/r²,
    w·cos(2πr/L) and w·sin(2πr/L): (nodes r_k = R₁ + k·h, C0, Cc, Cs) with C(r_k) = ∫_{R₁}^{r_k}."""
    length = p.pulse_length_m
    h = length / p.steps_per_pulse
    ramp = p.overlap_full_m - p.overlap_start_m
    if ramp > 0:  # R₂ on a node: the kink of ξ between cells
        h = ramp / max(1, round(ramp / h))
    n = int(math.ceil((reach_m - p.overlap_start_m) / h)) + 1
    mid = p.overlap_start_m + (np.arange(n) + 0.5) * h
    w = overlap(mid, p) * np.exp(-2.0 * alpha * mid) / (mid * mid)
    phase = 2.0 * np.pi * mid / length
    zero = np.zeros(1)
    c0 = np.concatenate([zero, np.cumsum(w) * h])
    cc = np.concatenate([zero, np.cumsum(w * np.cos(phase)) * h])
    cs = np.concatenate([zero, np.cumsum(w * np.sin(phase)) * h])
    return p.overlap_start_m + np.arange(n + 1) * h, c0, cc, cs


def _integral(rt, r0, p: HahnerParameters, cums) -> np.ndarray:
    """I(R_t; R₀) (s/m²) for arrays R_t and R₀ (broadcast) from the running sums ``cums``."""
    nodes, c0, cc, cs = cums
    length = p.pulse_length_m
    rt = np.asarray(rt, np.float64)
    a = np.maximum(rt - length, p.overlap_start_m)
    b = np.minimum(rt, r0)

    def span(c):
        return np.interp(b, nodes, c) - np.interp(a, nodes, c)
    theta = 2.0 * np.pi * rt / length
    # sin²(π(R_t − r)/L) = ½ − ½[cos θ_t cos θ_r + sin θ_t sin θ_r]; dt = 2 dr / c
    j = 0.5 * span(c0) - 0.5 * (np.cos(theta) * span(cc) + np.sin(theta) * span(cs))
    return np.where(b > a, np.maximum(j, 0.0) * (2.0 / LIGHT_SPEED), 0.0)


def _reach(p: HahnerParameters) -> float:
    return p.overlap_full_m + 3.0 * p.pulse_length_m


def soft_target_integral(r, alpha: float, p: HahnerParameters = HahnerParameters(), r0=math.inf) -> np.ndarray:
    """I(R; R₀) in s/m² at ranges ``r`` (metres, array) for extinction ``alpha`` (1/m, exactly: no table)
    and a hard target at ``r0`` (inf: none); ranges up to R₂ + 3L."""
    return _integral(r, np.asarray(r0, np.float64), p, _cumulative(float(alpha), p, _reach(p)))


def _refine(x: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(value, position) of each row's sampled maximum (rows of ``j`` over the rows of ``x``, evenly
    spaced), refined by a parabola through its three samples."""
    x, j = np.atleast_2d(x), np.atleast_2d(j)
    rows = np.arange(len(j))
    k = np.clip(np.argmax(j, axis=1), 1, j.shape[1] - 2)
    ja, jb, jc = j[rows, k - 1], j[rows, k], j[rows, k + 1]
    den = ja - 2.0 * jb + jc
    ok = (den < 0) & (jb >= ja) & (jb >= jc)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(ok, 0.5 * (ja - jc) / den, 0.0)
    best = np.argmax(j, axis=1)
    value = np.where(ok, jb - 0.25 * (ja - jc) * d, j[rows, best])
    pos = np.where(ok, x[rows, k] + d * (x[:, 1] - x[:, 0]), x[rows, best])
    return value, pos


@lru_cache(maxsize=32)
def _open_response(alpha: float, p: HahnerParameters) -> tuple[tuple, np.ndarray]:
    """(the running sums, I(R; ∞) at their nodes)."""
    cums = _cumulative(alpha, p, _reach(p))
    return cums, _integral(cums[0], np.inf, p, cums)


def open_fog_response(alpha: float, p: HahnerParameters = HahnerParameters()) -> tuple[np.ndarray, np.ndarray]:
    """(R, I(R; ∞)): the fog's response with no target in the way (s/m²) on the integration grid (metres,
    from R₁ to R₂ + 3L) at the exact ``alpha`` — cached per α and parameters."""
    cums, curve = _open_response(float(alpha), p)
    return cums[0], curve


@lru_cache(maxsize=32)
def _far_peak(alpha: float, p: HahnerParameters) -> tuple[float, float]:
    """(I_max, R_f) with no target in the way."""
    cums, curve = _open_response(alpha, p)
    value, pos = _refine(cums[0], curve)
    return float(value[0]), float(pos[0])


@lru_cache(maxsize=32)
def _peak_table(alpha: float, p: HahnerParameters) -> tuple[float, float, np.ndarray, np.ndarray, np.ndarray]:
    """(I_max, R_f) with no target in the way, and the table (R₀, I_max(R₀), R_f(R₀)) of the targets
    closer than R_f, every :data:`PEAK_TABLE_STEP_M`, each maximum searched over R ∈ [R₀, R₀ + L]."""
    cums, _ = _open_response(alpha, p)
    value, pos = _far_peak(alpha, p)
    r0 = np.arange(p.overlap_start_m, pos + PEAK_TABLE_STEP_M, PEAK_TABLE_STEP_M)
    grid = r0[:, None] + np.linspace(0.0, p.pulse_length_m, PEAK_SAMPLES)[None, :]
    imax, rf = _refine(grid, _integral(grid, r0[:, None], p, cums))
    return value, pos, r0, imax, rf


def clear_cache() -> None:
    """Forget the fog peaks computed so far (they are cached per α and parameters)."""
    _peak_table.cache_clear()
    _far_peak.cache_clear()
    _open_response.cache_clear()


def fog_peak(alpha: float, p: HahnerParameters = HahnerParameters()) -> tuple[float, float]:
    """(I_max in s/m², R_f in metres): the peak of the fog's response with no target in the way — the
    same for every target beyond R_f."""
    return _far_peak(p.integral_alpha(alpha), p)


def soft_target_peaks(alpha: float, r0, p: HahnerParameters = HahnerParameters()) -> tuple[np.ndarray, np.ndarray]:
    """(I_max, R_f) per target range R₀ (arrays, s/m² and metres): :func:`fog_peak` for R₀ ≥ R_f; a closer
    target cuts the fog off at R₀ (0 within R₁): its peak from a table every 1 cm of R₀ (linear between)."""
    value, pos, table_r0, table_i, table_r = _peak_table(p.integral_alpha(alpha), p)
    r0 = np.asarray(r0, np.float64)
    near = r0 < pos
    imax = np.where(near, np.interp(r0, table_r0, table_i, left=0.0), value)
    rf = np.where(near, np.interp(r0, table_r0, table_r), pos)
    return imax, rf


def fed_intensity(scan: PointCloud, feed: str = "viewer") -> np.ndarray:
    """The intensities the reference is fed (float64): ``viewer`` — a 0–1 scan × 255 and rounded (their
    KITTI viewer), a 0–255 scan as stored; ``raw`` — the stored values as they are (:data:`FEEDS`)."""
    if feed not in FEEDS:
        raise ValueError(f"unknown feed {feed!r} (known: {', '.join(FEEDS)})")
    raw = np.asarray(scan.raw_intensity, np.float64)
    if feed == "viewer" and scan.scale == "0-1":
        return np.round(raw * 255.0)
    return raw


@dataclass(frozen=True, eq=False)
class HahnerFog:
    """One fog level by the reference: per input point its ``outcome`` (int8, fogsim's codes), output
    ``xyz`` (N×3 float64; every point stays, scattered ones moved), ``intensity`` (float64, integers),
    ``ray_distance`` (signed distance along the point's own ray, metres: R₀, or R_f + δ when scattered,
    negative behind the sensor) and the ``parameters`` (α, β_b, the fog peak, the constants)."""

    outcome: np.ndarray
    xyz: np.ndarray
    intensity: np.ndarray
    ray_distance: np.ndarray
    parameters: dict

    @property
    def scattered(self) -> np.ndarray:
        return self.outcome == CLUTTER


def hahner_fog(xyz, intensity, alpha: float, rng: np.random.Generator,
               p: HahnerParameters = HahnerParameters()) -> HahnerFog:
    """The reference's fog at extinction ``alpha`` (1/m) on points ``xyz`` (N×3, sensor frame, metres)
    with the fed intensities ``intensity`` (N; :func:`fed_intensity`). ``rng`` draws one uniform δ per
    input point, in input order (used where the point is scattered)."""
    alpha = float(alpha)
    if not (math.isfinite(alpha) and alpha >= 0):
        raise ValueError(f"α must be a finite number ≥ 0 (1/m), got {alpha}")
    xyz = np.asarray(xyz, np.float64)
    i = np.asarray(intensity, np.float64).reshape(-1)
    if xyz.shape != (len(i), 3):
        raise ValueError(f"xyz must be N×3 with one intensity per point, got {xyz.shape} and {i.shape}")
    r0 = np.linalg.norm(xyz, axis=1)
    delta = rng.uniform(-p.scatter_noise_m, p.scatter_noise_m, len(i))
    bb = p.backscatter(alpha)
    beta0 = p.target_reflectivity / math.pi
    imax, rf = soft_target_peaks(alpha, r0, p)
    i_hard = np.round(i * np.exp(-2.0 * alpha * r0))
    i_soft = i * r0 * r0 * (bb / beta0) * imax
    scattered = i_soft > i_hard
    dist = np.where(scattered, rf + delta, r0)
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = np.where(scattered, dist / r0, 1.0)
    out_xyz = xyz * factor[:, None]
    out_i = np.where(scattered, np.round(i_soft), i_hard)
    outcome = np.where(scattered, CLUTTER, np.where(i_hard == i, KEPT, ATTENUATED)).astype(np.int8)
    peak_i, peak_r = fog_peak(alpha, p)
    params = {"alpha": alpha, "backscatter_per_m_sr": bb, "integral_alpha": p.integral_alpha(alpha),
              "fog_peak_range_m": peak_r, "fog_peak_integral_s_per_m2": peak_i, "constants": asdict(p)}
    return HahnerFog(outcome, out_xyz, out_i, dist, params)
