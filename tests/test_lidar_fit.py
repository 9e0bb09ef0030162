"""``fogsim lidar-fit`` / ``lidar-compare`` (:mod:`fogsim.lidar.fit`, :mod:`fogsim.lidar.scan_stats`,
:mod:`fogsim.lidar.fit_report`): the distance against hand-computed cases; known fog parameters fitted back
from scans the project's own fogger made (the clear fixture sweeps fogged with a known calibration and other
random draws, written by hand in the KITTI layout); a fit never worsens its distance; the calibration it writes
is read by ``--lidar-calibration``; the report's pictures show the real and simulated histograms.

Fixture: two KITTI-format sweeps (:func:`lidar_fixtures.kitti_sweep`, 64 beams × 400 azimuths) and the
``hdl64e`` preset with a 400-step sweep (so the sweeps are full sweeps of its grid)."""
from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

import lidar_fixtures as lf
from fogsim.cli import main
from fogsim.lidar.fit import (
    MODEL_PARAMETERS,
    PARAMETER_SPACE,
    FitProblem,
    beta_of_visibility,
    fit,
)
from fogsim.lidar.fit_report import SERIES_COLOURS
from fogsim.lidar.fog import LidarFogger
from fogsim.lidar.formats import read_points
from fogsim.lidar.points import PointCloud
from fogsim.lidar.rays import empty_rays
from fogsim.lidar.scan_stats import NEAR_M, NEAR_STEP_M, RANGE_EDGES_M, ScanStatistics, distance, statistics
from fogsim.lidar.sensors import load_sensor
from fogsim.presets import presets_dir
from fogsim.schema.lidar import CALIBRATION_KEYS, LIDAR_FOG_MODELS

pytest.importorskip("scipy")

STEPS = 400
BETA = 0.03
#: the fog the "real" scans were made with, and how close a fit must come back (relative)
TRUTH = {"fog_echo_scale": 0.2, "max_range_m": 200.0}
TOLERANCE = {"fog_echo_scale": 0.15, "max_range_m": 0.10}


def sensor_dict() -> dict:
    d = json.loads((presets_dir() / "lidar" / "hdl64e.json").read_text())
    d.pop("horizontal_resolution_deg")
    # the 0.5.0 radiometry (0.8 at 120 m, 5 m overlap, ρ = 2.55 I): a sensor whose threshold margin the fog
    # uses up at β 0.03, so a fitted max_range_m is identifiable (0.6.0's hdl64e loses almost nothing there)
    return {**d, "steps_per_sweep": STEPS, "name": "hdl64e-400", "reference_reflectivity": 0.8, "overlap_full_m": 5.0,
            "reflectivity_per_intensity": 2.55}


def foggy(scan: PointCloud, calibration: dict, seed: int, beta: float = BETA) -> PointCloud:
    """``scan`` fogged as ``fogsim fog --points`` fogs it (its empty rays included) under ``calibration``."""
    sensor = load_sensor(sensor_dict())
    block = {"name": "truth", **calibration, "sources": dict.fromkeys(calibration, "test")}
    fogger = LidarFogger(scan, sensor, {"calibration": block}, empty_rays(scan, sensor))
    return fogger(beta, np.random.default_rng(seed)).cloud


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """in/clear/00000{0,1}.bin, in/foggy/00000{0,1}.bin (the same sweeps fogged with TRUTH, other draws),
    in/sensor.json; returns (root, clear clouds, foggy clouds)."""
    root = tmp_path_factory.mktemp("fit")
    for d in ("clear", "foggy", "work"):
        (root / "in" / d).mkdir(parents=True)
    (root / "in" / "sensor.json").write_text(json.dumps(sensor_dict()))
    clear, fogged = [], []
    for seed in (0, 1):
        work = root / "in" / "work" / str(seed)
        work.mkdir()
        scan = read_points(lf.kitti_sweep(work, steps=STEPS, seed=seed), "kitti")
        (root / "in" / "clear" / f"{seed:06d}.bin").write_bytes((work / "sweep.bin").read_bytes())
        cloud = foggy(scan, TRUTH, 100 + seed)
        (root / "in" / "foggy" / f"{seed:06d}.bin").write_bytes(lf.kitti_bin(cloud.xyz, cloud.raw_intensity))
        clear.append(scan)
        fogged.append(read_points(root / "in" / "foggy" / f"{seed:06d}.bin", "kitti"))
    return root, clear, fogged


def cloud_at(ranges, intensity=0.5) -> PointCloud:
    r = np.asarray(ranges, np.float64)
    xyz = np.stack([r, np.zeros_like(r), np.zeros_like(r)], 1).astype(np.float32)
    return PointCloud.from_raw(xyz, np.full(len(r), intensity, np.float32), "0-1", "test")


# ----------------------------------------------------------------------------- the distance
def test_distance_by_hand():
    """All returns at 4.5 m vs all at 5.5 m: one range bin apart of 21 (range term 1/20), 2 near bins of
    0.5 m apart (near_range 1 m / 10 m), the same near share and intensities; D = √(0.05² + 0.1²)."""
    assert RANGE_EDGES_M[4:7] == (4.0, 5.0, 6.0) and NEAR_M == 10.0 and NEAR_STEP_M == 0.5
    clear = statistics([cloud_at([4.5] * 50 + [25.0] * 50)])
    real, sim = statistics([cloud_at([4.5] * 40)]), statistics([cloud_at([5.5] * 40)])
    total, terms = distance(real, sim, clear)
    assert terms["range"] == pytest.approx(1 / 20)
    assert terms["near_range"] == pytest.approx(0.1)
    assert terms["near_share"] == 0 and terms["intensity"] == 0
    assert terms["far_survival"] == 0  # both lost the 25 m returns: survival 0 and 0
    assert total == pytest.approx(math.hypot(0.05, 0.1))
    assert distance(real, real, clear)[0] == 0
    # the far survival: half the 25 m returns kept vs none, read against the clear scans' 50 per scan
    half = statistics([cloud_at([4.5] * 40 + [25.0] * 25)])
    assert half.survival(clear)[1] == pytest.approx(0.5)
    assert distance(half, real, clear)[1]["far_survival"] == pytest.approx(0.5)  # one far bin with data
    # weights enter squared-summed
    assert distance(real, sim, clear, {"range": 4.0, "near_range": 0.0})[0] == pytest.approx(2 * 0.05)


def test_statistics_pool_scans_and_quantiles():
    a, b = cloud_at([1.5, 2.5, 35.0], 0.25), cloud_at([2.5, 90.0], 0.75)
    s = ScanStatistics().add(a).add(b)
    assert (s.scans, s.returns) == (2, 5)
    assert s.near_share == pytest.approx(3 / 5)
    assert s.far_per_scan.tolist() == [0.0, 0.0, 0.5, 0.0, 0.5]
    q = s.intensity_quantiles()  # 3 returns at 0.25, 2 at 0.75 (each in its own 1/1024 bin)
    assert q[0] == pytest.approx(0.25, abs=1e-3) and q[-1] == pytest.approx(0.75, abs=1e-3)


# ----------------------------------------------------------------------------- the fit
def test_objective_is_deterministic(data):
    """Common random numbers: the same parameters give the same distance, bit for bit; the seed changes it."""
    _, clear, real = data
    p = FitProblem(clear, real, sensor_dict(), None, BETA, ("fog_echo_scale",))
    a, b = p.evaluate({"fog_echo_scale": 0.3}, BETA), p.evaluate({"fog_echo_scale": 0.3}, BETA)
    assert a[0] == b[0] and a[1] == b[1]
    other = FitProblem(clear, real, sensor_dict(), None, BETA, ("fog_echo_scale",), seed=1)
    assert other.evaluate({"fog_echo_scale": 0.3}, BETA)[0] != a[0]


def test_fit_recovers_known_parameters(data):
    """Echo scale and threshold margin (max_range_m) back within 15 % and 10 % from the datasheet's (1, 120 m),
    in 100 evaluations; the fitted distance is far below the start's and no worse than the truth's."""
    _, clear, real = data
    p = FitProblem(clear, real, sensor_dict(), None, BETA, tuple(TRUTH))
    r = fit(p, 100)
    for k, v in TRUTH.items():
        assert r.values[k] == pytest.approx(v, rel=TOLERANCE[k]), (k, r.values)
    assert r.distance < 0.1 * r.start_distance
    assert r.distance <= p.evaluate(TRUTH, BETA)[0] * 1.25
    assert r.evaluations <= 100 and len(r.trace) == r.evaluations
    assert all(b <= a for a, b in zip(r.trace, r.trace[1:]))  # the best so far never rises


def test_fit_recovers_the_visibility(data):
    """Visibility unknown: β and the echo scale fitted together (max_range_m known, 100 evaluations): β within
    10 %, the echo scale within 25 %."""
    _, clear, real = data
    start = {"max_range_m": 200.0, "sources": {"max_range_m": "test"}}
    p = FitProblem(clear, real, sensor_dict(), {"calibration": start}, None, ("fog_echo_scale",))
    r = fit(p, 100)
    assert r.beta_fitted and r.beta == pytest.approx(BETA, rel=0.10)
    assert r.values["fog_echo_scale"] == pytest.approx(0.2, rel=0.25)


def test_fit_never_worsens_its_distance(data):
    """From the truth itself, a fit can only keep or lower the distance; one evaluation scores the start alone."""
    _, clear, real = data
    truth = {**TRUTH, "sources": dict.fromkeys(TRUTH, "test")}
    p = FitProblem(clear, real, sensor_dict(), {"calibration": truth}, BETA, ("fog_echo_scale", "fluctuation_sigma"))
    start = p.evaluate({**TRUTH, "fluctuation_sigma": 0.5}, BETA)[0]
    r = fit(p, 12)
    assert r.start_distance == start and r.distance <= start
    one = fit(p, 1)
    assert one.evaluations == 1 and one.distance == start and one.values == one.start_values


def test_fit_recovers_the_stf2020_constants(data):
    """stf2020's per-sensor noise level and gain (the two numbers its authors fitted in their chamber): scans
    fogged with n 0.08, g 0.2 are fitted back from the HDL-64 S2's (0.05, 0.35) within 10 % in 60 evaluations;
    hahner2021 has no calibration key to fit (its released constants are not the sensor's): its fit is the
    visibility alone."""
    _, clear, _ = data
    truth = {"stf_noise_level": 0.08, "stf_gain": 0.2}
    sensor = load_sensor(sensor_dict())
    block = {"name": "truth", **truth, "sources": dict.fromkeys(truth, "test")}
    real = [LidarFogger(s, sensor, {"model": "stf2020", "calibration": block})(BETA, np.random.default_rng(300 + i))
            .cloud for i, s in enumerate(clear)]
    p = FitProblem(clear, real, sensor_dict(), {"model": "stf2020"}, BETA)
    assert p.parameters == ("stf_noise_level", "stf_gain") and p.start == {"stf_noise_level": 0.05, "stf_gain": 0.35}
    r = fit(p, 60)
    for k, v in truth.items():
        assert r.values[k] == pytest.approx(v, rel=0.10), (k, r.values)
    assert r.distance < 0.05 * r.start_distance
    hahner = FitProblem(clear, real, sensor_dict(), {"model": "hahner2021"}, None)
    assert hahner.parameters == () and fit(hahner, 8).beta_fitted
    with pytest.raises(ValueError, match="stf_noise_level"):  # no published n, g and no start given
        FitProblem(clear, real, {**sensor_dict(), "stf_noise_level": None, "stf_gain": None}, {"model": "stf2020"},
                   BETA)


@pytest.mark.slow
def test_fit_recovers_three_parameters(data, tmp_path):
    """Echo scale, pulse width and threshold margin together (250 evaluations): each within 15 %."""
    _, clear, _ = data
    truth = {**TRUTH, "pulse_half_power_ns": 20.0}
    real = [foggy(s, truth, 200 + i) for i, s in enumerate(clear)]
    r = fit(FitProblem(clear, real, sensor_dict(), None, BETA, tuple(truth)), 250)
    for k, v in truth.items():
        assert r.values[k] == pytest.approx(v, rel=0.15), (k, r.values)


def test_parameter_table():
    """Every model's fitted keys are calibration keys with a search range; each model the schema knows is taken
    by name through the spec and can be scored (a model without a fit entry is refused a fit, naming the table)."""
    for model, keys in MODEL_PARAMETERS.items():
        assert model in LIDAR_FOG_MODELS
        assert set(keys) <= set(PARAMETER_SPACE) <= set(CALIBRATION_KEYS)


@pytest.mark.parametrize("model", LIDAR_FOG_MODELS)
def test_every_model_can_be_scored(data, model):
    """Each model the schema knows, by name: scored (a model the fit table knows must fog any sensor; another
    may refuse this custom sensor, with its reason)."""
    _, clear, real = data
    p = FitProblem(clear[:1], real[:1], sensor_dict(), {"model": model}, BETA, ())
    total, terms, sim = p.evaluate(p.start, BETA)
    if sim is None:
        assert model not in MODEL_PARAMETERS and p.last_error, p.last_error
        return
    assert sim.scans == 1 and 0 <= total < 1 and set(terms) == {"range", "near_share", "near_range", "far_survival",
                                                                "intensity"}


# ----------------------------------------------------------------------------- the commands
def run(*argv) -> int:
    return main([str(a) for a in argv])


def test_lidar_fit_writes_a_calibration_fog_reads(data, tmp_path, capsys):
    root, _, _ = data
    out = tmp_path / "fit"
    code = run("lidar-fit", "--clear", root / "in" / "clear", "--foggy", root / "in" / "foggy", "--point-format",
               "kitti", "--sensor", root / "in" / "sensor.json", "--visibility", math.log(20) / BETA,
               "--parameters", "fog_echo_scale,max_range_m", "--evaluations", 100, "--out", out, "--quiet")
    assert code == 0
    line = capsys.readouterr().out
    assert "lidar-fit: distance" in line and "calibration.json" in line
    cal = json.loads((out / "calibration.json").read_text())
    assert cal["name"] == "fit-hdl64e-400-soft-target"
    assert set(cal["sources"]) == {"fog_echo_scale", "max_range_m"}
    assert cal["fog_echo_scale"] == pytest.approx(0.2, rel=0.3)
    report = json.loads((out / "report.json").read_text())
    assert report["distance"]["fitted"]["total"] <= report["distance"]["default"]["total"]
    assert report["parameters"]["fog_echo_scale"]["fitted"] == cal["fog_echo_scale"]
    assert set(report["statistics"]) == {"clear", "real", "default", "fitted"}
    assert "| near field (< 10 m) |" in (out / "report.md").read_text()
    # the calibration is what --lidar-calibration reads: fog the clear scans with it
    level = tmp_path / "fogged"
    assert run("fog", "--quiet", "--points", root / "in" / "clear", "--point-format", "kitti", "--sensor",
               root / "in" / "sensor.json", "--lidar-calibration", out / "calibration.json", "--levels", "paper",
               "--out", level) == 0
    side = json.loads(next(level.glob("beta0.03*/000000.json")).read_text())
    assert side["sensor"]["calibration"] == cal["name"]
    assert side["sensor"]["fog_echo_scale"] == cal["fog_echo_scale"]
    assert side["sensor"]["max_range_m"] == cal["max_range_m"]


def test_report_png_shows_real_and_simulated(data, tmp_path):
    root, _, _ = data
    out = tmp_path / "fit"
    assert run("lidar-fit", "--clear", root / "in" / "clear", "--foggy", root / "in" / "foggy", "--point-format",
               "kitti", "--sensor", root / "in" / "sensor.json", "--visibility", 100, "--parameters",
               "fog_echo_scale", "--evaluations", 8, "--out", out, "--quiet") == 0
    for name in ("histograms.png", "distance.png"):
        img = cv2.cvtColor(cv2.imread(str(out / name)), cv2.COLOR_BGR2RGB)
        assert img is not None and img.shape[0] > 200 and img.shape[1] > 500
    img = cv2.cvtColor(cv2.imread(str(out / "histograms.png")), cv2.COLOR_BGR2RGB)
    for series in ("real", "default", "fitted", "clear"):  # each set's line is drawn (its exact colour)
        assert (img == SERIES_COLOURS[series]).all(axis=2).sum() > 200, series


def test_lidar_compare_scores_without_fitting(data, tmp_path, capsys):
    """The truth calibration scores lower than the datasheet; the number is FitProblem's distance."""
    root, clear, real = data
    truth_file = tmp_path / "truth.json"
    truth_file.write_text(json.dumps({"name": "truth", **TRUTH, "sources": dict.fromkeys(TRUTH, "test")}))
    scores = {}
    for cal in ("datasheet", truth_file):
        out = tmp_path / f"cmp-{'file' if cal == truth_file else cal}"
        assert run("lidar-compare", "--clear", root / "in" / "clear", "--foggy", root / "in" / "foggy",
                   "--point-format", "kitti", "--sensor", root / "in" / "sensor.json", "--visibility",
                   math.log(20) / BETA, "--lidar-calibration", cal, "--out", out, "--quiet") == 0
        rec = json.loads((out / "report.json").read_text())
        scores[str(cal)] = rec["distance"]["simulated"]["total"]
        assert (out / "histograms.png").is_file() and not (out / "calibration.json").exists()
    assert scores[str(truth_file)] < 0.2 * scores["datasheet"]
    p = FitProblem(clear, real, sensor_dict(), None, beta_of_visibility(math.log(20) / BETA), ())
    assert scores["datasheet"] == pytest.approx(p.evaluate(p.start, p.beta)[0], rel=1e-12)


def test_nuscenes_format_compare(tmp_path):
    """A nuScenes-format sweep (every column by hand) against its own fog, through the default hdl32e."""
    (tmp_path / "c").mkdir()
    (tmp_path / "f").mkdir()
    path = lf.nuscenes_sweep(tmp_path / "c")
    scan = read_points(path, "nuscenes")
    sensor = load_sensor("hdl32e")
    cloud = LidarFogger(scan, sensor, None, empty_rays(scan, sensor))(0.02, np.random.default_rng(3)).cloud
    (tmp_path / "f" / "fog.pcd.bin").write_bytes(lf.stf_bin(cloud.xyz, cloud.raw_intensity, cloud.ring))
    assert run("lidar-compare", "--clear", tmp_path / "c", "--foggy", tmp_path / "f", "--point-format", "nuscenes",
               "--visibility", math.log(20) / 0.02, "--out", tmp_path / "out", "--quiet") == 0
    rec = json.loads((tmp_path / "out" / "report.json").read_text())
    assert rec["sensor"] == "hdl32e" and rec["distance"]["simulated"]["total"] < 0.01  # the same fog, other draws


@pytest.mark.parametrize("argv, says", [
    (["--visibility", "-5"], "--visibility must be a number of metres > 0"),
    (["--parameters", "fog_echo_scale,warp"], "cannot fit warp"),
    (["--weights", "range=2,colour=1"], "unknown distance term 'colour'"),
    (["--evaluations", "0"], "--evaluations must be ≥ 1"),
    (["--lidar-model", "hahner2021", "--visibility", "100"], "hahner2021 has no calibration key to fit"),
])
def test_bad_flags_one_line(data, tmp_path, capsys, argv, says):
    root, _, _ = data
    code = run("lidar-fit", "--clear", root / "in" / "clear", "--foggy", root / "in" / "foggy", "--point-format",
               "kitti", "--sensor", root / "in" / "sensor.json", "--out", tmp_path / "o", *argv)
    err = capsys.readouterr().err
    assert code == 2 and says in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_bad_inputs_one_line(data, tmp_path, capsys):
    root, _, _ = data
    empty = tmp_path / "empty"
    empty.mkdir()
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "x.bin").write_bytes(b"\0" * 15)
    for foggy_dir, says in ((empty, "holds no .bin scans"), (bad, "x.bin: size 15 bytes"),
                            (root / "in" / "clear", "is given as a clear and as a foggy scan")):
        code = run("lidar-fit", "--clear", root / "in" / "clear", "--foggy", foggy_dir, "--point-format", "kitti",
                   "--sensor", root / "in" / "sensor.json", "--out", tmp_path / "o")
        err = capsys.readouterr().err
        assert code == 2 and says in err and "Traceback" not in err, err
    assert not (tmp_path / "o").exists()
    with pytest.raises(SystemExit):  # lidar-compare needs the visibility
        run("lidar-compare", "--clear", root / "in" / "clear", "--foggy", root / "in" / "foggy", "--point-format",
            "kitti", "--out", tmp_path / "o")


def test_out_inside_an_input_is_refused(data, tmp_path, capsys):
    root, _, _ = data
    code = run("lidar-compare", "--clear", root / "in" / "clear", "--foggy", root / "in" / "foggy", "--point-format",
               "kitti", "--sensor", root / "in" / "sensor.json", "--visibility", 100, "--out",
               root / "in" / "foggy" / "report")
    err = capsys.readouterr().err
    assert code == 2 and "--out lies inside --foggy" in err and not (root / "in" / "foggy" / "report").exists()
