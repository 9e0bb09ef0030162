"""KITTI (and Seeing Through Fog) read as a library — calibration, labels, samples, the scan projected into
image 2 — and each fog level written back as a KITTI tree, read here by a reader written from the format's
spec alone (file names, 4 float32 per point, 15 label fields, calib keys)."""
from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

import kitti_tree as kt
from fogsim.dataset.kitti import KittiTree
from fogsim.errors import InputError
from fogsim.lidar.boxes import points_in_boxes
from fogsim.lidar.fog import LidarFogger
from fogsim.readers.kitti.boxes import label_box, label_boxes
from fogsim.readers.kitti.calib import read_kitti_calib, stf_calib_from_tf
from fogsim.readers.kitti.labels import KITTI_CLASSES, KittiLabels, label_records
from fogsim.readers.kitti.samples import kitti_samples, read_split, stf_samples


@pytest.fixture
def tree(tmp_path):
    return kt.write_kitti(tmp_path / "kitti")


# ----------------------------------------------------------------------------- calibration
def test_calibration_and_the_projection_p2_r0_tr(tree):
    calib = read_kitti_calib(tree / "training" / "calib" / "000000.txt")
    tr = np.vstack([kt.TR, [0, 0, 0, 1]])
    r0 = np.eye(4)
    r0[:3, :3] = kt.R0
    np.testing.assert_allclose(calib.projection(2), kt.P2 @ r0 @ tr, atol=1e-9)
    K = calib.intrinsics(kt.WIDTH, kt.HEIGHT)
    assert (K.fx, K.fy, K.cx, K.cy) == (kt.FX, kt.FX, 79.5, 23.5)
    np.testing.assert_allclose(calib.camera_centre(2), [-0.06, 0, 0], atol=1e-12)  # P2 = K·[I | t]
    p = np.array([[10.0, 1.0, 0.5]])
    uv, depth, ray = calib.project_velo(p)
    cam = (r0 @ tr @ [10.0, 1.0, 0.5, 1.0])[:3]
    by_hand = kt.P2 @ np.append(cam, 1.0)
    np.testing.assert_allclose(uv[0], by_hand[:2] / by_hand[2] + 0.5)  # + 0.5: pixel centres → edges
    assert depth[0] == pytest.approx(by_hand[2]) and ray[0] == pytest.approx(np.linalg.norm(cam - [-0.06, 0, 0]))
    np.testing.assert_allclose(calib.velo_from_rect(cam[None]), p, atol=1e-9)


@pytest.mark.parametrize("text,message", [
    (kt.calib_text(drop="Tr_velo_to_cam"), "missing calibration key Tr_velo_to_cam"),
    (kt.calib_text(drop="P2"), "missing calibration key P2"),
    (kt.calib_text().replace("R0_rect: ", "R0_rect: 1 "), "R0_rect has 10 values"),
    (kt.calib_text().replace(f"P2: {kt.FX:.12e}", "P2: 0").replace(f"0.000000000000e+00 {kt.FX:.12e}", "0 0", 1),
     "singular"),
    ("P0: 1 2 3\nnonsense\n", "expected 'KEY: values'"),
    (kt.calib_text().replace("P3:", "P3: x"), "not all numbers"),
])
def test_a_bad_calibration_is_one_line_naming_the_file(tmp_path, text, message):
    path = tmp_path / "000000.txt"
    path.write_text(text)
    with pytest.raises(InputError) as e:
        read_kitti_calib(path)
    assert str(e.value).startswith(str(path)) and message in str(e.value) and "\n" not in str(e.value)


def test_a_singular_r0_rect_is_refused(tmp_path):
    path = tmp_path / "c.txt"
    path.write_text(kt.calib_text().replace(" ".join(f"{v:.12e}" for v in kt.R0.ravel()), " ".join(["0"] * 9)))
    with pytest.raises(InputError, match="R0_rect is singular"):
        read_kitti_calib(path)


def test_stf_calibrations_sixteen_value_tr_and_the_ros_files(tmp_path):
    path = tmp_path / "stf.txt"
    path.write_text(kt.calib_text(tr16=True, imu=False))
    c = read_kitti_calib(path, require_imu=False)
    assert c.Tr_imu_to_velo is None and np.allclose(c.Tr_velo_to_cam[:3], kt.TR)
    with pytest.raises(InputError, match="Tr_imu_to_velo"):
        read_kitti_calib(path)
    # STF's ROS calibration: numbers as in the repository's calib_tf_tree_full.json / calib_cam_stereo_left.json;
    # the result must be its own KITTI-form conversion (kitti_stereo_velodynehdl_calib.txt's Tr_velo_to_cam)
    import json

    def tf(child, t, q):
        return {"header": {"frame_id": "body"}, "child_frame_id": child,
                "transform": {"translation": dict(zip("xyz", t)), "rotation": dict(zip("xyzw", q))}}
    tree = [tf("lidar_hdl64_s3_roof", (1.4185, -0.00125, 1.30225),
               (-2.7999696667896407e-05, -0.006999886834005389, -0.003999891334003365, 0.9999675003067072)),
            tf("cam_stereo_left_optical", (2.11688, 0.086961, 0.89075),
               (-0.49797334687178507, 0.49859243146922594, -0.5013107060281987, 0.5021112517245825))]
    folder = tmp_path / "calibs"
    folder.mkdir()
    (folder / "calib_tf_tree_full.json").write_text(json.dumps(tree))
    (folder / "calib_cam_stereo_left.json").write_text(json.dumps(
        {"P": [2355.722801, 0.0, 988.138054, 0.0, 0.0, 2355.722801, 508.051838, 0.0, 0.0, 0.0, 1.0, 0.0]}))
    ros = stf_calib_from_tf(folder)
    published = np.array([[0.008165559536184884, -0.9999654854673377, -0.0015334638999611712, 0.08749686458036277],
                          [-0.007155442920435107, 0.001475045689574084, -0.9999733115822772, -0.4164032939864676],
                          [0.9999410599000692, 0.008176314223727743, -0.007143151380269915, -0.6955577980059064]])
    np.testing.assert_allclose(ros.Tr_velo_to_cam[:3], published, atol=1e-6)
    assert ros.intrinsics(1920, 1024).fx == pytest.approx(2355.722801)
    (folder / "calib_tf_tree_full.json").write_text(json.dumps(tree[:1]))
    with pytest.raises(InputError, match="cam_stereo_left_optical"):
        stf_calib_from_tf(folder)


# ----------------------------------------------------------------------------- labels
def test_labels_fields_dontcare_and_distance(tree):
    calib = read_kitti_calib(tree / "training" / "calib" / "000000.txt")
    text = (tree / "training" / "label_2" / "000000.txt").read_text()
    classes, recs = label_records(text, "l", kt.WIDTH, kt.HEIGHT, calib)
    assert classes == KITTI_CLASSES
    car = recs[0]
    assert car["class"] == "Car" and car["kept"] and car["truncation"] == 0.1 and car["occlusion"] == 1
    left, top, right, bottom = (float(v) for v in text.split()[4:8])
    assert car["bbox"] == [max(0, left), max(0, top), min(kt.WIDTH, right + 1), min(kt.HEIGHT, bottom + 1)]
    # the ray distance camera-2 centre → the box centre (bottom centre raised by h/2), by hand
    c = kt.CARS["000000"]
    centre = kt.velo_to_rect(np.array([[c.x, c.y, c.z + c.height / 2]]))[0]
    assert car["distance_m"] == pytest.approx(np.linalg.norm(centre - [-0.06, 0, 0]), abs=0.02)
    assert "camera 2" in car["distance_source"] and car["planar_depth_m"] == pytest.approx(centre[2], abs=0.02)
    dont = [r for r in recs if r["reason"] == "DontCare region"]
    assert len(dont) == len(KITTI_CLASSES) and {r["class"] for r in dont} == set(KITTI_CLASSES)
    assert not any(r["kept"] for r in dont) and all(r["distance_m"] is None for r in dont)
    scored = label_records(text.splitlines()[0] + " 0.87\n", "l", kt.WIDTH, kt.HEIGHT, calib)[1]
    assert scored[0]["score"] == 0.87
    assert label_records("Car 0.00 0 0 0 0 50 50 1.5 1.6 4.0 1 1.5 10 0\n", "l", 160, 48)[1][0]["difficulty"] == 1


@pytest.mark.parametrize("line,message", [
    ("Car 0.00 0 0.1 1 2 3 4 1.5 1.6 4.0 1 2 3", "line 2: 14 fields, expected 15"),
    ("Car 0.00 0 0.1 1 2 3 4 1.5 1.6 4.0 1 2 3 0.5 0.9 7", "line 2: 17 fields"),
    ("Car 0.00 zero 0.1 1 2 3 4 1.5 1.6 4.0 1 2 3 0.5", "line 2: fields 2–15 must be numbers"),
    ("Bus 0.00 0 0.1 1 2 3 4 1.5 1.6 4.0 1 2 3 0.5", "unknown object type 'Bus'"),
])
def test_a_bad_label_line_is_one_line_naming_file_and_line(tmp_path, line, message):
    path = tmp_path / "000000.txt"
    path.write_text("Car 0.00 0 0.1 1 2 3 4 1.5 1.6 4.0 1 2 3 0.5\n" + line + "\n")
    with pytest.raises(InputError) as e:
        KittiLabels(str(path), None, 100, 100)()
    assert str(e.value).startswith(str(path)) and message in str(e.value)


def test_label_boxes_in_the_lidar_frame_hold_the_car_points(tree):
    calib = read_kitti_calib(tree / "training" / "calib" / "000001.txt")
    text = (tree / "training" / "label_2" / "000001.txt").read_text()
    recs = label_records(text, "l", kt.WIDTH, kt.HEIGHT, calib)[1]
    boxes = label_boxes(recs, calib)
    assert boxes[0] is not None and all(b is None for b in boxes[1:])
    car = kt.CARS["000001"]
    box = label_box(recs[0], calib)
    np.testing.assert_allclose(box.centre, [car.x, car.y, car.z + car.height / 2], atol=0.01)
    np.testing.assert_allclose(box.axes[:, 0], [math.cos(car.yaw), math.sin(car.yaw), 0], atol=0.01)
    centre = np.array([car.x, car.y, car.z + car.height / 2])
    pts = centre + 0.9 * (car.surface() - centre)  # the label rounds to cm and 0.01 rad: stay off the faces
    outside = centre + 1.15 * (car.surface() - centre)
    counts = points_in_boxes(np.concatenate([pts, outside]), [box])
    assert counts[0] == len(pts)


# ----------------------------------------------------------------------------- samples
def test_kitti_samples_splits_and_what_they_hold(tree):
    every = kitti_samples(tree)
    assert [s.key for s in every] == [f"training/image_2/{i}" for i in sorted(kt.CARS)]
    assert [s.meta["frame"] for s in kitti_samples(tree, "train")] == ["000000", "000001"]
    assert [s.meta["frame"] for s in kitti_samples(tree, tree / "ImageSets" / "val.txt")] == ["000002"]
    s = every[0]
    assert s.intrinsics.fx == kt.FX and (s.intrinsics.width, s.intrinsics.height) == (kt.WIDTH, kt.HEIGHT)
    assert s.read_image().shape == (kt.HEIGHT, kt.WIDTH, 3) and s.depth is None
    labels = s.labels()
    assert labels.classes == KITTI_CLASSES and labels.objects[0]["class"] == "Car"
    uv, ray = s.meta["lidar_points"]()
    assert uv.shape == (len(ray), 2) and ray.dtype == np.float32 and (ray > 0).all()
    pickle.loads(pickle.dumps(s))  # samples travel to worker processes
    with pytest.raises(InputError, match="ImageSets/test.txt"):
        kitti_samples(tree, "test")


def test_a_set_that_does_not_match_is_one_line_naming_what_is_missing(tree):
    (tree / "training" / "velodyne" / "000001.bin").unlink()
    (tree / "training" / "label_2" / "000002.txt").unlink()
    with pytest.raises(InputError) as e:
        kitti_samples(tree)
    text = str(e.value)
    assert "frame 000001: no scan training/velodyne/000001.bin" in text and "1 more frame miss files" in text
    assert "\n" not in text
    with pytest.raises(InputError, match="not a KITTI object tree"):
        kitti_samples(tree / "training" / "calib")
    bad = tree / "ImageSets" / "weird.txt"
    bad.write_text("../etc\n")
    with pytest.raises(InputError, match="not a frame id"):
        read_split(bad)


def test_the_scan_completes_into_camera_depth_through_lidar_depth(tree):
    from fogsim.depth.lidar_source import lidar_samples, meta_points_source

    samples = lidar_samples(kitti_samples(tree), "lidar:linear", None, points_source=meta_points_source,
                            has_lidar=None)
    s = samples[0]
    image = s.read_image()
    ray, _, record = s.depth.read_with_record(image)
    assert ray.shape == image.shape[:2] and record["points_in_image"] > 0 and s.depth.is_ray_distance
    # the wall straight ahead is ~30 m from camera 2: the completed depth agrees where the wall is seen
    uv, r = s.meta["lidar_points"]()
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < kt.WIDTH) & (uv[:, 1] >= 0) & (uv[:, 1] < kt.HEIGHT)
    rows, cols = np.floor(uv[inside, 1]).astype(int), np.floor(uv[inside, 0]).astype(int)
    assert np.median(np.abs(ray[rows, cols] - r[inside])) < 0.5


def test_stf_layout_as_a_variant(tmp_path):
    root = tmp_path / "SeeingThroughFogData"
    calib = kt.write_stf(root)
    samples = stf_samples(root, calib=calib)
    assert [s.meta["frame"] for s in samples] == list(kt.STF_IDS)
    s = samples[0]
    assert s.key == f"cam_stereo_left_lut/{kt.STF_IDS[0]}" and s.meta["return_mode"] == "strongest"
    objects = s.labels().objects
    car = [o for o in objects if o["kept"]]
    assert len(car) == 1 and car[0]["class"] == "PassengerCar"
    assert {o["reason"] for o in objects if not o["kept"]} == {"unlabelled type 'train'"}
    cloud = s.meta["lidar_points"].cloud()
    assert cloud.scale == "0-255" and cloud.ring is not None
    split = tmp_path / "dense_fog_day.txt"
    split.write_text("2018-10-29_16-00-52,02660\n")
    assert [x.meta["frame"] for x in stf_samples(root, split, calib=calib)] == [kt.STF_IDS[1]]
    with pytest.raises(InputError, match="no calibration"):
        stf_samples(root)
    with pytest.raises(InputError, match="lidar_hdl64_last"):
        stf_samples(root, returns="last", calib=calib)


# ----------------------------------------------------------------------------- the writer, read back by the spec
def spec_read_frame(level_root, fid):
    return kt.read_kitti_frame(level_root, fid)


def test_each_fog_level_is_written_as_a_kitti_tree_read_back_by_the_spec(tree, tmp_path):
    out = tmp_path / "out"
    samples = kitti_samples(tree)
    for level, beta in (("clear", 0.0), ("beta_0.06", 0.06)):
        kitti = KittiTree(out, level)
        for k, s in enumerate(samples):
            fid = s.meta["frame"]
            cloud = s.meta["lidar_points"].cloud()
            fogged = LidarFogger(cloud, "hdl64e")(beta, np.random.default_rng(k))
            calib = read_kitti_calib(s.meta["calib"])
            kitti.write_frame(fid, s.read_image(), fogged.cloud, calib, s.labels().objects)
            assert kitti.frame_complete(fid)
            pts, cal, labels, size = spec_read_frame(out / "kitti" / level, fid)
            assert size == (kt.WIDTH, kt.HEIGHT)
            np.testing.assert_array_equal(pts[:, :3], fogged.cloud.xyz)
            np.testing.assert_allclose(pts[:, 3], fogged.cloud.intensity)
            if beta == 0:  # the clear level's velodyne file is the input, bit for bit
                assert (out / "kitti" / level / "training" / "velodyne" / f"{fid}.bin").read_bytes() == \
                    (tree / "training" / "velodyne" / f"{fid}.bin").read_bytes()
            np.testing.assert_allclose(np.reshape(cal["P2"], (3, 4)), kt.P2, atol=1e-9)
            source_lines = (tree / "training" / "label_2" / f"{fid}.txt").read_text().split("\n")
            source = [ln.split() for ln in source_lines if ln]  # DontCare once, every value as read
            assert [f[0] for f in labels] == [f[0] for f in source]
            np.testing.assert_allclose([[float(v) for v in f[1:]] for f in labels],
                                       [[float(v) for v in f[1:]] for f in source], atol=5e-3)
        kitti.write_image_sets({"train": ["000000", "000001"], "val": ["000002"]})
        assert (out / "kitti" / level / "ImageSets" / "val.txt").read_text() == "000002\n"
    # an STF scan (0–255) goes into the KITTI tree as 0–1 reflectance
    root = tmp_path / "stf"
    calib = kt.write_stf(root)
    s = stf_samples(root, calib=calib)[0]
    cloud = s.meta["lidar_points"].cloud()
    KittiTree(out, "stf").write_frame("000000", s.read_image(), cloud, read_kitti_calib(calib, require_imu=False),
                                      s.labels().objects)
    pts, cal, labels, _ = spec_read_frame(out / "kitti" / "stf", "000000")
    np.testing.assert_allclose(pts[:, 3], cloud.raw_intensity / 255, rtol=1e-6)
    assert cal["Tr_imu_to_velo"] == [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0] and labels[0][0] == "PassengerCar"
