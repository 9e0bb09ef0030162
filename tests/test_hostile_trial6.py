"""The sixth hostile-input trial's defects (``shared/notes/reliability-defects-6.md``, D01–D24: the radar,
the PCD codec, LiDAR calibrations and ``export nuscenes``), each as the trial reproduced it, in the style
of :mod:`test_hostile_sensors`: the exit code, one line naming the file (or flag) and the problem, no
traceback, the inputs unchanged, nothing partial.

Memory bounds are checked without timing: a sparse file (``truncate``) that would need gigabytes, read in
a process of its own under a 1.5 GB address-space limit (``RLIMIT_AS``) — reading the body would fail with
MemoryError; the refusal must come from the header first.
"""
from __future__ import annotations

import json
import os
import shutil
import struct
from pathlib import Path

import numpy as np
import pytest

import lidar_fixtures as lf
from conftest import HANG_S, run_hostile_case
from fogsim.cli import main
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
    _kitti_dataset,
    _npy_header,
    _ply,
    _points,
    _radar,
    radar_bytes,
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


# ----------------------------------------------------------------------------- D08: an output's subfolders resolved
def _linked_level(build, level: str, into: str):
    """``build``'s command after ``OUT/<level>`` was made a link to the input folder ``tmp/in/<into>``."""
    def wrapped(tmp: Path) -> list[str]:
        argv = build(tmp)
        (tmp / "out").mkdir()
        (tmp / "out" / level).symlink_to(tmp / "in" / into, target_is_directory=True)
        return argv
    return wrapped


def _deeper_link(tmp: Path) -> list[str]:
    """OUT/beta0.06/sub links to the input's sub/ (a scan's key has folders: sub/a)."""
    argv = _points("sub/a.bin", lambda p: p.parent.mkdir() or lf.kitti_bin(*_scan_kitti()), "kitti")(tmp)
    (tmp / "out" / "beta0.06").mkdir(parents=True)
    (tmp / "out" / "beta0.06" / "sub").symlink_to(tmp / "in" / "scans" / "sub", target_is_directory=True)
    return argv


LINKS = [
    Case("d08-points-level-folder-links-into-the-input", _linked_level(
        _points("a.bin", lambda p: None, "kitti"), "beta0.06", "scans"), 2,
         ("out/beta0.06", "is a link below --out to", "which is --points", "remove the link")),
    Case("d08-radar-level-folder-links-into-the-input", _linked_level(
        _radar(BAD, lambda p: None), "beta0.06", "RADAR_FRONT"), 2, ("out/beta0.06", "which is --points")),
    Case("d08-link-around-the-input", _linked_level(_points("a.bin", lambda p: None, "kitti"), "beta0.06", "."), 2,
         ("out/beta0.06", "which contains --points")),
    Case("d08-link-deeper-into-the-input", _deeper_link, 2, ("out/beta0.06/sub", "which lies inside --points")),
]


def test_d08_a_link_elsewhere_is_written_through(tmp_path):
    """A level folder linked to a folder that is no input (a scratch disk) is still allowed."""
    build = _points("a.bin", lambda p: lf.kitti_bin(*_scan_kitti()), "kitti")
    argv = build(tmp_path)
    (tmp_path / "scratch").mkdir()
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "beta0.06").symlink_to(tmp_path / "scratch", target_is_directory=True)
    assert main(argv) == 0
    assert (tmp_path / "scratch" / "a.bin").is_file()


# ------------------------------------------------------------ D09–D12, D16, D21, D22, D24: export nuscenes
def _dataset(tmp: Path, radar: bool = False) -> Path:
    """tmp/in/ds: a fogged KITTI set (levels clear and beta0.06, LiDAR); ``radar``: each frame also gets a
    radar block with a nuScenes sweep per level (as a render with --radar writes them)."""
    ds = _kitti_dataset(tmp)
    if radar:
        for path in sorted((ds / "meta").glob("*.json")):
            meta = json.loads(path.read_text())
            levels = {}
            for key in ("clear", "beta0.06"):
                sweep = ds / "radar" / key / f"{meta['frame']}.pcd"
                sweep.parent.mkdir(parents=True, exist_ok=True)
                sweep.write_bytes(radar_bytes(6 if key == "clear" else 3))
                levels[key] = {"file": f"radar/{key}/{meta['frame']}.pcd"}
            meta["radar"] = {"format": "nuscenes-radar", "sensor": "ars408-lr", "levels": levels}
            path.write_text(json.dumps(meta))
    return ds


def _first_meta(ds: Path) -> tuple[Path, dict]:
    path = sorted((ds / "meta").glob("*.json"))[0]
    return path, json.loads(path.read_text())


def _edit_meta(ds: Path, edit) -> None:
    path, meta = _first_meta(ds)
    edit(meta)
    path.write_text(json.dumps(meta))


def _export_case(change=None, *flags: str, radar: bool = False, out: str = "{tmp}/out"):
    def build(tmp: Path) -> list[str]:
        ds = _dataset(tmp, radar)
        if change is not None:
            change(tmp, ds)
        return ["export", "nuscenes", str(ds), "--out", out.replace("{tmp}", str(tmp)), "--quiet", *flags]
    return build


def _meta_edit(edit):
    def change(tmp: Path, ds: Path) -> None:
        _edit_meta(ds, lambda m: edit(tmp, m))
    return change


def _key(block: str, key: str):
    return _meta_edit(lambda tmp, m: m[block]["levels"].__setitem__(key.replace("{tmp}", str(tmp)),
                                                                    m[block]["levels"].pop("beta0.06")))


def _file(block: str, level: str, file: str | None = None, make=None):
    def edit(tmp: Path, meta: dict) -> None:
        target = tmp / "in" / "outside" / ("x.pcd" if block == "radar" else "x.bin")
        if make is not None:
            make(tmp, target, meta)
        meta[block]["levels"][level]["file"] = (file or str(target)).replace("{tmp}", str(tmp))
    return _meta_edit(edit)


def _outside_copy(tmp: Path, target: Path, meta: dict) -> None:
    """A real scan / sweep outside the dataset (a copy of the frame's own)."""
    ds = tmp / "in" / "ds"
    block = "radar" if target.suffix == ".pcd" else "lidar"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_bytes((ds / meta[block]["levels"]["clear"]["file"]).read_bytes())


def _link_out_of_the_dataset(tmp: Path, ds: Path) -> None:
    """The frame's clear scan replaced by a link to a copy outside the dataset."""
    _, meta = _first_meta(ds)
    scan = ds / meta["lidar"]["levels"]["clear"]["file"]
    outside = tmp / "in" / "outside" / "x.bin"
    outside.parent.mkdir(parents=True)
    outside.write_bytes(scan.read_bytes())
    scan.unlink()
    scan.symlink_to(outside)


def _last_meta(edit):
    def change(tmp: Path, ds: Path) -> None:
        path = sorted((ds / "meta").glob("*.json"))[-1]
        meta = json.loads(path.read_text())
        edit(meta)
        path.write_text(json.dumps(meta))
    return change


def _damage(block: str, level: str, how):
    def change(tmp: Path, ds: Path) -> None:
        _, meta = sorted(((p, json.loads(p.read_text())) for p in (ds / "meta").glob("*.json")))[-1]
        how(ds / meta[block]["levels"][level]["file"])
    return change


EXPORT = [
    # D09: level keys read back from a frame record are folder names, never paths
    Case("d09-lidar-key-traversal", _export_case(_key("lidar", "../escaped")), 2,
         ("meta/", "lidar.levels: fog level key '../escaped' may hold only")),
    Case("d09-lidar-key-absolute", _export_case(_key("lidar", "{tmp}/abs_escape")), 2,
         ("meta/", "lidar.levels: fog level key", "it names a folder")),
    Case("d09-radar-key-traversal", _export_case(_key("radar", "../escaped_radar"), radar=True), 2,
         ("meta/", "radar.levels: fog level key '../escaped_radar'")),
    Case("d09-key-dot-dot", _export_case(_key("lidar", "..")), 2, ("meta/", "fog level key '..'")),
    Case("d09-key-overwrites-another-root", _export_case(lambda t, ds: (
        (t / "in" / "nusc_real" / "samples" / "LIDAR_TOP").mkdir(parents=True),
        (t / "in" / "nusc_real" / "samples" / "LIDAR_TOP" / "000000.pcd.bin").write_bytes(b"precious"),
        _key("lidar", "{tmp}/in/nusc_real")(t, ds))), 2, ("meta/", "fog level key")),
    Case("d09-export-levels-a-path", _export_case(None, "--levels", "../x"), 2, ("fog level key '../x'",)),
    # D10: level files inside the dataset, links resolved
    Case("d10-lidar-file-absolute", _export_case(_file("lidar", "clear", make=_outside_copy)), 2,
         ("meta/", "lidar.levels.clear.file: must be a path inside the dataset")),
    Case("d10-radar-file-absolute", _export_case(_file("radar", "clear", make=_outside_copy), radar=True), 2,
         ("meta/", "radar.levels.clear.file: must be a path inside the dataset")),
    Case("d10-lidar-file-traversal", _export_case(_file("lidar", "clear", "../outside/x.bin", _outside_copy)), 2,
         ("meta/", "lidar.levels.clear.file: must be a path inside the dataset")),
    Case("d10-lidar-file-links-out", _export_case(_link_out_of_the_dataset), 2,
         ("meta/", "lidar.levels.clear.file", "outside the dataset")),
    # D11: nothing partial when a frame fails (the last frame's files: the others would be written first)
    Case("d11-missing-scan", _export_case(_damage("lidar", "beta0.06", lambda p: p.unlink())), 2,
         ("beta0.06", "not found")),
    Case("d11-truncated-scan", _export_case(_damage("lidar", "clear", lambda p: p.write_bytes(p.read_bytes()[:-3]))),
         2, ("clear", "not a whole number of 16-byte kitti records")),
    Case("d11-missing-radar", _export_case(_damage("radar", "clear", lambda p: p.unlink()), radar=True), 2,
         ("radar/clear", "not found")),
    Case("d11-meta-format-wrong", _export_case(_last_meta(lambda m: m["lidar"].update(format="nuscenes"))), 2,
         ("not a whole number of 20-byte nuscenes records",)),
    # D16: an --out inside the dataset only as a folder of its own
    Case("d16-out-in-meta", _export_case(out="{tmp}/in/ds/meta"), 2,
         ("ds/meta", "holds files that are not an earlier export (one of the dataset's own folders)")),
    Case("d16-out-below-meta", _export_case(out="{tmp}/in/ds/meta/nusc"), 2,
         ("ds/meta/nusc", "lies inside the dataset's meta/")),
    Case("d16-out-around-the-dataset", _export_case(out="{tmp}/in"), 2, ("contains the dataset",)),
    # D21, D22: empty values and the messages
    Case("d21-levels-empty", _export_case(None, "--levels", ""), 2, ("--levels names no level",)),
    Case("d22-levels-commas", _export_case(None, "--levels", ",,"), 2, ("--levels names no level",)),
    Case("d22-dataset-missing", lambda t: ["export", "nuscenes", str(t / "in" / "nope"), "--out", str(t / "out")], 2,
         ("in/nope: not found",)),
    Case("d22-dataset-is-a-file", lambda t: (t / "in").mkdir() or (t / "in" / "afile").write_text("x") and [
        "export", "nuscenes", str(t / "in" / "afile"), "--out", str(t / "out")], 2,
         ("in/afile: is a file, not a folder",)),
    Case("d22-out-is-a-file", _export_case(lambda t, ds: (t / "in" / "afile").write_text("precious"),
                                           out="{tmp}/in/afile"), 2, ("in/afile: is a file, not a folder",)),
    Case("d22-dataset-symlink-loop", lambda t: (t / "in").mkdir() or (t / "in" / "loop").symlink_to(
        t / "in" / "loop") or ["export", "nuscenes", str(t / "in" / "loop"), "--out", str(t / "out")], 2,
         ("in/loop: the dataset argument is, or passes through, a symlink loop",)),
    Case("d22-out-holds-other-files", _export_case(lambda t, ds: (t / "mine").mkdir() or (
        t / "mine" / "notes.txt").write_text("x"), out="{tmp}/mine"), 2,
         ("mine: holds files that are not an earlier",)),
]


def test_d09_nothing_is_written_outside_out(tmp_path, capsys):
    """D09: the trial's escapes (a ``..`` key, an absolute key) leave no file outside ``--out``."""
    for change in (_key("lidar", "../escaped"), _key("lidar", "{tmp}/abs_escape"), _key("radar", "../escaped_r")):
        for p in list(tmp_path.iterdir()):
            shutil.rmtree(p)
        argv = _export_case(change, radar=True)(tmp_path)
        assert main(argv) == 2
        assert sorted(p.name for p in tmp_path.iterdir()) == ["in"], capsys.readouterr().err


def test_d11_a_failed_export_leaves_the_earlier_one_whole(tmp_path, capsys):
    """D11: the first export is complete; a second, failing on its last frame, leaves it as it was (no
    sample of the failed run, its summary intact) and no hidden folder beside it."""
    from conftest import tree_digest

    ds = _dataset(tmp_path, radar=True)
    out = tmp_path / "nusc"
    assert main(["export", "nuscenes", str(ds), "--out", str(out), "--quiet"]) == 0
    before = tree_digest(out)
    _damage("lidar", "beta0.06", lambda p: p.write_bytes(p.read_bytes()[:-3]))(tmp_path, ds)
    assert main(["export", "nuscenes", str(ds), "--out", str(out), "--quiet"]) == 2
    assert tree_digest(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "nusc"], capsys.readouterr().err
    assert main(["export", "nuscenes", str(ds), "--out", str(tmp_path / "new"), "--quiet"]) == 2
    assert not (tmp_path / "new").exists()


def test_d11_folders_in_the_way_of_an_earlier_export_are_replaced(tmp_path):
    """D11 (EX_target_is_dir, EX_summary_is_dir): a folder where a sample or the summary goes — the export is
    written beside and replaces the earlier one whole, so the run completes (or, failing, changes nothing)."""
    ds = _dataset(tmp_path)
    out = tmp_path / "nusc"
    frame = sorted(p.stem for p in (ds / "meta").glob("*.json"))[1]
    (out / "clear" / "samples" / "LIDAR_TOP" / f"{frame}.pcd.bin").mkdir(parents=True)
    (out / "fogsim_nuscenes.json").mkdir()
    assert main(["export", "nuscenes", str(ds), "--out", str(out), "--quiet"]) == 0
    assert (out / "clear" / "samples" / "LIDAR_TOP" / f"{frame}.pcd.bin").is_file()
    assert json.loads((out / "fogsim_nuscenes.json").read_text())["samples_per_level"] == {"clear": 3, "beta0.06": 3}


def test_d16_an_out_of_its_own_inside_the_dataset_is_exported(tmp_path):
    """D16: DATASET/nuscenes (a new folder directly in it) is allowed, twice (the second replaces the first),
    and the dataset's own files are untouched."""
    from conftest import tree_digest

    ds = _dataset(tmp_path, radar=True)
    before = tree_digest(ds)
    for _ in range(2):
        assert main(["export", "nuscenes", str(ds), "--out", str(ds / "nuscenes"), "--quiet"]) == 0
    assert (ds / "nuscenes" / "fogsim_nuscenes.json").is_file()
    shutil.rmtree(ds / "nuscenes")
    assert tree_digest(ds) == before


def test_d24_a_killed_exports_leftovers_are_removed(tmp_path):
    """D24: a dead writer's ``.part`` file inside an earlier export and a killed run's hidden folder beside
    it are gone after the next export."""
    import socket

    ds = _dataset(tmp_path)
    out = tmp_path / "nusc"
    assert main(["export", "nuscenes", str(ds), "--out", str(out), "--quiet"]) == 0
    host = socket.gethostname().replace(".", "_").replace("-", "_") or "host"
    part = out / "beta0.06" / "samples" / "LIDAR_TOP" / f".000039.pcd.bin.{host}-999999999.tgvt90s0.part"
    part.write_bytes(b"half")
    staging = tmp_path / f".nusc.{host}-999999999.abc.part"
    (staging / "clear").mkdir(parents=True)
    assert main(["export", "nuscenes", str(ds), "--out", str(out), "--quiet"]) == 0
    assert not list(out.rglob("*.part")) and not staging.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "nusc"]


def test_d12_empty_sweeps_finalize_and_export(tmp_path, capsys):
    """D12: a level whose sweeps saw nothing (0 points: a sensor whose range reaches nothing) finalizes (shares
    of 0 points are 0, not a ZeroDivisionError) and exports (an empty sample, as the render wrote it)."""
    ds = _dataset(tmp_path)
    for path in sorted((ds / "meta").glob("*.json")):
        meta = json.loads(path.read_text())
        for entry in meta["lidar"]["levels"].values():
            (ds / entry["file"]).write_bytes(b"")
            entry["outcomes"] = {k: 0 for k in entry.get("outcomes", {"kept": 0})}
        path.write_text(json.dumps(meta))
    assert main(["fog", "--finalize-only", "--out", str(ds), "--quiet"]) == 0, capsys.readouterr().err
    report = json.loads((ds / "dataset.json").read_text())["lidar"]["outcomes"]
    assert report and all(v["points"] == 0 and set(v["shares"].values()) == {0.0} for v in report.values())
    assert main(["export", "nuscenes", str(ds), "--out", str(tmp_path / "nusc"), "--quiet"]) == 0, \
        capsys.readouterr().err
    samples = list((tmp_path / "nusc").rglob("*.pcd.bin"))
    assert samples and all(p.stat().st_size == 0 for p in samples)


@pytest.mark.blender
def test_d12_a_render_whose_sweep_sees_nothing_finalizes_and_exports(tmp_path):
    """D12 as the trial ran it: ``render --lidar near_only.json`` (max range 1.5 m: no return) writes its
    dataset (no ZeroDivisionError at finalize), ``--finalize-only`` again, and the export reads its empty
    scans."""
    import subprocess
    import sys

    from test_blender import _need_bpy

    _need_bpy()
    sensor = _write_json(tmp_path / "near_only.json", LIDAR_SENSOR | {"max_range_m": 1.5, "min_range_m": 0.5,
                                                                      "overlap_full_m": 0.0})
    out = tmp_path / "out"
    base = [sys.executable, "-m", "fogsim", "render", "--frames", "1", "--resolution", "32x24", "--samples", "1",
            "--levels", "clear,0.06", "--lidar", str(sensor), "--out", str(out), "--quiet"]
    for argv in (base, base + ["--finalize-only"]):
        res = subprocess.run(argv, capture_output=True, text=True, timeout=HANG_S)
        assert "Traceback" not in res.stderr and (out / "dataset.json").is_file(), res.stderr[-3000:]
    outcomes = json.loads((out / "dataset.json").read_text())["lidar"]["outcomes"]
    assert outcomes and all(level["points"] == 0 for level in outcomes.values())
    assert main(["export", "nuscenes", str(out), "--out", str(tmp_path / "nusc"), "--quiet"]) == 0
    assert all(p.stat().st_size == 0 for p in (tmp_path / "nusc").rglob("*.pcd.bin"))


# ------------------------------------------------------------ D13, D15, D20–D23: the run's flags, checked up front
def _calibration(doc: dict):
    """``--points`` of a good KITTI scan with ``--lidar-calibration in/cal.json`` holding ``doc``."""
    def build(tmp: Path) -> list[str]:
        argv = _points("a.bin", lambda p: None, "kitti")(tmp)
        return argv + ["--lidar-calibration", str(_write_json(tmp / "in" / "cal.json", doc))]
    return build


BELOW_OVERLAP = {"name": "short", "max_range_m": 3.0, "sources": {"max_range_m": "assumed: a test"}}
FLAGS = [
    # D13: a calibration that does not fit the sensor, found before --out is claimed
    Case("d13-calibration-below-the-overlap", _calibration(BELOW_OVERLAP), 2,
         ("cal.json: --lidar-calibration does not fit the sensor hdl64e", "overlap_full_m must be below max_range_m")),
    # D23: calibrations held to the sources rule
    Case("d23-calibration-without-sources", _calibration({"name": "x", "pulse_half_power_ns": 5.0}), 2,
         ("cal.json", "sources: no entry for pulse_half_power_ns")),
    Case("d23-calibration-source-of-no-value", _calibration({"name": "x", "pulse_half_power_ns": 5.0, "sources": {
        "pulse_half_power_ns": "lab", "bogus_key": "lab"}}), 2, ("cal.json", "bogus_key is not a parameter")),
    # D15: --workers bounded for --points, LiDAR and radar
    Case("d15-lidar-workers-huge", _points("a.bin", lambda p: None, "kitti", "--workers", "100000"), 2,
         ("--workers: must be an integer in [1,",)),
    Case("d15-radar-workers-huge", _radar(BAD, lambda p: None, "--workers", "100000"), 2,
         ("--workers: must be an integer in [1,",)),
    # D20: --lidar-calibration with radar sweeps
    Case("d20-radar-lidar-calibration", _radar(BAD, lambda p: None, "--lidar-calibration", "reference"), 2,
         ("--lidar-calibration is for LiDAR scans",)),
    Case("d20-radar-lidar-calibration-file", lambda t: _radar(BAD, lambda p: None)(t) + [
        "--lidar-calibration", str(_write_json(t / "in" / "nan.json", {"max_range_m": "NaN"}))], 2,
         ("--lidar-calibration is for LiDAR scans",)),
    # D21: empty values and the flags of other inputs
    Case("d21-radar-sensor-empty", _radar(BAD, lambda p: None, "--sensor", ""), 2, ("--sensor is empty",)),
    Case("d21-lidar-sensor-empty", _points("a.bin", lambda p: None, "kitti", "--sensor", ""), 2,
         ("--sensor is empty",)),
    Case("d21-lidar-levels-empty", lambda t: _points("a.bin", lambda p: None, "kitti")(t) + ["--levels", ""], 2,
         ("--levels is empty",)),
    Case("d21-radar-levels-empty", lambda t: _radar(BAD, lambda p: None)(t) + ["--levels", ""], 2,
         ("--levels is empty",)),
    Case("d21-calibration-empty", _points("a.bin", lambda p: None, "kitti", "--lidar-calibration", ""), 2,
         ("--lidar-calibration is empty",)),
    Case("d21-points-with-depth", _points("a.bin", lambda p: None, "kitti", "--depth", "{tmp}/nowhere"), 2,
         ("--depth goes with another input", "not --points")),
    Case("d21-points-with-kitti-part", _points("a.bin", lambda p: None, "kitti", "--kitti-part", "testing"), 2,
         ("--kitti-part goes with another input",)),
    Case("d21-radar-with-depth", _radar(BAD, lambda p: None, "--depth", "{tmp}/nowhere"), 2,
         ("--depth goes with another input",)),
    # D22: a FIFO or a device given to --points
    Case("d22-points-fifo", lambda t: (t / "in").mkdir() or os.mkfifo(t / "in" / "x.pcd") or [
        "fog", "--points", str(t / "in" / "x.pcd"), "--point-format", "nuscenes-radar", "--out", str(t / "out")], 2,
         ("x.pcd: is not a regular file or a folder",)),
    Case("d22-points-dev-zero", lambda t: ["fog", "--points", "/dev/zero", "--point-format", "nuscenes-radar",
                                           "--out", str(t / "out")], 2, ("/dev/zero: is not a regular file",)),
]


def test_d13_the_corrected_rerun_is_accepted(tmp_path, capsys):
    """D13: the unfit calibration claimed nothing, so the corrected rerun into the same --out runs."""
    argv = _calibration(BELOW_OVERLAP)(tmp_path)
    assert main(argv) == 2 and not (tmp_path / "out").exists()
    good = _write_json(tmp_path / "in" / "ok.json", {"name": "ok", "max_range_m": 100.0,
                                                     "sources": {"max_range_m": "assumed: a test"}})
    assert main(argv[:-1] + [str(good)]) == 0, capsys.readouterr().err


def test_d13_kitti_with_an_unfit_calibration_is_refused_up_front(tmp_path, capsys):
    import kitti_tree as kt

    root = kt.write_kitti(tmp_path / "in" / "kitti")
    cal = _write_json(tmp_path / "in" / "cal.json", BELOW_OVERLAP)
    argv = ["fog", "--kitti", str(root), "--lidar", "--levels", "0,0.06", "--out", str(tmp_path / "out"), "--quiet"]
    assert main(argv + ["--lidar-calibration", str(cal)]) == 2
    assert "cal.json: --lidar-calibration does not fit the sensor hdl64e" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_d21_an_empty_levels_is_refused_by_every_command(tmp_path):
    """D21: ``--levels ''`` (an unset shell variable) is not the paper's five levels: camera fog and render."""
    from fogsim.fog.levels import parse_levels
    from fogsim.render.preset import load_render_preset

    for call in (lambda: parse_levels(""), lambda: parse_levels(None, " "),
                 lambda: load_render_preset(None, levels="")):
        with pytest.raises(ValueError, match="is empty"):
            call()
    assert [lv.key for lv in parse_levels(None)] == [lv.key for lv in parse_levels("paper")]


# ----------------------------------------------------------------------------- D14, D17, D18: radar levels
def devkit_read(path: Path) -> np.ndarray:
    """A nuScenes radar PCD read as the devkit's ``RadarPointCloud.from_file`` documents it: header lines by
    position (a comment, VERSION, FIELDS, SIZE, TYPE, COUNT, WIDTH, HEIGHT, VIEWPOINT, POINTS, DATA), DATA
    binary, WIDTH > 0, HEIGHT 1, COUNT 1, then packed little-endian records."""
    data = path.read_bytes()
    lines, at = [], 0
    while not (lines and lines[-1].startswith("DATA")):
        end = data.index(b"\n", at)
        lines.append(data[at:end].decode().strip())
        at = end + 1
    assert lines[0].startswith("#") and lines[1].startswith("VERSION") and len(lines) == 11
    fields, sizes, types, counts = (lines[i].split(" ")[1:] for i in (2, 3, 4, 5))
    assert int(lines[6].split(" ")[1]) > 0 and lines[7] == "HEIGHT 1" and set(counts) == {"1"}
    assert lines[10] == "DATA binary"
    code = {("F", "4"): "<f4", ("F", "8"): "<f8", ("I", "1"): "i1", ("I", "2"): "<i2", ("I", "4"): "<i4",
            ("U", "1"): "u1", ("U", "2"): "<u2", ("U", "4"): "<u4"}
    dtype = np.dtype([(n, code[t, z]) for n, z, t in zip(fields, sizes, types)])
    n = int(lines[6].split(" ")[1])
    return np.frombuffer(data[at:at + n * dtype.itemsize], dtype)


def _odd_sweep(n: int = 50) -> bytes:
    """A sweep with an extra field ``foo`` and dyn_prop stored as F (3.7): a layout of its own."""
    from test_hostile_sensors import radar_dtype

    base = radar_dtype()
    dtype = np.dtype([(name, "<f4" if name == "dyn_prop" else base[name]) for name in base.names] + [("foo", "<f4")])
    rec = np.zeros(n, dtype)
    rec["x"], rec["rcs"] = np.linspace(5.0, 150.0, n), np.linspace(-5.0, 15.0, n)
    rec["ambig_state"], rec["is_quality_valid"], rec["pdh0"], rec["dyn_prop"] = 3, 1, 1, 3.7
    rec["foo"] = np.arange(n, dtype=np.float32) + 0.25
    from fogsim.lidar.pcd import encode_pcd

    return encode_pcd(rec, "binary") + b"\n"


def test_d14_a_re_encoded_level_keeps_the_inputs_fields_and_types(tmp_path, capsys):
    """D14: at β 2 (a wet fog at 77 GHz) some detections are lost and the level is re-encoded: the kept
    records keep every field (``foo``) in its own type (dyn_prop F 3.7), bit for bit."""
    from fogsim.lidar.pcd import read_pcd
    from fogsim.radar.outcome_file import read_radar_outcomes

    src = tmp_path / "in" / BAD
    src.parent.mkdir()
    src.write_bytes(_odd_sweep())
    _, records = read_pcd(src)
    out = tmp_path / "out"
    assert main(["fog", "--points", str(src), "--point-format", "nuscenes-radar", "--levels", "0,2", "--out",
                 str(out), "--quiet"]) == 0, capsys.readouterr().err
    got = devkit_read(out / "beta2" / BAD)
    outcome = read_radar_outcomes(out / "beta2" / BAD.replace(".pcd", ".outcomes.npz"))[0]
    assert 0 < len(got) < len(records)
    assert got.dtype == records.dtype and got.tobytes() == records[outcome == 0].tobytes()
    assert (out / "clear" / BAD).read_bytes() == src.read_bytes()  # the devkit reads it: copied as it is


def _sweep_as(data: str, **header) -> bytes:
    from fogsim.lidar.pcd import encode_pcd
    from test_hostile_sensors import radar_dtype

    rec = np.zeros(6, radar_dtype())
    rec["x"], rec["rcs"] = np.linspace(5.0, 60.0, 6), 10.0
    rec["ambig_state"], rec["is_quality_valid"], rec["pdh0"] = 3, 1, 1
    if data == "binary_compressed":
        import lzf

        cols = b"".join(np.ascontiguousarray(rec[n]).tobytes() for n in rec.dtype.names)
        packed = lzf.compress(cols)
        return radar_header(6, data=data) + struct.pack("<II", len(packed), len(cols)) + packed
    raw = encode_pcd(rec, data)
    for key, value in header.items():
        raw = raw.replace(key.encode(), value.encode(), 1)
    return raw


@pytest.mark.parametrize("name, make", [
    ("ascii", lambda: _sweep_as("ascii")),
    ("binary_compressed", lambda: _sweep_as("binary_compressed")),
    ("header-tabs", lambda: _sweep_as("binary", **{"FIELDS x": "FIELDS\tx"})),
    ("no-version", lambda: _sweep_as("binary", **{"VERSION 0.7\n": ""})),
    ("points-zero", lambda: radar_header(0)),
])
def test_d17_an_all_kept_level_is_what_the_devkit_reads(tmp_path, capsys, name, make):
    """D17: a level that keeps every detection is the input's bytes only when the devkit can read them;
    an ASCII, compressed, tab-separated or VERSION-less input (or one of zero records) is re-encoded."""
    if name == "binary_compressed":
        pytest.importorskip("lzf")
    src = tmp_path / "in" / BAD
    src.parent.mkdir()
    src.write_bytes(make())
    out = tmp_path / "out"
    assert main(["fog", "--points", str(src), "--point-format", "nuscenes-radar", "--levels", "0", "--out",
                 str(out), "--quiet"]) == 0, capsys.readouterr().err
    got = devkit_read(out / "clear" / BAD)
    if name == "points-zero":
        assert len(got) == 1 and np.isnan(got[0]["x"])  # the empty sweep's convention
    else:
        np.testing.assert_array_equal(got["x"], np.linspace(5.0, 60.0, 6).astype(np.float32))


def test_d18_a_nan_in_the_first_of_several_records_is_refused(tmp_path, capsys):
    """D18: vx = NaN in record 0 of 50 is not the empty convention (one all-NaN record): refused, naming the
    file; fogsim's own empty sweep still reads as empty."""
    from fogsim.radar.detections import RadarScan
    from fogsim.radar.formats import encode_radar, read_radar

    src = tmp_path / "in" / BAD
    src.parent.mkdir()
    src.write_bytes(radar_bytes(50, edit=lambda r: r["vx"].__setitem__(0, np.nan)))
    assert main(["fog", "--points", str(src), "--point-format", "nuscenes-radar", "--levels", "0", "--out",
                 str(tmp_path / "out"), "--quiet"]) == 1
    assert "NaN" in capsys.readouterr().err
    empty = tmp_path / "empty.pcd"
    empty.write_bytes(encode_radar(RadarScan.checked(np.zeros((0, 3)), np.zeros(0)), "nuscenes-radar"))
    assert len(read_radar(empty)) == 0


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
    from fogsim.fog.points import PointFile

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


CASES = LINKS + EXPORT + FLAGS + WORDING


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_trial6_case(case: Case, tmp_path, capsys, monkeypatch):
    if "radar" in case.id or case.id.startswith("d19-ascii"):
        pytest.importorskip("itur")
    monkeypatch.chdir(tmp_path)
    for key, value in getattr(case, "env", {}).items():
        monkeypatch.setenv(key, value)
    err = run_hostile_case(case, tmp_path, capsys)
    if case.code:
        lines = [ln for ln in err.splitlines() if ln.startswith(("fogsim: error", "  failed:"))]
        assert lines and all(len(ln) < 1000 for ln in lines), err
        assert "MemoryError" not in err and "usecols" not in err and "all input arrays" not in err, err
        if case in EXPORT:
            assert not (tmp_path / "out").exists(), "a refused export wrote into --out"  # nothing partial (D11)
