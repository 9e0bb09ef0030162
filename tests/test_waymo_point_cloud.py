"""Waymo range images → the point-cloud record (both returns, inclinations from the calibration), on the
hand-computed wall fixtures of tests/waymo_lidar_fixtures.py, and fogged like any scan."""
from __future__ import annotations

import math

import numpy as np
import pytest

import waymo_lidar_fixtures as fx
from fogsim.errors import InputError
from fogsim.lidar.fog import LidarFogger
from fogsim.readers.waymo.lidar_cloud import laser_point_cloud, laser_sensor
from fogsim.readers.waymo.lidar_frame import NoLidar
from fogsim.readers.waymo.lidar_v1 import parse_v1_lidar


def _two_return_scene(**kw):
    scene = fx.wall_scene(**kw)
    laser = scene.lasers[0]
    second = laser.range_image.copy()
    second[..., 0] = np.where(second[..., 0] > 0, second[..., 0] + 7.5, -1.0)  # a farther echo behind each
    second[..., 1] = 3.0  # a retro-reflector: raw intensity above 1
    laser.range_image2 = second
    laser.projection2 = laser.projection
    return scene


def test_both_returns_in_the_lidar_frame_match_the_fixture_geometry():
    scene = _two_return_scene()
    frame = parse_v1_lidar(fx.frame_msg(scene), "fixture#record 0", returns=(1, 2))
    cloud = laser_point_cloud(frame, "TOP")
    laser = scene.lasers[0]
    valid = laser.range_image[..., 0] > 0
    n = int(valid.sum())
    assert len(cloud) == 2 * n and cloud.scale == "tanh"
    assert cloud.return_index[:n].tolist() == [1] * n and cloud.return_index[n:].tolist() == [2] * n
    rows = np.nonzero(valid)[0]
    assert np.array_equal(cloud.ring[:n], rows)
    # first return, lidar frame → vehicle frame by the extrinsic = the fixture's wall points
    vehicle = cloud.select(np.arange(n)).transformed(laser.extrinsic)
    np.testing.assert_allclose(vehicle.xyz, laser.points[valid], atol=2e-4)
    np.testing.assert_allclose(vehicle.xyz[:, 0], fx.WALL_X, atol=2e-4)
    # ranges are the range image's; the second return lies 7.5 m farther along the same beam
    np.testing.assert_allclose(cloud.range_m[:n], laser.range_image[..., 0][valid], rtol=1e-6)
    np.testing.assert_allclose(cloud.range_m[n:] - cloud.range_m[:n], 7.5, atol=1e-4)
    assert np.allclose(cloud.intensity[:n], math.tanh(0.5)) and np.allclose(cloud.raw_intensity[n:], 3.0)


def test_the_sensor_reads_inclinations_and_mount_from_the_calibration():
    beams = sorted(np.random.default_rng(0).uniform(-0.3, 0.05, 12).tolist())
    scene = fx.wall_scene(beams=beams)
    frame = parse_v1_lidar(fx.frame_msg(scene), "fixture#record 0")
    sensor = laser_sensor(frame)
    assert sensor.beams == 12 and sensor.name == "waymo-top"
    np.testing.assert_allclose(sensor.inclinations_rad, beams[::-1])  # row 0 = the highest beam
    np.testing.assert_allclose(sensor.mount_pose, scene.lasers[0].extrinsic, atol=1e-9)
    cloud = laser_point_cloud(frame)
    assert np.array_equal(cloud.estimated_rings(sensor.inclinations_rad), cloud.ring)
    out = LidarFogger(cloud, sensor)(0.06, np.random.default_rng(0))
    assert sum(out.counts().values()) == len(cloud) and out.record()["sensor"] == "waymo-top"


def test_frames_without_that_lidar_or_with_bad_intensities_are_named():
    scene = fx.wall_scene()
    with pytest.raises(NoLidar):
        laser_point_cloud(parse_v1_lidar(fx.frame_msg(scene, with_lasers=False), "f#0"))
    frame = parse_v1_lidar(fx.frame_msg(scene), "f#1")
    with pytest.raises(NoLidar, match="SIDE_LEFT"):
        laser_point_cloud(frame, "SIDE_LEFT")
    with pytest.raises(ValueError, match="unknown Waymo lidar"):
        laser_point_cloud(frame, "ROOF")
    scene.lasers[0].range_image[..., 1] = -2.0
    with pytest.raises(InputError) as e:
        laser_point_cloud(parse_v1_lidar(fx.frame_msg(scene), "f#2"))
    assert str(e.value).startswith("f#2 TOP") and "outside the declared tanh" in str(e.value)
