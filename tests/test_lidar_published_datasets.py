"""The published LiDAR fog models through ``fogsim fog --kitti/--stf --lidar`` end to end: each level's scan is
the model's for the documented seed (the trees written from the formats' specs, :mod:`kitti_tree`), the run
record and every level's record name the model, stf2020's added points are counted and appended, and the
cross-sensor report names the model."""
from __future__ import annotations

import json

import numpy as np

import kitti_tree as kt
from fogsim.cli import main
from fogsim.lidar.fog import LidarFogger
from fogsim.lidar.formats import read_points
from fogsim.lidar.outcome_file import read_outcomes
from fogsim.runs import level_seed

LEVELS = (("clear", 0.0), ("beta0.06", 0.06), ("beta0.12", 0.12))


def fog(*args) -> int:
    return main(["fog", "--quiet", *map(str, args)])


def test_kitti_with_hahner2021(tmp_path):
    root = kt.write_kitti(tmp_path / "in" / "kitti")
    out = tmp_path / "out"
    assert fog("--kitti", root, "--lidar", "--lidar-model", "hahner2021", "--levels", "0,0.06,0.12", "--out", out) == 0
    run = json.loads((out / "fogsim_run.json").read_text())["parameters"]
    assert run["lidar_fog"]["model"] == "hahner2021" and run["lidar_fog"]["hahner_variant"] == "batch"
    for fid in sorted(kt.CARS):
        key, frame = f"training/image_2/{fid}", f"training__image_2__{fid}"
        cloud = read_points(root / "training" / "velodyne" / f"{fid}.bin", "kitti")
        meta = json.loads((out / "meta" / f"{frame}.json").read_text())
        for level, beta in LEVELS:
            want = LidarFogger(cloud, "hdl64e", {"model": "hahner2021"})(
                beta, np.random.default_rng(level_seed(0, key, level)))
            got = read_points(out / "lidar" / level / f"{frame}.bin", "kitti")
            np.testing.assert_array_equal(got.xyz, want.cloud.xyz)
            np.testing.assert_array_equal(got.raw_intensity, want.cloud.raw_intensity)
            rec = meta["lidar"]["levels"][level]
            assert rec["model"] == "hahner2021" and rec["outcomes"]["lost"] == 0 and len(got) == len(cloud)
    dataset = json.loads((out / "dataset.json").read_text())
    assert dataset["lidar"]["lidar_fog_models"] == ["hahner2021 (batch)"]
    assert "LiDAR fog model: hahner2021 (batch)" in (out / "cross_sensor.md").read_text()


def test_stf_with_stf2020_counts_its_added_points(tmp_path):
    root = tmp_path / "in" / "stf"
    calib = kt.write_stf(root)
    out = tmp_path / "out"
    assert fog("--stf", root, "--stf-calib", calib, "--lidar", "--lidar-model", "stf2020", "--levels", "0,0.06,0.12",
               "--out", out) == 0
    added = 0
    for n, fid in enumerate(kt.STF_IDS):
        frame = f"cam_stereo_left_lut__{fid}"
        cloud = read_points(root / "lidar_hdl64_strongest" / f"{fid}.bin", "stf")
        meta = json.loads((out / "meta" / f"{frame}.json").read_text())
        for level, beta in LEVELS:
            want = LidarFogger(cloud, "hdl64-s3d", {"model": "stf2020"})(
                beta, np.random.default_rng(level_seed(0, f"cam_stereo_left_lut/{fid}", level)))
            got = read_points(out / "lidar" / level / f"{frame}.bin", "stf")
            np.testing.assert_array_equal(got.xyz, want.cloud.xyz)
            outcome, index = read_outcomes(out / "lidar" / level / f"{frame}.outcomes.npz")
            rec = meta["lidar"]["levels"][level]
            assert rec["model"] == "stf2020" and rec["added_points"] == want.added_points
            assert len(got) == int((index >= 0).sum()) + rec["empty_ray_clutter"] + rec["added_points"]
            added += rec["added_points"]
    assert added > 0
    dataset = json.loads((out / "dataset.json").read_text())
    assert dataset["lidar"]["lidar_fog_models"] == ["stf2020"] and (out / "lidar_bev.png").is_file()
    assert "bev_missing" not in dataset["lidar"]  # the added points are counted when the scans are read back
