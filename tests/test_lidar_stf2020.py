"""``lidar_fog.model stf2020`` (fogsim.lidar.stf2020) against the STF authors' chamber-fitted rule, computed
here: on KITTI-, nuScenes- and STF-format scans of surfaces at known ranges and intensities (written by hand
in the formats' byte layouts), d_max = ln((I + g)/n)/(2β), d_new = ln 2/β, the one-way attenuation of the
kept points, the loss probability 1 − e^(−β·d_max), cloud scatter to d_new, the random scatter (⌊5 %⌋ of the
eligible candidates, on their rays, uniform below min(d_max, d)), d_min = 2 m — with worked numbers and the
documented draws; the sensors' n and g (and the refusal without them), β = 0 bit for bit, seeding,
accounting, the random β field, and the CLI and record routes."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import lidar_fixtures as lf
from fogsim.cli import main
from fogsim.lidar.fog import ATTENUATED, CLUTTER, EMPTY_RAY_INDEX, KEPT, LOST, LidarFogger
from fogsim.lidar.formats import read_points
from fogsim.lidar.outcome_file import read_outcomes
from fogsim.lidar.stf2020 import RandomBetaField
from fogsim.runs import level_seed

#: (range m, STF intensity 0–255) — 40 rays each
SURFACES = [(1.5, 100.0), (8.0, 0.0), (25.0, 102.0), (40.0, 102.0), (60.0, 255.0), (120.0, 30.0)]
RAYS = 40
S2 = {"name": "stf-s2", "stf_noise_level": 0.05, "stf_gain": 0.35,
      "sources": {"stf_noise_level": "test", "stf_gain": "test"}}


def write_scans(folder):
    """The surfaces as STF (0–255), nuScenes (0–255) and KITTI (÷ 255) scans: {format: cloud}."""
    xyz, inten = [], []
    for k, (r, i) in enumerate(SURFACES):
        xyz.append(lf.ray_directions(RAYS, azimuth_deg=-150.0 + 50.0 * k) * r)
        inten += [i] * RAYS
    xyz, i255 = np.concatenate(xyz).astype(np.float32), np.asarray(inten, np.float32)
    ring = (np.arange(len(xyz)) % 32).astype(np.float32)
    (folder / "s.bin").write_bytes(lf.stf_bin(xyz, i255, ring))
    (folder / "n.pcd.bin").write_bytes(lf.stf_bin(xyz, i255, ring))
    (folder / "k.bin").write_bytes(lf.kitti_bin(xyz, (i255 / 255.0).astype(np.float32)))
    return {"stf": read_points(folder / "s.bin", "stf"), "nuscenes": read_points(folder / "n.pcd.bin", "nuscenes"),
            "kitti": read_points(folder / "k.bin", "kitti")}


@pytest.fixture(scope="module")
def scans(tmp_path_factory):
    return write_scans(tmp_path_factory.mktemp("stf2020"))


#: sensor and spec per format: the S3D's constants, KITTI's HDL-64E as an S2, nuScenes' HDL-32E with a file's
SETUP = {"stf": ("hdl64-s3d", {"model": "stf2020"}, 0.04, 0.45),
         "kitti": ("hdl64e", {"model": "stf2020"}, 0.05, 0.35),
         "nuscenes": ("hdl32e", {"model": "stf2020", "calibration": S2}, 0.05, 0.35)}


def expected(scan, beta, n, g, seed, kept_tolerance=0.5 / 255):
    """(outcome, normalised intensity out, range out, added (source rows, ranges)) by the rule written out."""
    d, i = scan.range_m, np.asarray(scan.intensity, np.float64)
    d_max = np.log((i + g) / n) / (2 * beta)
    d_new = math.log(2) / beta
    rng = np.random.default_rng(seed)
    lost_draw = rng.random(len(d)) < 1 - np.exp(-beta * d_max)
    outcome = np.full(len(d), LOST)
    inten, rout = np.full(len(d), np.nan), d.copy()
    for k in range(len(d)):
        if d[k] <= 2.0:
            continue
        if d[k] < d_max[k]:
            inten[k] = i[k] * math.exp(-beta * d[k])
            outcome[k] = KEPT if i[k] - inten[k] < kept_tolerance else ATTENUATED
        elif not lost_draw[k] and d[k] > d_new:
            outcome[k], inten[k], rout[k] = CLUTTER, i[k] / 2, d_new
    cand = [k for k in range(len(d)) if d[k] > 2.0 and not lost_draw[k] and d[k] <= d_new]
    u = np.array([rng.uniform(0, min(d_max[k], d[k])) for k in cand])
    keep = u > 2.0
    cand, u = np.asarray(cand, np.int64)[keep], u[keep]
    pick = rng.choice(len(cand), int(0.05 * len(cand)), replace=False)
    return outcome, inten, rout, (cand[pick], u[pick])


def test_worked_numbers_on_the_s3d(scans):
    """β 0.05, S3D (n 0.04, g 0.45), I = 102/255 = 0.4: d_max = ln(0.85/0.04)/0.1 = 30.564 m, d_new = 13.86 m,
    p_lost = 1 − √(0.04/0.85) = 0.783; the 25 m point is kept at 0.4·e^(−1.25) = 0.1146 (29.2 of 255)."""
    i, n, g, b = 0.4, 0.04, 0.45, 0.05
    assert math.log((i + g) / n) / (2 * b) == pytest.approx(30.5636, abs=1e-3)
    assert 1 - math.exp(-b * math.log((i + g) / n) / (2 * b)) == pytest.approx(0.78307, abs=1e-4)
    scan = scans["stf"]
    got = LidarFogger(scan, "hdl64-s3d", {"model": "stf2020"})(0.05, np.random.default_rng(0))
    at25 = np.isclose(scan.range_m, 25.0, atol=1e-3)
    assert (got.outcome[at25] == ATTENUATED).all()
    assert got.cloud.raw_intensity[got.output_index[at25]] == pytest.approx(102 * math.exp(-1.25), rel=1e-6)
    at40 = np.isclose(scan.range_m, 40.0, atol=1e-3)
    assert set(np.unique(got.outcome[at40])) <= {LOST, CLUTTER} and (got.outcome[at40] == LOST).any()
    moved = got.output_index[at40 & (got.outcome == CLUTTER)]
    assert np.linalg.norm(got.cloud.xyz[moved], axis=1) == pytest.approx(math.log(2) / 0.05, rel=1e-6)
    assert got.cloud.raw_intensity[moved] == pytest.approx(51.0, rel=1e-6)  # I/2


@pytest.mark.parametrize("fmt", ["stf", "nuscenes", "kitti"])
def test_each_point_follows_the_rule(scans, fmt):
    scan = scans[fmt]
    sensor, spec, n, g = SETUP[fmt]
    fogger = LidarFogger(scan, sensor, spec)
    for k, beta in enumerate((0.03, 0.06, 0.09, 0.12)):
        got = fogger(beta, np.random.default_rng(k))
        outcome, inten, rout, (src, u) = expected(scan, beta, n, g, k)
        np.testing.assert_array_equal(got.outcome, outcome)
        rows = got.output_index[outcome != LOST]
        assert (got.output_index[outcome == LOST] == -1).all()
        moved = (outcome != LOST) & (outcome != KEPT)
        np.testing.assert_allclose(got.cloud.intensity[got.output_index[moved]], inten[moved], rtol=1e-6, atol=1e-7)
        kept = outcome == KEPT
        np.testing.assert_array_equal(got.cloud.raw_intensity[got.output_index[kept]], scan.raw_intensity[kept])
        np.testing.assert_allclose(np.linalg.norm(got.cloud.xyz[rows].astype(np.float64), axis=1),
                                   rout[outcome != LOST], rtol=1e-6)
        # the added points: after the reported ones, on their source rays at u, index −1, their ring
        reported = int((outcome != LOST).sum())
        assert got.added_points == len(src) == len(got.cloud) - reported and got.empty_ray_clutter == 0
        extra = got.cloud.xyz[reported:].astype(np.float64)
        np.testing.assert_allclose(np.linalg.norm(extra, axis=1), u, rtol=1e-6)
        np.testing.assert_allclose(extra / u[:, None], scan.xyz[src] / scan.range_m[src][:, None], atol=1e-6)
        assert (got.cloud.index[reported:] == EMPTY_RAY_INDEX).all() and (got.cloud.index[:reported] >= 0).all()
        assert (u > 2.0).all()
        if scan.ring is not None:
            np.testing.assert_array_equal(got.cloud.ring[reported:], scan.ring[src])
        rec = got.record()
        assert sum(rec["outcomes"].values()) == len(scan) and rec["added_points"] == len(src)
        assert rec["points_out"] == reported + len(src) and rec["stf_noise_level"] == n and rec["stf_gain"] == g
        assert rec["within_d_min"] == RAYS  # the 1.5 m surface


def test_a_point_between_d_max_and_d_new_is_lost_but_may_scatter(scans):
    """A calibration whose n makes (I + g)/n < 4 puts d_new beyond d_max: n 0.2, g 0.35, I 0 → d_max =
    ln(1.75)/(2β) = 5.60 m at β 0.05, d_new 13.86 m: the 8 m surface is lost whatever the draw, and its rays
    spared by the draw are random-scatter candidates (u < 5.60 m)."""
    scan = scans["stf"]
    cal = {"name": "wide", "stf_noise_level": 0.2, "stf_gain": 0.35,
           "sources": {"stf_noise_level": "test", "stf_gain": "test"}}
    at8 = np.isclose(scan.range_m, 8.0, atol=1e-3)
    added = 0
    fogger = LidarFogger(scan, "hdl64-s3d", {"model": "stf2020", "calibration": cal})
    for seed in range(20):
        got = fogger(0.05, np.random.default_rng(seed))
        assert (got.outcome[at8] == LOST).all()
        outcome, _, _, (src, u) = expected(scan, 0.05, 0.2, 0.35, seed)
        np.testing.assert_array_equal(got.outcome, outcome)
        from_8 = at8[src]
        assert (u[from_8] < math.log(1.75) / 0.1).all()
        added += int(from_8.sum())
    assert added > 0


def test_sensors_without_n_and_g_are_refused(scans):
    with pytest.raises(ValueError, match="hdl32e has none"):
        LidarFogger(scans["nuscenes"], "hdl32e", {"model": "stf2020"})
    from fogsim.lidar.sensors import LidarSensor

    assert (LidarSensor.preset("hdl64-s3d").stf_noise_level, LidarSensor.preset("hdl64-s3d").stf_gain) == (0.04, 0.45)
    e = LidarSensor.preset("hdl64e")
    assert (e.stf_noise_level, e.stf_gain) == (0.05, 0.35) and "assumption" in e.sources["stf_gain"]


def test_beta_zero_seeding_and_per_point_beta(scans):
    for fmt, scan in scans.items():
        sensor, spec, n, g = SETUP[fmt]
        fogger = LidarFogger(scan, sensor, spec)
        clear = fogger(0.0, None)
        assert clear.cloud.same_as(scan) and clear.added_points == 0
        a, b, c = (fogger(0.06, np.random.default_rng(s)) for s in (4, 4, 5))
        assert a.cloud.same_as(b.cloud) and np.array_equal(a.outcome, b.outcome)
        assert not np.array_equal(a.outcome, c.outcome)
    scan = scans["stf"]
    betas = np.where(np.arange(len(scan)) % 2 == 0, 0.03, 0.12)
    got = LidarFogger(scan, "hdl64-s3d", {"model": "stf2020"})(betas, np.random.default_rng(1))
    d, i = scan.range_m, scan.intensity.astype(np.float64)
    attenuated = got.outcome == ATTENUATED
    rows = got.output_index[attenuated]
    np.testing.assert_allclose(got.cloud.intensity[rows], (i * np.exp(-betas * d))[attenuated], rtol=1e-6)
    assert got.record()["beta"] == "per point"


def test_the_random_beta_field(scans):
    """Drawn in the documented order and added to β: β + Σ|A sin(tan(y/x) + o) + B sin(tan(y/x) + f·z + p)|
    within [β, β + 0.1]; the loss draws follow it."""
    scan = scans["stf"]
    rng = np.random.default_rng(9)
    k = int(rng.integers(6, 10))
    f = rng.integers(0, 5, k)
    o, p = rng.uniform(0, 2 * np.pi, k), rng.uniform(0, 2 * np.pi, k)
    a, b = rng.uniform(0, 0.05 / k, k), rng.uniform(0, 0.05 / k, k)
    xyz = scan.xyz.astype(np.float64)
    ang = np.tan(xyz[:, 1] / xyz[:, 0])
    want = sum(np.abs(a[j] * np.sin(ang + o[j] + 1) + b[j] * np.sin(ang + f[j] * xyz[:, 2] + p[j] + f[j]))
               for j in range(k))
    field = RandomBetaField.draw(np.random.default_rng(9))
    np.testing.assert_allclose(field(xyz), want, rtol=1e-12)
    assert (want >= 0).all() and (want <= 0.1).all() and want.max() > 0
    fogger = LidarFogger(scan, "hdl64-s3d", {"model": "stf2020", "stf_beta_field": "random"})
    got = fogger(0.05, np.random.default_rng(9))
    assert got.record()["beta_field"]["components"] == k and got.record()["stf_beta_field"] == "random"
    beta = 0.05 + want
    d, i = scan.range_m, scan.intensity.astype(np.float64)
    att = got.outcome == ATTENUATED
    np.testing.assert_allclose(got.cloud.intensity[got.output_index[att]], (i * np.exp(-beta * d))[att], rtol=1e-6)


def test_the_cli_writes_the_model_its_counts_and_refuses_what_it_cannot(scans, tmp_path, capsys):
    def fog(*args):
        return main(["fog", "--quiet", *map(str, args)])

    src = tmp_path / "in" / "n015_LIDAR_TOP__1.pcd.bin"
    src.parent.mkdir()
    src.write_bytes(lf.stf_bin(scans["stf"].xyz, scans["stf"].raw_intensity, (np.arange(len(scans["stf"])) % 32)
                               .astype(np.float32)))
    argv = ("--points", src, "--point-format", "nuscenes", "--levels", "0,0.06")
    assert fog(*argv, "--lidar-model", "stf2020", "--out", tmp_path / "o1") == 2
    assert "hdl32e has none" in capsys.readouterr().err and not (tmp_path / "o1").exists()
    cal = tmp_path / "s2.json"
    cal.write_text(json.dumps(S2))
    out = tmp_path / "o2"
    assert fog(*argv, "--lidar-model", "stf2020", "--lidar-calibration", cal, "--out", out) == 0
    side = json.loads((out / "beta0.06" / "n015_LIDAR_TOP__1.json").read_text())
    assert side["model"] == "stf2020" and side["stf_noise_level"] == 0.05
    cloud = read_points(out / "beta0.06" / "n015_LIDAR_TOP__1.pcd.bin", "nuscenes")
    outcome, index = read_outcomes(out / "beta0.06" / "n015_LIDAR_TOP__1.outcomes.npz")
    assert len(cloud) == int((index >= 0).sum()) + side["added_points"] == side["points_out"]
    scan = read_points(src, "nuscenes")
    want = LidarFogger(scan, "hdl32e", {"model": "stf2020", "calibration": S2})(
        0.06, np.random.default_rng(level_seed(0, "n015_LIDAR_TOP__1", "beta0.06")))
    np.testing.assert_array_equal(outcome, want.outcome)
    assert np.array_equal(cloud.xyz, want.cloud.xyz) and np.array_equal(cloud.raw_intensity, want.cloud.raw_intensity)
    assert side["added_points"] == want.added_points
    out3 = tmp_path / "o3"
    assert fog(*argv, "--lidar-model", "hahner2021", "--hahner-variant", "viewer", "--out", out3) == 0
    side = json.loads((out3 / "beta0.06" / "n015_LIDAR_TOP__1.json").read_text())
    assert side["model"] == "hahner2021" and side["hahner_variant"] == "viewer" and side["outcomes"]["lost"] == 0
    for args, message in [(("--hahner-variant", "viewer"), "--hahner-variant goes with --lidar-model hahner2021"),
                          (("--lidar-model", "hahner2021", "--stf-beta-field", "random"),
                           "--stf-beta-field goes with --lidar-model stf2020")]:
        assert fog(*argv, *args, "--out", tmp_path / "o4") == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "o4").exists()


def test_a_render_preset_with_stf2020_needs_the_sensors_constants(tmp_path):
    """``fog_model.lidar.model: stf2020`` in a render preset: refused on loading, naming the preset, for a LiDAR
    without n and g; taken (and handed to the frames' fogger) for one with them."""
    from fogsim.errors import InputError
    from fogsim.presets import preset_path
    from fogsim.render.fog_settings import fog_settings
    from fogsim.render.preset import load_render_preset

    block = json.loads(preset_path("default").read_text())
    block.setdefault("fog_model", {})["lidar"] = {"model": "stf2020", "stf_beta_field": "random"}
    path = tmp_path / "stf.json"
    path.write_text(json.dumps(block))
    with pytest.raises(InputError, match="hdl32e has none") as err:
        load_render_preset(str(path), lidar="hdl32e")
    assert str(path) in str(err.value)
    cfg = load_render_preset(str(path), lidar="hdl64e")
    spec = fog_settings(cfg).lidar
    assert spec.model == "stf2020" and spec.stf_beta_field == "random"


def test_a_run_recorded_before_the_published_models_resumes(scans, tmp_path, capsys):
    """A ``fogsim_run.json`` whose ``lidar_fog`` block has no ``hahner_variant`` / ``stf_beta_field`` (fogsim
    0.5) resumes with the same flags; another model is still refused."""
    src = tmp_path / "a.bin"
    src.write_bytes(lf.kitti_bin(scans["kitti"].xyz, scans["kitti"].raw_intensity))
    out = tmp_path / "out"
    argv = ["fog", "--quiet", "--points", str(src), "--point-format", "kitti", "--levels", "0,0.06", "--out", str(out)]
    assert main(argv) == 0
    run = json.loads((out / "fogsim_run.json").read_text())
    for key in ("hahner_variant", "stf_beta_field"):
        del run["parameters"]["lidar_fog"][key]
    (out / "fogsim_run.json").write_text(json.dumps(run))
    capsys.readouterr()
    assert main(argv) == 0 and "1 already done" in capsys.readouterr().out
    assert main([*argv, "--lidar-model", "hahner2021"]) == 2
    assert "other parameters" in capsys.readouterr().err
