"""Hostile cases on the sensor surfaces (issue 41, item 4): point-cloud formats (``.bin``, ``.pcd.bin``,
``.npy``, PLY) through ``fogsim fog --points``, KITTI calibrations, labels, images and scans through
``fogsim fog --kitti --lidar``, custom sensor files, sidecars and outcome files, resume with other
parameters, outputs that claim to be done, image and depth headers that lie (item 3) — in the style of
:mod:`test_hostile`: each case builds its inputs under ``tmp/in``, runs one ``fogsim`` command and checks
the exit code, a one-line message naming the file, no traceback, every input byte-identical and nothing
partial. Below the table: the PCD codec's hostile files (the radar's nuScenes files go through it), the
bounded-memory runs (a 16 GB sparse scan under a 1.5 GB address-space limit, in a process of its own) and
Ctrl-C in the middle of a scan's levels, then resume.
"""
from __future__ import annotations

import io
import json
import math
import os
import resource
import shutil
import signal
import socket
import struct
import subprocess
import sys
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

import kitti_tree as kt
import lidar_fixtures as lf
from conftest import HANG_S, run_sensor_case, signal_mid_run
from fogsim.cli import main
from fogsim.errors import InputError
from fogsim.io.depth_files import write_depth
from fogsim.io.images import encode_image
from test_hostile import Case, fog, good_folder

ROOT = Path(__file__).resolve().parents[1]
#: a sparse file this large is refused by its size alone (16 GiB, as the issue's report): the processes of
#: their own below read it; the table's cases (whose inputs are hashed whole) lower the bound instead
HUGE = 16 << 30
#: the table's sparse inputs: 1 MiB (65,536 KITTI points) against a bound lowered to 1,000 points
SMALL = 1 << 20
LOW = {"FOGSIM_MAX_SCAN_POINTS": "1000"}
#: just above the 64 MiB bound on the documents users write (calibrations, labels, sensor files)
OVER_DOCUMENT = (64 << 20) + 1


@dataclass
class SensorCase(Case):
    """A :class:`test_hostile.Case` with environment variables set for the run."""

    env: dict = field(default_factory=dict)


def sparse(path: Path, size: int = HUGE, head: bytes = b"") -> None:
    """A sparse file of ``size`` bytes starting with ``head`` (skips the test where the file system
    cannot make one: its blocks would really be written)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        f.write(head)
        f.truncate(size)
    if os.stat(path).st_blocks * 512 > size // 2:
        path.unlink()
        pytest.skip("this file system cannot make sparse files")


# ----------------------------------------------------------------------------- --points inputs
def _good_scan() -> tuple[np.ndarray, np.ndarray]:
    xyz, rho, *_ = lf.surfaces_scan([lf.Surface(10.0, 0.5), lf.Surface(30.0, 0.2)])
    return xyz.astype(np.float32), rho


def _npy_bytes(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=False)
    return buf.getvalue()


def _npy_header(shape, descr: str = "<f4", body: bytes = b"\0" * 64, version: int = 1) -> bytes:
    """A ``.npy`` written from the format's description: magic, version, header dict, ``body``."""
    text = repr({"descr": descr, "fortran_order": False, "shape": tuple(shape)})
    size = 4 if version > 1 else 2
    pad = -(6 + 2 + size + len(text) + 1) % 64
    head = (text + " " * pad + "\n").encode("latin-1")
    return b"\x93NUMPY" + bytes([version, 0]) + len(head).to_bytes(size, "little") + head + body


def _ply(vertex: int, props: str = "property float x\nproperty float y\nproperty float z\n",
         body: bytes = b"\0" * 64, fmt: str = "binary_little_endian", extra: str = "") -> bytes:
    return (f"ply\nformat {fmt} 1.0\n{extra}element vertex {vertex}\n{props}end_header\n").encode() + body


def _good_ply(extra: str = "", ring=None) -> bytes:
    xyz, rho = _good_scan()
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")] + ([("ring", "<f4")] if ring else [])
    rec = np.zeros(len(xyz), fields)
    rec["x"], rec["y"], rec["z"], rec["intensity"] = *xyz.T, rho / 2.55
    props = "".join(f"property float {n}\n" for n, _ in fields)
    if ring:
        rec["ring"] = ring(len(xyz))
    return _ply(len(xyz), props, rec.tobytes(), extra=extra)


def _points(name: str, blob: Callable[[Path], bytes | None], fmt: str, *flags: str):
    """``fogsim fog --points`` of a folder holding a good scan of ``fmt`` and ``name`` (``blob(path)``
    returns its bytes, or None when it wrote the file itself)."""
    def build(tmp: Path) -> list[str]:
        folder = tmp / "in" / "scans"
        folder.mkdir(parents=True)
        xyz, rho = _good_scan()
        good = {"kitti": lf.kitti_bin(xyz, rho / 2.55), "stf": lf.stf_bin(xyz, 100 * rho, np.arange(len(xyz)) % 32),
                "nuscenes": lf.stf_bin(xyz, 100 * rho, np.arange(len(xyz)) % 32),
                "npy": _npy_bytes(np.column_stack([xyz, rho / 2.55]).astype(np.float32)), "ply": _good_ply()}[fmt]
        suffix = {"kitti": ".bin", "stf": ".bin", "nuscenes": ".pcd.bin", "npy": ".npy", "ply": ".ply"}[fmt]
        (folder / f"good{suffix}").write_bytes(good)
        data = blob(folder / name)
        if data is not None:
            (folder / name).write_bytes(data)
        sensor = ["--sensor", "hdl64e"] if fmt in ("npy", "ply") else []
        return ["fog", "--points", str(folder), "--point-format", fmt, "--levels", "0.06", "--out",
                str(tmp / "out"), "--quiet", *sensor, *flags]
    return build


def _sparse_at(size: int = HUGE, head: bytes = b""):
    def write(path: Path) -> None:
        sparse(path, size, head)
    return write


def _five(put: dict | None = None) -> bytes:
    rec = np.array([[10.0, 0.0, 0.0, 40.0, 3.0]] * 4, "<f4")
    for (row, col), value in (put or {}).items():
        rec[row, col] = value
    return rec.tobytes()


def _structured(names) -> bytes:
    rec = np.zeros(4, [(n, "<f4") for n in names])
    rec[names[0]] = 10.0
    return _npy_bytes(rec)


POINT_FORMATS = [
    # --- the bound: a file's size (or header) says how many points before anything is read
    SensorCase("points-kitti-sparse", _points("a.bin", _sparse_at(SMALL), "kitti"), 1,
               ("a.bin", "kitti scan of 1,048,576 bytes, 65,536 points exceeds the bound of 1,000 points per scan",
                "FOGSIM_MAX_SCAN_POINTS"), env=LOW),
    SensorCase("points-kitti-sparse-plus-3", _points("a.bin", _sparse_at(SMALL + 3), "kitti"), 1,
               ("a.bin", "exceeds the bound"), env=LOW),
    SensorCase("points-nuscenes-sparse", _points("n008_LIDAR_TOP__1.pcd.bin", _sparse_at(SMALL), "nuscenes"), 1,
               ("LIDAR_TOP__1.pcd.bin", "nuscenes scan", "exceeds the bound"), env=LOW),
    SensorCase("points-stf-sparse", _points("b.bin", _sparse_at(SMALL), "stf"), 1,
               ("b.bin", "stf scan", "exceeds the bound"), env=LOW),
    SensorCase("points-bound-lowered", _points("a.bin", lambda p: lf.kitti_bin(*_good_scan()), "kitti"), 1,
               ("a.bin", "16 points exceeds the bound of 10 points", "FOGSIM_MAX_SCAN_POINTS"),
               env={"FOGSIM_MAX_SCAN_POINTS": "10"}),
    SensorCase("points-bound-not-a-number", _points("a.bin", lambda p: None, "kitti"), 2,
               ("FOGSIM_MAX_SCAN_POINTS", "positive whole number", "'lots'"), env={"FOGSIM_MAX_SCAN_POINTS": "lots"}),
    SensorCase("points-bound-negative", _points("a.bin", lambda p: None, "kitti"), 2,
               ("FOGSIM_MAX_SCAN_POINTS", "got -5"), env={"FOGSIM_MAX_SCAN_POINTS": "-5"}),
    SensorCase("points-bound-raised", _points("a.bin", _sparse_at(1 << 20), "kitti"), 0, (),
               env={"FOGSIM_MAX_SCAN_POINTS": "100000"}),
    # --- .bin records
    Case("points-stf-ring-nan", _points("b.bin", lambda p: _five({(1, 4): math.nan}), "stf"), 1,
         ("b.bin", "ring column holds NaN")),
    Case("points-stf-not-whole-records", _points("b.bin", lambda p: _five()[:-4], "stf"), 1,
         ("b.bin", "not a whole number of 20-byte stf records")),
    Case("points-kitti-one-byte", _points("a.bin", lambda p: b"\0", "kitti"), 1, ("a.bin", "1 bytes")),
    Case("points-kitti-folder-named-bin", _points("d.bin", lambda p: p.mkdir() or None, "kitti"), 0, ()),
    # --- .npy: the header, read without loading
    Case("points-npy-header-lies", _points("a.npy", lambda p: _npy_header((1_000_000, 4)), "npy"), 1,
         ("a.npy", ".npy header declares float32 [1000000, 4] (16,000,000 bytes)", "holds only 64 bytes")),
    Case("points-npy-header-huge", _points("a.npy", lambda p: _npy_header((10**12, 4)), "npy"), 1,
         ("a.npy", "1,000,000,000,000 points exceeds the bound")),
    Case("points-npy-wide-not-points", _points("a.npy", lambda p: _npy_header((5, 10**9)), "npy"), 1,
         ("a.npy", "expected a numeric N×3, N×4 or N×5 array")),
    SensorCase("points-npy-sparse-header", _points("a.npy", _sparse_at(SMALL, _npy_header((SMALL // 16, 4), body=b"")),
                                                   "npy"), 1, ("a.npy", "65,536 points exceeds the bound"), env=LOW),
    Case("points-npy-object", _points("a.npy", lambda p: _npy_header((4,), "|O"), "npy"), 1, ("a.npy", "pickled")),
    Case("points-npy-3d", _points("a.npy", lambda p: _npy_bytes(np.zeros((2, 2, 4), np.float32)), "npy"), 1,
         ("a.npy", "expected a numeric N×3")),
    Case("points-npy-complex", _points("a.npy", lambda p: _npy_bytes(np.zeros((4, 4), np.complex64)), "npy"), 1,
         ("a.npy", "complex64")),
    Case("points-npy-structured-no-z", _points("a.npy", lambda p: _structured(["x", "y", "w"]), "npy"), 1,
         ("a.npy", "needs fields x, y, z")),
    Case("points-npy-structured-2d", _points("a.npy", lambda p: _npy_bytes(
        np.zeros((2, 2), [("x", "<f4"), ("y", "<f4"), ("z", "<f4")])), "npy"), 1, ("a.npy", "must be 1-D")),
    Case("points-npy-npz", _points("a.npy", lambda p: b"PK\x03\x04" + b"\0" * 60, "npy"), 1,
         ("a.npy", "npz archive")),
    Case("points-npy-garbage", _points("a.npy", lambda p: b"not numpy at all" * 4, "npy"), 1,
         ("a.npy", "not a readable .npy header")),
    Case("points-npy-version-3", _points("a.npy", lambda p: _npy_header((4, 4), version=3), "npy"), 1,
         ("a.npy", "version 3.0")),
    Case("points-npy-header-endless", _points("a.npy", lambda p: b"\x93NUMPY\x02\x00" + (10**6).to_bytes(4, "little")
                                              + b"{" * 100, "npy"), 1, ("a.npy", "not a readable .npy header")),
    Case("points-npy-big-endian", _points("a.npy", lambda p: _npy_bytes(
        np.column_stack([_good_scan()[0], _good_scan()[1] / 2.55]).astype(">f4")), "npy"), 0, ()),
    # --- PLY: the header's counts against the file
    Case("points-ply-header-lies", _points("a.ply", lambda p: _ply(4_000_000_000), "ply"), 1,
         ("a.ply", "PLY header claims 4,000,000,000 points", "holds only 64 bytes", "the header lies")),
    SensorCase("points-ply-over-bound", _points("a.ply", _sparse_at(12 * 2000 + 200, _ply(2000, body=b"")), "ply"), 1,
               ("a.ply", "2,000 points exceeds the bound of 1,000"), env=LOW),
    Case("points-ply-ascii-lies", _points("a.ply", lambda p: _ply(10**6, fmt="ascii", body=b"1 2 3\n"), "ply"), 1,
         ("a.ply", "claims 1,000,000 points")),
    Case("points-ply-no-end-header", _points("a.ply", lambda p: b"ply\nformat ascii 1.0\n" + b"comment x\n" * 8000,
                                             "ply"), 1, ("a.ply", "no end_header")),
    Case("points-ply-not-ply", _points("a.ply", lambda p: b"solid cube\nendsolid\n", "ply"), 1,
         ("a.ply", "does not start with 'ply'")),
    Case("points-ply-no-vertex", _points("a.ply", lambda p: b"ply\nformat ascii 1.0\nelement face 0\n"
                                         b"property list uchar int vertex_indices\nend_header\n", "ply"), 1,
         ("a.ply", "no vertex element")),
    Case("points-ply-no-z", _points("a.ply", lambda p: _ply(2, "property float x\nproperty float y\n", b"\0" * 16),
                                    "ply"), 1, ("a.ply", "need x, y, z")),
    Case("points-ply-negative-count", _points("a.ply", lambda p: _ply(-4), "ply"), 1,
         ("a.ply", "PLY header is malformed", "negative count")),
    Case("points-ply-count-not-number", _points("a.ply", lambda p: _ply(0).replace(b"vertex 0", b"vertex many"),
                                                "ply"), 1, ("a.ply", "PLY header is malformed")),
    Case("points-ply-format-unknown", _points("a.ply", lambda p: _ply(2, fmt="binary_middle_endian"), "ply"), 1,
         ("a.ply", "no known format")),
    Case("points-ply-scale-unknown", _points("a.ply", lambda p: _good_ply("comment fogsim intensity_scale 0-9\n"),
                                             "ply"), 1, ("a.ply", "unknown intensity scale '0-9'")),
    Case("points-ply-scale-contradicts", _points("a.ply", lambda p: _good_ply("comment fogsim intensity_scale 0-255\n"),
                                                 "ply", "--point-scale", "0-1"), 1,
         ("a.ply", "says its intensity scale is 0-255, not the declared 0-1")),
    Case("points-ply-ring-nan", _points("a.ply", lambda p: _good_ply(ring=lambda n: np.full(n, np.nan)), "ply"), 1,
         ("a.ply", "ring property holds NaN")),
    # --- the run itself
    Case("points-folder-without-scans", lambda t: _points("a.txt", lambda p: b"x", "kitti")(t)[:2]
         + [str(t / "in" / "empty"), "--point-format", "kitti", "--out", str(t / "out")], 2, ("no such file",)),
    Case("points-name-clash", lambda t: _points("sub/good.bin", lambda p: p.parent.mkdir() or lf.kitti_bin(
        *_good_scan()), "kitti")(t)[:2] + [str(t / "in/scans/good.bin"), str(t / "in/scans/sub/good.bin"),
                                           "--point-format", "kitti", "--out", str(t / "out")], 2,
         ("good.bin", "also that of")),
    Case("points-bare-bin-needs-format", lambda t: [a for a in _points("a.bin", lambda p: None, "kitti")(t)
                                                    if a not in ("--point-format", "kitti")], 2, ("--point-format",)),
    Case("points-out-is-a-file", lambda t: _points("notes.txt", lambda p: b"x", "kitti")(t)[:-3]
         + ["--out", str(t / "in" / "scans" / "notes.txt"), "--quiet"], 2, ("notes.txt",)),
]


# ----------------------------------------------------------------------------- sensor files
BASE_SENSOR = {"beams": 64, "vertical_fov_deg": [-24.9, 2.0], "horizontal_resolution_deg": 0.18,
               "max_range_m": 120.0, "intensity_scale": "0-1"}


def _sensor(doc: dict | str | bytes | None, *, write=None):
    """``--points`` of a good KITTI scan with ``--lidar-sensor in/s.json`` holding ``doc``."""
    def build(tmp: Path) -> list[str]:
        argv = _points("a.bin", lambda p: None, "kitti")(tmp)
        path = tmp / "in" / "s.json"
        if write is not None:
            write(path)
        else:
            text = doc if isinstance(doc, (str, bytes)) else json.dumps(doc)
            path.write_bytes(text if isinstance(text, bytes) else text.encode())
        return argv + ["--lidar-sensor", str(path)]
    return build


def _with(**change) -> dict:
    return {k: v for k, v in (BASE_SENSOR | change).items() if v is not None}


SENSORS = [
    Case("sensor-good", _sensor(BASE_SENSOR), 0, ()),
    Case("sensor-beams-zero", _sensor(_with(beams=0)), 2, ("s.json", "beams")),
    Case("sensor-beams-huge", _sensor(_with(beams=10**9)), 2, ("s.json", "beams")),
    Case("sensor-beams-string", _sensor(_with(beams="64")), 2, ("s.json", "beams")),
    Case("sensor-range-negative", _sensor(_with(max_range_m=-1)), 2, ("s.json", "max_range_m")),
    Case("sensor-range-nan", _sensor(json.dumps(_with()).replace("120.0", "NaN")), 2, ("s.json", "max_range_m")),
    Case("sensor-range-infinite", _sensor(json.dumps(_with()).replace("120.0", "Infinity")), 2,
         ("s.json", "max_range_m")),
    Case("sensor-fov-beyond-90", _sensor(_with(vertical_fov_deg=[-120, 2.0])), 2, ("s.json", "vertical_fov_deg")),
    Case("sensor-unknown-key", _sensor(_with(laser_power_w=5)), 2, ("s.json", "laser_power_w")),
    Case("sensor-scale-unknown", _sensor(_with(intensity_scale="0-7")), 2, ("s.json", "intensity_scale")),
    Case("sensor-missing-range", _sensor(_with(max_range_m=None)), 2, ("s.json", "max_range_m")),
    Case("sensor-not-json", _sensor("beams: 64"), 2, ("s.json", "not readable as JSON")),
    Case("sensor-not-utf8", _sensor(b"{\"beams\": \xff}"), 2, ("s.json", "not UTF-8")),
    Case("sensor-nested-deep", _sensor("[" * 5000 + "]" * 5000), 2, ("s.json", "nest")),
    Case("sensor-a-list", _sensor([1, 2, 3]), 2, ("s.json",)),
    Case("sensor-missing-file", lambda t: _points("a.bin", lambda p: None, "kitti")(t)
         + ["--lidar-sensor", str(t / "in" / "none.json")], 2, ("none.json", "not found")),
    Case("sensor-sparse-huge", _sensor(None, write=lambda p: sparse(p, OVER_DOCUMENT, b"{")), 2,
         ("s.json", "larger than 64 MiB")),
    Case("sensor-steps-huge", _sensor(_with(horizontal_resolution_deg=None, steps_per_sweep=10**9)), 2,
         ("s.json", "steps_per_sweep")),
]


# ------------------------------------------------------------------- KITTI: scans, calibrations, labels, images
def _kitti(edit: Callable[[Path], None] | None = None, *flags: str):
    def build(tmp: Path) -> list[str]:
        root = kt.write_kitti(tmp / "in" / "kitti")
        if edit:
            edit(root)
        return ["fog", "--kitti", str(root), "--lidar", "--levels", "0.06", "--no-kitti-trees", "--out",
                str(tmp / "out"), "--quiet", *flags]
    return build


def _file(rel: str, make: Callable[[Path], bytes | None]):
    def edit(root: Path) -> None:
        path = root / "training" / rel
        data = make(path)
        if data is not None:
            path.write_bytes(data)
    return edit


def _calib(edit: Callable[[str], str]):
    return _file("calib/000001.txt", lambda p: edit(p.read_text()).encode())


def _label(edit: Callable[[str], str]):
    return _file("label_2/000001.txt", lambda p: edit(p.read_text()).encode())


def _field(line_edit: Callable[[list[str]], list[str]]):
    return _label(lambda t: " ".join(line_edit(t.split("\n")[0].split())) + "\n")


def _png_claiming(width: int, height: int) -> bytes:
    """A whole PNG (right CRCs, IEND) whose IHDR declares ``width`` × ``height`` over one tiny IDAT."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return len(data).to_bytes(4, "big") + kind + data + zlib.crc32(kind + data).to_bytes(4, "big")
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b"")


def _jpeg_claiming(width: int, height: int) -> bytes:
    """A real JPEG whose frame header (SOF0) is rewritten to declare ``width`` × ``height``."""
    data = bytearray(encode_image(np.full((16, 16, 3), 90, np.uint8), ".jpg"))
    sof = data.find(b"\xff\xc0")
    data[sof + 5:sof + 9] = struct.pack(">HH", height, width)
    return bytes(data)


KITTI = [
    SensorCase("kitti-velodyne-sparse", _kitti(_file("velodyne/000001.bin", lambda p: sparse(p, SMALL))), 1,
               ("velodyne/000001.bin", "exceeds the bound of 1,000 points per scan"), env=LOW),
    Case("kitti-velodyne-folder", _kitti(_file("velodyne/000001.bin", lambda p: p.unlink() or p.mkdir())), 2,
         ("000001",)),
    Case("kitti-calib-nan", _kitti(_calib(lambda t: t.replace(t.split("P2: ")[1].split()[0], "nan", 1))), 2,
         ("calib/000001.txt",)),
    Case("kitti-calib-short-row", _kitti(_calib(lambda t: "\n".join(
        " ".join(ln.split()[:-1]) if ln.startswith("P2:") else ln for ln in t.splitlines()) + "\n")), 2,
         ("calib/000001.txt", "P2")),
    Case("kitti-calib-words", _kitti(_calib(lambda t: t.replace("Tr_velo_to_cam:", "Tr_velo_to_cam: a b c"))), 2,
         ("calib/000001.txt",)),
    Case("kitti-calib-not-utf8", _kitti(_file("calib/000001.txt", lambda p: b"P2: \xff\xfe\n")), 2,
         ("calib/000001.txt", "not UTF-8")),
    Case("kitti-calib-sparse-huge", _kitti(_file("calib/000001.txt", lambda p: sparse(p, OVER_DOCUMENT, b"P2: 1"))), 2,
         ("calib/000001.txt", "larger than 64 MiB")),
    Case("kitti-label-nan-size", _kitti(_field(lambda f: f[:8] + ["nan"] + f[9:])), 1, ("label_2/000001.txt",)),
    Case("kitti-label-negative-size", _kitti(_field(lambda f: f[:8] + ["-1.5"] + f[9:])), 1,
         ("label_2/000001.txt", "line 1: a Car's dimensions h w l must be positive")),
    Case("kitti-label-word-for-number", _kitti(_field(lambda f: f[:3] + ["left"] + f[4:])), 1,
         ("label_2/000001.txt", "line 1")),
    Case("kitti-label-not-utf8", _kitti(_file("label_2/000001.txt", lambda p: b"Car \xff\n")), 1,
         ("label_2/000001.txt", "not UTF-8")),
    Case("kitti-label-sparse-huge", _kitti(_file("label_2/000001.txt", lambda p: sparse(p, OVER_DOCUMENT, b"Car"))), 1,
         ("label_2/000001.txt", "larger than 64 MiB")),
    Case("kitti-image-png-header-huge", _kitti(_file("image_2/000001.png", lambda p: _png_claiming(100000, 100000))),
         1, ("image_2/000001.png", "PNG header declares 100000×100000", "--max-pixels")),
    Case("kitti-image-sparse", _kitti(_file("image_2/000001.png",
                                            lambda p: sparse(p, 4 * SMALL, _png_claiming(160, 48))), "--max-pixels",
                                      "8000"), 1,
         ("image_2/000001.png", "4,194,304 bytes is more than an image of at most 8,000 pixels takes")),
    Case("kitti-image-not-png", _kitti(_file("image_2/000001.png", lambda p: b"GIF89a" + b"\0" * 64)), 2,
         ("image_2/000001.png", "not a PNG image")),
    SensorCase("kitti-lidar-bound-env-bad", _kitti(), 2, ("FOGSIM_MAX_SCAN_POINTS",),
               env={"FOGSIM_MAX_SCAN_POINTS": "0"}),
]


# ----------------------------------------------------------------------------- images and depth that lie (item 3)
def _image(name: str, make: Callable[[Path], bytes | None], *flags: str):
    """``fogsim fog --input`` of a good folder with ``images/a.png`` replaced by ``make``'s bytes."""
    def build(tmp: Path) -> list[str]:
        base = good_folder(tmp)
        path = base / name
        data = make(path)
        if data is not None:
            path.write_bytes(data)
        return fog(base, tmp / "out", *flags)
    return build


def _exr_claiming(path: Path, width: int, height: int) -> bytes:
    """A real EXR whose dataWindow attribute is rewritten to declare ``width`` × ``height``."""
    write_depth(path, np.full((24, 32), 10.0, np.float32))
    data = bytearray(path.read_bytes())
    at = data.find(b"dataWindow\0box2i\0") + len(b"dataWindow\0box2i\0") + 4
    data[at:at + 16] = struct.pack("<4i", 0, 0, width - 1, height - 1)
    return bytes(data)


def _depth_npy(path: Path, blob: bytes) -> None:
    path.with_suffix(".exr").unlink()
    path.with_suffix(".npy").write_bytes(blob)


IMAGES = [
    Case("image-png-ihdr-huge", _image("images/a.png", lambda p: _png_claiming(100000, 100000)), 1,
         ("images/a.png", "PNG header declares 100000×100000 = 10000.0 MP", "limit of 40 MP")),
    Case("image-png-ihdr-over-max-pixels", _image("images/a.png", lambda p: _png_claiming(30, 30), "--max-pixels",
                                                  "800"), 1, ("images/a.png", "PNG header declares 30×30")),
    Case("image-jpeg-sof-huge", _image("images/a.png", lambda p: _jpeg_claiming(60000, 60000)), 1,
         ("images/a.png", "JPEG header declares 60000×60000")),
    Case("image-sparse", _image("images/a.png", lambda p: sparse(p, 4 * SMALL), "--max-pixels", "1000"), 1,
         ("images/a.png", "4,194,304 bytes", "not an image fogsim reads")),
    Case("depth-exr-window-huge", _image("depth/a.exr", lambda p: _exr_claiming(p, 100000, 100000)), 1,
         ("depth/a.exr", "EXR header declares 100000×100000")),
    Case("depth-npy-shape-huge", _image("depth/a.exr", lambda p: _depth_npy(p, _npy_header((100000, 100000))),
                                        "--depth-suffix", ""), 1, ("a.npy", "NPY header declares 100000×100000")),
    Case("depth-npy-header-lies", _image("depth/a.exr", lambda p: _depth_npy(p, _npy_header((24, 32), body=b"\0" * 8))),
         1, ("a.npy", "header declares float32 [24, 32] (3,072 bytes)", "holds only 8 bytes")),
    Case("depth-png16-ihdr-huge", _image("depth/a.exr", lambda p: p.unlink() or (p.with_suffix(".png").write_bytes(
        _png_claiming(70000, 70000)) and None), "--depth-scale", "0.001"), 1, ("a.png", "PNG header declares")),
]


# ----------------------------------------------------------------------------- resume, sidecars, outcome files, done
def _ran(*flags: str, then: Callable[[Path], None] | None = None, again: tuple[str, ...] | None = None):
    """A finished ``--points`` run into tmp/out (``flags``), ``then(tmp)``, and the command run again with
    ``again`` (default the same flags)."""
    def build(tmp: Path) -> list[str]:
        argv = _points("a.bin", lambda p: lf.kitti_bin(*_good_scan()), "kitti", *flags)(tmp)
        assert main(argv) == 0
        if then:
            then(tmp)
        base = argv[:argv.index("--levels")]
        return base + ["--levels", "0.06", "--out", str(tmp / "out"), "--quiet", *(flags if again is None else again)]
    return build


def _delete(rel: str):
    def then(tmp: Path) -> None:
        (tmp / "out" / rel).unlink()
    return then


def _edit_run_file(edit: Callable[[dict], None]):
    def then(tmp: Path) -> None:
        path = tmp / "out" / "fogsim_run.json"
        doc = json.loads(path.read_text())
        edit(doc)
        path.write_text(json.dumps(doc))
    return then


def _stale_part(tmp: Path) -> None:
    """A dead writer's leftover on this host (its pid above any pid the kernel hands out)."""
    host = socket.gethostname().replace(".", "_").replace("-", "_") or "host"
    (tmp / "out" / "beta0.06" / f".a.bin.{host}-999999999.x.part").write_bytes(b"half")


def _done_but_gone(tmp: Path) -> None:
    for p in (tmp / "out" / "beta0.06").glob("a.*"):
        if p.suffix != ".json":
            p.unlink()


RESUME = [
    Case("resume-other-levels", _ran(again=("--levels", "0.12")), 2, ("fogsim_run.json",)),
    Case("resume-other-seed", _ran(again=("--seed", "7")), 2, ("fogsim_run.json", "other parameters")),
    Case("resume-other-model", _ran(again=("--lidar-model", "attenuation")), 2, ("fogsim_run.json",)),
    Case("resume-other-sensor", _ran(again=("--lidar-sensor", "hdl32e")), 2, ("fogsim_run.json", "other parameters")),
    Case("resume-other-extinction", _ran(again=("--lidar-extinction-ratio", "2")), 2, ("fogsim_run.json",)),
    Case("resume-same", _ran(), 0, ()),
    Case("resume-run-file-garbage", _ran(then=lambda t: (t / "out" / "fogsim_run.json").write_text("{")), 2,
         ("fogsim_run.json",)),
    Case("resume-run-file-levels-string", _ran(then=_edit_run_file(lambda d: d["parameters"].update(levels="0.06"))),
         2, ("fogsim_run.json",)),
    Case("resume-run-file-deep", _ran(then=lambda t: (t / "out" / "fogsim_run.json").write_text("[" * 5000)), 2,
         ("fogsim_run.json", "nest")),
    Case("resume-stale-part-removed", _ran(then=_stale_part), 0, ()),
    Case("done-sidecar-without-scan", _ran(then=_done_but_gone), 0, ()),
    Case("done-sidecar-without-outcomes", _ran(then=_delete("beta0.06/a.outcomes.npz")), 0, ()),
    Case("done-sidecar-without-pcd", _ran(then=_delete("beta0.06/a.pcd")), 0, ()),
    Case("finalize-points-run", lambda t: _ran()(t) and ["fog", "--finalize-only", "--out", str(t / "out")], 2,
         ("fogsim_run.json", "fogged scans alone")),
]


# ----------------------------------------------------------------------------- PCD files (the radar's nuScenes files)
#: a nuScenes RADAR_* header's fields (18 per detection, 43 bytes a record), as the devkit's radar files have them
RADAR_FIELDS = ("x y z dyn_prop id rcs vx vy vx_comp vy_comp is_quality_valid ambig_state x_rms y_rms invalid_state "
                "pdh0 vx_rms vy_rms").split()
RADAR_SIZE = "4 4 4 1 2 4 4 4 4 4 1 1 1 1 1 1 1 1".split()
RADAR_TYPE = "F F F I I F F F F F I I I I I I I I".split()
RADAR_RECORD = sum(map(int, RADAR_SIZE))


def radar_header(points: int, data: str = "binary", **change: str) -> bytes:
    """A nuScenes radar PCD header (``change``: a key's value replaced, ``None`` drops the line)."""
    lines = {"VERSION": "0.7", "FIELDS": " ".join(RADAR_FIELDS), "SIZE": " ".join(RADAR_SIZE),
             "TYPE": " ".join(RADAR_TYPE), "COUNT": " ".join(["1"] * 18), "WIDTH": str(points), "HEIGHT": "1",
             "VIEWPOINT": "0 0 0 1 0 0 0", "POINTS": str(points), "DATA": data} | change
    text = "# .PCD v0.7 - Point Cloud Data file format\n" + "".join(
        f"{k} {v}\n" for k, v in lines.items() if v is not None)
    return text.encode()


def _lzf_sizes(compressed: int, uncompressed: int) -> bytes:
    return struct.pack("<II", compressed, uncompressed) + b"\0" * 16


# ------------------------------------------------------------------ radar sweeps (--point-format nuscenes-radar)
def radar_dtype() -> np.dtype:
    """nuScenes' radar record (packed, little-endian) from :data:`RADAR_FIELDS` / SIZE / TYPE."""
    code = {("F", "4"): "<f4", ("I", "1"): "i1", ("I", "2"): "<i2"}
    return np.dtype([(n, code[t, z]) for n, z, t in zip(RADAR_FIELDS, RADAR_SIZE, RADAR_TYPE)])


def radar_bytes(n: int = 6, edit: Callable[[np.ndarray], None] | None = None, **header: str) -> bytes:
    """A nuScenes radar sweep of ``n`` detections (5–60 m ahead, 0–15 dBsm), written from the format's spec."""
    rec = np.zeros(n, radar_dtype())
    rec["x"] = np.linspace(5.0, 60.0, n)
    rec["rcs"] = np.linspace(0.0, 15.0, n)
    rec["ambig_state"], rec["is_quality_valid"], rec["pdh0"] = 3, 1, 1
    if edit:
        edit(rec)
    return radar_header(n, **header) + rec.tobytes()


def _radar(name: str, blob: Callable[[Path], bytes | None], *flags: str):
    """``fogsim fog --points`` of a folder of nuScenes radar sweeps: a good one and ``name``."""
    def build(tmp: Path) -> list[str]:
        folder = tmp / "in" / "RADAR_FRONT"
        folder.mkdir(parents=True)
        (folder / "n008__RADAR_FRONT__1.pcd").write_bytes(radar_bytes())
        data = blob(folder / name)
        if data is not None:
            (folder / name).write_bytes(data)
        return ["fog", "--points", str(folder), "--point-format", "nuscenes-radar", "--levels", "0.06", "--out",
                str(tmp / "out"), "--quiet", *flags]
    return build


def _radar_ran(*again: str, then: Callable[[Path], None] | None = None):
    def build(tmp: Path) -> list[str]:
        argv = _radar("n008__RADAR_FRONT__2.pcd", lambda p: radar_bytes(4))(tmp)
        assert main(argv) == 0
        if then:
            then(tmp)
        return argv + list(again)
    return build


BAD = "n008__RADAR_FRONT__2.pcd"
RADAR = [
    Case("radar-points-lie", _radar(BAD, lambda p: radar_header(125) + b"\0" * 10), 1, (BAD, "the header lies")),
    SensorCase("radar-sparse-over-bound", _radar(BAD, _sparse_at(SMALL, radar_header(SMALL // RADAR_RECORD))), 1,
               (BAD, "24,385 points exceeds the bound of 1,000"), env=LOW),
    Case("radar-truncated", _radar(BAD, lambda p: radar_bytes(6)[:-30]), 1, (BAD, "truncated")),
    Case("radar-sparse-after-its-records", _radar(BAD, _sparse_at(4 * SMALL, radar_bytes(6))), 1,
         (BAD, "PCD binary body of", "far longer than its 6 points need (258 bytes)")),
    Case("radar-type-unknown", _radar(BAD, lambda p: radar_bytes(TYPE=" ".join(["Q"] + RADAR_TYPE[1:]))), 1,
         (BAD, "TYPE Q")),
    Case("radar-rcs-missing", _radar(BAD, lambda p: radar_bytes(FIELDS=" ".join(RADAR_FIELDS).replace(" rcs ",
                                                                                                     " rcz "))), 1,
         (BAD, "lack rcs")),
    Case("radar-rcs-as-integer", _radar(BAD, lambda p: radar_bytes(TYPE=" ".join(RADAR_TYPE[:5] + ["I"]
                                                                                   + RADAR_TYPE[6:])), "--quiet"), 0,
         ()),
    Case("radar-nan-second-record", _radar(BAD, lambda p: radar_bytes(edit=lambda r: r["x"].__setitem__(1, np.nan))),
         1, (BAD, "NaN")),
    Case("radar-rcs-infinite", _radar(BAD, lambda p: radar_bytes(edit=lambda r: r["rcs"].__setitem__(2, np.inf))),
         1, (BAD,)),
    Case("radar-not-pcd", _radar(BAD, lambda p: b"\x89PNG\r\n\x1a\n" + b"\0" * 64), 1, (BAD, "unknown key")),
    Case("radar-empty-file", _radar(BAD, lambda p: b""), 1, (BAD, "no DATA line")),
    Case("radar-lidar-flag", _radar(BAD, lambda p: None, "--lidar-model", "attenuation"), 2,
         ("--lidar-model is for LiDAR scans",)),
    Case("radar-sensor-lidar-name", _radar(BAD, lambda p: None, "--sensor", "hdl64e"), 2, ("hdl64e",)),
    Case("radar-sensor-file-not-json", lambda t: _radar(BAD, lambda p: None)(t) + ["--sensor", str(
        _write(t / "in" / "r.json", b"{radar"))], 2, ("r.json", "not readable as JSON")),
    Case("radar-sensor-file-sparse-huge", lambda t: _radar(BAD, lambda p: None)(t) + ["--sensor", str(
        _write(t / "in" / "r.json", None, OVER_DOCUMENT))], 2, ("r.json", "larger than 64 MiB")),
    Case("radar-temperature-for-lidar", _points("a.bin", lambda p: None, "kitti", "--radar-temperature", "5"), 2,
         ("--radar-temperature", "nuscenes-radar")),
    Case("radar-resume-other-temperature", _radar_ran("--radar-temperature", "-5"), 2,
         ("fogsim_run.json", "other parameters")),
    Case("radar-resume-same", _radar_ran(), 0, ()),
    Case("radar-done-sidecar-without-sweep", _radar_ran(then=_delete("beta0.06/n008__RADAR_FRONT__2.pcd")), 0, ()),
    SensorCase("radar-bound-env-bad", _radar(BAD, lambda p: None), 2, ("FOGSIM_MAX_SCAN_POINTS",),
               env={"FOGSIM_MAX_SCAN_POINTS": "many"}),
]


def _write(path: Path, data: bytes | None, size: int = 0) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if data is None:
        sparse(path, size, b"{")
    else:
        path.write_bytes(data)
    return path


# ----------------------------------------------------------------------------- export nuscenes
_DATASETS: dict[str, Path] = {}


def _kitti_dataset(tmp: Path) -> Path:
    """tmp/in/ds: a finished ``fogsim fog --kitti --lidar`` dataset (levels clear and 0.06), built once."""
    if "kitti" not in _DATASETS:
        import tempfile

        cache = Path(tempfile.mkdtemp(prefix="fogsim-hostile-sensors-"))
        root = kt.write_kitti(cache / "kitti")
        assert main(["fog", "--kitti", str(root), "--lidar", "--levels", "0,0.06", "--out", str(cache / "ds"),
                     "--quiet"]) == 0
        _DATASETS["kitti"] = cache / "ds"
    dest = tmp / "in" / "ds"
    shutil.copytree(_DATASETS["kitti"], dest)
    return dest


def _export(edit: Callable[[Path], None] | None = None, *flags: str, out: str = "{tmp}/out"):
    def build(tmp: Path) -> list[str]:
        ds = _kitti_dataset(tmp)
        if edit:
            edit(ds)
        return ["export", "nuscenes", str(ds), "--out", out.replace("{tmp}", str(tmp)), "--quiet", *flags]
    return build


def _meta(edit: Callable[[dict], None]):
    def change(ds: Path) -> None:
        path = sorted((ds / "meta").glob("*.json"))[0]
        doc = json.loads(path.read_text())
        edit(doc)
        path.write_text(json.dumps(doc))
    return change


def _level_scan(make: Callable[[Path], bytes | None]):
    def change(ds: Path) -> None:
        meta = json.loads(sorted((ds / "meta").glob("*.json"))[0].read_text())
        path = ds / meta["lidar"]["levels"]["beta0.06"]["file"]
        data = make(path)
        if data is not None:
            path.write_bytes(data)
    return change


EXPORT = [
    Case("export-good", _export(), 0, ()),
    SensorCase("export-scan-sparse-over-bound", _export(_level_scan(lambda p: sparse(p, SMALL))), 2,
               ("beta0.06", "65,536 points exceeds the bound of 5,000"),
               env={"FOGSIM_MAX_SCAN_POINTS": "5000"}),  # the fixture's own scans hold ≈ 1,000 points
    Case("export-scan-truncated", _export(_level_scan(lambda p: p.read_bytes()[:-6])), 2,
         ("beta0.06", "not a whole number of 16-byte kitti records")),
    Case("export-scan-missing", _export(_level_scan(lambda p: p.unlink())), 2, ("beta0.06", "not found")),
    Case("export-meta-format-unknown", _export(_meta(lambda d: d["lidar"].update(format="las"))), 2,
         ("meta/", "lidar: needs a point format")),
    Case("export-meta-level-without-file", _export(_meta(lambda d: d["lidar"]["levels"]["beta0.06"].pop("file"))),
         2, ("meta/", "lidar.levels.beta0.06: has no scan file")),
    Case("export-meta-inclinations-nan", _export(_meta(lambda d: d["lidar"]["sensor"].update(
        inclinations_deg=[float("nan")]))), 2, ("meta/", "inclinations_deg")),
    Case("export-meta-not-json", _export(lambda ds: sorted((ds / "meta").glob("*.json"))[0].write_text("{")), 2,
         ("meta/",)),
    Case("export-out-is-dataset", _export(None, out="{tmp}/in/ds"), 2, ("is the dataset itself",)),
    Case("export-levels-unknown", _export(None, "--levels", "beta0.5"), 2,
         ("no frame has LiDAR or radar level(s) beta0.5",)),
    Case("export-dataset-missing", lambda t: ["export", "nuscenes", str(t / "in" / "none"), "--out",
                                              str(t / "out")], 2, ("none",)),
]


# ----------------------------------------------------------------------------- Waymo v1 record lengths
def _tfrecord_claiming(length: int, size: int):
    """``fogsim fog --waymo`` of a sparse TFRecord whose first record's length field (its CRC right) claims
    ``length`` bytes."""
    def build(tmp: Path) -> list[str]:
        from fogsim.readers.waymo.tfrecord import masked_crc32c

        head = struct.pack("<Q", length)
        sparse(tmp / "in" / "seg.tfrecord", size, head + struct.pack("<I", masked_crc32c(head)))
        return ["fog", "--waymo", str(tmp / "in" / "seg.tfrecord"), "--levels", "0.06", "--out", str(tmp / "out"),
                "--quiet"]
    return build


WAYMO = [
    Case("waymo-record-length-huge", _tfrecord_claiming(1 << 40, SMALL), 2,
         ("seg.tfrecord#record 0", "1,099,511,627,776 bytes exceeds the bound of 268,435,456 bytes per record")),
    Case("waymo-record-length-past-end", _tfrecord_claiming(SMALL * 2, SMALL), 2,
         ("seg.tfrecord#record 0", "runs past the end")),
]


CASES = POINT_FORMATS + SENSORS + KITTI + IMAGES + RESUME + RADAR + EXPORT + WAYMO


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_hostile_sensor_surface(case: Case, tmp_path, capsys, monkeypatch):
    run_sensor_case(case, tmp_path, capsys, monkeypatch, needs_itur=case.id.startswith("radar-"))
    if case.id.startswith("done-"):  # the sidecar did not claim the scan done: the level was written again
        assert all((tmp_path / "out" / "beta0.06" / f"a{s}").is_file() for s in (".bin", ".outcomes.npz", ".pcd"))
    if case.id == "radar-done-sidecar-without-sweep":
        assert (tmp_path / "out" / "beta0.06" / BAD).is_file()
    if case.id == "resume-stale-part-removed":
        assert not list((tmp_path / "out").rglob("*.part"))


def test_at_least_sixty_cases():
    ids = [c.id for c in CASES] + [c[0] for c in PCD_CASES]
    assert len(ids) >= 60 and len(set(ids)) == len(ids)


PCD_CASES = [  # (id, file bytes (or a writer of the file), words of the one-line refusal)
    ("pcd-radar-points-lie", radar_header(125) + b"\0" * 10, "the header lies"),
    ("pcd-radar-points-over-bound", radar_header(4_000_000_000) + b"\0" * 64, "exceeds the bound"),
    ("pcd-radar-16g-sparse", lambda p: sparse(p, HUGE, radar_header(HUGE // RADAR_RECORD)), "exceeds the bound"),
    ("pcd-radar-truncated-body", radar_header(5) + b"\0" * (4 * RADAR_RECORD + 20), "truncated, or the header lies"),
    ("pcd-radar-type-unknown", radar_header(1, TYPE=" ".join(["X"] + RADAR_TYPE[1:])) + b"\0" * 43,
     "TYPE X with SIZE 4"),
    ("pcd-radar-float-of-3-bytes", radar_header(1, SIZE=" ".join(["3"] + RADAR_SIZE[1:])) + b"\0" * 43, "SIZE 3"),
    ("pcd-radar-width-height", radar_header(4, WIDTH="2", HEIGHT="3") + b"\0" * 400, "WIDTH 2 × HEIGHT 3 ≠ POINTS 4"),
    ("pcd-radar-negative-points", radar_header(-1, WIDTH="-1"), "negative sizes"),
    ("pcd-radar-field-twice", radar_header(1, FIELDS=" ".join(["x"] + RADAR_FIELDS[:-1])) + b"\0" * 43,
     "names a field twice"),
    ("pcd-radar-key-twice", radar_header(1).replace(b"HEIGHT 1\n", b"HEIGHT 1\nHEIGHT 1\n") + b"\0" * 43,
     "repeats HEIGHT"),
    ("pcd-radar-count-zero", radar_header(1, COUNT=" ".join(["0"] + ["1"] * 17)) + b"\0" * 43, "COUNT 0 < 1"),
    ("pcd-radar-fewer-types", radar_header(1, TYPE=" ".join(RADAR_TYPE[:-1])) + b"\0" * 43, "one entry per field"),
    ("pcd-radar-viewpoint-6", radar_header(1, VIEWPOINT="0 0 0 1 0 0") + b"\0" * 43, "VIEWPOINT"),
    ("pcd-radar-no-points-line", radar_header(1, POINTS=None) + b"\0" * 43, "lacks POINTS"),
    ("pcd-radar-points-word", radar_header(1, POINTS="many") + b"\0" * 43, "malformed"),
    ("pcd-radar-data-unknown", radar_header(1, data="zip") + b"\0" * 43, "DATA 'zip'"),
    ("pcd-radar-comments-only", b"# comment\n" * 7000, "no DATA line in its first 65536 bytes"),
    ("pcd-radar-empty-file", b"", "no DATA line"),
    ("pcd-radar-not-pcd", b"\x89PNG\r\n\x1a\n" + b"\0" * 64, "unknown key"),
    ("pcd-radar-ascii-short", radar_header(2, data="ascii") + (" ".join(["1"] * 18) + "\n").encode(),
     "the ASCII body has 1 lines"),
    ("pcd-radar-ascii-fraction-in-int", radar_header(1, data="ascii") + (" ".join(["1.5"] * 18) + "\n").encode(),
     "not whole numbers"),
    ("pcd-radar-ascii-word", radar_header(1, data="ascii") + (" ".join(["a"] * 18) + "\n").encode(), "not numbers"),
    ("pcd-radar-ascii-endless-body", radar_header(1, data="ascii") + b"1 " * 100_000, "far longer"),
    ("pcd-radar-compressed-sizes-lie", radar_header(2, data="binary_compressed") + _lzf_sizes(16, 10**9),
     "do not match"),
    ("pcd-radar-compressed-short", radar_header(2, data="binary_compressed") + b"\0\0", "8-byte size prefix"),
    ("pcd-radar-folder", lambda p: p.mkdir(), "is a folder"),
    ("pcd-radar-16g-after-its-records", lambda p: sparse(p, HUGE, radar_header(2) + b"\0" * 2 * RADAR_RECORD),
     "far longer than its 2 points need"),
]


@pytest.mark.parametrize("case", PCD_CASES, ids=[c[0] for c in PCD_CASES])
def test_hostile_pcd_file(case, tmp_path):
    from fogsim.lidar.pcd import read_pcd

    _, raw, words = case
    if "compressed" in case[0]:
        pytest.importorskip("lzf")
    path = tmp_path / "in" / "RADAR_FRONT__1.pcd"
    path.parent.mkdir()
    if callable(raw):
        raw(path)
    else:
        path.write_bytes(raw)
    before = _stamp(path)
    with pytest.raises(InputError) as info:
        read_pcd(path)
    message = str(info.value)
    assert message.startswith(str(path)) and words in message and "\n" not in message, message
    assert _stamp(path) == before


def _stamp(path: Path) -> tuple:
    """What shows an input unchanged without reading a sparse 16 GB file whole: size, times, the first MiB."""
    st = path.stat()
    head = b"" if path.is_dir() else path.open("rb").read(SMALL)
    return st.st_size, st.st_mtime_ns, st.st_ctime_ns, head


# ----------------------------------------------------------------------------- bounded memory, in a process of its own
#: the address space a refusing run may take (the interpreter, numpy and OpenCV need ≈ 0.6 GB of it)
ADDRESS_SPACE = 1536 << 20


def _limited():
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))


def run_limited(argv: list[str], cwd: Path, env: dict | None = None) -> subprocess.CompletedProcess:
    """``python -m fogsim …`` (or ``python -c …``) under a 1.5 GB address-space limit: reading a 16 GB file
    whole would fail with MemoryError (or be killed) instead of being refused by its size."""
    return subprocess.run([sys.executable, *argv], capture_output=True, text=True, timeout=HANG_S, cwd=cwd,
                          preexec_fn=_limited, env=dict(os.environ, PYTHONPATH=str(ROOT)) | (env or {}))


def _bounded(res: subprocess.CompletedProcess, code: int, *words: str) -> None:
    err = res.stderr
    assert res.returncode == code, err[-3000:]
    assert "Traceback" not in err and "MemoryError" not in err and "Unable to allocate" not in err, err[-3000:]
    lines = [ln for ln in err.splitlines() if ln.startswith(("error:", "fogsim: error:", "  failed:"))]
    assert lines and all(w in lines[0] for w in words), err[-3000:]


@pytest.mark.parametrize("fmt, name", [("kitti", "a.bin"), ("nuscenes", "n_LIDAR_TOP__1.pcd.bin"),
                                       ("nuscenes-radar", "n008__RADAR_FRONT__1.pcd")])
def test_a_16g_scan_through_points_is_refused_in_bounded_memory(tmp_path, fmt, name):
    if fmt == "nuscenes-radar":
        pytest.importorskip("itur")
    sparse(tmp_path / "in" / name, HUGE, radar_header(HUGE // RADAR_RECORD) if fmt == "nuscenes-radar" else b"")
    res = run_limited(["-m", "fogsim", "fog", "--points", str(tmp_path / "in"), "--point-format", fmt,
                       "--out", str(tmp_path / "out"), "--quiet"], tmp_path)
    _bounded(res, 1, name, "exceeds the bound of 10,000,000 points per scan")


def test_a_16g_velodyne_scan_through_kitti_is_refused_in_bounded_memory(tmp_path):
    root = kt.write_kitti(tmp_path / "kitti", frames={"000007": kt.CARS["000000"], "000008": kt.CARS["000001"]})
    sparse(root / "training" / "velodyne" / "000008.bin")
    res = run_limited(["-m", "fogsim", "fog", "--kitti", str(root), "--lidar", "--levels", "0.06", "--out",
                       str(tmp_path / "out"), "--quiet"], tmp_path)
    _bounded(res, 1, "velodyne/000008.bin", "bound of 10,000,000 points per scan")
    assert len(list((tmp_path / "out" / "meta").glob("*.json"))) == 1  # the other frame is written


@pytest.mark.parametrize("name, head", [
    ("a.ply", _ply(4_000_000_000)),
    ("a.npy", _npy_header((1_000_000_000, 4), body=b"")),
])
def test_lying_headers_are_refused_in_bounded_memory(tmp_path, name, head):
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / name).write_bytes(head)
    res = run_limited(["-m", "fogsim", "fog", "--points", str(tmp_path / "in"), "--point-format", name[2:],
                       "--sensor", "hdl64e", "--out", str(tmp_path / "out"), "--quiet"], tmp_path)
    _bounded(res, 1, name, "header")


def test_a_16g_radar_pcd_and_image_are_refused_in_bounded_memory(tmp_path):
    sparse(tmp_path / "RADAR_FRONT__1.pcd", HUGE, radar_header(HUGE // RADAR_RECORD))
    sparse(tmp_path / "big.png", HUGE, _png_claiming(64, 64))
    code = ("import sys\nfrom fogsim.errors import InputError\nfrom fogsim.lidar.pcd import read_pcd\n"
            "from fogsim.io.images import read_image\n"
            "for read, path in ((read_pcd, 'RADAR_FRONT__1.pcd'), (read_image, 'big.png')):\n"
            "    try:\n        read(path)\n"
            "    except InputError as exc:\n        print('error:', exc, file=sys.stderr)\n")
    res = run_limited(["-c", code], tmp_path)
    assert res.returncode == 0, res.stderr[-3000:]
    lines = res.stderr.splitlines()
    assert len(lines) == 2 and "exceeds the bound" in lines[0] and "not an image fogsim reads" in lines[1], res.stderr


# --------------------------------------------------------------------- Ctrl-C between a scan's levels, then resume
@pytest.mark.slow
def test_ctrl_c_in_the_middle_of_the_levels_then_resume(tmp_path):
    """SIGINT once the first scan's first level is written and before the last scan's last level is (the
    run stopped while it is sent): exit 130, one line, nothing partial; the rerun finishes, and every
    output is byte-identical to an uninterrupted run's."""
    folder = tmp_path / "in"
    folder.mkdir()
    xyz, rho = _good_scan()
    for i in range(120):
        (folder / f"s{i:03d}.bin").write_bytes(lf.kitti_bin(xyz + np.float32(0.01 * i), rho / 2.55))
    levels = "0.03,0.06,0.09,0.12"
    argv = [sys.executable, "-m", "fogsim", "fog", "--points", str(folder), "--point-format", "kitti", "--levels",
            levels, "--quiet"]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = tmp_path / "out"
    first, last = out / "beta0.03" / "s000.json", out / "beta0.12" / "s119.json"
    proc = subprocess.Popen([*argv, "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=tmp_path, env=env, start_new_session=True)
    signal_mid_run(proc, first.is_file, lambda: not last.exists(), signal.SIGINT, "the first level was written")
    _, err = proc.communicate(timeout=HANG_S)
    assert proc.returncode == 130, err[-3000:]
    assert [ln for ln in err.splitlines() if ln.strip()] == ["fogsim: error: interrupted"], err[-3000:]
    assert not list(out.rglob("*.part")) and not last.exists()
    res = subprocess.run([*argv, "--out", str(out)], capture_output=True, text=True, cwd=tmp_path, env=env,
                         timeout=HANG_S)
    assert res.returncode == 0 and "already done" in res.stdout, res.stderr[-3000:]
    whole = tmp_path / "whole"
    res = subprocess.run([*argv, "--out", str(whole)], capture_output=True, text=True, cwd=tmp_path, env=env,
                         timeout=HANG_S)
    assert res.returncode == 0, res.stderr[-3000:]
    files = sorted(p.relative_to(whole) for p in whole.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(out) for p in out.rglob("*") if p.is_file())
    per_level = len(list((whole / "beta0.03").glob("s000.*")))  # scan, outcomes, sidecar (and a .pcd for viewers)
    assert per_level >= 3 and len(files) == 1 + 120 * 4 * per_level
    for rel in files:
        if rel.name != "fogsim_run.json":
            assert (out / rel).read_bytes() == (whole / rel).read_bytes(), rel
    shutil.rmtree(whole)
