"""``fogsim fog --kitti ROOT --lidar`` and ``--stf ROOT --lidar`` end to end (issue 29 items 3, 4, 6).

The fixture trees are written from the formats' specs (:mod:`kitti_tree`); every level is read back with a
KITTI reader written from the spec (:func:`kitti_tree.read_kitti_frame`), the fogged scans are checked
against the LiDAR model for the documented seed (and, with ``--lidar-model attenuation``, against the
threshold's closed form computed here from the preset's numbers), the camera against Koschmieder at the
scan's own distances, the per-object counts against the label boxes, the table against the meta records.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import kitti_tree as kt
from conftest import tree_digest
from fogsim.cli import main
from fogsim.io.images import read_image
from fogsim.lidar.fog import ATTENUATED, CLUTTER, KEPT, LOST, LidarFogger
from fogsim.lidar.objects import cross_sensor_table
from fogsim.lidar.outcome_file import read_outcomes
from fogsim.lidar.sensors import LidarSensor
from fogsim.readers.kitti.boxes import label_box
from fogsim.readers.kitti.calib import read_kitti_calib
from fogsim.readers.kitti.labels import KITTI_CLASSES, label_records
from fogsim.runs import level_seed

PAPER = (("clear", 0.0), ("beta0.03", 0.03), ("beta0.06", 0.06), ("beta0.09", 0.09), ("beta0.12", 0.12))
IDS = sorted(kt.CARS)


def fog(*args) -> int:
    return main(["fog", "--quiet", *map(str, args)])


def frame(fid: str) -> str:
    return f"training__image_2__{fid}"


def spec_scan(path) -> np.ndarray:
    """A KITTI velodyne file read from the spec: float32 × 4 little-endian."""
    data = path.read_bytes()
    assert len(data) % 16 == 0
    return np.frombuffer(data, "<f4").reshape(-1, 4)


def expected_level(scan_path, key: str, level: str, beta: float, sensor="hdl64e", fmt="kitti", spec=None,
                   seed: int = 0):
    """What the model gives this scan at this level for the documented seed rule."""
    from fogsim.lidar.formats import read_points

    cloud = read_points(scan_path, fmt)
    rng = np.random.default_rng(level_seed(seed, key, level))
    return cloud, LidarFogger(cloud, sensor, spec)(beta, rng)


@pytest.fixture(scope="module")
def kitti_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("kitti")
    root = kt.write_kitti(tmp / "in" / "kitti")
    before = tree_digest(tmp / "in")
    out = tmp / "out"
    assert fog("--kitti", root, "--lidar", "--levels", "paper", "--out", out) == 0
    assert tree_digest(tmp / "in") == before  # the input is never touched
    return root, out


def test_every_level_is_a_labelled_dataset_and_a_kitti_tree_read_back_by_the_spec(kitti_run):
    root, out = kitti_run
    dataset = json.loads((out / "dataset.json").read_text())
    assert [lv["key"] for lv in dataset["levels"]] == [k for k, _ in PAPER]
    assert dataset["classes"] == list(KITTI_CLASSES) and dataset["counts"]["Car"] == 3
    for level, beta in PAPER:
        for fid in IDS:
            assert (out / "images" / level / f"{frame(fid)}.png").is_file()
            yolo = (out / "labels" / level / f"{frame(fid)}.txt").read_text().splitlines()
            assert len(yolo) == 1 and yolo[0].split()[0] == "0"  # the car; DontCare is not a YOLO box
            pts, calib, labels, size = kt.read_kitti_frame(out / "kitti" / level, fid)
            assert size == (kt.WIDTH, kt.HEIGHT)
            np.testing.assert_allclose(np.reshape(calib["P2"], (3, 4)), kt.P2, atol=1e-9)
            np.testing.assert_allclose(np.reshape(calib["Tr_velo_to_cam"], (3, 4)), kt.TR, atol=1e-9)
            source = [ln.split() for ln in (root / "training" / "label_2" / f"{fid}.txt").read_text().splitlines()]
            assert [f[0] for f in labels] == [f[0] for f in source] == ["Car", "DontCare"]
            np.testing.assert_allclose([[float(v) for v in f[1:]] for f in labels],
                                       [[float(v) for v in f[1:]] for f in source], atol=5e-3)
            # the tree's scan is the level's scan, and the tree's image the level's camera image
            _, expected = expected_level(root / "training" / "velodyne" / f"{fid}.bin",
                                         f"training/image_2/{fid}", level, beta)
            np.testing.assert_array_equal(pts[:, :3], expected.cloud.xyz)
            np.testing.assert_array_equal(pts[:, 3], expected.cloud.raw_intensity)
            assert (out / "kitti" / level / "training" / "image_2" / f"{fid}.png").read_bytes() == \
                (out / "images" / level / f"{frame(fid)}.png").read_bytes()
        sets = {n: (out / "kitti" / level / "ImageSets" / f"{n}.txt").read_text().split() for n in
                ("train", "val", "trainval", "test")}
        split = {p: sorted(line.rsplit("__", 1)[1].split(".")[0] for line in
                           (out / "splits" / f"{level}_{p}.txt").read_text().split()) for p in ("train", "val")}
        assert sets["train"] == split["train"] and sets["val"] == split["val"] and sets["test"] == []
        assert sets["trainval"] == sorted(split["train"] + split["val"])
    assert json.loads((out / "kitti" / "frame_ids.json").read_text()) == {f: frame(f) for f in IDS}
    clear = out / "kitti" / "clear" / "training" / "velodyne"
    for fid in IDS:  # β = 0: the input scan, bit for bit
        assert (clear / f"{fid}.bin").read_bytes() == (root / "training" / "velodyne" / f"{fid}.bin").read_bytes()
        assert (out / "lidar" / "clear" / f"{frame(fid)}.bin").read_bytes() == (clear / f"{fid}.bin").read_bytes()


def test_the_fogged_scans_are_the_models_for_the_documented_seed(kitti_run):
    root, out = kitti_run
    for level, beta in PAPER:
        for fid in IDS:
            cloud, expected = expected_level(root / "training" / "velodyne" / f"{fid}.bin",
                                             f"training/image_2/{fid}", level, beta)
            got = spec_scan(out / "lidar" / level / f"{frame(fid)}.bin")
            np.testing.assert_array_equal(got[:, :3], expected.cloud.xyz)
            np.testing.assert_array_equal(got[:, 3], expected.cloud.raw_intensity)
            outcome, index = read_outcomes(out / "lidar" / level / f"{frame(fid)}.outcomes.npz")
            np.testing.assert_array_equal(outcome, expected.outcome)
            np.testing.assert_array_equal(index, expected.output_index)
            meta = json.loads((out / "meta" / f"{frame(fid)}.json").read_text())
            entry = meta["lidar"]["levels"][level]
            assert entry["outcomes"] == expected.counts() and entry["beta"] == beta
            assert entry["seed"] == level_seed(0, f"training/image_2/{fid}", level)
            assert entry["file"] == f"lidar/{level}/{frame(fid)}.bin"
    # fog did something, and more with β: the clutter share of the scans grows, the kept share falls
    totals = json.loads((out / "dataset.json").read_text())["lidar"]["outcomes"]
    clutter = [totals[k]["shares"]["clutter"] for k, _ in PAPER]
    assert clutter[0] == 0 and all(a < b for a, b in zip(clutter, clutter[1:]))
    assert totals["clear"]["shares"]["kept"] == 1.0


def test_attenuation_model_against_its_closed_form(tmp_path):
    """``--lidar-model attenuation``: a point is lost exactly when q0·e^(−2βR) < 1, with
    q0 = max((ρ/ρ_ref)(R_max/R)²·ξ(R), 1), ρ = max(s·I, 0.02), ξ = min(1, (R/R_o)²) — with the hdl64e
    preset's numbers (ρ_ref, R_max, R_o, s read from it), computed here, with the echo fluctuation off (a
    ``--lidar-calibration`` file: σ = 0, so the clear-air floor e^σ is 1); no clutter."""
    root = kt.write_kitti(tmp_path / "in" / "kitti")
    out = tmp_path / "out"
    steady = tmp_path / "steady.json"
    steady.write_text(json.dumps({"name": "steady", "fluctuation_sigma": 0.0,
                                  "sources": {"fluctuation_sigma": "assumed: off, for the closed form"}}))
    assert fog("--kitti", root, "--lidar", "--lidar-model", "attenuation", "--lidar-calibration", steady,
               "--levels", "0.06,0.12", "--out", out) == 0
    preset = LidarSensor.preset("hdl64e")
    rho_ref, r_max, r_o, s = (preset.reference_reflectivity, preset.max_range_m, preset.overlap_full_m,
                              preset.reflectivity_per_intensity)
    assert preset.retro_reflective_from is None and preset.intensity_range_exponent == 0.0  # ρ linear in I
    for fid in IDS:
        raw = spec_scan(root / "training" / "velodyne" / f"{fid}.bin")
        r = np.linalg.norm(raw[:, :3].astype(np.float64), axis=1)
        rho = np.maximum(s * raw[:, 3].astype(np.float64), 0.02)
        q0 = np.maximum(rho / rho_ref * (r_max / r) ** 2 * np.minimum(1.0, (r / r_o) ** 2), 1.0)
        for level, beta in (("beta0.06", 0.06), ("beta0.12", 0.12)):
            outcome, index = read_outcomes(out / "lidar" / level / f"{frame(fid)}.outcomes.npz")
            lost = q0 * np.exp(-2 * beta * r) < 1.0
            assert lost.any() and not lost.all()  # both outcomes occur: the rule is tested
            np.testing.assert_array_equal(outcome == LOST, lost)
            assert not (outcome == CLUTTER).any() and (outcome[~lost] != LOST).all()
            got = spec_scan(out / "lidar" / level / f"{frame(fid)}.bin")
            assert len(got) == (~lost).sum()
            # attenuated reflectance: I·e^(−2βR) at the (noisy) range along the same ray
            att = np.flatnonzero(outcome == ATTENUATED)
            np.testing.assert_allclose(got[index[att], 3], raw[att, 3] * np.exp(-2 * beta * r[att]), rtol=1e-5)
            dirs = got[index[att], :3] / np.linalg.norm(got[index[att], :3], axis=1, keepdims=True)
            np.testing.assert_allclose(dirs, raw[att, :3] / r[att, None], atol=1e-5)
            kept = np.flatnonzero(outcome == KEPT)
            np.testing.assert_array_equal(got[index[kept]], raw[kept])
        assert (out / "meta" / f"{frame(fid)}.json").is_file()


def test_labels_camera_and_objects(kitti_run):
    root, out = kitti_run
    coco = json.loads((out / "coco" / "beta0.06.json").read_text())
    crowd = [a for a in coco["annotations"] if a["iscrowd"]]
    assert len(crowd) == len(IDS)  # DontCare: one ignore region of every class per label line
    assert {a["category_id"] for a in crowd} == {len(KITTI_CLASSES) + 1} and all(a["every_class"] for a in crowd)
    assert coco["categories"][-1]["name"] == "DontCare"
    for fid in IDS:
        meta = json.loads((out / "meta" / f"{frame(fid)}.json").read_text())
        car = meta["objects"][0]
        assert car["class"] == "Car" and car["truncation"] == 0.1 and car["occlusion"] == 1
        c = kt.CARS[fid]
        centre = kt.velo_to_rect(np.array([[c.x, c.y, c.z + c.height / 2]]))[0]
        assert car["distance_m"] == pytest.approx(np.linalg.norm(centre - [-0.06, 0, 0]), abs=0.02)
        assert all("lidar_points" not in r for r in meta["objects"][1:])  # DontCare has no 3D box
        calib = read_kitti_calib(root / "training" / "calib" / f"{fid}.txt")
        text = (root / "training" / "label_2" / f"{fid}.txt").read_text()
        box = label_box(label_records(text, "l", kt.WIDTH, kt.HEIGHT, calib)[1][0], calib)
        for level, beta in PAPER:
            _, expected = expected_level(root / "training" / "velodyne" / f"{fid}.bin",
                                         f"training/image_2/{fid}", level, beta)
            assert car["lidar_points"][level] == int(box.contains(expected.cloud.xyz).sum())
        assert car["lidar_points"]["clear"] > 100  # the car's surface is in its box
        assert meta["sample"]["frame"] == fid and "lidar_points" not in meta["sample"]
        assert meta["lidar"]["sensor"]["name"] == "hdl64e" and meta["encoding"] == "lidar:ipbasic"


def test_the_camera_fog_uses_the_scans_distances(kitti_run):
    """Koschmieder (sRGB blend, airlight 255) at the pixels the wall's points project to, at their own ray
    distance from camera 2 — the depth came from the projected scan."""
    root, out = kitti_run
    for fid in IDS:
        calib = read_kitti_calib(root / "training" / "calib" / f"{fid}.txt")
        raw = spec_scan(root / "training" / "velodyne" / f"{fid}.bin")
        wall = raw[:, 0] == 30.0
        uv, depth, ray = calib.project_velo(raw[wall, :3])
        col, row = np.floor(uv[:, 0]).astype(int), np.floor(uv[:, 1]).astype(int)
        inside = (depth > 0) & (col >= 0) & (col < kt.WIDTH) & (row >= 0) & (row < kt.HEIGHT)
        left, top, right, bottom = kt.image_box(kt.CARS[fid])
        inside &= ~((col >= left - 2) & (col <= right + 2) & (row >= top - 2) & (row <= bottom + 2))
        assert inside.sum() > 20
        for level, beta in PAPER[1:]:
            got = read_image(out / "images" / level / f"{frame(fid)}.png").astype(np.float64)
            t = np.exp(-beta * ray[inside])
            want = 150 * t + 255 * (1 - t)
            assert np.median(np.abs(got[row[inside], col[inside], 0] - want)) <= 1.0


def test_the_cross_sensor_table_counts_the_records(kitti_run):
    _, out = kitti_run
    dataset = json.loads((out / "dataset.json").read_text())
    block = dataset["lidar"]
    metas = [json.loads((out / "meta" / f"{frame(f)}.json").read_text()) for f in IDS]
    records = [r for m in metas for r in m["objects"]]
    for row in block["cross_sensor"]:
        lo, hi = row["bin"][0], math.inf if row["bin"][1] is None else row["bin"][1]
        inside = [r for r in records if r["kept"] and r.get("lidar_points") and lo <= r["distance_m"] < hi]
        seen = sum(r["lidar_points"][row["level"]] >= 5 for r in inside)
        cam = [r["visibility"][row["level"]]["visible"] for r in inside]
        assert row["objects"] == len(inside) and row["lidar_seen"] == seen
        assert row["camera_seen"] == sum(cam) and row["camera_objects"] == len(cam)
    assert block["min_points"] == 5 and block["objects_counted"] == 3
    assert block["distance_bins_m"][-1] is None  # ∞ as JSON null
    rows = cross_sensor_table(records, [k for k, _ in PAPER])
    assert [r["lidar_seen"] for r in rows] == [r["lidar_seen"] for r in block["cross_sensor"]]
    report = (out / "cross_sensor.md").read_text()
    assert "| clear |" in report and "lidar_bev.png" in report and "LiDAR outcomes per level" in report
    for name in ("lidar_bev.png", "lidar_points_vs_distance.png"):
        img = read_image(out / name)
        assert img.ndim == 3 and img.shape[0] > 100 and len(np.unique(img.reshape(-1, 3), axis=0)) > 3
    run = json.loads((out / "fogsim_run.json").read_text())["parameters"]
    assert run["lidar"]["min_points"] == 5 and run["lidar"]["sensor"] is None
    assert run["lidar_fog"]["model"] == "soft-target" and run["inputs"]["depth_from"] == "lidar"
    assert run["inputs"]["kitti_part"] == "training"


def test_heterogeneous_fog_gives_each_ray_the_cameras_beta(tmp_path):
    """``--heterogeneity``: each point's β is β × the camera's density field at its pixel (β outside the
    image), the field drawn from the sample's seed — the camera and the LiDAR see one patchy fog."""
    from fogsim.fog.engine import FogSettings, Heterogeneity
    from fogsim.lidar.formats import read_points
    from fogsim.runs import sample_seed

    root = kt.write_kitti(tmp_path / "in" / "kitti", {"000000": kt.CARS["000000"]})
    out = tmp_path / "out"
    assert fog("--kitti", root, "--lidar", "--levels", "0.06", "--heterogeneity", "0.5", "--heterogeneity-scale",
               "8", "--seed", "3", "--out", out) == 0
    key = "training/image_2/000000"
    density = FogSettings(heterogeneity=Heterogeneity(0.5, 8.0)).density((kt.HEIGHT, kt.WIDTH),
                                                                          np.random.default_rng(sample_seed(3, key)))
    cloud = read_points(root / "training" / "velodyne" / "000000.bin", "kitti")
    calib = read_kitti_calib(root / "training" / "calib" / "000000.txt")
    uv = calib.project_velo(cloud.xyz)[0]
    col, row = np.floor(uv[:, 0]), np.floor(uv[:, 1])
    inside = np.isfinite(col) & (col >= 0) & (col < kt.WIDTH) & (row >= 0) & (row < kt.HEIGHT)
    betas = np.full(len(cloud), 0.06)
    betas[inside] = 0.06 * density[row[inside].astype(int), col[inside].astype(int)].astype(np.float64)
    assert inside.sum() > 100 and betas.std() > 0.005
    expected = LidarFogger(cloud, "hdl64e")(betas, np.random.default_rng(level_seed(3, key, "beta0.06")))
    outcome, _ = read_outcomes(out / "lidar" / "beta0.06" / f"{frame('000000')}.outcomes.npz")
    np.testing.assert_array_equal(outcome, expected.outcome)
    np.testing.assert_array_equal(spec_scan(out / "lidar" / "beta0.06" / f"{frame('000000')}.bin")[:, :3],
                                  expected.cloud.xyz)
    homogeneous = LidarFogger(cloud, "hdl64e")(0.06, np.random.default_rng(level_seed(3, key, "beta0.06")))
    assert not np.array_equal(homogeneous.outcome, expected.outcome)
    meta = json.loads((out / "meta" / f"{frame('000000')}.json").read_text())
    assert meta["lidar"]["levels"]["beta0.06"]["beta"] == "per point"


def test_resume_shards_and_other_parameters(tmp_path, capsys):
    root = kt.write_kitti(tmp_path / "in" / "kitti")
    whole, parts = tmp_path / "whole", tmp_path / "parts"
    assert fog("--kitti", root, "--lidar", "--levels", "0,0.09", "--out", whole) == 0
    for i in range(2):
        assert fog("--kitti", root, "--lidar", "--levels", "0,0.09", "--shard", f"{i}/2", "--out", parts) == 0
    assert not (parts / "dataset.json").exists()
    assert fog("--finalize-only", "--out", parts) == 0
    pool = tmp_path / "pool"
    assert fog("--kitti", root, "--lidar", "--levels", "0,0.09", "--workers", "2", "--out", pool) == 0
    for sub in ("lidar", "kitti", "images", "labels"):
        assert tree_digest(whole / sub) == tree_digest(parts / sub) == tree_digest(pool / sub), sub
    capsys.readouterr()
    assert fog("--kitti", root, "--lidar", "--levels", "0,0.09", "--out", whole) == 0
    assert "3 already done" in capsys.readouterr().out
    # a frame whose meta is missing is redone, scans first (the meta is written last)
    (whole / "meta" / f"{frame('000001')}.json").unlink()
    (whole / "lidar" / "beta0.09" / f"{frame('000001')}.bin").unlink()
    assert fog("--kitti", root, "--lidar", "--levels", "0,0.09", "--out", whole) == 0
    assert tree_digest(whole / "lidar") == tree_digest(parts / "lidar")
    # other LiDAR parameters into the same folder are refused; so is adding --lidar to a camera-only run
    for extra in (("--lidar-model", "attenuation"), ("--lidar-extinction-ratio", "1.2"), ("--lidar-min-points", "3"),
                  ("--lidar-sensor", "hdl32e")):
        assert fog("--kitti", root, "--lidar", "--levels", "0,0.09", *extra, "--out", whole) == 2, extra
        assert "other parameters" in capsys.readouterr().err
    camera = tmp_path / "camera"
    assert fog("--kitti", root, "--levels", "0,0.09", "--out", camera) == 0
    assert not (camera / "lidar").exists() and "lidar" not in json.loads((camera / "dataset.json").read_text())
    assert "lidar" not in json.loads((camera / "fogsim_run.json").read_text())["parameters"]
    assert fog("--kitti", root, "--levels", "0,0.09", "--out", camera) == 0  # a run without --lidar resumes
    assert fog("--kitti", root, "--lidar", "--levels", "0,0.09", "--out", camera) == 2


def test_testing_part_and_splits(tmp_path):
    """``--kitti-part testing`` (no label_2): images and scans only, the KITTI tree under testing/;
    ``--split val`` reads ImageSets/val.txt."""
    root = kt.write_kitti(tmp_path / "in" / "kitti")
    (root / "testing").mkdir()
    for d in ("image_2", "velodyne", "calib"):
        (root / "training" / d).rename(root / "testing" / d)
    out = tmp_path / "out"
    assert fog("--kitti", root, "--kitti-part", "testing", "--lidar", "--levels", "0.06", "--out", out) == 0
    assert not (out / "meta").exists()
    for fid in IDS:
        side = json.loads((out / "beta0.06" / "testing" / "image_2" / f"{fid}.json").read_text())
        assert side["lidar"]["file"] == f"lidar/beta0.06/testing__image_2__{fid}.bin"
        pts, _, labels, _ = kt.read_kitti_frame(out / "kitti" / "beta0.06", fid, part="testing")
        assert labels is None and len(pts) == side["lidar"]["points_out"]
    root2 = kt.write_kitti(tmp_path / "in" / "k2")
    out2 = tmp_path / "out2"
    assert fog("--kitti", root2, "--split", "val", "--levels", "0.06", "--out", out2) == 0
    assert [p.name for p in (out2 / "meta").iterdir()] == [f"{frame('000002')}.json"]
    out3 = tmp_path / "out3"  # training frames without their labels: the tree's training/ without label_2
    assert fog("--kitti", root2, "--no-labels", "--lidar", "--levels", "0.06", "--out", out3) == 0
    tree = out3 / "kitti" / "beta0.06" / "training"
    assert sorted(p.name for p in tree.iterdir()) == ["calib", "image_2", "velodyne"]


# ----------------------------------------------------------------------------- Seeing Through Fog
@pytest.mark.parametrize("returns", ["strongest", "last"])
def test_stf_through_the_same_reader(tmp_path, returns):
    from dataclasses import replace

    root = tmp_path / "in" / "stf"
    calib = kt.write_stf(root, returns)
    out = tmp_path / "out"
    argv = ["--stf", root, "--stf-calib", calib, "--lidar", "--levels", "paper", "--out", out]
    assert fog(*argv, *(("--stf-returns", "last") if returns == "last" else ())) == 0
    ids = {f"{n:06d}": fid for n, fid in enumerate(kt.STF_IDS)}
    frames = {k: f"cam_stereo_left_lut__{fid}" for k, fid in ids.items()}
    assert json.loads((out / "kitti" / "frame_ids.json").read_text()) == frames
    sensor = LidarSensor.preset("hdl64-s3d")
    if returns == "last":
        sensor = replace(sensor, return_mode="last")
    for kid, fid in ids.items():
        scan = root / f"lidar_hdl64_{returns}" / f"{fid}.bin"
        meta = json.loads((out / "meta" / f"{frames[kid]}.json").read_text())
        assert meta["lidar"]["sensor"]["return_mode"] == returns and meta["lidar"]["kitti"]["id"] == kid
        for level, beta in PAPER:
            cloud, expected = expected_level(scan, f"cam_stereo_left_lut/{fid}", level, beta, sensor, "stf")
            data = (out / "lidar" / level / f"{frames[kid]}.bin").read_bytes()  # STF's own record: 5 float32
            got = np.frombuffer(data, "<f4").reshape(-1, 5)
            np.testing.assert_array_equal(got[:, :3], expected.cloud.xyz)
            np.testing.assert_array_equal(got[:, 3], expected.cloud.raw_intensity)
            np.testing.assert_array_equal(got[:, 4], expected.cloud.ring)
            if beta == 0:
                assert data == scan.read_bytes()
            pts, cal, labels, _ = kt.read_kitti_frame(out / "kitti" / level, kid)
            np.testing.assert_array_equal(pts[:, :3], expected.cloud.xyz)
            np.testing.assert_allclose(pts[:, 3], expected.cloud.raw_intensity / 255, rtol=1e-6)  # 0–1 in KITTI
            assert cal["Tr_imu_to_velo"] == [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]
            assert [f[0] for f in labels] == ["PassengerCar", "train"]
        car = meta["objects"][0]
        assert car["class"] == "PassengerCar" and car["lidar_points"]["clear"] > 100
    dataset = json.loads((out / "dataset.json").read_text())
    assert dataset["classes"][0] == "PassengerCar" and dataset["lidar"]["objects_counted"] == 2
    if returns == "last":  # the run records the return mode it fogged with
        run = json.loads((out / "fogsim_run.json").read_text())["parameters"]
        assert run["lidar_fog"]["return_mode"] == "last" and run["inputs"]["stf_returns"] == "last"


def test_usage_errors_exit_2_before_out_is_claimed(tmp_path, capsys):
    root = kt.write_kitti(tmp_path / "in" / "kitti")
    stf = tmp_path / "in" / "stf"
    kt.write_stf(stf)
    out = tmp_path / "out"
    cases = [
        (("--kitti", root, "--lidar-model", "attenuation"), "--lidar-model goes with --lidar"),
        (("--kitti", root, "--depth-dir", tmp_path), "--kitti brings its own camera"),
        (("--kitti", root, "--stf-returns", "last"), "--stf-returns goes with --stf"),
        (("--stf", stf, "--lidar"), "no calibration"),
        (("--kitti", root, "--lidar", "--lidar-sensor", "hdl99"), "unknown LiDAR sensor 'hdl99'"),
        (("--kitti", root, "--lidar", "--lidar-min-points", "0"), "--lidar-min-points"),
        (("--kitti", root, "--lidar", "--lidar-extinction-ratio", "0"), "--lidar-extinction-ratio"),
        (("--kitti", root, "--split", "test"), "ImageSets/test.txt"),
        (("--kitti", root, "--out", root / "training"), "lies inside --kitti"),
    ]
    for args, message in cases:
        argv = [*args] if "--out" in args else [*args, "--out", out]
        assert fog(*argv, "--levels", "0.06") == 2, args
        assert message in capsys.readouterr().err, args
        assert not out.exists(), args


def test_a_ray_cast_street_the_lidar_loses_far_cars_first(tmp_path):
    """The docs' fixture (:data:`kitti_tree.STREET`, ray-cast: fewer points on farther cars): per distance bin
    the share of cars the LiDAR still sees never rises with β, and at β = 0.12 it has lost every car beyond
    20 m while it still sees every car within 10 m; the clear scan sees every car."""
    root = kt.write_kitti_street(tmp_path / "in" / "kitti", kt.STREET)
    out = tmp_path / "out"
    assert fog("--kitti", root, "--lidar", "--levels", "paper", "--out", out) == 0
    rows = json.loads((out / "dataset.json").read_text())["lidar"]["cross_sensor"]
    share = {(r["level"], r["bin_label"]): r["lidar_share"] for r in rows if r["objects"]}
    bins = sorted({b for _, b in share}, key=lambda b: float(b.split("–")[0].lstrip("≥ ").split(" ")[0]))
    for b in bins:
        values = [share[(k, b)] for k, _ in PAPER]
        assert values[0] == 1.0 and all(x >= y for x, y in zip(values, values[1:])), (b, values)
    assert share[("beta0.12", "0–10 m")] == 1.0
    assert share[("beta0.12", "20–40 m")] == share[("beta0.12", "40–80 m")] == 0.0
    counts = [r["lidar_points"]["clear"] for m in (out / "meta").iterdir()
              for r in json.loads(m.read_text())["objects"]]
    assert len(counts) == 24 and min(counts) >= 5
