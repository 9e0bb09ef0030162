"""Stereo matching on pairs with known disparity, and the rectified right camera."""
import numpy as np
import pytest

from fogsim.camera import Intrinsics, StereoCamera
from fogsim.depth.stereo import (
    SGBMParams,
    disparity_range,
    hole_fraction,
    right_world_to_camera,
    sgbm_disparity,
    wls_disparity,
)
from fogsim.scene.pose import camera_to_world, world_to_camera


def test_sgbm_recovers_a_known_shift():
    rng = np.random.default_rng(0)
    h, w, shift = 96, 160, 12
    texture = (rng.random((h, w + shift)) * 255).astype(np.uint8)
    left = np.repeat(texture[:, :w, None], 3, axis=2)
    right = np.repeat(texture[:, shift:, None], 3, axis=2)  # x_right = x_left − d
    cam = StereoCamera(0.2, Intrinsics(100.0, 100.0, 79.5, 47.5, w, h))
    d = sgbm_disparity(left, right, cam, SGBMParams(num_disparities=32))
    valid = d > 0
    assert np.median(np.abs(d[valid] - shift)) < 0.25
    assert not valid[:, :32].any()  # the left band (x < numDisparities) has no match
    assert 0.15 < hole_fraction(d) < 0.5


def test_textureless_surface_is_a_hole():
    flat = np.full((64, 128, 3), 128, np.uint8)
    d = sgbm_disparity(flat, flat, StereoCamera(0.2, Intrinsics(100.0, 100.0, 63.5, 31.5, 128, 64)),
                       SGBMParams(num_disparities=16))
    assert hole_fraction(d) > 0.95


def test_disparity_range_covers_the_closest_depth():
    n = disparity_range(0.209, 2262.0, 2.5)
    assert n % 16 == 0 and n >= 0.209 * 2262 / 2.5 > n - 16


def test_right_camera_sees_points_shifted_by_baseline_fx_over_z():
    K = Intrinsics.from_hfov(60.0, 200, 100)
    left = world_to_camera(camera_to_world([1.0, 2.0, 1.5], yaw_deg=7.0, pitch_deg=-2.0))
    right = right_world_to_camera(left, 0.3)
    p = np.array([3.0, 25.0, 2.0, 1.0])
    pl, pr = left @ p, right @ p
    ul, ur = K.fx * pl[0] / pl[2] + K.cx, K.fx * pr[0] / pr[2] + K.cx
    assert pl[2] == pytest.approx(pr[2]) and pl[1] == pytest.approx(pr[1])
    assert ul - ur == pytest.approx(0.3 * K.fx / pl[2])


def test_wls_keeps_the_disparities_and_smooths():
    """A near square in front of a far textured wall: WLS agrees with the known disparities.
    (OpenCV's WLS leaves L/R-inconsistent occlusions undefined, so it is no hole fill by itself.)"""
    rng = np.random.default_rng(1)
    h, w, far, near = 96, 192, 8, 24
    wall = (rng.random((h, w + far)) * 255).astype(np.uint8)
    box = (rng.random((40, 60 + near)) * 255).astype(np.uint8)
    left, right = wall[:, :w].copy(), wall[:, far:far + w].copy()
    left[28:68, 90:150] = box[:, :60]
    right[28:68, 90 - near:150 - near] = box[:, :60]
    to_rgb = lambda g: np.repeat(g[:, :, None], 3, axis=2)  # noqa: E731
    cam = StereoCamera(0.2, Intrinsics(100.0, 100.0, 95.5, 47.5, w, h))
    p = SGBMParams(num_disparities=32)
    sgbm = sgbm_disparity(to_rgb(left), to_rgb(right), cam, p)
    dense = wls_disparity(to_rgb(left), to_rgb(right), cam, p)
    for d in (sgbm, dense):
        assert abs(np.median(d[40:60, 100:140]) - near) < 0.5 and abs(np.median(d[5:20, 60:80]) - far) < 0.5
    assert 0 < hole_fraction(dense) < 0.5 and not (dense[:, :32] > 0).any()
