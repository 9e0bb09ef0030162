"""The camera model after the fog (fogsim.sensor), checked against its formulas.

Vignetting against cos⁴θ from the ray angle; noise mean and variance against
s/full_well + (read/full_well)²; distortion against OpenCV's forward model (projectPoints) and
cv2.undistortPoints round trips; a blob lands where the forward model puts it; masks keep exact
values; exposure doubles linear light per EV; JPEG is OpenCV's; the identity sensor changes nothing.
"""
import math

import cv2
import numpy as np
import pytest

from fogsim.camera import Intrinsics
from fogsim.colour import srgb_to_linear
from fogsim.sensor import (
    Sensor,
    apply_sensor,
    distort_nearest,
    distort_points,
    distortion_maps,
    jpeg,
    shot_read_noise,
    undistort_points,
    vignette_gain,
)

K = Intrinsics(fx=80.0, fy=80.0, cx=63.5, cy=47.5, width=128, height=96)
COEFFS = (-0.18, 0.04, 0.001, -0.002, 0.0)


def test_vignetting_is_cos_to_the_power():
    g = vignette_gain(K, 4.0)
    assert g.shape == (96, 128) and g.max() <= 1.0
    for u, v in ((63.5, 47.5), (0, 0), (127, 20), (40, 95)):
        theta = math.atan(math.hypot((u - K.cx) / K.fx, (v - K.cy) / K.fy))
        if float(u).is_integer() and float(v).is_integer():
            assert g[int(v), int(u)] == pytest.approx(math.cos(theta) ** 4, rel=1e-6)
    assert g[0, 0] < 0.6 and np.all(vignette_gain(K, 0.0) == 1.0)
    assert vignette_gain(K, 2.0)[0, 0] == pytest.approx(math.sqrt(g[0, 0]), rel=1e-6)


@pytest.mark.parametrize("s, full_well, read", [(0.25, 500.0, 3.0), (0.02, 2000.0, 10.0), (0.7, 100.0, 0.0)])
def test_noise_mean_and_variance(s, full_well, read):
    flat = np.full((400, 500), s, np.float32)
    out = shot_read_noise(flat, full_well, read, np.random.default_rng(1))
    expected = s / full_well + (read / full_well) ** 2
    assert out.mean() == pytest.approx(s, abs=4 * math.sqrt(expected / flat.size))
    assert out.var() == pytest.approx(expected, rel=0.03)  # 200 000 samples: σ of the estimate ≈ 0.3 %
    again = shot_read_noise(flat, full_well, read, np.random.default_rng(1))
    assert np.array_equal(out, again)
    assert not np.array_equal(out, shot_read_noise(flat, full_well, read, np.random.default_rng(2)))


def test_distortion_round_trips_with_undistort_points():
    rng = np.random.default_rng(0)
    uv = np.column_stack([rng.uniform(10, 118, 50), rng.uniform(8, 88, 50)])
    d = distort_points(uv, K, COEFFS)
    Km = np.array([[K.fx, 0, K.cx], [0, K.fy, K.cy], [0, 0, 1]])
    back = undistort_points(d.reshape(-1, 1, 2), Km, COEFFS).reshape(-1, 2)  # OpenCV 4 and 5
    assert np.abs(back - uv).max() < 1e-3
    # the forward model by hand (OpenCV's radial-tangential formula)
    x, y = (uv[:, 0] - K.cx) / K.fx, (uv[:, 1] - K.cy) / K.fy
    k1, k2, p1, p2, k3 = COEFFS
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3
    xd, yd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x), y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    assert np.abs(d - np.column_stack([K.fx * xd + K.cx, K.fy * yd + K.cy])).max() < 1e-6
    # the remap table: the distorted pixel q sees the pinhole pixel map[q], which distorts back to q
    mx, my = distortion_maps(K, COEFFS)
    q = np.array([[5, 7], [120, 90], [64, 48], [30, 80]])
    src = np.column_stack([mx[q[:, 1], q[:, 0]], my[q[:, 1], q[:, 0]]])
    assert np.abs(distort_points(src, K, COEFFS) - q).max() < 1e-3
    assert np.abs(src[2] - q[2]).max() < 0.1  # the centre barely moves


def test_a_blob_lands_where_the_lens_puts_it():
    p = np.array([100.3, 20.7])  # near a corner: barrel distortion pulls it toward the centre
    v, u = np.mgrid[0:96, 0:128].astype(np.float32)
    blob = np.exp(-((u - p[0]) ** 2 + (v - p[1]) ** 2) / (2 * 1.5 ** 2))
    img = np.repeat((blob * 255).round().astype(np.uint8)[..., None], 3, axis=2)
    out = apply_sensor(img, K, Sensor(distortion=COEFFS), np.random.default_rng(0))
    w = srgb_to_linear(out[..., 0] / 255.0)
    w = np.where(w > 0.05 * w.max(), w, 0)
    centroid = np.array([(w * u).sum() / w.sum(), (w * v).sum() / w.sum()])
    target = distort_points(p, K, COEFFS)[0]
    assert np.linalg.norm(centroid - target) < 0.2 and np.linalg.norm(target - p) > 2


def test_masks_and_depth_keep_exact_values():
    mask = np.zeros((96, 128), np.uint16)
    mask[30:60, 20:50], mask[10:40, 90:125] = 7, 300
    depth = np.full((96, 128), 12.5, np.float32)
    depth[mask == 300] = 40.25
    dm = distort_nearest(mask, K, COEFFS, 0)
    dd = distort_nearest(depth, K, COEFFS, np.inf)
    assert set(np.unique(dm)) <= {0, 7, 300} and set(np.unique(dd[np.isfinite(dd)])) <= {12.5, 40.25}
    assert np.array_equal(dm == 300, dd == np.float32(40.25))
    assert not np.array_equal(dm, mask)
    assert np.isinf(dd[0, 0]) and dm[0, 0] == 0  # barrel: the corner sees outside the render


def test_exposure_jpeg_and_identity():
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (96, 128, 3), dtype=np.uint8)
    assert np.array_equal(apply_sensor(img, K, Sensor(), rng), img)
    grey = np.full((96, 128, 3), 100, np.uint8)
    up = apply_sensor(grey, K, Sensor(exposure_ev=1.0), rng)
    assert srgb_to_linear(up[0, 0, 0] / 255.0) == pytest.approx(2 * srgb_to_linear(100 / 255.0), rel=0.01)
    ok, buf = cv2.imencode(".jpg", img[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 30])
    assert np.array_equal(jpeg(img, 30), cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1])
    err = {q: np.abs(apply_sensor(img, K, Sensor(jpeg_quality=q), rng).astype(int) - img).mean() for q in (95, 20)}
    assert 0 < err[95] < err[20]


def test_from_dict_defaults_and_errors():
    s = Sensor.from_dict({"distortion": [-0.1], "noise": {}, "vignetting": 4})
    assert s.distortion == (-0.1, 0.0, 0.0, 0.0, 0.0) and s.full_well_e == 1000.0 and s.read_noise_e == 2.0
    assert Sensor.from_dict({}) == Sensor() and not Sensor().distorts
    with pytest.raises(ValueError, match="sensor.jpeg_quality"):
        Sensor.from_dict({"jpeg_quality": 0})
    with pytest.raises(ValueError, match="sensor.distortion"):
        Sensor.from_dict({"distortion": [0, 0, 0, 0, 0, 0]})


# ----------------------------------------------------------------------------- in a dataset frame
def test_commit_frame_with_a_sensor(tmp_path):
    """commit_frame with distortion, vignetting, noise and JPEG: the mask and depth written are
    the pinhole ones resampled through the lens (exact values), the YOLO labels are the tight
    boxes of that distorted mask (recomputed by brute force), every level's image differs from
    the pinhole commit, the noise is seeded (same frame → same bytes), meta records the model."""
    from dataclasses import replace

    from conftest import expected_yolo_lines
    from fogsim.dataset.layout import DatasetLayout
    from fogsim.io.depth_files import read_depth_file, read_uint16_map
    from fogsim.io.images import read_image
    from fogsim.render.frame import DescribedFrame, FramePasses, commit_frame, describe_frame, scene_meshes
    from fogsim.render.preset import load_render_preset
    from fogsim.render.silhouette import silhouette_areas
    from fogsim.scene.classes import LABELLED
    from test_frame_commit import H, W, passes

    base = load_render_preset("default", frames=1, resolution=f"{W}x{H}")
    desc = describe_frame(base, 0)
    meshes = scene_meshes(desc)
    Kf = Intrinsics.from_dict(desc["camera"]["intrinsics"])
    labelled = {o["id"]: [(v, f) for v, f, _ in meshes[o["id"]]] for o in desc["objects"] if o["class"] in LABELLED}
    sil = silhouette_areas(labelled, Kf, np.asarray(desc["camera"]["world_to_camera"]))
    rgb, depth, mask, rects, _ = passes(desc, sil, Kf)
    spec = {"distortion": [-0.25, 0.05], "vignetting": 4, "noise": {"full_well_e": 800, "read_noise_e": 3},
            "jpeg_quality": 85}
    cfg = replace(base, sensor=spec)
    assert cfg.to_dict()["sensor"] == spec and "sensor" not in base.to_dict()
    out = {}
    for name, c in (("pinhole", base), ("sensor", cfg), ("again", cfg)):
        layout = DatasetLayout(tmp_path / name)
        meta = commit_frame(layout, c, DescribedFrame(0, desc, meshes), FramePasses(rgb, depth, mask))
        out[name] = (layout, meta)
    layout, meta = out["sensor"]
    coeffs = (-0.25, 0.05, 0.0, 0.0, 0.0)
    dmask = distort_nearest(mask, Kf, coeffs, 0)
    assert np.array_equal(read_uint16_map(layout.mask("000000")), dmask)
    assert np.array_equal(read_depth_file(layout.depth("000000")), distort_nearest(depth, Kf, coeffs, np.inf))
    visible = {r["id"]: r["visible_fraction"] for r in meta["objects"]}
    lines = expected_yolo_lines(dmask, desc["objects"], visible, 25, 0.1)
    assert lines and lines != expected_yolo_lines(mask, desc["objects"], visible, 25, 0.1)
    for lv in cfg.levels:
        assert layout.label(lv.key, "000000").read_text() == "".join(x + "\n" for x in lines)
        a = read_image(layout.image(lv.key, "000000"))
        assert np.abs(a.astype(int) - read_image(out["pinhole"][0].image(lv.key, "000000"))).mean() > 2
        assert np.array_equal(a, read_image(out["again"][0].image(lv.key, "000000")))
    s = meta["sensor"]
    assert s["settings"] == spec and s["distortion"]["coefficients"] == list(coeffs)
    assert s["noise"]["full_well_e"] == 800 and s["jpeg_quality"] == 85
    assert out["pinhole"][1]["sensor"] is None


def test_sensor_in_a_preset_file(tmp_path):
    import json

    from fogsim.errors import InputError
    from fogsim.presets import presets_dir
    from fogsim.render.preset import load_render_preset

    default = json.loads((presets_dir() / "default.json").read_text())
    path = tmp_path / "p.json"
    path.write_text(json.dumps(default | {"sensor": {"vignetting": 4, "jpeg_quality": 70}}))
    assert load_render_preset(str(path)).sensor == {"vignetting": 4, "jpeg_quality": 70}
    for bad, message in (({"jpeg_quality": 101}, "sensor.jpeg_quality"), ({"iso": 100}, "unknown key"),
                         ({"distortion": [2]}, "sensor.distortion"), ({"noise": {"full_well_e": 0}}, "full_well_e")):
        path.write_text(json.dumps(default | {"sensor": bad}))
        with pytest.raises(InputError) as err:
            load_render_preset(str(path))
        assert str(path) in str(err.value) and message in str(err.value)


# ----------------------------------------------------------------------------- motion blur
def test_frame_motion_moves_the_camera_forward_and_the_driving_vehicles():
    from fogsim.render.frame import describe_frame
    from fogsim.render.preset import load_render_preset
    from fogsim.scene.lights import VEHICLE_CLASSES, is_driving
    from fogsim.scene.motion import frame_motion

    desc = describe_frame(load_render_preset("default"), 0)
    assert frame_motion(None, desc, 5) is None
    spec = {"shutter_s": 0.02, "ego_speed_mps": [10, 12], "traffic_speed_mps": [6, 6]}
    m = frame_motion(spec, desc, 5)
    assert m == frame_motion(spec, desc, 5) and m != frame_motion(spec, desc, 6)
    w2c = np.asarray(desc["camera"]["world_to_camera"])
    axis = w2c[2, :3]  # the optical axis in world coordinates
    v = np.asarray(m["camera_velocity_mps"])
    assert 10 <= np.linalg.norm(v) <= 12 and v[2] == 0 and v @ axis > 0.9 * np.linalg.norm(v)
    driving = {o["id"] for o in desc["objects"] if o["class"] in VEHICLE_CLASSES and is_driving(o, desc["street"])}
    assert driving and set(m["object_velocity_mps"]) == driving
    for oid, vel in m["object_velocity_mps"].items():
        heading = np.asarray(next(o for o in desc["objects"] if o["id"] == oid)["transform"])[:3, 1]
        assert np.linalg.norm(vel) == pytest.approx(6.0) and np.dot(vel, heading) > 0.99 * 6.0


@pytest.mark.blender
@pytest.mark.parametrize("kind", ["bpy", "blender"])
def test_motion_blur_blurs_the_image_not_the_labels(kind, tmp_path):
    """A render with sensor.motion_blur and one without, same seed: identical labels, masks and
    depth (the sharp render's), a different image; meta records the velocities."""
    import json

    from fogsim.io.images import read_image
    from fogsim.presets import presets_dir
    from test_blender import dataset_digest, render_dataset

    preset = tmp_path / "blur.json"
    default = json.loads((presets_dir() / "default.json").read_text())
    preset.write_text(json.dumps(default | {"sensor": {"motion_blur": {"shutter_s": 0.05}}}))
    out = {"sharp": tmp_path / "sharp", "blur": tmp_path / "blurred"}
    for name, extra in (("sharp", []), ("blur", ["--preset", str(preset)])):
        res = render_dataset(kind, out[name], "--frames", "1", "--seed", "1", *extra, timeout=300)
        assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    assert dataset_digest(out["sharp"]) == dataset_digest(out["blur"])
    a, b = (read_image(out[n] / "images" / "clear" / "000000.png").astype(float) for n in ("sharp", "blur"))
    assert np.abs(a - b).mean() > 1.0
    meta = json.loads((out["blur"] / "meta" / "000000.json").read_text())
    mb = meta["render"]["motion_blur"]
    assert mb["shutter_s"] == 0.05 and mb["object_velocity_mps"]
    assert 8 <= np.linalg.norm(mb["camera_velocity_mps"]) <= 14
