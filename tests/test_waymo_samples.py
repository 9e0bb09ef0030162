"""Waymo samples (``fogsim.readers.waymo.samples``, ``.images``) on v1 and v2 fixtures built here:
keys, intrinsics, images, depth folders, damaged and empty inputs, the CLI."""
from __future__ import annotations

import pickle
import sys

import numpy as np
import pytest

from fogsim.camera import Intrinsics
from fogsim.errors import InputError, MissingDependency, exit_code
from fogsim.io.images import encode_image
from fogsim.readers.base import DepthSpec
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo import waymo_v1_samples, waymo_v2_samples
from fogsim.readers.waymo.tfrecord import index_tfrecord, write_tfrecord

CONTEXT = "1005081002024129653_5313_150_5333_150"
TIMESTAMPS = (1510593602340000, 1510593602440000)
W, H = 16, 12
# camera id → (f_u, f_v, c_u, c_v, k1, k2, p1, p2, k3)
CALIB = {1: (20.0, 21.0, 7.5, 5.5, 0.1, 0.2, 0.3, 0.4, 0.5),
         2: (30.0, 31.0, 8.0, 6.0, -0.1, -0.2, -0.3, -0.4, -0.5)}


def _front(t: int) -> np.ndarray:
    """Noise image: exact through PNG."""
    return np.random.default_rng(t).integers(0, 256, (H, W, 3), dtype=np.uint8)


def _front_left(t: int) -> np.ndarray:
    """Smooth image: close through JPEG."""
    y, x = np.mgrid[0:H, 0:W]
    return np.stack([x * 12 + t, y * 16, np.full_like(x, 128)], axis=2).astype(np.uint8)


def _calibration(camera: int, packed: bool) -> bytes:
    values = CALIB[camera]
    intrinsic = (pw.packed_doubles(2, values) if packed
                 else b"".join(pw.double_field(2, v) for v in values))
    extrinsic = pw.bytes_field(3, pw.packed_doubles(1, np.eye(4).ravel()))
    return (pw.varint_field(1, camera) + intrinsic + extrinsic + pw.varint_field(4, W)
            + pw.varint_field(5, H) + pw.varint_field(6, 2))


def _camera_image(camera: int, data: bytes) -> bytes:
    return (pw.varint_field(1, camera) + pw.bytes_field(2, data)
            + pw.bytes_field(3, pw.packed_doubles(1, np.eye(4).ravel())) + pw.double_field(5, 1.5))


def _frame(context: str, t: int) -> bytes:
    """A Frame with two calibrations (unpacked and packed doubles), two images, a laser."""
    ctx = (pw.bytes_field(1, context) + pw.bytes_field(2, _calibration(1, packed=False))
           + pw.bytes_field(2, _calibration(2, packed=True)))
    images = (pw.bytes_field(4, _camera_image(1, encode_image(_front(t), ".png")))
              + pw.bytes_field(4, _camera_image(2, encode_image(_front_left(t), ".jpg"))))
    laser = pw.bytes_field(5, pw.varint_field(1, 1) + pw.bytes_field(2, b"\x00" * 64))
    return (pw.bytes_field(1, ctx) + pw.varint_field(2, TIMESTAMPS[t])
            + pw.bytes_field(3, pw.packed_doubles(1, np.eye(4).ravel())) + images + laser)


@pytest.fixture
def v1_file(tmp_path):
    path = tmp_path / "segment-1.tfrecord"
    write_tfrecord(path, [_frame(CONTEXT, 0), _frame(CONTEXT, 1)])
    return path


def _key(t: int, camera: str) -> str:
    return f"{CONTEXT}/{TIMESTAMPS[t]}_{camera}"


@pytest.mark.parametrize("where", ["in the data", "in the header"])
def test_truncated_file_names_file_and_record(v1_file, where):
    raw = v1_file.read_bytes()
    second = index_tfrecord(v1_file)[1][0] - 12  # start of record 1's header
    v1_file.write_bytes(raw[:-3] if where == "in the data" else raw[:second + 5])
    with pytest.raises(InputError, match="truncated") as err:
        waymo_v1_samples(v1_file)
    assert err.value.source == f"{v1_file}#record 1"


# ----------------------------------------------------------------------------- v1
def test_v1_samples_keys_intrinsics_and_images(v1_file):
    samples = waymo_v1_samples(v1_file, cameras=("FRONT", "FRONT_LEFT"))
    assert [s.key for s in samples] == [_key(0, "FRONT"), _key(0, "FRONT_LEFT"),
                                        _key(1, "FRONT"), _key(1, "FRONT_LEFT")]
    assert samples[3].source == f"{v1_file}#record 1 FRONT_LEFT"
    assert samples[0].intrinsics == Intrinsics(20.0, 21.0, 7.5, 5.5, W, H)
    assert samples[1].intrinsics == Intrinsics(30.0, 31.0, 8.0, 6.0, W, H)
    assert samples[1].meta["distortion"] == dict(zip(("k1", "k2", "p1", "p2", "k3"), CALIB[2][4:]))
    assert all(s.depth is None for s in samples)
    np.testing.assert_array_equal(samples[2].read_image(), _front(1))
    jpeg = samples[3].read_image().astype(int)
    assert jpeg.shape == (H, W, 3) and np.abs(jpeg - _front_left(1)).mean() < 4


def test_v1_camera_selection(v1_file, tmp_path):
    assert [s.key for s in waymo_v1_samples(v1_file, cameras=("front_left",))] == \
        [_key(0, "FRONT_LEFT"), _key(1, "FRONT_LEFT")]
    with pytest.raises(InputError, match="none of its 2 frames"):  # not in these frames
        waymo_v1_samples(v1_file, cameras=("SIDE_LEFT",))
    with pytest.raises(ValueError, match="FRONT_RIGHT"):
        waymo_v1_samples(v1_file, cameras=("BACK",))


def test_v1_folder_sorted_and_sanitized_context(tmp_path, v1_file):
    write_tfrecord(tmp_path / "segment-0.tfrecord", [_frame("a b/../c", 0)])
    samples = waymo_v1_samples(tmp_path)
    assert [s.key for s in samples] == [f"a_b_.._c/{TIMESTAMPS[0]}_FRONT",
                                        _key(0, "FRONT"), _key(1, "FRONT")]
    assert samples[0].meta["context"] == "a b/../c"


def test_v1_duplicate_frames_refused(tmp_path, v1_file):
    (tmp_path / "copy.tfrecord").write_bytes(v1_file.read_bytes())
    with pytest.raises(InputError, match="duplicate"):
        waymo_v1_samples(tmp_path)


def test_v1_not_a_frame(tmp_path):
    path = tmp_path / "other.tfrecord"
    write_tfrecord(path, [pw.varint_field(3, 1)])
    with pytest.raises(InputError, match="not a Waymo Frame") as err:
        waymo_v1_samples(path)
    assert err.value.source == f"{path}#record 0"


def test_depth_dir_matching(v1_file, tmp_path):
    depth_dir = tmp_path / "depth"
    (depth_dir / CONTEXT).mkdir(parents=True)
    for t in (0, 1):
        np.save(depth_dir / f"{_key(t, 'FRONT')}.npy", np.ones((H, W), np.float32))
    template = DepthSpec(path="", encoding="metric", kind="ray", png_scale=0.01)
    samples = waymo_v1_samples(v1_file, depth_dir=depth_dir, depth=template)
    assert samples[1].depth == DepthSpec(str(depth_dir / f"{_key(1, 'FRONT')}.npy"),
                                         "metric", "ray", 0.01)
    with pytest.raises(InputError, match="depth map") as err:
        waymo_v1_samples(v1_file, cameras=("FRONT_LEFT",), depth_dir=depth_dir)
    assert err.value.source == str(depth_dir / f"{_key(0, 'FRONT_LEFT')}.exr")


def test_samples_pickle(v1_file):
    samples = pickle.loads(pickle.dumps(waymo_v1_samples(v1_file, cameras=("FRONT",))))
    np.testing.assert_array_equal(samples[0].read_image(), _front(0))


# ----------------------------------------------------------------------------- v2
def _write_v2(root, pa, pq):
    """camera_image with 3 cameras per frame (row groups of 4) and camera_calibration."""
    rows = [(t, cam) for t in (0, 1) for cam in (1, 2, 4)]
    images = {1: lambda t: encode_image(_front(t), ".png"),
              2: lambda t: encode_image(_front_left(t), ".jpg"),
              4: lambda t: encode_image(_front(t), ".png")}
    table = pa.table({
        "key.segment_context_name": [CONTEXT] * len(rows),
        "key.frame_timestamp_micros": pa.array([TIMESTAMPS[t] for t, _ in rows], pa.int64()),
        "key.camera_name": pa.array([cam for _, cam in rows], pa.int8()),
        "[CameraImageComponent].image": pa.array([images[c](t) for t, c in rows], pa.binary()),
    })
    (root / "camera_image").mkdir(parents=True)
    pq.write_table(table, root / "camera_image" / f"{CONTEXT}.parquet", row_group_size=4)
    cal = "[CameraCalibrationComponent]"
    names = ("f_u", "f_v", "c_u", "c_v", "k1", "k2", "p1", "p2", "k3")
    columns = {"key.segment_context_name": [CONTEXT] * 2,
               "key.camera_name": pa.array([1, 2], pa.int8()),
               f"{cal}.width": pa.array([W, W], pa.int32()),
               f"{cal}.height": pa.array([H, H], pa.int32())}
    columns |= {f"{cal}.intrinsic.{n}": [CALIB[1][i], CALIB[2][i]] for i, n in enumerate(names)}
    (root / "camera_calibration").mkdir()
    pq.write_table(pa.table(columns), root / "camera_calibration" / f"{CONTEXT}.parquet")


def test_v2_matches_v1(tmp_path, v1_file):
    pa = pytest.importorskip("pyarrow", exc_type=ImportError)
    pq = pytest.importorskip("pyarrow.parquet", exc_type=ImportError)
    _write_v2(tmp_path / "training", pa, pq)
    v2 = waymo_v2_samples(tmp_path / "training", cameras=("FRONT", "FRONT_LEFT"))
    v1 = waymo_v1_samples(v1_file, cameras=("FRONT", "FRONT_LEFT"))
    assert [(s.key, s.intrinsics, s.meta["distortion"]) for s in v2] == \
        [(s.key, s.intrinsics, s.meta["distortion"]) for s in v1]
    assert v2[3].source.endswith("#row 4 FRONT_LEFT")
    for a, b in zip(pickle.loads(pickle.dumps(v2)), v1):
        np.testing.assert_array_equal(a.read_image(), b.read_image())


def test_v2_unreadable_files(tmp_path):
    pa = pytest.importorskip("pyarrow", exc_type=ImportError)
    pq = pytest.importorskip("pyarrow.parquet", exc_type=ImportError)
    (tmp_path / "camera_image").mkdir()
    path = tmp_path / "camera_image" / "x.parquet"
    pq.write_table(pa.table({"key.segment_context_name": ["a"]}), path)
    with pytest.raises(InputError, match="missing column") as err:
        waymo_v2_samples(tmp_path)
    assert err.value.source == str(path)
    path.write_bytes(b"not parquet")
    with pytest.raises(InputError, match="not a readable parquet"):
        waymo_v2_samples(tmp_path)


def test_v2_errors(tmp_path, monkeypatch):
    with pytest.raises(InputError, match="camera_image"):
        waymo_v2_samples(tmp_path)
    (tmp_path / "camera_image").mkdir()
    (tmp_path / "camera_image" / "x.parquet").write_bytes(b"not parquet")
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)  # as if pyarrow were missing
    with pytest.raises(MissingDependency, match=r"pip install -e '\.\[waymo\]'") as err:
        waymo_v2_samples(tmp_path)
    assert exit_code(err.value) == 2  # a setup error, not a failed run


def test_v2_without_pyarrow_exits_2_through_the_cli(tmp_path, monkeypatch, capsys):
    from fogsim.cli import main

    split = tmp_path / "training"
    (split / "camera_image").mkdir(parents=True)
    (split / "camera_image" / "x.parquet").write_bytes(b"not parquet")
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    assert main(["fog", "--waymo", str(split), "--levels", "0.06", "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "'waymo' extra" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


# ----------------------------------------------------------------------------- through the CLI
def test_cli_fogs_waymo_with_depth_dir(v1_file, tmp_path, capsys):
    from fogsim.camera import Intrinsics, planar_to_ray
    from fogsim.cli import main
    from fogsim.io.depth_files import write_depth
    from fogsim.io.images import read_image

    depth = np.random.default_rng(4).uniform(2, 80, (H, W)).astype(np.float32)
    for t in (0, 1):
        write_depth(tmp_path / "depth" / f"{_key(t, 'FRONT')}.exr", depth)
    out = tmp_path / "out"
    assert main(["fog", "--waymo", str(v1_file), "--depth-dir", str(tmp_path / "depth"), "--levels", "0.06",
                 "--workers", "2", "--out", str(out), "--quiet"]) == 0
    f_u, f_v, c_u, c_v = CALIB[1][:4]
    ray = planar_to_ray(depth, Intrinsics(f_u, f_v, c_u, c_v, W, H)).astype(np.float64)
    t = np.exp(-0.06 * ray)[..., None]
    got = read_image(out / "beta0.06" / f"{_key(1, 'FRONT')}.png")
    assert np.abs(got - (_front(1) * t + 255 * (1 - t))).max() <= 0.5 + 1e-2
    capsys.readouterr()
    # no --depth-dir: a setup error of the whole run (exit 2), found before OUT is claimed
    assert main(["fog", "--waymo", str(v1_file), "--levels", "0.06", "--out", str(tmp_path / "o2"), "--quiet"]) == 2
    assert "has no depth" in capsys.readouterr().err
    assert not (tmp_path / "o2").exists()


# ----------------------------------------------------------------------------- damaged / empty inputs
def _depth_for(tmp_path, keys):
    from fogsim.io.depth_files import write_depth

    for key in keys:
        write_depth(tmp_path / "depth" / f"{key}.exr", np.full((H, W), 20.0, np.float32))
    return tmp_path / "depth"


def _fog(*args):
    from fogsim.cli import main

    return main(["fog", "--levels", "0.06", "--quiet", *map(str, args)])


def test_flipped_byte_in_a_record_is_refused_unless_no_verify(v1_file, tmp_path, capsys, crc_impl):
    """#4: a damaged record is found by its data CRC in the plain install (numpy fallback)."""
    raw = bytearray(v1_file.read_bytes())
    offset, length = index_tfrecord(v1_file)[1]
    raw[offset + length - 30] ^= 0xFF  # inside the laser blob: the images decode fine
    v1_file.write_bytes(bytes(raw))
    depth = _depth_for(tmp_path, [_key(t, "FRONT") for t in (0, 1)])
    assert _fog("--waymo", v1_file, "--depth-dir", depth, "--out", tmp_path / "o") == 2
    err = capsys.readouterr().err
    assert f"{v1_file}#record 1: corrupt TFRecord (data CRC mismatch" in err
    assert not (tmp_path / "o").exists()
    assert _fog("--waymo", v1_file, "--depth-dir", depth, "--out", tmp_path / "o2", "--no-verify") == 0
    assert "fogged 2 of 2" in capsys.readouterr().out


def _frame_with_front(context: str, t: int, front: bytes) -> bytes:
    ctx = pw.bytes_field(1, context) + pw.bytes_field(2, _calibration(1, packed=False))
    return (pw.bytes_field(1, ctx) + pw.varint_field(2, TIMESTAMPS[t])
            + pw.bytes_field(4, _camera_image(1, front)))


def _big_jpeg() -> bytes:
    y, x = np.mgrid[0:240, 0:320]  # the aspect ratio of the calibration (W×H)
    img = np.stack([x % 256, y % 256, (x + y) % 256], axis=2).astype(np.uint8)
    return encode_image(img, ".jpg")


@pytest.mark.parametrize("damage, message", [("truncated", "truncated JPEG"),
                                             ("zeroed", "corrupt image data")])
def test_damaged_jpeg_in_a_frame_fails_that_image(tmp_path, capfd, damage, message):
    """#3: JPEG bytes that are damaged inside an intact record (its CRC is right)."""
    good = _big_jpeg()
    bad = bytearray(good)
    if damage == "truncated":
        bad = bad[:len(bad) // 2]
    else:
        bad[len(bad) // 3:len(bad) // 3 + 2000] = bytes(2000)
    path = tmp_path / "seg.tfrecord"
    write_tfrecord(path, [_frame_with_front(CONTEXT, 0, good), _frame_with_front(CONTEXT, 1, bytes(bad))])
    samples = waymo_v1_samples(path)
    assert samples[0].read_image().shape == (240, 320, 3)
    with pytest.raises(InputError, match=message) as err:
        samples[1].read_image()
    assert err.value.source == f"{path}#record 1 FRONT"
    capfd.readouterr()
    depth = tmp_path / "depth"
    from fogsim.io.depth_files import write_depth

    for t in (0, 1):
        write_depth(depth / f"{_key(t, 'FRONT')}.exr", np.full((240, 320), 20.0, np.float32))
    assert _fog("--waymo", path, "--depth-dir", depth, "--out", tmp_path / "o") == 1
    err = capfd.readouterr().err
    assert f"{path}#record 1 FRONT: {message}" in err and "Premature end" not in err
    assert (tmp_path / "o" / "beta0.06" / f"{_key(0, 'FRONT')}.png").is_file()
    assert not (tmp_path / "o" / "beta0.06" / f"{_key(1, 'FRONT')}.png").exists()


def test_nothing_to_do_is_an_error(v1_file, tmp_path, capsys):
    """#16: an empty .tfrecord, or cameras in no frame, exit 2 like an empty image folder."""
    empty = tmp_path / "empty.tfrecord"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match="no frames") as err:
        waymo_v1_samples(empty)
    assert err.value.source == str(empty)
    depth = tmp_path / "depth"
    depth.mkdir()
    assert _fog("--waymo", empty, "--depth-dir", depth, "--out", tmp_path / "o") == 2
    assert f"{empty}: no frames in it" in capsys.readouterr().err
    assert _fog("--waymo", v1_file, "--cameras", "REAR", "--depth-dir", depth, "--out", tmp_path / "o2") == 2
    err = capsys.readouterr().err
    assert "none of its 2 frames has an image from camera(s) REAR" in err and "FRONT, FRONT_LEFT" in err
    assert not (tmp_path / "o").exists() and not (tmp_path / "o2").exists()


def test_v2_null_or_mistyped_key_is_named(tmp_path, capsys):
    """#15: a null segment name (or timestamp) is a clear error naming file and row."""
    pa = pytest.importorskip("pyarrow", exc_type=ImportError)
    pq = pytest.importorskip("pyarrow.parquet", exc_type=ImportError)
    root = tmp_path / "v2"
    (root / "camera_image").mkdir(parents=True)
    path = root / "camera_image" / "x.parquet"
    image = encode_image(_front(0), ".png")
    pq.write_table(pa.table({
        "key.segment_context_name": pa.array([CONTEXT, None], pa.string()),
        "key.frame_timestamp_micros": pa.array([TIMESTAMPS[0], TIMESTAMPS[1]], pa.int64()),
        "key.camera_name": pa.array([1, 1], pa.int8()),
        "[CameraImageComponent].image": pa.array([image, image], pa.binary()),
    }), path)
    with pytest.raises(InputError, match="key.segment_context_name is None") as err:
        waymo_v2_samples(root)
    assert err.value.source == f"{path}#row 1 FRONT"
    assert _fog("--waymo", root, "--out", tmp_path / "o") == 2
    assert f"{path}#row 1 FRONT: malformed Waymo v2 key" in capsys.readouterr().err
    pq.write_table(pa.table({
        "key.segment_context_name": pa.array([CONTEXT], pa.string()),
        "key.frame_timestamp_micros": pa.array([None], pa.int64()),
        "key.camera_name": pa.array([1], pa.int8()),
        "[CameraImageComponent].image": pa.array([image], pa.binary()),
    }), path)
    with pytest.raises(InputError, match="key.frame_timestamp_micros is None"):
        waymo_v2_samples(root)
    with pytest.raises(InputError, match="none of its 1 camera_image rows"):
        waymo_v2_samples(root, cameras=("REAR",))


def test_non_finite_waymo_calibration_is_named(tmp_path):
    path = tmp_path / "seg.tfrecord"
    cal = (pw.varint_field(1, 1) + pw.packed_doubles(2, (float("nan"), 21.0, 7.5, 5.5, 0, 0, 0, 0, 0))
           + pw.varint_field(4, W) + pw.varint_field(5, H))
    ctx = pw.bytes_field(1, CONTEXT) + pw.bytes_field(2, cal)
    frame = (pw.bytes_field(1, ctx) + pw.varint_field(2, TIMESTAMPS[0])
             + pw.bytes_field(4, _camera_image(1, encode_image(_front(0), ".png"))))
    write_tfrecord(path, [frame])
    with pytest.raises(InputError, match="unusable camera calibration .*finite") as err:
        waymo_v1_samples(path)
    assert err.value.source.startswith(f"{path}#record 0")
