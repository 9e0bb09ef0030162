"""fogsim.radar.formats and .detections: nuScenes RADAR_* PCD and .npy sweeps, checked against a reader
written here from the format's documentation (the nuScenes devkit's RadarPointCloud.from_file docstring and
PCL's PCD v0.7 text), and read back by pypcd4."""
from __future__ import annotations

import struct

import numpy as np
import pytest

from fogsim.errors import InputError
from fogsim.radar.detections import RadarScan
from fogsim.radar.formats import (
    EXTRA_FIELDS,
    NUSCENES_DEFAULTS,
    read_radar,
    write_radar,
)

# the nuScenes devkit's documented header of a RADAR_* file (FIELDS, SIZE, TYPE)
SPEC_FIELDS = ("x y z dyn_prop id rcs vx vy vx_comp vy_comp is_quality_valid ambig_state x_rms y_rms "
               "invalid_state pdh0 vx_rms vy_rms").split()
SPEC_SIZE = [4, 4, 4, 1, 2, 4, 4, 4, 4, 4, 1, 1, 1, 1, 1, 1, 1, 1]
SPEC_TYPE = "F F F I I F F F F F I I I I I I I I".split()
LUT = {("F", 4): "f", ("F", 8): "d", ("I", 1): "b", ("I", 2): "h", ("I", 4): "i", ("U", 1): "B", ("U", 2): "H"}


def spec_bytes(rows: list[tuple]) -> bytes:
    """A RADAR_* file built from the spec's text: comment, the header keys one a line, binary records."""
    header = ["# .PCD v0.7 - Point Cloud Data file format", "VERSION 0.7", "FIELDS " + " ".join(SPEC_FIELDS),
              "SIZE " + " ".join(map(str, SPEC_SIZE)), "TYPE " + " ".join(SPEC_TYPE), "COUNT " + " ".join(["1"] * 18),
              f"WIDTH {len(rows)}", "HEIGHT 1", "VIEWPOINT 0 0 0 1 0 0 0", f"POINTS {len(rows)}", "DATA binary"]
    fmt = "<" + "".join(LUT[(t, s)] for t, s in zip(SPEC_TYPE, SPEC_SIZE))
    return ("\n".join(header) + "\n").encode() + b"".join(struct.pack(fmt, *r) for r in rows) + b"\n"


def spec_read(data: bytes) -> tuple[dict, list[tuple]]:
    """A reader from the spec's text: the header lines by position (comment, VERSION, FIELDS, SIZE, TYPE,
    COUNT, WIDTH, HEIGHT, VIEWPOINT, POINTS, DATA), then WIDTH records unpacked field by field."""
    lines, pos = [], 0
    while True:
        end = data.index(b"\n", pos)
        lines.append(data[pos:end].decode())
        pos = end + 1
        if lines[-1].startswith("DATA"):
            break
    assert lines[0].startswith("#") and lines[1].startswith("VERSION")
    head = {ln.split()[0]: ln.split()[1:] for ln in lines[1:]}
    assert head["DATA"] == ["binary"] and head["HEIGHT"] == ["1"] and set(head["COUNT"]) == {"1"}
    sizes, types = [int(s) for s in head["SIZE"]], head["TYPE"]
    rows = []
    for _ in range(int(head["WIDTH"][0])):
        row = []
        for t, s in zip(types, sizes):
            assert pos + s < len(data)  # the devkit asserts bytes follow every field it unpacks
            row.append(struct.unpack("<" + LUT[(t, s)], data[pos:pos + s])[0])
            pos += s
        rows.append(tuple(row))
    return head, rows


ROWS = [  # x y z dyn_prop id rcs vx vy vx_comp vy_comp qv ambig x_rms y_rms invalid pdh0 vx_rms vy_rms
    (12.5, -1.25, 0.0, 0, 3, 7.5, -3.0, 0.25, 0.5, 0.0, 1, 3, 19, 18, 0, 1, 17, 3),
    (80.0, 4.0, 0.0, 1, 41, -2.0, -9.5, -0.5, 0.0, 0.0, 1, 3, 20, 19, 4, 1, 16, 3),
    (191.25, -20.5, 0.0, 2, 99, 21.5, -30.0, 3.0, -4.0, 0.5, 0, 2, 21, 20, 0, 5, 18, 4),
]


def test_spec_fixture_reads_into_the_record_with_every_field(tmp_path):
    path = tmp_path / "RADAR_FRONT__1.pcd"
    path.write_bytes(spec_bytes(ROWS))
    scan = read_radar(path)
    a = np.array(ROWS, np.float64)
    assert np.array_equal(scan.xyz, a[:, 0:3].astype(np.float32))
    assert np.array_equal(scan.rcs_dbsm, a[:, 5].astype(np.float32))
    assert np.array_equal(scan.velocity, a[:, 6:8].astype(np.float32))
    assert np.array_equal(scan.velocity_comp, a[:, 8:10].astype(np.float32))
    assert np.isnan(scan.snr_db).all() and (scan.kind == -1).all() and (scan.object_id == -1).all()
    assert scan.extra.dtype.names == EXTRA_FIELDS
    for k, name in enumerate(SPEC_FIELDS):
        if name in EXTRA_FIELDS:
            assert scan.extra[name].tolist() == [r[k] for r in ROWS], name
    assert np.allclose(scan.range_m, np.linalg.norm(a[:, :3], axis=1))
    # radial velocity: the vector projected on the ray, + = receding
    az = np.arctan2(a[:, 1], a[:, 0])
    assert np.allclose(scan.radial_velocity, a[:, 6] * np.cos(az) + a[:, 7] * np.sin(az), atol=1e-6)


def test_written_sweep_matches_the_spec_reader_and_round_trips(tmp_path):
    src = tmp_path / "in.pcd"
    src.write_bytes(spec_bytes(ROWS))
    scan = read_radar(src)
    out = tmp_path / "out.pcd"
    write_radar(out, scan)
    head, rows = spec_read(out.read_bytes())
    assert head["FIELDS"] == SPEC_FIELDS and [int(s) for s in head["SIZE"]] == SPEC_SIZE and head["TYPE"] == SPEC_TYPE
    assert rows == spec_read(src.read_bytes())[1] == [tuple(np.float32(v).item() if isinstance(v, float) else v
                                                            for v in r) for r in ROWS]
    assert read_radar(out).same_as(scan)


def test_rendered_sweep_gets_the_documented_defaults(tmp_path):
    scan = RadarScan.checked([[10, 0, 0], [0, 20, 0]], [5.0, -1.0], velocity=[[-4.0, 0.0], [0.0, 0.1]],
                             snr_db=[30.0, 14.0], object_id=[7, -1], kind=[0, 3])
    path = tmp_path / "r.pcd"
    write_radar(path, scan, "nuscenes-radar")
    _, rows = spec_read(path.read_bytes())
    col = {n: [r[k] for r in rows] for k, n in enumerate(SPEC_FIELDS)}
    assert col["dyn_prop"] == [0, 1]  # moving (|v_r| 4 m/s), stationary (0.1 m/s)
    assert col["id"] == [0, 1]
    for name, value in NUSCENES_DEFAULTS.items():
        assert col[name] == [value, value]


def test_pypcd4_reads_the_written_sweep(tmp_path):
    pypcd4 = pytest.importorskip("pypcd4")
    src = tmp_path / "in.pcd"
    src.write_bytes(spec_bytes(ROWS))
    out = tmp_path / "out.pcd"
    write_radar(out, read_radar(src))
    pc = pypcd4.PointCloud.from_path(out)
    assert tuple(pc.fields) == tuple(SPEC_FIELDS)
    data = pc.pc_data
    assert np.array_equal(data["x"], np.array([r[0] for r in ROWS], np.float32))
    assert data["id"].dtype == np.int16 and data["id"].tolist() == [r[4] for r in ROWS]
    assert data["pdh0"].dtype == np.int8 and data["pdh0"].tolist() == [r[15] for r in ROWS]


def test_empty_sweep_uses_the_devkit_convention(tmp_path):
    path = tmp_path / "e.pcd"
    write_radar(path, RadarScan.empty())
    head, rows = spec_read(path.read_bytes())
    assert head["POINTS"] == ["1"] and np.isnan(rows[0][0])  # one NaN record: the devkit's empty sweep
    assert len(read_radar(path)) == 0


@pytest.mark.parametrize("damage, words", [
    (lambda b: b.replace(b" rcs ", b" rcz "), "lack rcs"),
    (lambda b: b[:-20], "truncated"),
    (lambda b: b"hello\n", "PCD header"),
])
def test_bad_files_are_refused_naming_them(tmp_path, damage, words):
    path = tmp_path / "bad.pcd"
    path.write_bytes(damage(spec_bytes(ROWS)))
    with pytest.raises(InputError, match=words) as err:
        read_radar(path)
    assert str(path) in str(err.value)


def test_nan_past_the_first_record_is_refused(tmp_path):
    rows = [ROWS[0], (float("nan"),) + ROWS[1][1:]]
    path = tmp_path / "nan.pcd"
    path.write_bytes(spec_bytes(rows))
    with pytest.raises(InputError, match="NaN"):
        read_radar(path)


def test_header_beyond_the_bound_is_refused_before_reading(tmp_path, monkeypatch):
    monkeypatch.setenv("FOGSIM_MAX_SCAN_POINTS", "2")
    path = tmp_path / "big.pcd"
    path.write_bytes(spec_bytes(ROWS))
    with pytest.raises(InputError, match="exceeds the bound"):
        read_radar(path)
    npy = tmp_path / "big.npy"
    write_radar(npy, RadarScan.checked(np.ones((3, 3)), np.zeros(3)))
    with pytest.raises(InputError, match="exceeds the bound"):
        read_radar(npy)


def test_npy_round_trips_every_column(tmp_path):
    src = tmp_path / "in.pcd"
    src.write_bytes(spec_bytes(ROWS))
    scan = read_radar(src)
    scan = RadarScan.checked(scan.xyz, scan.rcs_dbsm, scan.velocity, scan.velocity_comp, [20.0, 15.0, np.nan],
                             [4, -1, 2], [0, 2, 1], [5, 6, 7], "x", scan.extra)
    path = tmp_path / "s.npy"
    write_radar(path, scan)
    back = read_radar(path)
    assert back.same_as(scan)
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], object), allow_pickle=True)
    with pytest.raises(InputError, match="pickled"):
        read_radar(tmp_path / "obj.npy")
    np.save(tmp_path / "plain.npy", np.zeros((3, 4), np.float32))
    with pytest.raises(InputError, match="structured"):
        read_radar(tmp_path / "plain.npy")


def test_record_checks_and_selects():
    with pytest.raises(InputError, match="N×3"):
        RadarScan.checked(np.zeros((2, 2)), [0, 0])
    with pytest.raises(InputError, match="infinite RCS"):
        RadarScan.checked(np.ones((2, 3)), [0, np.inf])
    with pytest.raises(InputError, match="kind"):
        RadarScan.checked(np.ones((1, 3)), [0], kind=[7])
    scan = RadarScan.checked([[1, 0, 0], [0, 2, 0], [3, 0, 0]], [1, 2, 3])
    part = scan.select(np.array([False, True, True]))
    assert part.index.tolist() == [1, 2] and np.allclose(part.range_m, [2, 3])
    assert np.allclose(part.azimuth_rad, [np.pi / 2, 0])
    assert part.copy().same_as(part) and not part.same_as(scan)


def test_open3d_reads_the_positions(tmp_path):
    o3d = pytest.importorskip("open3d")
    src = tmp_path / "in.pcd"
    src.write_bytes(spec_bytes(ROWS))
    out = tmp_path / "out.pcd"
    write_radar(out, read_radar(src))
    got = np.asarray(o3d.io.read_point_cloud(str(out)).points)
    assert np.allclose(got, np.array([r[:3] for r in ROWS], np.float32))
