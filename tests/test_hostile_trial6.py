"""The sixth hostile-input trial's defects of the readers and sensors (``shared/notes/reliability-defects-6.md``,
D01–D07 and D19: the PCD codec, ``.npy`` and PLY, the radar, LiDAR and radar sensor grids, the messages),
each as the trial reproduced it, in the style of :mod:`test_hostile_sensors`: the exit code, one line naming
the file and the problem, no traceback, the inputs unchanged, nothing partial. The outputs' defects (D08–D18,
D20–D24): :mod:`test_hostile_trial6_runs`.

Memory bounds are checked without timing: a sparse file (``truncate``) that would need gigabytes, read in
a process of its own under a 1.5 GB address-space limit (``RLIMIT_AS``) — reading the body would fail with
MemoryError; the refusal must come from the header first.
"""
from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest

import lidar_fixtures as lf
from conftest import run_sensor_case
from fogsim.errors import InputError
from test_hostile import Case
from test_hostile_sensors import (
    HUGE,
    RADAR_FIELDS,
    RADAR_RECORD,
    RADAR_SIZE,
    RADAR_TYPE,
    _bounded,
    _good_scan,
    _npy_header,
    _ply,
    _points,
    _radar,
    radar_header,
    run_limited,
    sparse,
)

BAD = "n008__RADAR_FRONT__2.pcd"
#: the trial's sparse bodies: 4 GiB (under the ASCII bound of 48 characters a number for 10⁷ points)
FOUR_GB = 4 << 30


# ------------------------------------------------------------------ D01–D04: readers bounded before they allocate
def _fog_points_limited(tmp_path: Path, name: str, fmt: str, *flags: str):
    return run_limited(["-m", "fogsim", "fog", "--points", str(tmp_path / "in" / name), "--point-format", fmt,
                        "--levels", "0.06", "--out", str(tmp_path / "out"), "--quiet", *flags], tmp_path)


def test_d01_a_binary_compressed_pcd_is_refused_from_its_size_prefix(tmp_path):
    """D01: POINTS 1, DATA binary_compressed and a 16 GB (sparse) body: refused from the header and the
    8-byte size prefix, never read whole."""
    pytest.importorskip("lzf")
    pytest.importorskip("itur")
    sparse(tmp_path / "in" / BAD, HUGE, radar_header(1, data="binary_compressed"))
    _bounded(_fog_points_limited(tmp_path, BAD, "nuscenes-radar"), 1, BAD, "binary_compressed sizes (0 → 0 bytes)",
             "do not match the header's 1 points (43 bytes)")


def _read_pcd_limited(tmp_path: Path, path: Path):
    """``read_pcd(path)`` in a process of its own under the 1.5 GB address-space limit; its refusal on stderr."""
    code = ("import sys\nfrom fogsim.errors import InputError\nfrom fogsim.lidar.pcd import read_pcd\n"
            f"try:\n    read_pcd({str(path)!r})\n"
            "except InputError as exc:\n    print('error:', exc, file=sys.stderr)\n")
    return run_limited(["-c", code], tmp_path)


def test_d01_a_right_prefix_before_a_huge_body_is_refused_too(tmp_path):
    pytest.importorskip("lzf")
    import lzf

    from fogsim.lidar.pcd import read_pcd

    packed = lzf.compress(b"\x01\x02" * 43)
    head = radar_header(2, data="binary_compressed") + struct.pack("<II", len(packed), 2 * RADAR_RECORD) + packed
    path = tmp_path / "RADAR_FRONT__1.pcd"
    path.write_bytes(head)
    assert read_pcd(path)[1].tobytes() != bytes(86)  # the well-formed file reads (its columns)
    sparse(path, HUGE, head)
    _bounded(_read_pcd_limited(tmp_path, path), 0, "RADAR_FRONT__1.pcd", "far longer than its")


def test_d02_an_ascii_pcd_without_newlines_is_refused_at_its_first_long_row(tmp_path):
    """D02: POINTS 9,999,999 DATA ascii over a 4 GB body of NULs (no newline): parsed a chunk at a time, the
    first row longer than its numbers may take is refused."""
    pytest.importorskip("itur")
    sparse(tmp_path / "in" / BAD, FOUR_GB, radar_header(9_999_999, data="ascii"))
    _bounded(_fog_points_limited(tmp_path, BAD, "nuscenes-radar"), 1, BAD, "PCD ASCII row 1 is longer than")


def test_d02_an_ascii_pcd_is_parsed_in_chunks(tmp_path):
    """The chunked parse reads a sweep larger than one chunk exactly as written (values, types)."""
    from fogsim.lidar.pcd import ASCII_CHUNK_BYTES, encode_pcd, read_pcd
    from test_hostile_sensors import radar_dtype

    rng = np.random.default_rng(6)
    rec = np.zeros(40_000, radar_dtype())
    for name in RADAR_FIELDS:
        rec[name] = rng.integers(-100, 100, len(rec)) if rec.dtype[name].kind == "i" else rng.normal(0, 50, len(rec))
    data = encode_pcd(rec, "ascii")
    assert len(data) > 2 * ASCII_CHUNK_BYTES
    path = tmp_path / "a.pcd"
    path.write_bytes(data)
    _, got = read_pcd(path)
    for name in RADAR_FIELDS:
        np.testing.assert_array_equal(got[name], rec[name])


def _count_1e8(path: Path) -> None:
    head = radar_header(5, FIELDS=" ".join(RADAR_FIELDS + ["junk"]), SIZE=" ".join(RADAR_SIZE + ["8"]),
                        TYPE=" ".join(RADAR_TYPE + ["F"]), COUNT=" ".join(["1"] * 18 + ["100000000"]))
    sparse(path, 5 * (RADAR_RECORD + 800_000_000) + len(head), head)


def test_d03_a_field_of_count_1e8_is_refused_from_the_header(tmp_path):
    """D03: an extra field of COUNT 100,000,000 (SIZE 8) makes 5 points 4 GB: refused from the header, before
    the body is read — by the radar reader (COUNT > 1) and by the PCD codec itself (a point's record may
    take 256 bytes)."""
    pytest.importorskip("itur")
    _count_1e8(tmp_path / "in" / BAD)
    _bounded(_fog_points_limited(tmp_path, BAD, "nuscenes-radar"), 1, BAD, "PCD field junk has COUNT 100,000,000")
    _bounded(_read_pcd_limited(tmp_path, tmp_path / "in" / BAD), 0, BAD, "takes 800,000,043 bytes",
             "field junk: COUNT 100,000,000 × SIZE 8", "256 bytes")


def test_d03_a_scan_over_the_byte_bound_is_refused(tmp_path, monkeypatch):
    """Within the point bound, within the record bound, over the bytes: 1,000 points × 200 bytes against a
    bound lowered to 1,000 points (64 bytes each)."""
    from fogsim.lidar.pcd import read_pcd

    monkeypatch.setenv("FOGSIM_MAX_SCAN_POINTS", "1000")
    head = radar_header(1000, FIELDS="x y z w", SIZE="8 8 8 8", TYPE="F F F F", COUNT="1 1 1 22")
    path = tmp_path / "a.pcd"
    path.write_bytes(head + b"\0" * 1000 * 200)
    with pytest.raises(InputError, match="1,000 points × 200 bytes = 200,000 bytes exceeds the bound of 64,000"):
        read_pcd(path)


def test_d03_a_structured_npy_with_a_huge_field_is_refused_from_its_header(tmp_path):
    """D03: a LiDAR .npy whose structured dtype has a 100 MB void field, shape (40,): 4 GB from 40 points."""
    descr = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("pad", "|V100000000")]
    head = _npy_header((40,), descr, body=b"")
    sparse(tmp_path / "in" / "a.npy", 40 * 100_000_012 + len(head), head)
    _bounded(_fog_points_limited(tmp_path, "a.npy", "npy", "--sensor", "hdl64e"), 1, "a.npy",
             "takes 100,000,012 bytes", "256 bytes")


def test_d03_radar_count_above_one_is_refused_from_the_header(tmp_path):
    """The radar reader refuses COUNT > 1 from the header, before the body."""
    from fogsim.radar.formats import read_radar

    head = radar_header(2, COUNT=" ".join(["1"] * 17 + ["2"]))
    path = tmp_path / BAD
    sparse(path, len(head) + 2 * (RADAR_RECORD + 1) + (1 << 30), head)  # 1 GB after the records: never read
    with pytest.raises(InputError, match="vy_rms has COUNT 2"):
        read_radar(path, "nuscenes-radar")


def _ply_elements(vertex: int, other: int, fmt: str = "binary_little_endian") -> bytes:
    return (f"ply\nformat {fmt} 1.0\nelement vertex {vertex}\nproperty float x\nproperty float y\nproperty float z\n"
            f"element junk {other}\nproperty float a\nend_header\n").encode()


def test_d04_a_ply_element_other_than_vertex_is_never_read(tmp_path):
    """D04: ``element vertex 3`` then ``element junk 900000000`` (3.6 GB): only the vertex element is read
    (and the other element's count is bounded like the vertices')."""
    head = _ply_elements(3, 900_000_000)
    sparse(tmp_path / "in" / "a.ply", len(head) + 3 * 12 + 900_000_000 * 4, head)
    _bounded(_fog_points_limited(tmp_path, "a.ply", "ply", "--sensor", "hdl64e"), 1, "a.ply",
             "element junk of 900,000,000 rows exceeds the bound of 10,000,000")


def test_d04_only_the_vertex_element_is_read(tmp_path):
    """A PLY whose vertex element comes after another fixed-size element and before a face list: the
    vertices read exactly, whatever follows them."""
    from fogsim.lidar.formats import read_points

    xyz = np.arange(12, dtype="<f4").reshape(4, 3) + 1
    head = ("ply\nformat binary_little_endian 1.0\nelement camera 1\nproperty double f\n"
            "element vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 2\nproperty list uchar int vertex_indices\nend_header\n").encode()
    faces = (b"\x03" + np.array([0, 1, 2], "<i4").tobytes()) * 2
    path = tmp_path / "a.ply"
    path.write_bytes(head + np.float64(2.5).tobytes() + xyz.tobytes() + faces)
    np.testing.assert_array_equal(read_points(path, "ply").xyz, xyz)
    ascii_ply = ("ply\nformat ascii 1.0\nelement camera 1\nproperty double f\nelement vertex 4\nproperty float x\n"
                 "property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                 "end_header\n2.5\n" + "".join(" ".join(f"{v:g}" for v in row) + "\n" for row in xyz)
                 + "3 0 1 2\n")
    path.write_text(ascii_ply)
    np.testing.assert_array_equal(read_points(path, "ply").xyz, xyz)


def test_d04_an_ascii_ply_without_newlines_is_refused_at_its_first_long_line(tmp_path):
    """D04: an ASCII PLY declaring 9,999,999 vertices over a 4 GB body of NULs (no newline)."""
    sparse(tmp_path / "in" / "a.ply", FOUR_GB, _ply(9_999_999, fmt="ascii", body=b""))
    _bounded(_fog_points_limited(tmp_path, "a.ply", "ply", "--sensor", "hdl64e"), 1, "a.ply",
             "PLY ASCII line 1 is longer than")


# ----------------------------------------------------------------------------- D05–D07: sensor grids bounded where read
LIDAR_SENSOR = {"beams": 64, "vertical_fov_deg": [-24.9, 2.0], "horizontal_resolution_deg": 0.18,
                "max_range_m": 120.0, "intensity_scale": "0-1"}


def _write_json(path: Path, doc: dict) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("change, says", [
    ({"horizontal_resolution_deg": 1e-6}, "64 beams × horizontal_resolution_deg 1e-06 over 360°: 360,000,000 steps"),
    ({"beams": 1024, "horizontal_resolution_deg": None, "steps_per_sweep": 200_000},
     "1024 beams × steps_per_sweep 200,000 = 204,800,000 rays a sweep"),
])
def test_d05_a_lidar_grid_is_bounded_where_the_sensor_is_read(tmp_path, change, says):
    """D05: beams × steps (steps from a resolution too) bounded when the sensor file is read: one line naming
    it, exit 2, before --out is claimed — never the 21.5 GiB empty-ray grid (run under the 1.5 GB limit)."""
    doc = {k: v for k, v in (LIDAR_SENSOR | change).items() if v is not None}
    sensor = _write_json(tmp_path / "in" / "s.json", doc)
    (tmp_path / "in" / "a.bin").write_bytes(lf.kitti_bin(*_scan_kitti()))
    res = _fog_points_limited(tmp_path, "a.bin", "kitti", "--sensor", str(sensor))
    _bounded(res, 2, "s.json", says, "2,000,000")
    assert not (tmp_path / "out").exists()


def _scan_kitti():
    xyz, rho = _good_scan()
    return xyz, rho / 2.55


def test_d05_the_render_refuses_the_grid_before_blender(tmp_path):
    """``render --lidar FILE``: the same bound, from the preset's check (before Blender, before --out)."""
    from fogsim.render.preset import load_render_preset

    sensor = _write_json(tmp_path / "hres.json", LIDAR_SENSOR | {"horizontal_resolution_deg": 1e-6})
    with pytest.raises(InputError, match="hres.json: .*rays a sweep, more than the 2,000,000"):
        load_render_preset(None, lidar=str(sensor))


@pytest.mark.parametrize("flag", ["--lidar", "--radar"])
def test_d05_d06_render_refuses_the_sensor_before_claiming_its_output(tmp_path, flag):
    """The trial's ``render --lidar hres_tiny.json`` / ``--radar az_res_tiny.json``: exit 2 naming the sensor
    file, no render_run.json — never the 2.68 GiB (8.73 TiB) ray grid (under the 1.5 GB limit)."""
    sensor = _write_json(tmp_path / "s.json", LIDAR_SENSOR | {"horizontal_resolution_deg": 1e-6}) \
        if flag == "--lidar" else _radar_sensor(tmp_path, azimuth_resolution_deg=1e-9)
    res = run_limited(["-m", "fogsim", "render", "--frames", "1", "--resolution", "32x24", "--samples", "1",
                       "--out", str(tmp_path / "out"), "--quiet", flag, str(sensor)], tmp_path)
    _bounded(res, 2, sensor.name, "finer than the 0.01°" if flag == "--radar" else "rays a sweep")
    assert not (tmp_path / "out" / "render_run.json").exists()


def _radar_sensor(tmp_path: Path, **change) -> Path:
    from fogsim.presets import presets_dir

    doc = json.loads((presets_dir() / "radar" / "ars408-lr.json").read_text())
    for key, value in change.items():
        if "." in key:
            doc[key.split(".")[0]][key.split(".")[1]] = value
        else:
            doc[key] = value
    return _write_json(tmp_path / "radar.json", doc)


@pytest.mark.parametrize("change, says", [
    ({"azimuth_resolution_deg": 1e-9}, "azimuth_resolution_deg 1e-09 is finer than the 0.01°"),  # D06
    ({"azimuth_resolution_deg": 1e-2}, "makes a render cast 120,000 × 56 = 6,720,000 rays a sweep"),  # D06
    ({"near_range.azimuth_resolution_deg": 1e-3}, "near_range.azimuth_resolution_deg 0.001 is finer"),
    ({"range_resolution_m": 1e-6}, "range_resolution_m 1e-06 m over 250 m is 250,000,000 range cells"),  # D07
    ({"near_range.range_resolution_m": 1e-3}, "near_range.range_resolution_m 0.001 m over 70 m is 70,000 range"),
])
def test_d06_d07_a_radar_grid_is_bounded_where_the_sensor_is_read(tmp_path, change, says):
    """D06: an azimuth resolution that makes the ray grid unbounded; D07: a range resolution whose cells
    overflow the clustering's 16-bit packing (a KeyError in the trial): refused naming the sensor file, by
    the render's preset check (before Blender) and by ``fog --points`` alike."""
    from fogsim.radar.sensors import load_radar_sensor
    from fogsim.render.preset import load_render_preset

    path = _radar_sensor(tmp_path, **change)
    with pytest.raises(InputError, match="radar.json") as info:
        load_render_preset(None, radar=str(path))
    assert says in str(info.value)
    with pytest.raises(InputError, match="radar.json"):
        load_radar_sensor(path)


def test_the_bundled_radars_grids_are_as_before():
    """The bound leaves the bundled radars' ray grids (and hence their renders) as they were."""
    from fogsim.radar.sensors import RadarSensor
    from fogsim.render.radar_scan import ray_grid

    assert len(ray_grid(RadarSensor.preset("ars408-lr"))[0]) == 1200 * 56
    assert len(ray_grid(RadarSensor.preset("srr-corner"))[0]) == 1500 * 80


# ----------------------------------------------------------------------------- D19: fogsim's words
def _ascii_sweep(rows: list[str], points: int | None = None) -> bytes:
    return radar_header(len(rows) if points is None else points, data="ascii") + "".join(
        r + "\n" for r in rows).encode()


GOOD_ROW = " ".join(["1"] * 18)

WORDING = [
    Case("d19-ascii-extra-column", _radar(BAD, lambda p: _ascii_sweep([GOOD_ROW] * 4 + [GOOD_ROW + " 1"])), 1,
         (BAD, "PCD ASCII row 5 has 19 numbers, the header declares 18 per point")),
    Case("d19-ascii-text-row", _radar(BAD, lambda p: _ascii_sweep([GOOD_ROW] * 5 + ["hello world"])), 1,
         (BAD, "PCD ASCII row 6 has 2 numbers, the header declares 18 per point")),
    Case("d19-ascii-word", _radar(BAD, lambda p: _ascii_sweep([GOOD_ROW, " ".join(["1"] * 17 + ["x"])])), 1,
         (BAD, "PCD ASCII row 2 is not numbers")),
    Case("d19-npy-sub-array-x", _points("a.npy", lambda p: _npy_bytes_of(
        np.zeros(4, [("x", "<f4", (3,)), ("y", "<f4"), ("z", "<f4")])), "npy"), 1,
         ("a.npy", "field x is a sub-array of shape (3,)")),
]


def test_d19_running_out_of_memory_is_said_in_words():
    """D19: a sample that ends in a MemoryError without text (the trial's ``…: MemoryError:``) is reported as
    memory running out."""
    from fogsim.fog.batch import _worker
    from fogsim.fog.point_files import PointFile

    class Hungry:
        def fog_one(self, item):
            raise MemoryError()

    source, error = _worker((Hungry(), PointFile("a", "in/a.bin")))
    assert source == "in/a.bin" and error.startswith("out of memory (MemoryError)")


def _npy_bytes_of(array: np.ndarray) -> bytes:
    import io

    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=False)
    return buf.getvalue()


CASES = WORDING


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_trial6_case(case: Case, tmp_path, capsys, monkeypatch):
    run_sensor_case(case, tmp_path, capsys, monkeypatch, needs_itur=case.id.startswith("d19-ascii"))
