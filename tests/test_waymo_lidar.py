"""Waymo LiDAR (v1 and v2) → per-camera sparse ray distance, on fixtures whose geometry is
computed by hand in tests/waymo_lidar_fixtures.py (a wall at x = 20 m seen by a TOP lidar and
a pinhole camera 1.5 m to its left)."""
from __future__ import annotations

import math
import pickle
import sys
import zlib

import numpy as np
import pytest

import waymo_lidar_fixtures as fx
from fogsim.errors import InputError, MissingDependency
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo.address import V2Frame
from fogsim.readers.waymo.lidar import LidarPoints, lidar_points_for_sample
from fogsim.readers.waymo.lidar_frame import LaserCalibration, LidarFrame
from fogsim.readers.waymo.lidar_geometry import (
    beam_inclinations,
    camera_points,
    camera_ray_depth,
    filter_bleed_through,
    range_image_to_points,
    sparse_ray_depth,
)
from fogsim.readers.waymo.lidar_v1 import parse_v1_lidar, read_v1_lidar
from fogsim.readers.waymo.lidar_v2 import read_v2_lidar
from fogsim.readers.waymo.matrix import (
    decode_matrix,
    decode_varints,
    decode_varints_int32,
    encode_matrix,
    encode_varints,
)
from fogsim.readers.waymo.tfrecord import index_tfrecord, write_tfrecord


def _frame(scene: fx.Scene, returns=(1,)) -> LidarFrame:
    return parse_v1_lidar(fx.frame_msg(scene), "fixture#record 0", returns)


def _v1_file(tmp_path, scenes, **kw):
    path = tmp_path / "segment-lidar.tfrecord"
    write_tfrecord(path, [fx.frame_msg(s, fx.TIMESTAMP + i, **kw) for i, s in enumerate(scenes)])
    return path


# ----------------------------------------------------------------------------- matrices
@pytest.mark.parametrize("packed_shape", [True, False])
def test_matrix_float_packed_and_unpacked_shape(packed_shape):
    a = np.random.default_rng(0).normal(size=(3, 5, 4)).astype(np.float32)
    for blob in (fx.compressed(a, packed_shape), encode_matrix(a, packed_shape=packed_shape)):
        out = decode_matrix(blob, "float", "m")
        assert out.dtype == np.float32 and out.shape == (3, 5, 4)
        np.testing.assert_array_equal(out, a)
    # unpacked float data: one fixed32 entry per value, written by hand
    shape = pw.bytes_field(1, b"".join(pw.encode_varint(d) for d in (2, 1, 1)))
    msg = b"\x0d" + fx.float32_bits(1.5) + b"\x0d" + fx.float32_bits(-2.25) + pw.bytes_field(2, shape)
    np.testing.assert_array_equal(decode_matrix(msg, "float", "m", compressed=False).ravel(), [1.5, -2.25])


@pytest.mark.parametrize("packed_shape", [True, False])
def test_matrix_int32_negative_varints(packed_shape):
    a = np.array([[[-1, 0, 5, 127, 128, 1919]], [[-1, -2, 1280, 2**31 - 1, -(2**31), 3]]], np.int32)
    raw = fx.matrix_message(a, packed_shape)
    assert pw.encode_varint(-1) == b"\xff" * 9 + b"\x01"  # a 10-byte varint …
    assert pw.encode_varint(-1) in raw  # … is what the fixture holds
    out = decode_matrix(zlib.compress(raw), "int32", "proj")
    assert out.dtype == np.int32
    np.testing.assert_array_equal(out, a)
    np.testing.assert_array_equal(decode_matrix(encode_matrix(a), "int32", "proj"), a)
    # unpacked data entries decode too
    assert (decode_matrix(encode_matrix(a, packed_data=False, packed_shape=packed_shape), "int32", "p")
            == a).all()


def test_vectorised_varints_match_protobuf_wire():
    values = np.random.default_rng(1).integers(-(2**31), 2**31, 5000).astype(np.int64)
    values[:10] = [0, 1, 127, 128, 16383, 16384, -1, -128, 2**31 - 1, -(2**31)]
    blob = b"".join(pw.encode_varint(int(v)) for v in values)
    np.testing.assert_array_equal(decode_varints(np.frombuffer(blob, np.uint8), "x"), values)
    np.testing.assert_array_equal(decode_varints_int32(np.frombuffer(blob, np.uint8), "x"), values)
    assert encode_varints(values) == blob


@pytest.mark.parametrize("value", [2**31, 2**32 + 5, -(2**31) - 1, 2**63 - 1])
def test_int32_varints_out_of_range_are_refused(value):
    blob = pw.encode_varint(3) + pw.encode_varint(value)
    with pytest.raises(InputError, match="int32 range"):
        decode_varints_int32(np.frombuffer(blob, np.uint8), "x")


def test_matrix_errors_name_the_source():
    a = np.zeros((2, 3, 4), np.float32)
    blob = fx.compressed(a)
    with pytest.raises(InputError, match="seg#record 3 TOP.*corrupt zlib"):
        decode_matrix(blob[:-5] + b"xxxxx", "float", "seg#record 3 TOP")
    bad_shape = pw.bytes_field(1, a.tobytes()) + pw.bytes_field(2, pw.bytes_field(1, bytes([2, 3, 5])))
    with pytest.raises(InputError, match="shape \\[2, 3, 5\\] does not hold its 24"):
        decode_matrix(zlib.compress(bad_shape), "float", "m")
    truncated = pw.bytes_field(1, b"\x05\xff") + pw.bytes_field(2, pw.bytes_field(1, bytes([2, 1, 1])))
    with pytest.raises(InputError, match="truncated varint"):
        decode_matrix(truncated, "int32", "m", compressed=False)
    too_big = pw.bytes_field(1, pw.encode_varint(2**40)) + pw.bytes_field(2, pw.bytes_field(1, bytes([1, 1, 1])))
    with pytest.raises(InputError, match="int32 range"):
        decode_matrix(too_big, "int32", "m", compressed=False)


# ----------------------------------------------------------------------------- geometry
def test_inclinations_uniform_and_per_beam_are_reversed():
    cal = LaserCalibration(2, np.eye(4), -0.4, 0.4)
    incl = beam_inclinations(cal, 4)
    np.testing.assert_allclose(incl, [0.3, 0.1, -0.1, -0.3])  # min + (k+0.5)/H·(max−min), reversed
    beams = LaserCalibration(1, np.eye(4), -1, 1, np.array([-0.3, -0.1, 0.02]))
    np.testing.assert_allclose(beam_inclinations(beams, 3), [0.02, -0.1, -0.3])
    with pytest.raises(ValueError, match="3 beam inclinations but its range image has 4 rows"):
        beam_inclinations(beams, 4)


def test_middle_column_points_along_vehicle_x_whatever_the_mounting_yaw():
    E = fx.transform(fx.rz(math.radians(35)), [1.0, 0.0, 2.0])
    cal = LaserCalibration(1, E, 0.0, 0.0)
    ri = np.ones((1, 4, 1), np.float32)  # inclination 0, range 1
    p = range_image_to_points(ri, cal)[0] - E[:3, 3]
    # columns j = 0..3 → vehicle azimuth ((W − j − 0.5)/W·2 − 1)·π: 3π/4, π/4, −π/4, −3π/4
    np.testing.assert_allclose(np.degrees(np.arctan2(p[:, 1], p[:, 0])), [135, 45, -45, -135], atol=1e-9)


def test_range_image_points_are_the_wall():
    laser = fx.wall_laser(beams=None)
    cal = LaserCalibration(1, laser.extrinsic, laser.incl_min, laser.incl_max)
    p = range_image_to_points(laser.range_image, cal)
    valid = laser.range_image[..., 0] > 0
    assert valid.sum() > 100
    np.testing.assert_allclose(p[valid, 0], fx.WALL_X, atol=1e-4)
    np.testing.assert_allclose(p[valid], laser.points[valid], atol=1e-4)


def test_per_beam_inclinations_from_the_frame():
    beams = sorted(np.random.default_rng(2).uniform(-0.3, 0.05, 12).tolist())
    scene = fx.wall_scene(beams=beams)
    frame = _frame(scene)
    np.testing.assert_allclose(frame.calibrations[1].beam_inclinations, beams)
    la = scene.lasers[0]
    p = range_image_to_points(frame.returns[1][1].range_image, frame.calibrations[1])
    valid = la.range_image[..., 0] > 0
    np.testing.assert_allclose(p[valid], la.points[valid], atol=1e-4)


def test_camera_ray_distance_is_from_the_camera_centre():
    scene = fx.wall_scene()
    cam, la = scene.cameras[0], scene.lasers[0]
    pts = camera_points(_frame(scene), "FRONT")
    u, v, ok = fx.project(la.points, cam)
    seen = ok & (la.range_image[..., 0] > 0)
    assert len(pts.ray) == seen.sum() > 50
    assert (pts.lidar == 1).all()
    # the same cells, in row-major order: pixel = floor of the true projection
    np.testing.assert_array_equal(pts.uv, np.stack([np.floor(u[seen]), np.floor(v[seen])], -1))
    truth = np.linalg.norm(la.points[seen] - cam.extrinsic[:3, 3], axis=1)
    np.testing.assert_allclose(pts.ray, truth, atol=1e-3)
    assert np.abs(pts.ray - np.linalg.norm(la.points[seen], axis=1)).max() > 0.1  # not the vehicle-origin norm
    # the wall is 20 − c_x ahead of this camera (planar), within the pixel quantisation
    planar = pts.ray / np.sqrt(1 + ((pts.uv[:, 0] + 0.5 - cam.cu) / cam.f) ** 2
                               + ((pts.uv[:, 1] + 0.5 - cam.cv) / cam.f) ** 2)
    np.testing.assert_allclose(planar, fx.WALL_X - cam.extrinsic[0, 3], rtol=5e-3)
    # the sparse map: each pixel is the nearest point landing on it
    depth = sparse_ray_depth(pts.uv, pts.ray, cam.width, cam.height)
    expect = np.zeros((cam.height, cam.width), np.float32)
    for (x, y), r in zip(np.floor(np.stack([u[seen], v[seen]], -1)).astype(int), truth):
        expect[y, x] = r if expect[y, x] == 0 else min(expect[y, x], r)
    np.testing.assert_allclose(depth, expect, atol=1e-3)
    assert depth.dtype == np.float32 and (depth > 0).sum() > 50


def test_second_projection_slot_and_yawed_camera():
    lidar = fx.transform(fx.rz(math.radians(7.0)), [1.2, 0.1, 2.0])
    front = fx.front_camera(lidar=lidar)
    left = fx.front_camera(offset=(0.2, 0.5, 0.1), yaw=math.radians(30), name=fx.FRONT_LEFT, lidar=lidar)
    scene = fx.wall_scene(cameras=[front, left])
    la = scene.lasers[0]
    assert ((la.projection[..., 0] == 1) & (la.projection[..., 3] == 2)).any()  # cells seen by both
    pts = camera_points(_frame(scene), fx.FRONT_LEFT)
    u, v, ok = fx.project(la.points, left)
    seen = ok & (la.range_image[..., 0] > 0)
    assert len(pts.ray) == seen.sum()
    np.testing.assert_array_equal(pts.uv, np.stack([np.floor(u[seen]), np.floor(v[seen])], -1))
    np.testing.assert_allclose(pts.ray, np.linalg.norm(la.points[seen] - left.extrinsic[:3, 3], axis=1), atol=1e-3)


def test_invalid_ranges_are_dropped_even_with_a_projection():
    scene = fx.wall_scene()
    la = scene.lasers[0]
    hit = np.argwhere(la.projection[..., 0] == 1)[:5]
    la.range_image[hit[:, 0], hit[:, 1], 0] = [-1, 0, -1, 0, -1]
    n = ((la.projection[..., 0] == 1) & (la.range_image[..., 0] > 0)).sum()
    assert len(camera_points(_frame(scene), 1).ray) == n


def test_per_cell_pose_compensation_yaw_shift():
    scene = fx.wall_scene()
    la = scene.lasers[0]
    h, w = la.range_image.shape[:2]
    F = fx.transform(fx.rz(0.5), [100.0, 50.0, 1.0])  # frame pose, vehicle → world
    scene.pose = F
    delta = 0.002 * np.arange(w)  # per-column yaw shift of the sweep, and a forward drift
    pose = np.zeros((h, w, 6), np.float32)
    for j in range(w):
        cell = F @ fx.transform(fx.rz(delta[j]), [0.01 * j, 0, 0])
        pose[:, j, 2] = math.atan2(cell[1, 0], cell[0, 0])  # roll = pitch = 0
        pose[:, j, 3:] = cell[:3, 3]
    la.pose = pose
    frame = _frame(scene)
    assert 1 in frame.pixel_poses
    p = range_image_to_points(frame.returns[1][1].range_image, frame.calibrations[1],
                                 frame.pixel_poses[1], frame.pose)
    valid = la.range_image[..., 0] > 0
    i, j = np.nonzero(valid)
    expect = np.stack([fx.rz(delta[jj]) @ la.points[ii, jj] + [0.01 * jj, 0, 0] for ii, jj in zip(i, j)])
    np.testing.assert_allclose(p[valid], expect, atol=2e-3)  # float32 pose (world coordinates ≈ 100 m)
    # and the ray distances are those of the compensated points
    pts = camera_points(frame, "front")
    assert not np.allclose(pts.ray, camera_points(_frame(fx.wall_scene()), "front").ray, atol=1e-2)


def test_pose_rotation_order_roll_pitch_yaw():
    roll, pitch, yaw, t = 0.1, -0.2, 0.7, np.array([3.0, -1.0, 0.5])
    pose = np.array([[[roll, pitch, yaw, *t]]], np.float64)
    cal = LaserCalibration(1, np.eye(4), 0.3, 0.3)
    p0 = range_image_to_points(np.full((1, 1, 1), 10.0), cal)[0, 0]
    p = range_image_to_points(np.full((1, 1, 1), 10.0), cal, pose, np.eye(4))[0, 0]
    np.testing.assert_allclose(p, fx.rz(yaw) @ fx.ry(pitch) @ fx.rx(roll) @ p0 + t, atol=1e-9)
    with pytest.raises(ValueError, match="no pose"):
        range_image_to_points(np.full((1, 1, 1), 10.0), cal, pose, None)


def test_all_lidars_and_second_return():
    scene = fx.wall_scene()
    E_side = fx.transform(fx.rz(math.radians(90)), [1.0, 0.9, 1.0])
    side = fx.wall_laser(fx.SIDE_LEFT, E_side, h=6, w=40, incl_min=-0.5, incl_max=0.5, max_range=25.0)
    side.projection = fx.camera_projection(side.points, scene.cameras)
    scene.lasers.append(side)
    la = scene.lasers[0]
    la.range_image2 = la.range_image.copy()
    la.range_image2[..., 0] = np.where(la.range_image[..., 0] > 0, la.range_image[..., 0] + 1.0, -1)
    la.projection2 = la.projection
    frame = _frame(scene, returns=(1, 2))
    first = camera_points(frame, "FRONT")
    assert set(np.unique(first.lidar)) == {1, 3}
    n_side = (first.lidar == 3).sum()
    assert n_side == ((side.projection[..., 0] == 1) & (side.range_image[..., 0] > 0)).sum() > 0
    both = camera_points(frame, "FRONT", returns=(1, 2))
    assert len(both.ray) == len(first.ray) + (first.lidar == 1).sum()
    second = camera_points(frame, "FRONT", returns=(2,))
    assert (second.ray > first.ray[first.lidar == 1].min()).all()


# ----------------------------------------------------------------------------- sparse maps
def test_min_pooling_two_points_one_pixel():
    uv = np.array([[3.2, 4.7], [3.9, 4.1], [0.0, 0.0], [10.0, 2.0], [-0.5, 1.0], [2.0, 5.0]])
    ray = np.array([10.0, 8.0, 4.0, 3.0, 2.0, np.nan])
    d = sparse_ray_depth(uv, ray, 10, 6)
    assert d.shape == (6, 10) and d.dtype == np.float32
    assert d[4, 3] == 8.0 and d[0, 0] == 4.0
    assert (d > 0).sum() == 2  # u = 10 and u = −0.5 are outside, NaN is ignored


def test_bleed_filter_drops_far_point_among_near_ones():
    d = np.zeros((40, 60), np.float32)
    d[10:13, 10:16:2] = 5.0  # a near cluster
    d[11, 13] = 30.0  # a far point seen through its edge
    d[12, 15] = 5.4  # within 10 % of the near ones: kept
    d[30, 40] = 30.0  # isolated far point: kept
    d[30, 44] = 31.0  # and its far neighbour, within 10 %
    out, dropped = filter_bleed_through(d, window=7, margin=0.10)
    assert dropped == 1 and out[11, 13] == 0
    assert out[30, 40] == 30.0 and out[30, 44] == 31.0 and out[12, 15] == np.float32(5.4)
    assert ((out > 0) == ((d > 0) & ~((np.arange(40)[:, None] == 11) & (np.arange(60) == 13)))).all()
    # a window too small to reach the near neighbours keeps it
    assert filter_bleed_through(d, window=1)[1] == 0
    with pytest.raises(ValueError, match="odd"):
        filter_bleed_through(d, window=4)


def test_camera_ray_depth_wall_has_no_bleed():
    scene = fx.wall_scene()
    depth, dropped = camera_ray_depth(_frame(scene), "FRONT", fx.IMAGE_W, fx.IMAGE_H)
    assert dropped == 0 and (depth > 0).sum() > 50


# ----------------------------------------------------------------------------- files, errors
def test_v1_file_points_provider_is_picklable_and_matches(tmp_path):
    scene = fx.wall_scene()
    path = _v1_file(tmp_path, [scene], packed_shape=False)
    (offset, length), = index_tfrecord(path)
    provider = LidarPoints.v1(path, offset, length, f"{path}#record 0")
    provider = pickle.loads(pickle.dumps(provider))
    uv, ray = provider("FRONT")
    ref = camera_points(_frame(scene), 1)
    np.testing.assert_array_equal(uv, ref.uv)
    np.testing.assert_array_equal(ray, ref.ray)
    assert provider.frame() is provider.frame()  # decoded once for several cameras


def test_lidar_points_for_v1_sample(tmp_path):
    from fogsim.io.images import encode_image
    from fogsim.readers.waymo import waymo_v1_samples

    scene = fx.wall_scene()
    image = encode_image(np.zeros((fx.IMAGE_H, fx.IMAGE_W, 3), np.uint8), ".png")
    path = _v1_file(tmp_path, [scene], image=image)
    sample, = waymo_v1_samples(path, ["FRONT"])
    uv, ray = lidar_points_for_sample(sample)("FRONT")
    np.testing.assert_array_equal(ray, camera_points(_frame(scene), 1).ray)


def test_frame_without_lidar_is_a_clear_error(tmp_path):
    path = _v1_file(tmp_path, [fx.wall_scene()], with_lasers=False)
    (offset, length), = index_tfrecord(path)
    with pytest.raises(InputError, match=r"#record 0: frame has no LiDAR range images \("):
        LidarPoints.v1(path, offset, length, f"{path}#record 0")("FRONT")


def test_corrupt_zlib_in_a_record_names_the_record(tmp_path):
    scene = fx.wall_scene()
    la = scene.lasers[0]
    good = fx.compressed(la.range_image)
    msg = fx.frame_msg(scene)
    bad = msg.replace(good, good[:10] + bytes(len(good) - 10))
    assert bad != msg
    path = tmp_path / "seg.tfrecord"
    write_tfrecord(path, [bad])
    (offset, length), = index_tfrecord(path)
    with pytest.raises(InputError, match=r"seg\.tfrecord#record 0 TOP return 1 range_image_compressed: "
                                         r"corrupt zlib"):
        read_v1_lidar(path, offset, length, f"{path}#record 0")


def test_missing_camera_calibration_and_projection(tmp_path):
    scene = fx.wall_scene()
    with pytest.raises(InputError, match="no calibration .*FRONT_LEFT"):
        camera_points(_frame(scene), "FRONT_LEFT")
    scene.lasers[0].projection = None
    with pytest.raises(InputError, match="no LiDAR camera projections"):
        camera_points(_frame(scene), "FRONT")
    with pytest.raises(ValueError, match="unknown Waymo camera"):
        camera_points(_frame(scene), "NOSE")


# ----------------------------------------------------------------------------- v2
def _posed_scene() -> fx.Scene:
    scene = fx.wall_scene()
    side = fx.wall_laser(fx.SIDE_LEFT, fx.transform(fx.rz(1.2), [1.0, 0.9, 1.0]), h=6, w=40,
                         incl_min=-0.5, incl_max=0.5, max_range=25.0)
    side.projection = fx.camera_projection(side.points, scene.cameras)
    scene.lasers.append(side)
    la = scene.lasers[0]
    h, w = la.range_image.shape[:2]
    scene.pose = fx.transform(fx.rz(0.3), [10.0, 5.0, 0.5])
    la.pose = np.zeros((h, w, 6), np.float32)
    la.pose[..., 2] = 0.3 + 0.001 * np.arange(w)
    la.pose[..., 3:] = [10.0, 5.0, 0.5]
    return scene


def test_v2_tables_give_the_v1_points(tmp_path):
    pytest.importorskip("pyarrow")
    scene = _posed_scene()
    fx.write_v2(tmp_path, scene, camera_key_as_string=True, pose_as_float32=True)
    v2 = LidarPoints.v2(tmp_path, fx.CONTEXT, fx.TIMESTAMP)
    v2 = pickle.loads(pickle.dumps(v2))
    frame = v2.frame()
    assert sorted(frame.returns) == [1, 3] and list(frame.pixel_poses) == [1]
    assert frame.calibrations[3].beam_inclinations is None
    got, ref = v2.points("FRONT"), camera_points(_frame(scene), "FRONT")
    np.testing.assert_array_equal(got.uv, ref.uv)
    np.testing.assert_array_equal(got.lidar, ref.lidar)
    np.testing.assert_allclose(got.ray, ref.ray, atol=1e-3)  # the v2 vehicle pose is float32
    assert len(got.ray) > 50


def test_v2_selects_the_frame_by_its_keys(tmp_path):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    scene = fx.wall_scene()
    fx.write_v2(tmp_path, scene)
    # a second frame in the lidar table, with another range: must not be mixed in
    file = tmp_path / "lidar" / f"{fx.CONTEXT}.parquet"
    t = pq.read_table(file)
    other = t.set_column(1, "key.frame_timestamp_micros", pa.array([fx.TIMESTAMP + 100000], pa.int64()))
    pq.write_table(pa.concat_tables([other, t]), file)
    pts = read_v2_lidar(tmp_path, fx.CONTEXT, fx.TIMESTAMP)
    np.testing.assert_array_equal(pts.returns[1][1].range_image, scene.lasers[0].range_image)
    with pytest.raises(InputError, match="frame has no LiDAR range images \\(no rows in"):
        read_v2_lidar(tmp_path, fx.CONTEXT, fx.TIMESTAMP + 1)
    with pytest.raises(InputError, match="frame has no LiDAR range images \\(.*not found"):
        read_v2_lidar(tmp_path, "other_context", fx.TIMESTAMP)


def test_v2_lidar_without_pyarrow_is_a_missing_dependency(tmp_path, monkeypatch):
    pytest.importorskip("pyarrow")
    fx.write_v2(tmp_path, fx.wall_scene())
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)  # as if pyarrow were missing
    with pytest.raises(MissingDependency, match="'waymo' extra"):
        read_v2_lidar(tmp_path, fx.CONTEXT, fx.TIMESTAMP)


def test_v2_lidar_pose_without_vehicle_pose_is_refused(tmp_path):
    pytest.importorskip("pyarrow")
    fx.write_v2(tmp_path, _posed_scene())
    (tmp_path / "vehicle_pose" / f"{fx.CONTEXT}.parquet").unlink()
    with pytest.raises(InputError, match="per-cell lidar poses"):
        read_v2_lidar(tmp_path, fx.CONTEXT, fx.TIMESTAMP)


def test_lidar_points_for_v2_sample(tmp_path):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq

    from fogsim.io.images import encode_image
    from fogsim.readers.waymo import waymo_v2_samples

    scene = _posed_scene()
    fx.write_v2(tmp_path, scene)
    (tmp_path / "camera_image").mkdir()
    image = encode_image(np.zeros((fx.IMAGE_H, fx.IMAGE_W, 3), np.uint8), ".png")
    pq.write_table(pa.table({"key.segment_context_name": [fx.CONTEXT],
                             "key.frame_timestamp_micros": pa.array([fx.TIMESTAMP], pa.int64()),
                             "key.camera_name": pa.array([1], pa.int8()),
                             "[CameraImageComponent].image": pa.array([image], pa.binary())}),
                   tmp_path / "camera_image" / f"{fx.CONTEXT}.parquet")
    sample, = waymo_v2_samples(tmp_path, ["FRONT"])
    provider = lidar_points_for_sample(sample)
    assert provider.where == V2Frame(str(tmp_path), fx.CONTEXT, fx.TIMESTAMP)
    uv, ray = provider("FRONT")
    np.testing.assert_allclose(ray, camera_points(_frame(scene), 1).ray, atol=1e-3)


@pytest.mark.slow
def test_bench_decode_runs_on_real_sizes():
    from fogsim.bench.waymo_lidar import bench_decode

    r = bench_decode(1)
    assert r["points"] > 10000 and 0 < r["pixels"] <= r["points"] and r["dropped"] < r["pixels"]
    assert r["decode_ms"] > 0 and r["python_varints_ms"] > 0
