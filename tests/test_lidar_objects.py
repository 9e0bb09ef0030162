"""Per-object LiDAR points per fog level, the cross-sensor table (LiDAR beside camera), and the pictures."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fogsim.lidar.boxes import Box3D, points_in_box, points_in_boxes
from fogsim.lidar.fog import CLUTTER, LidarFogger
from fogsim.lidar.objects import attach_lidar_points, cross_sensor_table, object_points, table_markdown
from fogsim.lidar.pictures import OUTCOME_COLOURS, bev_image, bev_levels, points_vs_distance, write_png
from fogsim.lidar.points import PointCloud


def test_points_in_an_oriented_box():
    box = Box3D.from_yaw([10, 0, 0], 4.0, 2.0, 1.5, math.radians(30))
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    along = np.array([[10 + 1.9 * c, 1.9 * s, 0.7], [10 + 2.1 * c, 2.1 * s, 0], [10 - 0.9 * s, 0.9 * c, 0],
                      [10 - 1.1 * s, 1.1 * c, 0], [10, 0, 0.76]])
    assert box.contains(along).tolist() == [True, False, True, False, False]
    assert points_in_box(along, box) == 2 and points_in_boxes(along, [box, box]).tolist() == [2, 2]
    assert len(box.corners()) == 8 and np.allclose(box.corners().mean(0), [10, 0, 0])


def _street():
    """Two cars as point blocks: a near bright one (10 m) and a far dark one (35 m), 60 points each."""
    g = np.stack(np.meshgrid(np.linspace(-1.5, 1.5, 6), np.linspace(-0.6, 0.6, 5), [0.0, 0.5]), -1).reshape(-1, 3)
    near, far = g + [10, 0, 0], g + [35, 3, 0]
    xyz = np.concatenate([near, far]).astype(np.float32)
    inten = np.concatenate([np.full(len(g), 0.9 / 2.55), np.full(len(g), 0.1 / 2.55)]).astype(np.float32)
    boxes = [Box3D.from_yaw([10, 0, 0.25], 3.4, 1.6, 1.0, 0.0), Box3D.from_yaw([35, 3, 0.25], 3.4, 1.6, 1.0, 0.0), None]
    return PointCloud.from_raw(xyz, inten, "0-1", "street"), boxes, len(g)


def test_points_per_object_per_level_and_the_cross_sensor_table():
    scan, boxes, n = _street()
    # the echo fluctuation off (σ = 0): the thresholds alone decide, so every point of a car shares its fate
    fogger = LidarFogger(scan, "hdl64e", {"calibration": {"fluctuation_sigma": 0.0,
                                                          "sources": {"fluctuation_sigma": "assumed: off"}}})
    levels = {"clear": scan, "b0.03": fogger(0.03, np.random.default_rng(0)).cloud,
              "b0.12": fogger(0.12, np.random.default_rng(0)).cloud}
    counts = object_points(levels, boxes)
    assert counts[2] is None and counts[0] == {"clear": n, "b0.03": n, "b0.12": n}  # the near bright car stays
    fluctuating = object_points({"b0.12": LidarFogger(scan, "hdl64e")(0.12, np.random.default_rng(0)).cloud}, boxes)
    assert 0.75 * n < fluctuating[0]["b0.12"] < n and fluctuating[1]["b0.12"] == 0  # a few lose to the fog's echo
    assert counts[1]["clear"] == n and counts[1]["b0.12"] == 0  # the far dark one is gone
    records = [{"kept": True, "distance_m": 10.0, "visibility": {"clear": {"visible": True}, "b0.03": {"visible": True},
                                                                 "b0.12": {"visible": True}}},
               {"kept": True, "distance_m": 35.0, "visibility": {"clear": {"visible": True}, "b0.03": {"visible": True},
                                                                 "b0.12": {"visible": False}}},
               {"kept": False, "distance_m": None}]
    attach_lidar_points(records, levels, boxes)
    assert "lidar_points" not in records[2]
    rows = cross_sensor_table(records, list(levels), bins=(0, 20, 50), min_points=5)
    by = {(r["level"], r["bin"][0]): r for r in rows}
    assert by[("clear", 0)]["lidar_share"] == 1.0 and by[("clear", 20)]["camera_share"] == 1.0
    assert by[("b0.12", 20)]["lidar_seen"] == 0 and by[("b0.12", 20)]["camera_share"] == 0.0
    assert by[("b0.12", 0)]["objects"] == 1 and by[("b0.12", 0)]["lidar_share"] == 1.0
    assert len(rows) == 3 * 2 and "| b0.12 |" in table_markdown(rows)
    with pytest.raises(ValueError, match="increasing"):
        cross_sensor_table(records, ["clear"], bins=(0, 0))


def test_the_birds_eye_views_and_the_points_per_distance_picture(tmp_path):
    scan, boxes, _ = _street()
    fogged = LidarFogger(scan, "hdl64e")(0.12, np.random.default_rng(0))
    assert (fogged.outcome == CLUTTER).any()
    img = bev_image(scan, fogged, extent_m=40, px_per_m=4, boxes=boxes)
    assert img.shape == (320, 320, 3) and img.dtype == np.uint8
    colours = {tuple(c) for c in img.reshape(-1, 3)}
    assert OUTCOME_COLOURS[CLUTTER] in colours  # the fog echo, drawn near the sensor
    near = img[150:170, 150:170].reshape(-1, 3)
    assert any(tuple(c) == OUTCOME_COLOURS[CLUTTER] for c in near)
    strip_img = bev_levels(scan, {"clear": None, "b0.12": fogged}, width=200, extent_m=40, px_per_m=4)
    assert strip_img.shape[1] > 400
    records = [{"kept": True, "distance_m": 10.0, "lidar_points": {"clear": 60, "b0.12": 60}},
               {"kept": True, "distance_m": 35.0, "lidar_points": {"clear": 60, "b0.12": 0}}]
    pic = points_vs_distance(records, ["clear", "b0.12"])
    assert pic.shape == (400, 640, 3) and (pic != 255).any()
    write_png(tmp_path / "bev.png", strip_img)
    assert (tmp_path / "bev.png").read_bytes()[:4] == b"\x89PNG"
