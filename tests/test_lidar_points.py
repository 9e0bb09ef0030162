"""The point-cloud record and its files: KITTI / nuScenes / STF ``.bin``, PLY, ``.npy`` read from bytes
written here from the formats' specs, written back bit for bit, and every bad input one line naming the file."""
from __future__ import annotations

import io
import math

import numpy as np
import pytest

import lidar_fixtures as lfx
from fogsim.errors import InputError
from fogsim.lidar.formats import detect_format, encode_points, read_points, write_points
from fogsim.lidar.points import PointCloud
from fogsim.lidar.scales import scale


@pytest.fixture
def xyz():
    rng = np.random.default_rng(0)
    return (rng.normal(size=(50, 3)) * 10).astype(np.float32)


def test_kitti_bin_reads_as_its_spec_says(tmp_path, xyz):
    inten = np.linspace(0, 1, len(xyz)).astype(np.float32)
    path = tmp_path / "000001.bin"
    path.write_bytes(lfx.kitti_bin(xyz, inten))
    cloud = read_points(path, "kitti")
    assert cloud.scale == "0-1" and cloud.ring is None and cloud.source == str(path)
    assert cloud.xyz.dtype == np.float32 and np.array_equal(cloud.xyz, xyz)
    assert np.array_equal(cloud.intensity, inten) and np.array_equal(cloud.index, np.arange(len(xyz)))
    np.testing.assert_allclose(cloud.range_m, np.linalg.norm(xyz.astype(np.float64), axis=1), rtol=1e-12)
    np.testing.assert_allclose(cloud.azimuth, np.arctan2(xyz[:, 1], xyz[:, 0]), rtol=1e-6)
    el = np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1]))
    np.testing.assert_allclose(cloud.elevation, el, rtol=1e-6)


@pytest.mark.parametrize("fmt,name", [("stf", "frame.bin"), ("nuscenes", "n008__LIDAR_TOP__1.pcd.bin")])
def test_five_column_formats_carry_ring_and_the_0_255_scale(tmp_path, xyz, fmt, name):
    inten = np.arange(len(xyz), dtype=np.float32) * 5  # 0 … 245, whole numbers
    ring = (np.arange(len(xyz)) % 32).astype(np.float32)
    path = tmp_path / name
    path.write_bytes(lfx.stf_bin(xyz, inten, ring))
    cloud = read_points(path, fmt if fmt == "stf" else None)
    assert cloud.scale == "0-255" and cloud.ring.dtype == np.int16
    assert np.array_equal(cloud.ring, ring.astype(np.int16))
    assert np.array_equal(cloud.raw_intensity, inten)
    np.testing.assert_allclose(cloud.intensity, inten / 255.0, rtol=1e-6)


@pytest.mark.parametrize("fmt", ["kitti", "stf", "nuscenes", "ply", "npy"])
def test_writing_a_scan_back_in_its_own_format_is_bit_identical(tmp_path, fmt):
    rng = np.random.default_rng(1)
    xyz = rng.normal(size=(200, 3)).astype(np.float32) * 30
    xyz[0] = [-0.0, 0.0, 1e-30]  # signed zero, a denormal-ish small value: bits, not values
    if fmt == "kitti":
        data = lfx.kitti_bin(xyz, rng.uniform(0, 1, 200).astype(np.float32))
        src = tmp_path / "a.bin"
    elif fmt in ("stf", "nuscenes"):
        data = lfx.stf_bin(xyz, rng.uniform(0, 255, 200).astype(np.float32), (np.arange(200) % 64).astype(np.float32))
        src = tmp_path / ("a.bin" if fmt == "stf" else "a.pcd.bin")
    elif fmt == "npy":
        buf = io.BytesIO()
        np.save(buf, np.hstack([xyz, rng.uniform(0, 1, (200, 1)).astype(np.float32)]))
        data, src = buf.getvalue(), tmp_path / "a.npy"
    else:
        cloud = PointCloud.from_raw(xyz, rng.uniform(0, 255, 200), "0-255", "made", ring=np.arange(200) % 64,
                                    return_index=np.ones(200))
        data, src = encode_points(cloud, "ply"), tmp_path / "a.ply"
    src.write_bytes(data)
    cloud = read_points(src, fmt)
    out = tmp_path / ("b" + src.name[1:])
    write_points(out, cloud, fmt)
    assert out.read_bytes() == data
    assert read_points(out, fmt).same_as(cloud)


def test_ply_keeps_its_scale_ring_and_return_and_reads_other_tools_files(tmp_path):
    cloud = PointCloud.from_raw(np.ones((3, 3), np.float32), [0.5, 1.5, 7.0], "tanh", "w", ring=[0, 1, 2],
                                return_index=[1, 2, 1])
    write_points(tmp_path / "w.ply", cloud)
    back = read_points(tmp_path / "w.ply")
    assert back.scale == "tanh" and back.ring.tolist() == [0, 1, 2] and back.return_index.tolist() == [1, 2, 1]
    np.testing.assert_allclose(back.intensity, np.tanh([0.5, 1.5, 7.0]), rtol=1e-6)
    # an ASCII PLY from another tool: no comment, no intensity → the caller's scale, intensity 0
    text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\n" \
           "end_header\n1 2 3\n4 5 6\n"
    (tmp_path / "o.ply").write_text(text)
    other = read_points(tmp_path / "o.ply", scale="0-255")
    assert other.scale == "0-255" and other.xyz.tolist() == [[1, 2, 3], [4, 5, 6]]
    assert other.intensity.tolist() == [0, 0]


def test_npy_layouts(tmp_path):
    a = np.array([(1.0, 2.0, 3.0, 40.0, 5)], dtype=[("x", "f4"), ("y", "f4"), ("z", "f4"), ("intensity", "f4"),
                                                    ("ring", "u1")])
    np.save(tmp_path / "s.npy", a)
    s = read_points(tmp_path / "s.npy", scale="0-255")
    assert s.ring.tolist() == [5] and s.raw_intensity.tolist() == [40.0]
    np.save(tmp_path / "p.npy", np.array([[1.0, 2.0, 3.0]]))  # N×3 float64 → float32, intensity 0
    p = read_points(tmp_path / "p.npy")
    assert p.xyz.dtype == np.float32 and p.intensity.tolist() == [0.0]


def test_transform_select_and_rings():
    xyz = np.array([[10, 0, 0], [0, 10, 0], [10, 0, -10 * math.tan(math.radians(5))]], np.float32)
    c = PointCloud.from_raw(xyz, [0.1, 0.2, 0.3], "0-1", "t")
    pose = np.eye(4)
    pose[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # yaw +90°
    pose[:3, 3] = [1, 2, 3]
    moved = c.transformed(pose)
    np.testing.assert_allclose(moved.xyz, [[1, 12, 3], [-9, 2, 3], [1, 12, 3 + xyz[2, 2]]], atol=1e-5)
    sub = c.select(np.array([False, True, True]))
    assert sub.index.tolist() == [1, 2] and np.array_equal(sub.xyz, xyz[1:])
    rings = c.estimated_rings(np.radians([2.0, 0.0, -5.0, -10.0]))
    assert rings.tolist() == [1, 1, 2]


# ----------------------------------------------------------------------------- bad input: one line naming the file
def _one_line(exc: InputError, path) -> str:
    text = str(exc)
    assert "\n" not in text and text.startswith(str(path))
    return text


@pytest.mark.parametrize("fmt,size", [("kitti", 4 * 4 * 3 + 5), ("stf", 5 * 4 * 2 + 16)])
def test_a_bin_that_is_not_whole_records_is_refused(tmp_path, fmt, size):
    path = tmp_path / "bad.bin"
    path.write_bytes(b"\0" * size)
    with pytest.raises(InputError) as e:
        read_points(path, fmt)
    assert "not a whole number" in _one_line(e.value, path)


def test_a_kitti_scan_read_as_stf_is_refused_by_its_size_or_its_scale(tmp_path):
    xyz = np.ones((5, 3), np.float32)
    path = tmp_path / "k.bin"
    path.write_bytes(lfx.kitti_bin(xyz, np.full(5, 0.5, np.float32)))  # 80 bytes = 4 STF records
    with pytest.raises(InputError) as e:
        read_points(path, "stf")
    _one_line(e.value, path)


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_non_finite_coordinates_are_refused(tmp_path, value):
    xyz = np.ones((4, 3), np.float32)
    xyz[2, 1] = value
    path = tmp_path / "n.bin"
    path.write_bytes(lfx.kitti_bin(xyz, np.zeros(4, np.float32)))
    with pytest.raises(InputError) as e:
        read_points(path, "kitti")
    assert "NaN or infinite coordinates" in _one_line(e.value, path) and "row 2" in str(e.value)


def test_intensities_outside_the_declared_scale_are_refused(tmp_path):
    xyz = np.ones((3, 3), np.float32)
    path = tmp_path / "k.bin"
    path.write_bytes(lfx.kitti_bin(xyz, np.array([0.2, 200.0, 0.1], np.float32)))  # a "0–1" file holding 200
    with pytest.raises(InputError) as e:
        read_points(path, "kitti")
    assert "outside the declared 0-1 scale" in _one_line(e.value, path)
    neg = tmp_path / "s.bin"
    neg.write_bytes(lfx.stf_bin(xyz, np.array([3, -1, 300], np.float32), np.zeros(3, np.float32)))
    with pytest.raises(InputError, match="outside the declared 0-255"):
        read_points(neg, "stf")
    nan = tmp_path / "nan.bin"
    nan.write_bytes(lfx.kitti_bin(xyz, np.array([0.2, np.nan, 0.1], np.float32)))
    with pytest.raises(InputError, match="NaN or infinite"):
        read_points(nan, "kitti")


def test_0_1_data_declared_0_255_is_refused(tmp_path):
    n = 500
    xyz = np.ones((n, 3), np.float32)
    path = tmp_path / "s.bin"
    path.write_bytes(lfx.stf_bin(xyz, np.linspace(0.01, 0.99, n).astype(np.float32), np.zeros(n, np.float32)))
    with pytest.raises(InputError) as e:
        read_points(path, "stf")
    assert "0–1 data" in _one_line(e.value, path)


def test_an_empty_scan_is_refused(tmp_path):
    path = tmp_path / "e.bin"
    path.write_bytes(b"")
    with pytest.raises(InputError) as e:
        read_points(path, "kitti")
    assert "empty scan" in _one_line(e.value, path)


def test_fractional_rings_missing_files_pickles_and_damaged_ply_are_refused(tmp_path):
    xyz = np.ones((2, 3), np.float32)
    path = tmp_path / "r.bin"
    path.write_bytes(lfx.stf_bin(xyz, np.array([1, 2], np.float32), np.array([0.5, 1], np.float32)))
    with pytest.raises(InputError, match="whole numbers"):
        read_points(path, "stf")
    with pytest.raises(InputError, match="file not found"):
        read_points(tmp_path / "missing.bin", "kitti")
    obj = tmp_path / "o.npy"
    obj.write_bytes(_object_npy())
    with pytest.raises(InputError, match="pickled"):
        read_points(obj)
    bad = tmp_path / "b.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nend_header\n\0\0")
    with pytest.raises(InputError) as e:
        read_points(bad)
    _one_line(e.value, bad)
    with pytest.raises(ValueError, match="say which format"):
        detect_format("x.bin")


def _object_npy() -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    return buf.getvalue()


def test_scales_normalise_and_invert():
    raw = np.array([0, 100, 255], np.float32)
    s = scale("0-255")
    np.testing.assert_allclose(s.normalise(raw), raw / 255, rtol=1e-7)
    norm, back = s.from_linear(s.to_linear(s.normalise(raw)))
    np.testing.assert_allclose(back, raw, rtol=1e-6)
    t = scale("tanh")
    assert t.to_linear(t.normalise(np.float32([3.0])), np.float32([3.0]))[0] == 3.0
    assert scale("0-1").problem(np.float32([0, 1.5])) and scale("tanh").problem(np.float32([-1]))
    with pytest.raises(ValueError, match="unknown intensity scale"):
        scale("0-100")


def test_writes_are_atomic_and_need_rings_for_five_columns(tmp_path):
    cloud = PointCloud.from_raw(np.ones((2, 3), np.float32), [0.1, 0.2], "0-1", "k")
    with pytest.raises(ValueError, match="ring"):
        write_points(tmp_path / "x.bin", cloud, "stf")
    assert not list(tmp_path.iterdir())  # nothing half-written
    write_points(tmp_path / "x.bin", cloud, "kitti")
    assert [p.name for p in tmp_path.iterdir()] == ["x.bin"]
    with_rings = PointCloud.from_raw(np.ones((2, 3), np.float32), [0.1, 0.2], "0-1", "k", ring=[3, 4])
    write_points(tmp_path / "y.bin", with_rings, "stf")  # 0–1 → 0–255 through the normalised value
    back = read_points(tmp_path / "y.bin", "stf")
    np.testing.assert_allclose(back.raw_intensity, [25.5, 51.0], rtol=1e-6)
