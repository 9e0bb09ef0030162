"""``fogsim fog --waymo … --lidar`` on the Waymo LiDAR fixtures (:mod:`waymo_lidar_fixtures`: a TOP lidar whose
forward beams hit a wall, a FRONT camera; the frame written from the spec): each level's scan in the lidar
frame (PLY: raw intensity, ring = range-image row, return index), equal to the model's for the documented
seed; the per-object count of the laser box matched to a camera label, counted here in the vehicle frame."""
from __future__ import annotations

import json

import numpy as np
import pytest

import waymo_fixtures as wfx
import waymo_lidar_fixtures as lfx
from fogsim.cli import main
from fogsim.io.images import encode_image
from fogsim.lidar.fog import LidarFogger
from fogsim.lidar.formats import read_points
from fogsim.lidar.outcome_file import read_outcomes
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo.lidar_cloud import laser_point_cloud, laser_sensor
from fogsim.readers.waymo.lidar_v1 import parse_v1_lidar
from fogsim.readers.waymo.tfrecord import write_tfrecord
from fogsim.runs import level_seed

STAMP = lfx.TIMESTAMP
#: a laser box on the wall (vehicle frame): x 19.5–20.5, y −0.5–3.5, z 0.5–2.5
BOX = wfx.Box3D("wall-box", wfx.TYPE_VEHICLE, (20.0, 1.5, 1.5), length=1.0, width=4.0, height=2.0, heading=0.0)


def _frame(scene) -> bytes:
    image = encode_image(np.full((lfx.IMAGE_H, lfx.IMAGE_W, 3), 60, np.uint8), ".png")
    laser = pw.bytes_field(6, wfx.label_message(wfx.box3d_message(BOX), BOX.type, BOX.id, num_points=40))
    cam = wfx.Box2D("cam-box", wfx.TYPE_VEHICLE, 140.0, 110.0, 60.0, 40.0, laser_id=BOX.id)
    labels = pw.bytes_field(8, wfx.camera_labels_message(lfx.FRONT, [wfx.camera_label(cam)]))
    return lfx.frame_msg(scene, STAMP, image=image) + laser + labels


def _fog_segment(tmp, *flags):
    """A one-frame segment of the wall scene written under ``tmp/in`` and fogged with ``--lidar`` and ``flags``
    into ``tmp/out``: (scene, segment, out)."""
    scene = lfx.wall_scene()
    src = tmp / "in" / "seg.tfrecord"
    src.parent.mkdir(parents=True)
    write_tfrecord(src, [_frame(scene)])
    out = tmp / "out"
    assert main(["fog", "--waymo", str(src), "--depth-from", "lidar", "--lidar", "--quiet", *flags,
                 "--out", str(out)]) == 0
    return scene, src, out


@pytest.fixture(scope="module")
def waymo_run(tmp_path_factory):
    return _fog_segment(tmp_path_factory.mktemp("waymo"), "--levels", "paper")


def test_each_level_is_the_models_scan_in_the_lidar_frame(waymo_run):
    scene, src, out = waymo_run
    frame = parse_v1_lidar(_frame(scene), "x", returns=(1, 2))
    cloud, sensor = laser_point_cloud(frame), laser_sensor(frame)
    key = f"{lfx.CONTEXT}/{STAMP}"
    name = f"{lfx.CONTEXT}__{STAMP}"
    valid = scene.lasers[0].range_image[..., 0] > 0
    assert len(cloud) == valid.sum() and cloud.scale == "tanh"
    for level, beta in (("clear", 0.0), ("beta0.06", 0.06), ("beta0.12", 0.12)):
        expected = LidarFogger(cloud, sensor)(beta, np.random.default_rng(level_seed(0, key, level)))
        got = read_points(out / "lidar" / level / f"{name}.ply")
        np.testing.assert_array_equal(got.xyz, expected.cloud.xyz)
        np.testing.assert_array_equal(got.raw_intensity, expected.cloud.raw_intensity)
        np.testing.assert_array_equal(got.ring, expected.cloud.ring)
        np.testing.assert_array_equal(got.return_index, expected.cloud.return_index)
        assert got.scale == "tanh"
        outcome, index = read_outcomes(out / "lidar" / level / f"{name}.outcomes.npz")
        np.testing.assert_array_equal(outcome, expected.outcome)
        if beta == 0:  # clear: the decoded points, the wall's truth in the vehicle frame
            vehicle = got.transformed(sensor.mount_pose).xyz
            np.testing.assert_allclose(vehicle, scene.lasers[0].points[valid], atol=1e-3)
    assert not (out / "kitti").exists()  # Waymo has no KITTI calibration: no KITTI trees


def test_the_matched_laser_box_is_counted_per_level(waymo_run):
    scene, _, out = waymo_run
    meta = json.loads((out / "meta" / f"{lfx.CONTEXT}__{STAMP}_FRONT.json").read_text())
    obj = meta["objects"][0]
    assert obj["laser_id"] == BOX.id and obj["laser_box"]["size_m"] == [1.0, 4.0, 2.0]
    extrinsic = scene.lasers[0].extrinsic
    name = f"{lfx.CONTEXT}__{STAMP}"
    for level in ("clear", "beta0.03", "beta0.06", "beta0.09", "beta0.12"):
        pts = read_points(out / "lidar" / level / f"{name}.ply").xyz.astype(np.float64)
        vehicle = pts @ extrinsic[:3, :3].T + extrinsic[:3, 3]  # the lidar→vehicle extrinsic, by hand
        lo, hi = np.array([19.5, -0.5, 0.5]), np.array([20.5, 3.5, 2.5])
        assert obj["lidar_points"][level] == int(((vehicle >= lo) & (vehicle <= hi)).all(axis=1).sum())
    assert obj["lidar_points"]["clear"] > 5
    assert meta["lidar"]["key"] == f"{lfx.CONTEXT}/{STAMP}" and meta["lidar"]["format"] == "ply"
    assert meta["lidar"]["sensor"]["name"] == "waymo-top"
    dataset = json.loads((out / "dataset.json").read_text())
    assert dataset["lidar"]["objects_counted"] == 1


def test_no_lidar_in_the_data_is_refused_before_out(tmp_path, capsys):
    src = tmp_path / "seg.tfrecord"
    image = encode_image(np.full((lfx.IMAGE_H, lfx.IMAGE_W, 3), 60, np.uint8), ".png")
    write_tfrecord(src, [lfx.frame_msg(lfx.wall_scene(), STAMP, with_lasers=False, image=image)])
    depth = tmp_path / "depth" / lfx.CONTEXT
    from fogsim.io.depth_files import write_depth

    write_depth(depth / f"{STAMP}_FRONT.exr", np.full((lfx.IMAGE_H, lfx.IMAGE_W), 20.0, np.float32))
    out = tmp_path / "out"
    assert main(["fog", "--waymo", str(src), "--depth-dir", str(tmp_path / "depth"), "--lidar", "--levels", "0.06",
                 "--quiet", "--out", str(out)]) == 2
    assert "no LiDAR in this data" in capsys.readouterr().err and not out.exists()


def test_patchy_fog_follows_the_camera_projection(tmp_path):
    """``--heterogeneity``: a TOP point the range image projects into FRONT gets β × the field at that pixel,
    the others β."""
    from fogsim.fog.engine import FogSettings, Heterogeneity
    from fogsim.runs import sample_seed

    scene, src, out = _fog_segment(tmp_path, "--levels", "0.09", "--heterogeneity", "0.6", "--heterogeneity-scale",
                                   "16")
    field = FogSettings(heterogeneity=Heterogeneity(0.6, 16.0)).density(
        (lfx.IMAGE_H, lfx.IMAGE_W), np.random.default_rng(sample_seed(0, f"{lfx.CONTEXT}/{STAMP}_FRONT")))
    laser = scene.lasers[0]
    rows, cols = np.nonzero(laser.range_image[..., 0] > 0)  # the cloud's rows: return 1, row-major
    proj = laser.projection[rows, cols]
    seen = proj[:, 0] == lfx.FRONT
    betas = np.full(len(rows), 0.09)
    betas[seen] = 0.09 * field[proj[seen, 2], proj[seen, 1]].astype(np.float64)
    assert seen.sum() > 50 and not seen.all()
    frame = parse_v1_lidar(_frame(scene), "x", returns=(1, 2))
    expected = LidarFogger(laser_point_cloud(frame), laser_sensor(frame))(
        betas, np.random.default_rng(level_seed(0, f"{lfx.CONTEXT}/{STAMP}", "beta0.09")))
    got = read_points(out / "lidar" / "beta0.09" / f"{lfx.CONTEXT}__{STAMP}.ply")
    np.testing.assert_array_equal(got.xyz, expected.cloud.xyz)
