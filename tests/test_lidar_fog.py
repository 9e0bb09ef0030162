"""The LiDAR fog model against its closed form, computed here independently (the LiDAR equation written
out, the fog echo by adaptive quadrature and a bounded optimiser), on KITTI- and STF-format scans of
surfaces at known ranges and reflectivities built by tests/lidar_fixtures.py."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import lidar_fixtures as lfx
from fogsim.lidar.fog import ATTENUATED, CLUTTER, KEPT, LOST, OUTCOMES, LidarFogger
from fogsim.lidar.formats import read_points, write_points
from fogsim.lidar.points import PointCloud
from fogsim.lidar.rays import laser_origins
from fogsim.lidar.reference import reference_fog
from fogsim.lidar.sensors import LidarSensor
from fogsim.lidar.soft_target import NODE_STEP, echo_per_point, fog_echo, fog_waveform
from fogsim.schema.lidar import LidarFogSpec

scipy_integrate = pytest.importorskip("scipy.integrate")
scipy_optimize = pytest.importorskip("scipy.optimize")

C = 299_792_458.0
PAPER = (0.03, 0.06, 0.09, 0.12)
# the hdl64e preset, written out: R_max 120 m for ρ_ref 0.8, τ_H 10 ns, ξ = min(1, (R/5)²), ρ = 2.55·I,
# fluctuation σ_g 0.5 (ln g ~ N(0, σ_g²) per ray: the clear signal max(q·g, e^(σ_g + |ln g|)), the fog echo q_f·g)
R_MAX, RHO_REF, TAU, R_O, S, R_MIN, SIGMA0, SIGMA1, SIGMA_G = 120.0, 0.8, 10e-9, 5.0, 2.55, 1.0, 0.02, 0.10, 0.5
#: the sensor these closed forms are written for: the hdl64e preset with its radiometry pinned to the values
#: above (they check the model; the bundled calibration's own numbers are checked in test_lidar_fog_rays.py)
HDL64 = replace(LidarSensor.preset("hdl64e"), reference_reflectivity=RHO_REF, overlap_full_m=R_O,
                reflectivity_per_intensity=S)
#: the fluctuation off (σ_g = 0): the deterministic thresholds, for the closed forms of a shape in ρ, R, β
STEADY = {"calibration": {"fluctuation_sigma": 0.0, "sources": {"fluctuation_sigma": "assumed: off"}}}
L = C * TAU
SURFACES = [lfx.Surface(r, rho) for r in (1.5, 3.0, 4.5, 6.0, 9.0, 13.0, 18.0, 25.0, 33.0, 41.0, 52.0, 63.0, 77.0)
            for rho in (0.05, 0.1, 0.3, 0.6, 0.9)]


# ----------------------------------------------------------------------------- the closed form
def xi(r):
    return min(1.0, (r / R_O) ** 2)


def clear_signal(rho, r, su=0.0, sigma=0.0):
    """The clear-air signal over the threshold of a hard return whose fluctuation is ln g_h = ``su``
    (σ_g = ``sigma``): max(q·g_h, e^(σ_g + |ln g_h|)) — the point was detected in clear air, with a margin of
    at least one σ_g (spread like the fluctuation)."""
    return max(max(rho, 0.02) / RHO_REF * (R_MAX / r) ** 2 * xi(r) * math.exp(su), math.exp(sigma + abs(su)))


def draws(n, seed):
    """(ln g_h, ln g_f) of n points — the hard return's and the fog echo's fluctuations — of a level drawn
    from default_rng(seed): the range noise first, then these."""
    rng = np.random.default_rng(seed)  # float32 standard normals, as the model documents
    rng.standard_normal(n, np.float32)
    sigma = np.float32(SIGMA_G)
    return sigma * rng.standard_normal(n, np.float32), sigma * rng.standard_normal(n, np.float32)


_ECHO = {}


def echo(beta):
    """(q_f, r_f) of the fog echo: max over R_t of π β_b ∫ sin²(π(R_t − R)/L) ξ e^(−2βR)/R² dR · R_max²/ρ_ref."""
    if beta not in _ECHO:
        def integral(rt):
            f = lambda r: math.sin(math.pi * (rt - r) / L) ** 2 * xi(r) * math.exp(-2 * beta * r) / r ** 2  # noqa: E731
            lo = max(1e-9, rt - L)
            return scipy_integrate.quad(f, lo, rt, points=[R_O] if lo < R_O < rt else None, epsrel=1e-11)[0]
        res = scipy_optimize.minimize_scalar(lambda rt: -integral(rt), bounds=(0.5, 12.0), method="bounded",
                                             options={"xatol": 1e-7})
        bb = 0.046 * beta / math.log(20)
        _ECHO[beta] = (math.pi * bb * -res.fun * R_MAX ** 2 / RHO_REF, res.x)
    return _ECHO[beta]


def expected(rho, r, beta, mode="strongest", model="soft-target", sh=0.0, sf=0.0, sigma=0.0):
    """The outcome of a point of reflectivity ρ at range r (hard returns: 'hard'), with its q's, for the
    ray's fluctuations ln g_h = ``sh`` (hard return), ln g_f = ``sf`` (fog echo), σ_g = ``sigma``."""
    qh = clear_signal(rho, r, sh, sigma) * math.exp(-2 * beta * r)
    qf, rf = echo(beta) if model == "soft-target" else (0.0, 0.0)
    w = min(max((r - rf) / (L / 2), 0.0), 1.0)  # the fog echo's share resolved from the target
    qc = qf * math.exp(sf) * w if rf >= R_MIN else 0.0
    hard = qh >= 1
    report_hard = hard and (qh >= qc if mode == "strongest" else True)
    if report_hard:
        return "hard", qh, qc
    return ("clutter" if qc >= 1 else "lost"), qh, qc


@pytest.fixture(scope="module")
def scans(tmp_path_factory):
    folder = tmp_path_factory.mktemp("surfaces")
    kitti, stf, rho, rng_m, sid = lfx.write_surfaces(folder, SURFACES)
    return {"kitti": read_points(kitti, "kitti"), "stf": read_points(stf, "stf"), "rho": rho, "range": rng_m,
            "kitti_path": kitti, "stf_path": stf}


def fogged(scan, beta, seed=0, sensor=HDL64, **spec):
    return LidarFogger(scan, sensor, spec or None)(beta, np.random.default_rng(seed))


# ----------------------------------------------------------------------------- the tests
def test_beta_zero_gives_the_input_back_bit_for_bit(scans, tmp_path):
    for fmt, sensor in (("kitti", HDL64), ("stf", "hdl64-s3d")):
        out = LidarFogger(scans[fmt], sensor)(0.0)
        assert out.cloud.same_as(scans[fmt]) and (out.outcome == KEPT).all()
        assert np.array_equal(out.output_index, np.arange(len(scans[fmt])))
        write_points(tmp_path / f"{fmt}.bin", out.cloud, fmt)
        assert (tmp_path / f"{fmt}.bin").read_bytes() == scans[f"{fmt}_path"].read_bytes()
    per_point = LidarFogger(scans["kitti"], HDL64)(np.zeros(len(scans["kitti"])))
    assert per_point.cloud.same_as(scans["kitti"])


def test_the_soft_target_integral_matches_quadrature():
    s = HDL64
    for beta in (0.0, 0.01, 0.06, 0.2):
        rt, j = fog_waveform(s, beta)
        for target in (1.0, 2.7, 4.0, 8.0, 15.0):
            k = int(round(target / (rt[1] - rt[0])))
            f = lambda r: math.sin(math.pi * (rt[k] - r) / L) ** 2 * xi(r) * math.exp(-2 * beta * r) / r ** 2  # noqa: E731
            lo = max(1e-12, rt[k] - L)
            ref = scipy_integrate.quad(f, lo, rt[k], points=[R_O] if lo < R_O < rt[k] else None, epsrel=1e-12)[0]
            assert j[k] == pytest.approx(ref, rel=2e-5), (beta, target)
        d = np.diff(j)
        peak = int(np.argmax(j))
        assert (d[:peak] >= -1e-15).all() and (d[peak:] <= 1e-15).all()  # one peak: unimodal
    for beta in PAPER:
        e = fog_echo(s, beta)
        qf, rf = echo(beta)
        assert e.signal == pytest.approx(qf, rel=1e-5) and e.range_m == pytest.approx(rf, abs=2e-3)


@pytest.mark.parametrize("mode", ["strongest", "last"])
@pytest.mark.parametrize("beta", PAPER)
def test_every_outcome_is_the_closed_form(scans, beta, mode):
    out = fogged(scans["kitti"], beta, return_mode=mode)
    cloud = scans["kitti"]
    sh, sf = draws(len(cloud), 0)
    for i, (rho, r) in enumerate(zip(scans["rho"], scans["range"])):
        want, qh, qc = expected(rho, r, beta, mode, sh=sh[i], sf=sf[i], sigma=SIGMA_G)
        assert abs(math.log(qh)) > 1e-6 and (qc == 0 or abs(math.log(qh / qc)) > 1e-6)  # no point on a boundary
        got = OUTCOMES[out.outcome[i]]
        if want == "hard":
            loss = cloud.intensity[i] * (1 - math.exp(-2 * beta * r))
            assert got == ("kept" if loss < 0.5 / 255 else "attenuated"), (i, rho, r)
        else:
            assert got == want, (i, rho, r, qh, qc)
    seen = set(np.unique(out.outcome).tolist())
    assert {ATTENUATED, CLUTTER} <= seen
    steady = fogged(scans["kitti"], beta, return_mode=mode, **STEADY)  # σ_g = 0: the thresholds alone
    for i, (rho, r) in enumerate(zip(scans["rho"], scans["range"])):
        want = expected(rho, r, beta, mode)[0]
        got = OUTCOMES[steady.outcome[i]]
        assert (got in ("kept", "attenuated")) if want == "hard" else got == want, (i, rho, r)
    assert (out.output_index[out.outcome == LOST] == -1).all()
    kept = out.output_index >= 0
    assert np.array_equal(out.cloud.index, np.flatnonzero(kept))  # input order, traceable
    assert len(out.cloud) == int(kept.sum())


def test_the_attenuation_model_has_no_clutter_and_loses_below_the_threshold(scans):
    sh, _ = draws(len(scans["kitti"]), 0)
    for beta in PAPER:
        out = fogged(scans["kitti"], beta, model="attenuation")
        assert not (out.outcome == CLUTTER).any()
        for i, (rho, r) in enumerate(zip(scans["rho"], scans["range"])):
            lost = clear_signal(rho, r, sh[i], SIGMA_G) * math.exp(-2 * beta * r) < 1
            assert (out.outcome[i] == LOST) == lost


def test_the_share_of_points_kept_per_range_bin_falls_with_beta_and_range(scans):
    bins = [(0, 10), (10, 20), (20, 35), (35, 55), (55, 80)]
    r = scans["range"]
    table = []
    for beta in (0.0,) + PAPER:
        out = fogged(scans["kitti"], beta, return_mode="last", **STEADY)
        hard = np.isin(out.outcome, (KEPT, ATTENUATED))
        row = []
        for lo, hi in bins:
            inside = (r >= lo) & (r < hi)
            share = hard[inside].mean()
            closed = np.mean([expected(rho, rr, beta, "last")[0] == "hard" if beta else True
                              for rho, rr in zip(scans["rho"][inside], r[inside])])
            assert share == pytest.approx(closed), (beta, lo)
            row.append(share)
        table.append(row)
    t = np.array(table)
    assert (np.diff(t, axis=0) <= 0).all() and (np.diff(t, axis=1) <= 0).all()  # falls with β and with range
    assert t[0].tolist() == [1.0] * len(bins) and t[-1, 0] == 1.0  # clear air keeps all; near points survive
    assert (t[1:, 1:].sum(axis=1) > 0).all() and (np.diff(t[1:, 1:].sum(axis=1)) < 0).all()  # strictly less per β
    assert (np.diff(t[1, :4]) < 0).all()  # and strictly less per range bin at β = 0.03 (to 55 m; beyond: none)


def _last_hard_range(scan, rho_of, reflectivity, beta):
    out = fogged(scan, beta, model="attenuation", **STEADY)
    pick = (rho_of == reflectivity) & np.isin(out.outcome, (KEPT, ATTENUATED))
    return scan.range_m[pick].max()


def test_a_dark_target_loses_its_points_before_a_bright_one():
    ranges = np.arange(5.0, 90.0, 0.25)
    surfaces = [lfx.Surface(float(r), rho, 1) for r in ranges for rho in (0.1, 0.9)]
    xyz, rho, _, _ = lfx.surfaces_scan(surfaces)
    scan = PointCloud.from_raw(xyz, (rho / 2.55).astype(np.float32), "0-1", "dark and bright")
    for beta in PAPER:
        dark = _last_hard_range(scan, rho, 0.1, beta)
        bright = _last_hard_range(scan, rho, 0.9, beta)
        assert dark < bright
        for reflectivity, got in ((0.1, dark), (0.9, bright)):  # the closed form: q0·e^(−2βR) = 1
            root = scipy_optimize.brentq(lambda rr: math.log(clear_signal(reflectivity, rr)) - 2 * beta * rr,
                                         R_O, 500.0)
            assert root - 0.25 < got <= root
    # in the default (strongest) mode a dark car is gone while a bright sign at its range is seen
    for r, beta in ((40.0, 0.02), (20.0, 0.06)):
        both = PointCloud.from_raw(np.array([[r, 0, 0], [0, r, 0]], np.float32),
                                   np.float32([0.05 / 2.55, 0.9 / 2.55]), "0-1", "car and sign")
        out = LidarFogger(both, HDL64, STEADY)(beta, np.random.default_rng(0))
        assert out.outcome[0] in (LOST, CLUTTER) and out.outcome[1] == ATTENUATED


def test_fog_clutter_lies_within_a_few_metres_on_the_same_ray(scans):
    for beta in PAPER:
        out = fogged(scans["kitti"], beta)
        c = out.outcome == CLUTTER
        assert c.any()
        pts = out.cloud.xyz[out.output_index[c]].astype(np.float64)
        rr = np.linalg.norm(pts, axis=1)
        qf, rf = echo(beta)
        assert (rr >= R_MIN).all() and (rr < rf + 1.0).all() and (rr < 5.0).all()
        src = scans["kitti"].xyz[c].astype(np.float64)
        o = laser_origins(scans["kitti"], LidarSensor.preset("hdl64e"))[c]  # KITTI's lasers sit 0.1–0.2 m off axis
        assert (np.linalg.norm(o, axis=1) > 0.1).all()
        a, b = pts - o, src - o
        cos = np.einsum("ij,ij->i", a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
        assert (cos > 1 - 1e-6).all()  # the same ray: the laser's line through the point
        assert (out.cloud.intensity[out.output_index[c]] < 0.01).all()  # a faint echo


def test_0_1_and_0_255_storage_give_the_same_outcomes(scans):
    on_axis = replace(HDL64, vertical_offsets_m=None)  # as the S3D: lasers on its axis
    for beta in PAPER + (0.0125,):
        for mode in ("strongest", "last"):
            a = LidarFogger(scans["kitti"], on_axis, {"return_mode": mode})(beta, np.random.default_rng(1))
            b = LidarFogger(scans["stf"], "hdl64-s3d", {"return_mode": mode})(beta, np.random.default_rng(1))
            assert np.array_equal(a.outcome, b.outcome) and np.array_equal(a.output_index, b.output_index)
            np.testing.assert_allclose(a.cloud.xyz, b.cloud.xyz, rtol=1e-6, atol=1e-6)
            np.testing.assert_allclose(a.cloud.intensity, b.cloud.intensity, rtol=1e-5, atol=1e-7)
            np.testing.assert_allclose(b.cloud.raw_intensity, 255 * a.cloud.intensity, rtol=1e-5, atol=1e-5)


def test_beta_0_09_lies_between_0_06_and_0_12_with_no_plateau():
    ranges = np.arange(5.0, 60.0, 0.01)
    scan = PointCloud.from_raw(np.stack([ranges, 0 * ranges, 0 * ranges], 1).astype(np.float32),
                               np.full(len(ranges), 0.3 / 2.55, np.float32), "0-1", "a long wall")
    fogger = LidarFogger(scan, HDL64, {"model": "attenuation", **STEADY})
    grid = np.round(np.arange(0.06, 0.1201, 0.001), 6)
    lost_from = [ranges[fogger(b, np.random.default_rng(0)).outcome != LOST].max() for b in grid]
    assert (np.diff(lost_from) < 0).all()  # strictly falling: every 0.001 1/m moves the loss range
    s = HDL64
    echoes = [fog_echo(s, b) for b in grid]
    assert (np.diff([e.signal for e in echoes]) > 0).all() and (np.diff([e.range_m for e in echoes]) < 0).all()
    i06, i09, i12 = (int(np.flatnonzero(np.isclose(grid, b))[0]) for b in (0.06, 0.09, 0.12))
    assert lost_from[i06] > lost_from[i09] > lost_from[i12]
    assert echoes[i06].signal < echoes[i09].signal < echoes[i12].signal


@pytest.mark.parametrize("sensor,spec", [
    ("hdl64e", {}), ("hdl64e", {"return_mode": "last"}), ("hdl64e", {"model": "attenuation"}),
    ("hdl64-s3d", {"extinction_ratio": 1.3, "backscatter_rule": "lidar-ratio", "lidar_ratio_sr": 30.0}),
    ("hdl32e", {"reflectivity_floor": 0.1}),
])
def test_vectorised_equals_the_per_point_loop(scans, sensor, spec):
    scan = scans["stf" if "s3d" in sensor or "32" in sensor else "kitti"]
    fs = LidarFogSpec.model_validate(spec)
    for beta in PAPER:
        out = LidarFogger(scan, sensor, fs)(beta, np.random.default_rng(5))
        oc, xyz, norm, raw = reference_fog(scan, sensor, beta, np.random.default_rng(5), fs)
        assert np.array_equal(out.outcome, oc)
        rep = oc != LOST
        np.testing.assert_allclose(out.cloud.xyz, xyz[rep], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(out.cloud.intensity, norm[rep], rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(out.cloud.raw_intensity, raw[rep], rtol=1e-6, atol=1e-6)


def test_vectorised_equals_the_loop_on_a_waymo_like_tanh_scan():
    rng = np.random.default_rng(3)
    n = 600
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    xyz = (d * rng.uniform(2, 70, n)[:, None]).astype(np.float32)
    scan = PointCloud.from_raw(xyz, rng.exponential(0.3, n), "tanh", "waymo-like", return_index=np.ones(n))
    sensor = LidarSensor.preset("waymo-top").with_inclinations(np.linspace(-0.3, 0.04, 64))
    for beta in PAPER:
        out = LidarFogger(scan, sensor)(beta, np.random.default_rng(2))
        oc, xyz_r, norm, raw = reference_fog(scan, sensor, beta, np.random.default_rng(2))
        assert np.array_equal(out.outcome, oc) and set(np.unique(oc)) >= {ATTENUATED}
        np.testing.assert_allclose(out.cloud.raw_intensity, raw[oc != LOST], rtol=1e-6, atol=1e-9)
        assert (out.cloud.return_index == 1).all()


def test_seeded_and_deterministic(scans):
    a, b = fogged(scans["kitti"], 0.06, seed=11), fogged(scans["kitti"], 0.06, seed=11)
    assert a.cloud.same_as(b.cloud) and np.array_equal(a.outcome, b.outcome)
    c = fogged(scans["kitti"], 0.06, seed=12)
    assert not np.array_equal(a.outcome, c.outcome)  # another seed: other fluctuations, other outcomes
    a, c = fogged(scans["kitti"], 0.06, seed=11, **STEADY), fogged(scans["kitti"], 0.06, seed=12, **STEADY)
    assert np.array_equal(a.outcome, c.outcome) and not a.cloud.same_as(c.cloud)  # σ_g = 0: only the noise differs
    with pytest.raises(ValueError, match="Generator"):
        LidarFogger(scans["kitti"], HDL64)(0.06)


def test_attenuated_points_keep_their_ray_and_fall_by_exp_minus_2_beta_r(scans):
    beta = 0.03
    out = fogged(scans["stf"], beta, sensor="hdl64-s3d")
    att = np.flatnonzero(out.outcome == ATTENUATED)
    src = scans["stf"]
    rows = out.output_index[att]
    want = src.raw_intensity[att] * np.exp(-2 * beta * src.range_m[att])
    np.testing.assert_allclose(out.cloud.raw_intensity[rows], want, rtol=1e-5)
    cos = np.einsum("ij,ij->i", out.cloud.xyz[rows].astype(np.float64), src.xyz[att].astype(np.float64))
    cos /= np.linalg.norm(out.cloud.xyz[rows], axis=1) * src.range_m[att]
    assert (cos > 1 - 1e-6).all()


def test_range_noise_grows_as_the_signal_falls():
    """Many points on two surfaces: the spread of R' − R is σ₁·√(1/q_h² − 1/q0²), larger on the fainter one."""
    n, beta = 4000, 0.06
    dirs = lfx.ray_directions(n, 0.0, spread_deg=10.0)
    spreads = []
    for r, rho in ((12.0, 0.9), (18.0, 0.3)):
        scan = PointCloud.from_raw((dirs * r).astype(np.float32), np.full(n, rho / 2.55, np.float32), "0-1", "noise")
        out = LidarFogger(scan, HDL64, {"return_mode": "last", **STEADY})(beta, np.random.default_rng(4))
        assert (out.outcome == ATTENUATED).all()
        dr = np.linalg.norm(out.cloud.xyz.astype(np.float64), axis=1) - scan.range_m
        q0 = clear_signal(rho, r)
        qh = q0 * math.exp(-2 * beta * r)
        sigma = SIGMA1 * math.sqrt(1 / qh ** 2 - 1 / q0 ** 2)
        assert np.std(dr) == pytest.approx(sigma, rel=0.06) and abs(np.mean(dr)) < 4 * sigma / math.sqrt(n)
        spreads.append(np.std(dr))
    assert spreads[1] > spreads[0]


def test_heterogeneous_beta(scans):
    scan = scans["kitti"]
    n = len(scan)
    values = np.array([0.0, 0.03, 0.07, 0.11])
    beta = values[np.arange(n) % 4]
    out = LidarFogger(scan, HDL64)(beta, np.random.default_rng(9))
    for b in values:  # exact: each point as if the whole scan were in its fog (same noise draws)
        alone = LidarFogger(scan, HDL64)(b, np.random.default_rng(9))
        pick = beta == b
        assert np.array_equal(out.outcome[pick], alone.outcome[pick])
    # many distinct values: interpolated between nodes ≤ NODE_STEP apart, within the stated bound
    s = HDL64
    many = np.random.default_rng(0).uniform(0.01, 0.15, 500)
    q, r, w = echo_per_point(s, many)
    exact = [fog_echo(s, b) for b in many]
    assert np.max(np.abs(q / [e.signal for e in exact] - 1)) < 1e-4
    assert np.max(np.abs(r - [e.range_m for e in exact])) < 1e-3
    assert NODE_STEP <= 2e-3
    field = np.random.default_rng(1).uniform(0.05, 0.07, n)
    per_point = LidarFogger(scan, HDL64)(field, np.random.default_rng(2))
    assert per_point.record()["beta"] == "per point" and per_point.counts()["lost"] + per_point.counts()["clutter"] > 0


def test_record_and_bad_beta(scans):
    out = fogged(scans["kitti"], 0.06)
    rec = out.record()
    assert rec["beta"] == 0.06 and rec["visibility_m"] == pytest.approx(math.log(20) / 0.06)
    assert rec["points_in"] == len(scans["kitti"]) == sum(rec["outcomes"].values())
    assert rec["points_out"] == len(out.cloud) and rec["sensor"] == "hdl64e" and rec["model"] == "soft-target"
    assert rec["fog_echo"]["range_m"] == pytest.approx(echo(0.06)[1], abs=2e-3)
    f = LidarFogger(scans["kitti"], HDL64)
    for bad in (-0.01, float("nan"), np.zeros(3)):
        with pytest.raises(ValueError, match="β"):
            f(bad, np.random.default_rng(0))
    with pytest.raises(ValueError, match="lidar_fog.model"):
        LidarFogger(scans["kitti"], HDL64, {"model": "hahner"})


def test_the_benchmark_runs(capsys):
    from fogsim.cli import main

    assert main(["bench", "lidar-fog", "--repeat", "1", "--loop-points", "100"]) == 0
    out = capsys.readouterr().out
    assert "per-point loop" in out and out.strip().splitlines()[-1].startswith("bench lidar-fog: 4 levels of 120000")
    assert "hahner2021, 4 levels" in out and "stf2020, 4 levels" in out and "× the default" in out


def test_the_outcome_file_beside_a_fogged_scan(scans, tmp_path):
    from fogsim.errors import InputError
    from fogsim.lidar.outcome_file import read_outcomes, write_outcomes

    out = fogged(scans["kitti"], 0.12, model="attenuation")
    path = tmp_path / "000000.outcomes.npz"
    write_outcomes(path, out)
    outcome, index = read_outcomes(path)
    assert np.array_equal(outcome, out.outcome) and np.array_equal(index, out.output_index)
    assert (outcome == LOST).any()
    bad = tmp_path / "bad.npz"
    np.savez(bad, outcome=out.outcome, output_index=np.where(out.output_index < 0, 0, out.output_index))
    with pytest.raises(InputError, match="output rows must be −1"):
        read_outcomes(bad)
    (tmp_path / "cut.npz").write_bytes(path.read_bytes()[:40])
    with pytest.raises(InputError, match="cut.npz"):
        read_outcomes(tmp_path / "cut.npz")
