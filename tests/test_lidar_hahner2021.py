"""``lidar_fog.model hahner2021`` (fogsim.lidar.hahner2021) against the released code's rule, computed here
point by point: on KITTI-, nuScenes- and STF-format scans of surfaces at known ranges and intensities (written
by hand in the formats' byte layouts), each point's outcome, intensity and place at β 0.03 … 0.12 — the
integer hard return round(i·e^(−2αR₀)), the fog response min(i·R₀²·(β_b/β₀)·I_max, 255) with β_b frozen at
α 0.06 (batch) or at α (viewer), I_max the soft-target peak (far: the peak; near: I(R₀), by quadrature),
scattering when it wins, to R_f·R₀/U(R₀ ± 10 m) with the documented draws; β = 0 bit for bit, seeding,
accounting, and the CLI, record and render routes."""
from __future__ import annotations

import math
import types

import numpy as np
import pytest

import lidar_fixtures as lf
from fogsim.lidar.fog import ATTENUATED, CLUTTER, KEPT, LidarFogger
from fogsim.lidar.formats import read_points
from fogsim.lidar.hahner import fog_peak

pytest.importorskip("scipy.integrate")
from test_lidar_hahner import paper_integral  # noqa: E402  (the paper's integral by adaptive quadrature)

LN20 = math.log(20.0)
BETA0 = 1e-6 / math.pi
#: (range m, reflectivity): fed intensity 100·ρ (KITTI ρ/2.55 × 255; 0–255 scans store 100·ρ)
SURFACES = [(3.0, 0.01), (10.0, 0.5), (20.0, 0.05), (40.0, 0.3), (58.0, 0.9), (60.0, 0.0), (600.0, 2.55)]
BETAS = (0.03, 0.06, 0.09, 0.12)


def write_scans(folder):
    """The surfaces as KITTI, STF and nuScenes scans (each read back by fogsim's reader): {format: cloud}."""
    xyz, rho, rng_m, sid = lf.surfaces_scan([lf.Surface(r, p, 8) for r, p in SURFACES])
    i01 = (rho / lf.REFLECTIVITY_PER_INTENSITY).astype(np.float32)
    i255 = (255.0 * rho / lf.REFLECTIVITY_PER_INTENSITY).astype(np.float32)
    (folder / "k.bin").write_bytes(lf.kitti_bin(xyz, i01))
    (folder / "s.bin").write_bytes(lf.stf_bin(xyz, i255, (np.arange(len(xyz)) % 64).astype(np.float32)))
    (folder / "n.pcd.bin").write_bytes(lf.stf_bin(xyz, i255, (np.arange(len(xyz)) % 32).astype(np.float32)))
    return {"kitti": read_points(folder / "k.bin", "kitti"), "stf": read_points(folder / "s.bin", "stf"),
            "nuscenes": read_points(folder / "n.pcd.bin", "nuscenes")}


@pytest.fixture(scope="module")
def scans(tmp_path_factory):
    return write_scans(tmp_path_factory.mktemp("hahner2021"))


SENSOR = {"kitti": "hdl64e", "stf": "hdl64-s3d", "nuscenes": "hdl32e"}


def expected(scan, alpha, seed, variant="batch"):
    """(outcome, fed intensity out, signed range out) per point, by the rule written out here."""
    raw = np.asarray(scan.raw_intensity, np.float64)
    fed = np.round(raw * 255.0) if scan.scale == "0-1" else raw  # KITTI × 255 rounded; 0–255 as stored
    r0 = scan.range_m
    bb = 0.046 * (0.06 if variant == "batch" else alpha) / LN20
    peak, rf_far = fog_peak(alpha)
    imax = np.array([peak if r >= rf_far else paper_integral(r, alpha) for r in r0])
    rf = np.where(r0 >= rf_far, rf_far, r0)
    i_hard = np.round(fed * np.exp(-2 * alpha * r0))
    i_soft = np.minimum(fed * r0 ** 2 * bb / BETA0 * imax, 255.0)
    scat = i_soft > i_hard
    rng = np.random.default_rng(seed)
    rng.integers(1, 20)
    u = np.array([rng.uniform(r - 10, r + 10) for r in r0[scat]])
    dist = r0.copy()
    dist[scat] = rf[scat] * r0[scat] / u
    outcome = np.where(scat, CLUTTER, np.where(i_hard == fed, KEPT, ATTENUATED))
    return outcome, np.where(scat, i_soft, i_hard), dist, fed


@pytest.mark.parametrize("fmt", ["kitti", "stf", "nuscenes"])
@pytest.mark.parametrize("variant", ["batch", "viewer"])
def test_each_point_follows_the_released_rule(scans, fmt, variant):
    scan = scans[fmt]
    fogger = LidarFogger(scan, SENSOR[fmt], {"model": "hahner2021", "hahner_variant": variant})
    for k, beta in enumerate(BETAS):
        got = fogger(beta, np.random.default_rng(k))
        outcome, fed_out, dist, fed = expected(scan, beta, k, variant)
        np.testing.assert_array_equal(got.outcome, outcome)
        np.testing.assert_array_equal(got.output_index, np.arange(len(scan)))  # none lost, none added
        assert len(got.cloud) == len(scan) and got.added_points == 0 and got.counts()["lost"] == 0
        raw = fed_out / 255.0 if fmt == "kitti" else fed_out
        moved = outcome != KEPT
        np.testing.assert_allclose(got.cloud.raw_intensity[moved], raw[moved], rtol=1e-5)
        np.testing.assert_array_equal(got.cloud.raw_intensity[~moved], scan.raw_intensity[~moved])
        np.testing.assert_array_equal(got.cloud.xyz[~moved | (outcome == ATTENUATED)],
                                      scan.xyz[~moved | (outcome == ATTENUATED)])  # the hard returns stay put
        along = np.einsum("ij,ij->i", got.cloud.xyz.astype(np.float64), scan.xyz.astype(np.float64)) / scan.range_m
        np.testing.assert_allclose(along, dist, rtol=2e-5)  # signed distance along each point's own ray


def test_the_numbers_that_tell_the_variants_and_the_integer_trap_apart(scans):
    """At α 0.03 the bright point at 58 m (fed 90) is scattered by the batch path (frozen β_b: fog response
    3.9 > its hard return 2) but not by the viewer (β_b halved: 1.97 < 2); the darkest near point (fed 1 at
    3 m) is scattered at 0.12 (its hard return rounds to 0) and kept at 0.03 (rounds to 1); fed 0 is never
    scattered; the far point's response is capped at 255."""
    scan = scans["stf"]
    r0 = scan.range_m
    batch = LidarFogger(scan, "hdl64-s3d", {"model": "hahner2021"})
    viewer = LidarFogger(scan, "hdl64-s3d", {"model": "hahner2021", "hahner_variant": "viewer"})
    at58 = np.isclose(r0, 58.0, atol=1e-3)
    assert (batch(0.03, np.random.default_rng(0)).outcome[at58] == CLUTTER).all()
    assert (viewer(0.03, np.random.default_rng(0)).outcome[at58] == ATTENUATED).all()
    near = np.isclose(r0, 3.0, atol=1e-3)
    assert (batch(0.12, np.random.default_rng(0)).outcome[near] == CLUTTER).all()
    assert (batch(0.03, np.random.default_rng(0)).outcome[near] == KEPT).all()
    zero = scan.raw_intensity == 0
    far = np.isclose(r0, 600.0, atol=1e-2)
    for beta in BETAS:
        got = batch(beta, np.random.default_rng(1))
        assert (got.outcome[zero] == KEPT).all()
        assert (got.cloud.raw_intensity[far] == 255.0).all() and (got.outcome[far] == CLUTTER).all()
    rec = batch(0.03, np.random.default_rng(0)).record()
    assert rec["model"] == "hahner2021" and rec["hahner_variant"] == "batch"
    assert rec["backscatter_per_m_sr"] == pytest.approx(0.046 * 0.06 / LN20)
    assert viewer(0.03, np.random.default_rng(0)).record()["backscatter_per_m_sr"] == pytest.approx(0.046 * 0.03 / LN20)


def test_the_three_formats_give_the_same_outcomes(scans):
    got = {f: LidarFogger(s, SENSOR[f], {"model": "hahner2021"})(0.09, np.random.default_rng(3))
           for f, s in scans.items()}
    assert np.array_equal(got["kitti"].outcome, got["stf"].outcome)
    assert np.array_equal(got["stf"].outcome, got["nuscenes"].outcome)
    assert set(np.unique(got["kitti"].outcome)) == {KEPT, ATTENUATED, CLUTTER}


def test_beta_zero_is_the_input_bit_for_bit_and_seeding(scans):
    for fmt, scan in scans.items():
        fogger = LidarFogger(scan, SENSOR[fmt], {"model": "hahner2021"})
        clear = fogger(0.0, None)
        assert clear.cloud.same_as(scan) and clear.counts()["kept"] == len(scan)
        a, b = fogger(0.12, np.random.default_rng(5)), fogger(0.12, np.random.default_rng(5))
        assert a.cloud.same_as(b.cloud)
        c = fogger(0.12, np.random.default_rng(6))
        assert np.array_equal(a.outcome, c.outcome) and not np.array_equal(a.cloud.xyz, c.cloud.xyz)
    with pytest.raises(ValueError, match="one β"):
        fogger(np.linspace(0.04, 0.06, len(scan)), np.random.default_rng(0))
    with pytest.raises(ValueError, match="Generator"):
        fogger(0.05, None)


def test_the_extinction_ratio_scales_alpha(scans):
    scan = scans["kitti"]
    a = LidarFogger(scan, "hdl64e", {"model": "hahner2021", "extinction_ratio": 2.0})(0.03, np.random.default_rng(2))
    b = LidarFogger(scan, "hdl64e", {"model": "hahner2021"})(0.06, np.random.default_rng(2))
    assert a.cloud.same_as(b.cloud) and a.record()["alpha"] == pytest.approx(0.06)


def test_the_render_route_takes_the_presets_model(scans):
    from fogsim.render.fog_settings import fog_settings

    config = types.SimpleNamespace(fog_model={"lidar": {"model": "hahner2021", "hahner_variant": "viewer"}},
                                   source="preset.json")
    fogger = fog_settings(config).lidar_fogger(scans["kitti"], "hdl64e")
    got = fogger(0.06, np.random.default_rng(0))
    want = LidarFogger(scans["kitti"], "hdl64e", {"model": "hahner2021", "hahner_variant": "viewer"})(
        0.06, np.random.default_rng(0))
    assert got.cloud.same_as(want.cloud) and got.record()["hahner_variant"] == "viewer"
    bad = types.SimpleNamespace(fog_model={"lidar": {"model": "hahner2022"}}, source="preset.json")
    with pytest.raises(Exception, match="hahner2021"):
        fog_settings(bad)


def test_the_dataset_cli_refuses_what_a_published_model_cannot(tmp_path, capsys):
    """Before anything is read: hahner2021 with patchy fog, stf2020 on Waymo's top LiDAR (no n, g)."""
    from fogsim.cli import main

    root = tmp_path / "data"
    root.mkdir()
    cases = [(("--kitti", root, "--lidar", "--lidar-model", "hahner2021", "--heterogeneity", "0.3"), "at one β"),
             (("--waymo", root, "--lidar", "--lidar-model", "stf2020"), "waymo-top has none")]
    for args, message in cases:
        assert main(["fog", "--quiet", *map(str, args), "--out", str(tmp_path / "o")]) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
