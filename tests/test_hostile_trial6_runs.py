"""The sixth hostile-input trial's defects of ``fogsim fog --points`` runs (``shared/notes/reliability-defects-6.md``,
D08, D13–D15, D17, D18, D20–D23: an output folder's links, calibrations, flags checked up front, radar levels),
each as the trial reproduced it, in the style of :mod:`test_hostile_sensors`: the exit code, one line naming the
file or flag and the problem, no traceback, the inputs unchanged, nothing partial. The readers' defects:
:mod:`test_hostile_trial6`; ``export nuscenes``: :mod:`test_hostile_trial6_export`.
"""
from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np
import pytest

import lidar_fixtures as lf
from conftest import run_sensor_case
from fogsim.cli import main
from test_hostile import Case
from test_hostile_sensors import (
    _points,
    _radar,
    radar_bytes,
    radar_header,
)
from test_hostile_trial6 import _scan_kitti, _write_json

BAD = "n008__RADAR_FRONT__2.pcd"
#: the trial's sparse bodies: 4 GiB (under the ASCII bound of 48 characters a number for 10⁷ points)
FOUR_GB = 4 << 30


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
    pytest.importorskip("itur")
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
    pytest.importorskip("itur")
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
    pytest.importorskip("itur")
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


CASES = LINKS + FLAGS


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_trial6_run_case(case: Case, tmp_path, capsys, monkeypatch):
    run_sensor_case(case, tmp_path, capsys, monkeypatch,
                    needs_itur="radar" in case.id or case.id.startswith("d22-points"))
