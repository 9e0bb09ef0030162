"""Real sensors' habits in the LiDAR fog model (issue 44 item 3): a sweep that stores every firing (nuScenes: a
firing without a return is a row at 0 m) keeps one row per firing, its no-return rows fogged in place; a KITTI scan
cropped to the camera gets the empty rays inside the camera's view; KITTI's HDL-64E lasers (two blocks, vertical
offsets) are the beams a point is binned to. Sweeps are ray-cast and written in the formats' byte layouts by
tests/lidar_fixtures.py; every count is checked against the geometry and the LiDAR equation written out here."""
from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

import lidar_fixtures as lf
from fogsim.cli import main
from fogsim.lidar.fog import CLUTTER, LOST, NO_RETURN, OUTCOMES, LidarFogger
from fogsim.lidar.formats import read_points
from fogsim.lidar.outcome_file import read_outcomes
from fogsim.lidar.points import PointCloud
from fogsim.lidar.rays import CameraView, empty_rays, no_returns
from fogsim.lidar.reference import reference_fog
from fogsim.lidar.sensors import LidarSensor
from fogsim.lidar.soft_target import fog_echo
from fogsim.schema.lidar import LidarFogSpec

STEADY = {"calibration": {"fluctuation_sigma": 0.0,  # the fluctuation off: the old deterministic thresholds
                          "sources": {"fluctuation_sigma": "assumed: off"}}}
SIGMA_G = 0.5  # the presets' fluctuation σ (ln units)


# ----------------------------------------------------------------------------- no-return rows (every firing stored)
@pytest.fixture(scope="module")
def firings(tmp_path_factory):
    path, truth = lf.nuscenes_firings(tmp_path_factory.mktemp("firings"))
    return path, read_points(path, "nuscenes"), truth


def test_a_sweep_that_stores_every_firing_keeps_one_row_per_firing(firings):
    """nuScenes stores every firing (a no-return as a row at 0 m): rows out = firings in at every level; a
    no-return row becomes its own row's clutter exactly when its fog echo q_f·g_f ≥ 1 (its row's draw), on its
    ray; otherwise it stays as it was; a row inside the blind zone (the roof) never sees the fog."""
    path, scan, truth = firings
    n = len(scan)
    assert n == lf.NUSCENES_FIRINGS * lf.NUSCENES_RINGS and truth["void"].mean() > 0.05 and truth["ego"].sum() > 100
    s = LidarSensor.preset("hdl32e")
    blank = no_returns(scan, s)
    assert np.array_equal(blank.rows, np.flatnonzero(truth["void"] | truth["ego"]))
    assert np.array_equal(blank.open, truth["void"][blank.rows])
    cos = np.einsum("ij,ij->i", blank.directions[blank.open], truth["direction"][blank.rows[blank.open]])
    assert np.degrees(np.arccos(np.minimum(cos, 1.0))).max() < 360.0 / lf.NUSCENES_FIRINGS  # within one firing
    rays = empty_rays(scan, s)
    assert rays is None or len(rays) == 0  # every firing is a row: no cell is left empty
    fogger = LidarFogger(scan, s, empty_rays=rays)
    void, ego = np.flatnonzero(truth["void"]), np.flatnonzero(truth["ego"])
    for beta in (0.0, 0.005, 0.01, 0.02, 0.03, 0.06, 0.09, 0.12):
        out = fogger(beta, np.random.default_rng(2))
        c = out.counts()
        assert len(out.cloud) == n and sum(c.values()) == n and np.array_equal(out.cloud.index, np.arange(n))
        assert np.array_equal(out.cloud.ring, scan.ring) and out.empty_ray_clutter == 0
        assert out.no_returns == len(blank) and c["no-return"] + out.no_return_clutter == len(blank)
        assert out.record()["no_returns"] == len(blank) and out.record()["points_out"] == n
        oc = out.outcome
        assert (oc[ego] == NO_RETURN).all() and out.cloud.same_as(out.cloud) and (oc[void] != LOST).all()
        stays = np.flatnonzero(oc == NO_RETURN)
        assert np.array_equal(out.cloud.xyz[stays], scan.xyz[stays])
        assert np.array_equal(out.cloud.raw_intensity[stays], scan.raw_intensity[stays])
        if beta == 0:
            assert out.cloud.same_as(scan) and c["no-return"] == len(blank)
            continue
        rng = np.random.default_rng(2)  # range noise, ln g_h, ln g_f per row: a no-return row's echo is q_f·g_f
        z = rng.standard_normal(n, np.float32)
        rng.standard_normal(n, np.float32)
        sf = np.float32(SIGMA_G) * rng.standard_normal(n, np.float32)
        e = fog_echo(s, beta)
        qc = e.signal * np.exp(sf[void].astype(np.float64))
        assert np.array_equal(oc[void] == CLUTTER, qc >= 1)
        lit = oc[void] == CLUTTER
        p = out.cloud.xyz[void[lit]].astype(np.float64)
        rr = np.linalg.norm(p, axis=1)  # at r_f + σ_c·z, σ_c² = σ₀² + (σ₁·(w_f/(L/2))/q_c)², not nearer than 1 m
        sigma_c = np.hypot(0.02, 0.1 * (e.width_m / (0.5 * s.pulse_length_m)) / qc[lit])
        np.testing.assert_allclose(rr, np.maximum(e.range_m + sigma_c * z[void[lit]], 1.0), atol=1e-4)
        assert (np.einsum("ij,ij->i", p / rr[:, None], truth["direction"][void[lit]]) > 0.9999).all()  # its ray
        lost = np.flatnonzero(oc == LOST)  # a lost return keeps its row, as the format stores it: a placeholder
        assert (out.output_index[lost] == lost).all() and not out.cloud.xyz[lost].any()
        assert not out.cloud.raw_intensity[lost].any()
        if beta == 0.03:
            assert lit.mean() > 0.5


def test_a_sweep_of_every_firing_through_the_cli(firings, tmp_path):
    path, scan, truth = firings
    out = tmp_path / "out"
    assert main(["fog", "--quiet", "--points", str(path), "--point-format", "nuscenes", "--levels", "0,0.01,0.03,0.09",
                 "--out", str(out)]) == 0
    for level in ("clear", "beta0.01", "beta0.03", "beta0.09"):
        side = json.loads((out / level / "firings.json").read_text())
        got = read_points(out / level / "firings.pcd.bin", "nuscenes")
        assert len(got) == side["points_out"] == side["points_in"] == len(scan), level
        assert sum(side["outcomes"].values()) == len(scan) and side["empty_ray_clutter"] == 0
        assert side["no_returns"] == int((truth["void"] | truth["ego"]).sum())
        assert side["outcomes"]["no-return"] + side["no_return_clutter"] == side["no_returns"]
        outcome, index = read_outcomes(out / level / "firings.outcomes.npz")
        assert np.array_equal(index, np.arange(len(scan))) and np.array_equal(np.bincount(outcome, minlength=5),
                                                                            [side["outcomes"][k] for k in OUTCOMES])


def test_no_return_rows_vectorised_equals_the_loop(firings):
    path, scan, truth = firings
    part = scan.select(np.arange(0, 120 * lf.NUSCENES_RINGS))  # 120 whole firings, in file order
    assert no_returns(part, LidarSensor.preset("hdl32e")).open.sum() > 100
    dirs = lf.ray_directions(20, 45.0, elevation_deg=9.0, spread_deg=3.0)
    for beta, spec in ((0.01, {}), (0.03, {"return_mode": "last"}), (0.06, {"model": "attenuation"})):
        fs = LidarFogSpec.model_validate(spec)
        out = LidarFogger(part, "hdl32e", fs, empty_rays=dirs)(beta, np.random.default_rng(4))
        oc, xyz, norm, raw = reference_fog(part, "hdl32e", beta, np.random.default_rng(4), fs, empty_rays=dirs)
        n = len(part)
        assert np.array_equal(out.outcome, oc[:n]) and out.empty_ray_clutter == int((oc[n:] == CLUTTER).sum())
        rows = np.concatenate([out.output_index[out.output_index >= 0], np.arange(n, len(oc))[oc[n:] == CLUTTER]])
        want = np.concatenate([np.flatnonzero(out.output_index >= 0), np.arange(n, len(oc))[oc[n:] == CLUTTER]])
        np.testing.assert_allclose(out.cloud.xyz, xyz[want], rtol=1e-6, atol=1e-5)
        np.testing.assert_allclose(out.cloud.raw_intensity, raw[want], rtol=1e-6, atol=1e-5)
        assert len(rows) == len(out.cloud)


def test_rows_nearer_than_the_minimum_range_without_a_ring_stay_as_they_were():
    """A KITTI-like scan (no ring) with a row at 0 m and one at 0.5 m: both no-return, neither becomes
    clutter (without a ring the placeholder's ray is unknown; the 0.5 m echo hides the fog behind it); no
    row is added for a lost return (KITTI stores returns only)."""
    xyz = np.array([[0, 0, 0], [0.5, 0, 0], [30.0, 0, 0], [0, 100.0, 0]], np.float32)
    scan = PointCloud.from_raw(xyz, [0.0, 0.2, 0.3, 0.01], "0-1", "near")
    for spec in (STEADY, {"model": "attenuation"}):
        out = LidarFogger(scan, "hdl64e", spec)(0.2, np.random.default_rng(0))
        assert list(out.outcome[:2]) == [NO_RETURN, NO_RETURN] and out.no_returns == 2 and out.no_return_clutter == 0
        assert np.array_equal(out.cloud.xyz[:2], xyz[:2]) and out.cloud.index[0] == 0
        assert out.outcome[3] == (CLUTTER if spec is STEADY else LOST)  # (the echo at β 0.2 beats a dark return)
        assert len(out.cloud) == 4 - (out.outcome == LOST).sum()


# ----------------------------------------------------------------------------- a cropped KITTI frame, real lasers
@pytest.fixture(scope="module")
def kitti_frame(tmp_path_factory):
    path, truth = lf.kitti_laser_frame(tmp_path_factory.mktemp("kitti_frame"))
    return path, read_points(path, "kitti"), truth


def uniform_hdl64(**extra):
    """The old hdl64e grid: 64 beams spaced uniformly over the datasheet's −24.9° … +2°."""
    return LidarSensor.from_dict({"name": "uniform", "beams": 64, "vertical_fov_deg": [-24.9, 2.0],
                                  "horizontal_resolution_deg": 0.18, "max_range_m": 120.0, "intensity_scale": "0-1",
                                  **extra})


def matched(rays, missing, within_deg=0.2):
    """Per found ray: it points at a ray the sensor fired without a return (within ``within_deg``)."""
    return (rays.directions @ missing.T).max(axis=1) > math.cos(math.radians(within_deg))


def test_estimated_beams_are_the_real_lasers(kitti_frame):
    """KITTI's HDL-64E: two blocks of lasers, each laser's line 0.1–0.2 m off the origin. The nearest beam by
    distance from its line is the laser that fired, for every point; by elevation alone (no offsets) a near
    point reads asin(h/R) high — up to several beams at 5–20 m."""
    path, scan, truth = kitti_frame
    s = LidarSensor.preset("hdl64e")
    assert np.array_equal(scan.estimated_rings(s.inclinations_rad, s.vertical_offsets_m), truth["laser"])
    assert (scan.estimated_rings(s.inclinations_rad) == truth["laser"]).mean() < 0.1


def test_a_cropped_scan_gets_the_empty_rays_in_the_cameras_view(kitti_frame):
    """A scan cropped to camera 2 (89 % of the sweep's cells empty) is no full sweep; with the camera's view
    (P2·R0·Tr, the image size) its empty rays are the in-view cells no point covers: every one a ray the sensor
    fired without a return (sky, windows, the far road) — none spurious with the real lasers, where uniform
    beams leave beams without a laser (and lasers without offsets leave near points in the wrong beam)."""
    path, scan, truth = kitti_frame
    s = LidarSensor.preset("hdl64e")
    view = CameraView(lf.kitti_projection(), *lf.KITTI_IMAGE)
    assert empty_rays(scan, s) is None  # cropped: the whole grid is mostly empty
    rays = empty_rays(scan, s, view)
    missing = truth["missing"]
    assert len(missing) > 2000 and rays.ring is None
    assert matched(rays, missing).all() and len(rays) > 0.7 * len(missing)  # a run of k empty cells counts k − 2
    assert view.sees(rays.directions).all()
    for sensor in (uniform_hdl64(), replace(s, vertical_offsets_m=None)):
        old = empty_rays(scan, sensor, view)
        assert (~matched(old, missing)).sum() > 500  # spurious empty rays: cells of beams no laser fills
    # the camera's own view: a ray projects into the image from 2 m to infinity
    down = np.array([[math.cos(math.radians(-20)), 0, math.sin(math.radians(-20))]])
    ahead, behind = np.array([[1.0, 0, 0]]), np.array([[-1.0, 0, 0]])
    assert view.sees(ahead)[0] and not view.sees(behind)[0] and not view.sees(down)[0]
    # in fog, each in-view empty ray may return the fog echo; every fog echo lies on its laser's line, so the
    # laser read back from the fogged scan is the one that fired (a clutter point at 2.6 m is far off the
    # line through the origin: asin(0.2 / 2.6) = 4.4°)
    out = LidarFogger(scan, s, empty_rays=rays)(0.06, np.random.default_rng(0))
    assert 0 < out.empty_ray_clutter <= len(rays) and len(out.cloud) == len(scan) - out.counts()["lost"] + \
        out.empty_ray_clutter
    back = out.cloud.estimated_rings(s.inclinations_rad, s.vertical_offsets_m)
    shown = out.output_index >= 0
    assert (out.outcome == CLUTTER).sum() > 1000
    assert np.array_equal(back[out.output_index[shown]], truth["laser"][shown])
    extra = out.cloud.xyz[len(out.cloud) - out.empty_ray_clutter:].astype(np.float64)
    laser = back[len(out.cloud) - out.empty_ray_clutter:]
    cells = np.degrees(np.arcsin(rays.directions[:, 2]))
    assert np.isin(np.round(np.degrees(s.inclinations_rad[laser]), 4), np.round(cells, 4)).all()
    assert (np.abs(np.linalg.norm(extra, axis=1) - fog_echo(s, 0.06).range_m) < 1.0).all()


def test_kitti_lidar_fogs_the_empty_rays_in_the_cameras_view(kitti_frame, tmp_path):
    """``fogsim fog --kitti ROOT --lidar``: the frame's calibration and image size give the view."""
    import cv2

    path, scan, truth = kitti_frame
    base = tmp_path / "kitti" / "training"
    for d in ("image_2", "velodyne", "calib"):
        (base / d).mkdir(parents=True)
    w, h = lf.kitti_image(1 / 3)
    cv2.imwrite(str(base / "image_2" / "000000.png"), np.full((h, w, 3), 120, np.uint8))
    (base / "velodyne" / "000000.bin").write_bytes(path.read_bytes())
    (base / "calib" / "000000.txt").write_text(lf.kitti_calib_text(1 / 3))
    out = tmp_path / "out"
    assert main(["fog", "--quiet", "--kitti", str(tmp_path / "kitti"), "--lidar", "--levels", "0,0.06",
                 "--no-kitti-trees", "--out", str(out)]) == 0
    level = json.loads((out / "beta0.06" / "training" / "image_2" / "000000.json").read_text())["lidar"]
    want = empty_rays(scan, LidarSensor.preset("hdl64e"), CameraView(lf.kitti_projection(1 / 3), w, h))
    assert level["empty_rays"] == len(want) > 2000 and level["empty_ray_clutter"] > 0
