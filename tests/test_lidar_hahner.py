"""The re-implementation of Hahner et al.'s LiDAR fog (fogsim.lidar.hahner) against its published equations
on geometry built here: the soft-target integral against adaptive quadrature of the paper's time-domain
form, the fog peak's range, the range beyond which every return scatters (the numbers the reference's
own tables give), the per-point rule (zero intensity never scatters, integer rounding, outcomes) and the
0–1 intensity trap on a KITTI-like sweep."""
from __future__ import annotations

import math

import numpy as np
import pytest

import lidar_fixtures as lfx
from fogsim.lidar.fog import ATTENUATED, CLUTTER, KEPT, LOST
from fogsim.lidar.hahner import (
    TABLE_ALPHAS,
    HahnerParameters,
    fed_intensity,
    fog_peak,
    hahner_fog,
    overlap,
    soft_target_integral,
    soft_target_peaks,
)
from fogsim.lidar.points import PointCloud
from fogsim.lidar.sensors import LIGHT_SPEED

integrate = pytest.importorskip("scipy.integrate")
P = HahnerParameters()
TAU = 20e-9


def paper_integral(rt: float, alpha: float, r0: float = math.inf) -> float:
    """∫₀^{2τ_H} sin²(πt/2τ_H) ξ(R − ct/2) e^(−2α(R − ct/2)) / (R − ct/2)² dt over the fog in front of R₀
    (the paper's time-domain convolution), by adaptive quadrature; ξ written out here (0.9 → 1 m)."""
    def xi(r):
        return min(1.0, max(0.0, (r - 0.9) / 0.1))

    def f(t):
        r = rt - LIGHT_SPEED * t / 2
        return math.sin(math.pi * t / (2 * TAU)) ** 2 * xi(r) * math.exp(-2 * alpha * r) / r ** 2 if r < r0 else 0.0
    t_hi = min(2 * TAU, 2 * (rt - 0.9) / LIGHT_SPEED)  # beyond: r < R₁, ξ = 0
    t_lo = max(0.0, 2 * (rt - r0) / LIGHT_SPEED)
    if t_hi <= t_lo:
        return 0.0
    kinks = [t for t in (2 * (rt - 1.0) / LIGHT_SPEED,) if t_lo < t < t_hi]
    return integrate.quad(f, t_lo, t_hi, points=kinks or None, epsabs=0, epsrel=1e-11, limit=200)[0]


@pytest.mark.parametrize("alpha", [0.005, 0.03, 0.09, 0.2])
def test_soft_target_integral_matches_quadrature(alpha):
    r = np.array([1.5, 3.0, 4.6, 6.0, 8.0, 12.0])
    got = soft_target_integral(r, alpha)
    want = np.array([paper_integral(x, alpha) for x in r])
    assert got == pytest.approx(want, rel=1e-4)
    # a target at 3 m cuts the fog off behind it
    cut = soft_target_integral(r, alpha, r0=3.0)
    assert cut == pytest.approx([paper_integral(x, alpha, 3.0) for x in r], rel=1e-4, abs=1e-16)
    assert (cut[r > 9.0] == 0).all()  # the window [R − L, R] (L = 6 m) lies wholly behind the target


def test_overlap_is_linear_from_0_9_to_1_m():
    assert overlap([0.5, 0.9, 0.95, 1.0, 30.0]).tolist() == pytest.approx([0, 0, 0.5, 1, 1])


@pytest.mark.parametrize("alpha", [0.005, 0.03, 0.06, 0.12, 0.2])
def test_fog_peak_near_4_6_m_and_at_the_quadrature_maximum(alpha):
    value, pos = fog_peak(alpha)
    assert 4.5 < pos < 4.72
    grid = np.arange(pos - 0.2, pos + 0.2, 0.01)
    brute = [paper_integral(x, alpha) for x in grid]
    assert value == pytest.approx(max(brute), rel=1e-4)
    assert abs(pos - grid[int(np.argmax(brute))]) < 0.011
    assert value == pytest.approx(paper_integral(pos, alpha), rel=1e-4)


def test_peak_moves_out_and_grows_as_fog_thins():
    peaks = [fog_peak(a) for a in (0.01, 0.05, 0.1, 0.2)]
    assert [p[1] for p in peaks] == sorted((p[1] for p in peaks), reverse=True)
    assert [p[0] for p in peaks] == sorted((p[0] for p in peaks), reverse=True)


@pytest.mark.parametrize("r0", [0.95, 1.5, 3.0, 4.2])
def test_targets_nearer_than_the_peak_cut_it(r0):
    imax, rf = soft_target_peaks(0.06, np.array([r0]))
    grid = np.arange(r0, r0 + 6.0, 0.005)
    brute = np.array([paper_integral(x, 0.06, r0) for x in grid])
    assert imax[0] == pytest.approx(brute.max(), rel=2e-3)
    assert abs(rf[0] - grid[int(np.argmax(brute))]) < 0.02
    assert imax[0] < fog_peak(0.06)[0]
    assert soft_target_peaks(0.06, np.array([0.5]))[0][0] == 0.0  # inside R₁: no fog seen at all


@pytest.mark.parametrize("alpha,r_thr", [(0.03, 62.0), (0.06, 36.0), (0.10, 24.0), (0.12, 20.0)])
def test_every_return_beyond_r_thr_scatters(alpha, r_thr):
    """The decision i_soft > i_hard does not depend on i (bar rounding): a bright ray of points from
    10 to 100 m scatters from r_thr on — 62 / 36 / 24 / 20 m, as read from the reference's own tables."""
    r = np.arange(10.0, 100.0, 0.05)
    xyz = np.stack([r, np.zeros_like(r), np.zeros_like(r)], 1)
    level = hahner_fog(xyz, np.full(len(r), 255.0), alpha, np.random.default_rng(0))
    first = r[np.argmax(level.outcome == CLUTTER)]
    assert (level.outcome[r >= first] == CLUTTER).all()
    assert first == pytest.approx(r_thr, abs=1.0)
    # the same threshold from the closed form R² e^(2αR) · (β_b/β₀) · I_max = 1, to the rounding of
    # i_hard (255·e^(−2αR) ≈ 6 there: ±½ moves the crossing by up to ≈ 1 m)
    bb, beta0, imax = P.backscatter(alpha), P.target_reflectivity / math.pi, fog_peak(alpha)[0]
    assert first == pytest.approx(_threshold(alpha, bb / beta0 * imax), abs=1.0)


def _threshold(alpha, k):
    lo, hi = 5.0, 500.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if mid * mid * math.exp(2 * alpha * mid) * k > 1 else (mid, hi)
    return lo


def test_point_rule_outcomes_intensities_and_places():
    alpha = 0.06
    xyz = np.array([[10.0, 0, 0], [0, 80.0, 0], [2.0, 0, 0], [0, 0, -50.0], [3.0, 4.0, 0]])
    i = np.array([200.0, 200.0, 1.0, 0.0, 0.0])
    rng = np.random.default_rng(3)
    level = hahner_fog(xyz, i, alpha, rng)
    assert level.outcome.tolist() == [ATTENUATED, CLUTTER, KEPT, KEPT, KEPT]
    assert LOST not in level.outcome
    r0 = np.linalg.norm(xyz, axis=1)
    assert level.intensity[0] == np.round(200 * math.exp(-2 * alpha * 10.0))
    assert level.intensity[2] == 1.0  # round(1·e^(−0.24)) = round(0.79) = 1: unchanged
    # the scattered point: on its ray at R_f + δ, δ the second uniform draw of ±10 m
    delta = np.random.default_rng(3).uniform(-10, 10, 5)
    imax, rf = fog_peak(alpha)
    assert level.ray_distance[1] == pytest.approx(rf + delta[1], abs=1e-6)
    assert level.xyz[1] == pytest.approx([0, rf + delta[1], 0], abs=1e-6)
    i_soft = 200.0 * r0[1] ** 2 * P.backscatter(alpha) / (P.target_reflectivity / math.pi) * imax
    assert level.intensity[1] == np.round(i_soft)
    keep = level.outcome != CLUTTER
    assert (level.xyz[keep] == xyz[keep]).all()


def test_zero_intensity_points_are_always_kept():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(3000, 3))
    xyz = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0.5, 150.0, (3000, 1))
    for alpha in (0.005, 0.06, 0.2):
        level = hahner_fog(xyz, np.zeros(3000), alpha, np.random.default_rng(0))
        assert (level.outcome == KEPT).all()
        assert (level.xyz == xyz).all() and (level.intensity == 0).all()
        bright = hahner_fog(xyz, np.full(3000, 100.0), alpha, np.random.default_rng(0))
        assert (bright.outcome == CLUTTER).any() == (alpha > 0.01)  # lit, they do (r_thr < 150 m)


def _sweep() -> PointCloud:
    xyz, refl = lfx.kitti_street_sweep()
    return PointCloud.from_raw(xyz, refl, "0-1", "sweep")


def test_the_0_1_trap_applies_to_unscaled_input_only():
    scan = _sweep()
    nonzero = 100.0 * float((scan.raw_intensity > 0).mean())
    viewer, raw = fed_intensity(scan, "viewer"), fed_intensity(scan, "raw")
    assert viewer.max() > 1 and (viewer == np.round(viewer)).all() and raw.max() <= 1
    clutter_scaled = []
    for k, beta in enumerate((0.03, 0.06, 0.09, 0.12)):
        trapped = hahner_fog(scan.xyz, raw, beta, np.random.default_rng(k))
        share = 100.0 * float((trapped.outcome == CLUTTER).mean())
        assert share > 0.95 * nonzero  # nearly every non-zero point: i_hard rounds to 0, i_soft > 0
        scaled = hahner_fog(scan.xyz, viewer, beta, np.random.default_rng(k))
        clutter_scaled.append(100.0 * float((scaled.outcome == CLUTTER).mean()))
    assert clutter_scaled == sorted(clutter_scaled) and clutter_scaled[-1] < 15.0
    assert clutter_scaled[0] < 2.0


def test_table_lookup_uses_the_nearest_tabulated_alpha():
    table = HahnerParameters(table_lookup=True)
    assert table.integral_alpha(0.09) == 0.1 and table.integral_alpha(0.12) == 0.12
    assert fog_peak(0.09, table) == fog_peak(0.1)
    assert fog_peak(0.09) != fog_peak(0.1)
    assert set(TABLE_ALPHAS) >= {0.03, 0.06, 0.1, 0.12}


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="α"):
        hahner_fog(np.zeros((1, 3)), [1.0], -0.1, np.random.default_rng(0))
    with pytest.raises(ValueError, match="N×3"):
        hahner_fog(np.zeros((2, 3)), [1.0], 0.1, np.random.default_rng(0))
    with pytest.raises(ValueError, match="feed"):
        fed_intensity(_sweep(), "x255")
