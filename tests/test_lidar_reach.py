"""Points per object against distance beside real KITTI's cars (fogsim.lidar.reach): the band is the
measured cars' n·R² and agrees with the S2's geometry; a render's meta is read into (class, distance,
points); the table's shares and the picture follow the rows given."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fogsim.lidar.reach import (
    CLASS_COLOURS,
    KITTI_CAR_BAND,
    KITTI_CAR_POINTS,
    KITTI_HDL64E_STEPS_DEG,
    geometric_points,
    kitti_car_band,
    object_points_by_distance,
    reach_picture,
    reach_table,
)


def test_the_band_holds_the_measured_cars_and_is_the_s2s_geometry():
    lo14, hi14 = kitti_car_band(14.0)
    lo33, hi33 = kitti_car_band(33.0)
    assert hi14 == pytest.approx(660) and lo33 == pytest.approx(55)
    for r, n, _ in KITTI_CAR_POINTS:
        lo, hi = kitti_car_band(r)
        assert lo - 1e-9 <= n <= hi + 1e-9
    # a car's rear (1.8 m × 1.26 m) every ray returned at the S2's steps: the band's top; half of it: its bottom
    top = geometric_points(1.8 * 1.26, 14.0, *KITTI_HDL64E_STEPS_DEG)
    assert top == pytest.approx(660, rel=0.03)
    assert KITTI_CAR_BAND[0] / KITTI_CAR_BAND[1] == pytest.approx(0.46, abs=0.01)
    assert geometric_points(2.0, 20.0, 0.2, 0.4) == pytest.approx(4 * geometric_points(2.0, 40.0, 0.2, 0.4))


def write_meta(root, frame, objects):
    (root / "meta").mkdir(parents=True, exist_ok=True)
    (root / "meta" / f"{frame:06d}.json").write_text(json.dumps({"lidar": {"objects": objects}}))


def obj(cls, centre, points, box=True):
    o = {"id": 1, "class": cls, "lidar_points": {"clear": points, "beta0.06": points // 2}}
    if box:
        o["box3d"] = {"lidar": {"centre_m": centre, "size_lwh_m": [4, 2, 1.5], "yaw": 0.0}}
    return o


def test_a_renders_objects_by_distance_and_the_table(tmp_path):
    write_meta(tmp_path, 0, [obj("car", [14.0, 0.0, -1.0], 2000), obj("car", [0.0, 14.0, -1.0], 400),
                             obj("pedestrian", [3.0, 4.0, 0.0], 50), obj("car", [5, 5, 0], 9, box=False)])
    write_meta(tmp_path, 1, [obj("car", [33.0, 0.0, 0.0], 10), obj("car", [-20.0, 0.0, 0.0], 300)])
    rows = object_points_by_distance(tmp_path)
    assert len(rows) == 5 and ("pedestrian", pytest.approx(5.0), 50) in rows
    assert [n for _, _, n in object_points_by_distance(tmp_path, "beta0.06")] == [1000, 200, 25, 5, 150]
    table = reach_table(rows)
    assert [r["class"] for r in table][0] == "car"  # cars first
    ten = next(r for r in table if r["class"] == "car" and r["bin"] == [10.0, 20.0])
    assert ten["objects"] == 2 and ten["median_points"] == 1200  # 14.036 m: band 304–657
    assert ten["above"] == 0.5 and ten["inside"] == 0.5 and ten["below"] == 0.0
    thirty = next(r for r in table if r["class"] == "car" and r["bin"] == [30.0, 40.0])
    assert thirty["below"] == 1.0
    assert "below" not in next(r for r in table if r["class"] == "pedestrian")


def test_the_picture_draws_the_band_the_kitti_cars_and_the_renders_cars():
    rows = [("car", 14.0, 700), ("car", 50.0, 20), ("pedestrian", 20.0, 30)]
    img = reach_picture(rows, size=(900, 540))
    assert img.shape == (540, 900, 3) and img.dtype == np.uint8
    colours = {tuple(c) for c in img.reshape(-1, 3)}
    assert (255, 222, 206) in colours and CLASS_COLOURS["car"] in colours and (0, 0, 0) in colours
    assert CLASS_COLOURS["pedestrian"] in colours
    assert CLASS_COLOURS["pedestrian"] not in {tuple(c) for c in reach_picture(rows[:2]).reshape(-1, 3)}
