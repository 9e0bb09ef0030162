"""Camera geometry, disparity coding and the paper-compatible decoding, by hand."""
import json
import math

import numpy as np
import pytest

from fogsim.camera import (
    Intrinsics,
    decode_disparity_png,
    depth_to_disparity,
    disparity_to_depth,
    encode_disparity_png,
    planar_to_ray,
)
from fogsim.errors import InputError
from fogsim.readers.cityscapes import load_cityscapes_camera
from fogsim.readers.paper import paper_distance_from_8bit


def test_ray_distance_at_corners_is_analytic():
    K = Intrinsics(fx=500.0, fy=450.0, cx=319.5, cy=239.5, width=640, height=480)
    Z = np.full((480, 640), 10.0, np.float32)
    ray = planar_to_ray(Z, K)
    for (v, u) in [(0, 0), (0, 639), (479, 0), (479, 639)]:
        X, Y = (u - K.cx) / K.fx * 10.0, (v - K.cy) / K.fy * 10.0
        assert ray[v, u] == pytest.approx(math.sqrt(X * X + Y * Y + 100.0), rel=1e-6)
    # the principal point is not a pixel centre here; the 4 around it are symmetric
    assert ray[239, 319] == pytest.approx(ray[240, 320], rel=1e-7)
    assert ray.min() > 10.0


def test_ray_keeps_inf_and_zero_and_checks_shape():
    K = Intrinsics.from_hfov(90, 4, 3)
    Z = np.array([[0, np.inf, 1, 1]] * 3, np.float32)
    ray = planar_to_ray(Z, K)
    assert ray[0, 0] == 0 and np.isinf(ray[0, 1])
    with pytest.raises(ValueError, match="4×3"):
        planar_to_ray(np.ones((4, 3), np.float32), K)


def test_hfov_and_scaling():
    K = Intrinsics.from_hfov(90.0, 200, 100)
    assert K.fx == pytest.approx(100.0) and K.cx == 99.5 and K.cy == 49.5
    K2 = K.scaled(400, 200)
    assert K2.fx == pytest.approx(200.0) and K2.cx == pytest.approx(199.5) and K2.cy == pytest.approx(99.5)
    assert Intrinsics.from_dict(K.to_dict()) == K


def test_disparity_16bit_round_trip():
    rng = np.random.default_rng(3)
    d = rng.uniform(0.1, 200, (30, 40)).astype(np.float32)
    d[0, :5] = 0
    p = encode_disparity_png(d)
    assert p.dtype == np.uint16 and np.all(p[0, :5] == 0)
    back = decode_disparity_png(p)
    assert np.abs(back - d).max() <= 1 / 512 + 1e-6  # quantisation step 1/256
    assert np.all(back[0, :5] == 0)
    assert np.array_equal(encode_disparity_png(back), p)  # exact on the grid


def test_disparity_depth_conversion():
    d = np.array([[0.0, 1.0, 47.28]], np.float32)
    z = disparity_to_depth(d, 0.209, 2262.0)
    assert z[0, 0] == 0 and z[0, 1] == pytest.approx(0.209 * 2262) and z[0, 2] == pytest.approx(10.0, rel=1e-3)
    back = depth_to_disparity(np.array([[np.inf, 10.0, 0.0]], np.float32), 0.209, 2262.0)
    assert back[0, 0] == 0 and back[0, 1] == pytest.approx(47.2758, rel=1e-4) and back[0, 2] == 0


def test_paper_decoding_reproduces_reference_constant():
    raw = np.array([[0, 1, 2, 126]], np.uint8)
    dist = paper_distance_from_8bit(raw)
    # reference: p < 2 → 32000 / 100; else (22 * 5.6) / ((p - 1) / 256) / 100
    expect = [320.0, 320.0, 22 * 5.6 / (1 / 256) / 100, 22 * 5.6 / (125 / 256) / 100]
    assert np.allclose(dist, [expect], rtol=1e-6)


def test_cityscapes_camera_json(tmp_path):
    path = tmp_path / "cam.json"
    path.write_text(json.dumps({"extrinsic": {"baseline": 0.209313}, "intrinsic": {
        "fx": 2262.52, "fy": 2265.30, "u0": 1096.98, "v0": 513.137}}))
    cam = load_cityscapes_camera(path, 2048, 1024)
    assert cam.baseline == pytest.approx(0.209313) and cam.intrinsics.cy == pytest.approx(513.137)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"intrinsic": {"fx": 1}}))
    with pytest.raises(InputError, match="bad.json"):
        load_cityscapes_camera(bad, 2048, 1024)
    with pytest.raises(InputError, match="missing.json.*not found"):
        load_cityscapes_camera(tmp_path / "missing.json", 2048, 1024)


def test_cityscapes_camera_json_round_trip(tmp_path):
    from fogsim.camera import StereoCamera

    cam = StereoCamera(0.209, Intrinsics(283.0, 283.0, 127.5, 63.5, 256, 128))
    path = tmp_path / "x_camera.json"
    path.write_text(json.dumps(cam.to_cityscapes_json()))
    assert load_cityscapes_camera(path, 256, 128) == cam
