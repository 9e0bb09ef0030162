"""Crafted dataset inputs and run-wide checks through the command line (issue 18, part B).

The inputs are built with fogsim's own writers (protobuf_wire, write_tfrecord, pyarrow for v2
parquet, the Cityscapes fixture tree) from the specs in the notes; every case checks what
:mod:`test_hostile` checks: the exit code, a message naming the file or the flag, no traceback,
inputs byte-identical, nothing partial (no ``*.part``, no empty file) and, on exit 2, nothing
written at all. A ``-retry`` case first runs the refused command (it must exit 2 without claiming
``--out``), then the corrected one into the same ``--out``, which must be accepted. Below the cases:
the memory bound of the range-image decoders, the umask of write_tfrecord, and a render onto a full
disk (root: a 300 KiB tmpfs).
"""
from __future__ import annotations

import json
import math
import zlib
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

import kitti_tree as kt
import lidar_fixtures as lf
import waymo_fixtures as wfx
import waymo_lidar_fixtures as lfx
from conftest import run_hostile_case, tree_digest
from fogsim.cli import main
from fogsim.io.depth_files import write_depth
from fogsim.io.images import encode_image, write_image
from fogsim.readers.waymo import protobuf_wire as pw
from fogsim.readers.waymo.tfrecord import write_tfrecord
from test_hostile import Case, fog, good_cityscapes, good_folder

STAMPS = (1_000_000, 2_000_000)
FRONT, FRONT_LEFT = 1, 2


# ----------------------------------------------------------------------------- Waymo v1 inputs
def _image() -> bytes:
    return encode_image(np.full((lfx.IMAGE_H, lfx.IMAGE_W, 3), 90, np.uint8), ".png")


def _car(**kw) -> wfx.Box2D:
    box = dict(id="cam-car", type=1, cx=lfx.IMAGE_W / 2, cy=lfx.IMAGE_H / 2 + 20, length=120, width=80) | kw
    return wfx.Box2D(**box)


def _labels(camera: int = FRONT, boxes=None) -> bytes:
    boxes = [_car()] if boxes is None else boxes
    return pw.bytes_field(8, wfx.camera_labels_message(camera, [wfx.camera_label(b) for b in boxes]))


def _depth_dir(tmp: Path, stamps=STAMPS) -> Path:
    depth = tmp / "in" / "depth"
    for t in stamps:
        write_depth(depth / lfx.CONTEXT / f"{t}_FRONT.exr", np.full((lfx.IMAGE_H, lfx.IMAGE_W), 20.0, np.float32))
    return depth


def _segment(tmp: Path, extra: bytes | Callable[[int], bytes] = b"", lasers: bool = True, scene=None,
             name: str = "seg.tfrecord") -> Path:
    """A v1 segment of two frames of the wall scene (image, LiDAR unless not ``lasers``) + ``extra``
    appended to each Frame (CRCs computed by write_tfrecord)."""
    scene = scene or lfx.wall_scene()
    path = tmp / "in" / name
    path.parent.mkdir(parents=True, exist_ok=True)
    write_tfrecord(path, [lfx.frame_msg(scene, t, with_lasers=lasers, image=_image())
                          + (extra(t) if callable(extra) else extra) for t in STAMPS])
    return path


def _fog_waymo(tmp: Path, src: Path, *extra: str, depth: bool = True) -> list[str]:
    argv = ["fog", "--waymo", str(src), "--cameras", "FRONT", "--levels", "0,0.06", "--out", str(tmp / "out"),
            "--quiet"]
    return argv + (["--depth-dir", str(_depth_dir(tmp))] if depth and "--depth-from" not in extra else []) + list(extra)


def _v1(extra=b"", *flags: str, lasers: bool = True, scene=None, depth: bool = True):
    def build(tmp: Path) -> list[str]:
        return _fog_waymo(tmp, _segment(tmp, extra, lasers, scene() if scene else None), *flags, depth=depth)
    return build


def _zip_bomb(declared: int) -> bytes:
    """A MatrixFloat whose data field declares ``declared`` bytes, zlib'd (1 MiB of zeros follow:
    the stream is small, what it claims is not)."""
    head = b"\x0a" + pw.encode_varint(declared)
    c = zlib.compressobj(9)
    return c.compress(head) + c.compress(bytes(1 << 20)) + c.flush()


def _bomb_frame(t: int) -> bytes:
    """A Frame whose TOP range_image_compressed is a zlib bomb (declares 3 GiB)."""
    scene = lfx.wall_scene()
    laser = scene.lasers[0]
    body = pw.varint_field(1, laser.name) + pw.bytes_field(2, pw.bytes_field(2, _zip_bomb(3 << 30)))
    return lfx.frame_msg(scene, t, with_lasers=False, image=_image()) + pw.bytes_field(5, body)


def _bomb(*flags: str):
    def build(tmp: Path) -> list[str]:
        path = tmp / "in" / "seg_bomb.tfrecord"
        path.parent.mkdir(parents=True, exist_ok=True)
        write_tfrecord(path, [_bomb_frame(t) + _labels() for t in STAMPS])
        return _fog_waymo(tmp, path, *flags)
    return build


def _ranges(value: float):
    """The wall scene with every valid range set to ``value`` metres."""
    def scene():
        s = lfx.wall_scene()
        ri = s.lasers[0].range_image
        ri[..., 0] = np.where(ri[..., 0] > 0, value, ri[..., 0])
        return s
    return scene


def _singular_extrinsic():
    scene = lfx.wall_scene()
    scene.cameras[0].extrinsic = scene.cameras[0].extrinsic.copy()
    scene.cameras[0].extrinsic[3] = 0.0  # bottom row 0: not a rigid transform (its rotation is fine)
    return scene


def _labels_bytes_name(t: int) -> bytes:
    """camera_labels whose name (field 1, an enum) is written as a string."""
    return pw.bytes_field(8, pw.bytes_field(1, "FRONT") + pw.bytes_field(2, wfx.camera_label(_car())))


# ----------------------------------------------------------------------------- Waymo v2 inputs
def _v2_frames() -> list[wfx.LabelFrame]:
    cam = wfx.Camera(width=lfx.IMAGE_W, height=lfx.IMAGE_H)
    return [wfx.LabelFrame(lfx.CONTEXT, t, {FRONT: cam}, camera_labels={FRONT: [wfx.Box2D("c", 1, 160, 140, 120, 80)]})
            for t in STAMPS]


def _v2_change(tag: str, column: str, values):
    """Rewrite ``column`` of the v2 table ``tag`` with ``values`` (a pyarrow array)."""
    def change(root: Path) -> None:
        import pyarrow.parquet as pq

        path = root / tag / f"{lfx.CONTEXT}.parquet"
        table = pq.read_table(path)
        table = table.set_column(table.schema.get_field_index(column), column, values(len(table)))
        pq.write_table(table, path)
    return change


def _v2(change: Callable[[Path], None] | None = None, *flags: str, lidar: bool = False):
    def build(tmp: Path) -> list[str]:
        root = tmp / "in" / "v2"
        wfx.write_v2(root, _v2_frames())
        if lidar:
            lfx.write_v2(root, lfx.wall_scene())
        if change:
            change(root)
        return _fog_waymo(tmp, root, *flags)
    return build


def _pa_list_int(n: int):
    import pyarrow as pa

    return pa.array([[FRONT]] * n, pa.list_(pa.int8()))


def _pa_str(value: str):
    def make(n: int):
        import pyarrow as pa

        return pa.array([value] * n, pa.string())
    return make


def _pa_float(value: float):
    def make(n: int):
        import pyarrow as pa

        return pa.array([value] * n, pa.float64())
    return make


# ----------------------------------------------------------------------------- Cityscapes inputs
def _cs_gt(change: Callable[[Path], None], *flags: str):
    def build(tmp: Path) -> list[str]:
        base = good_cityscapes(tmp)
        ids = np.zeros((20, 40), np.uint16)
        ids[5:15, 5:20] = 26000  # one car
        write_image(base / "gtFine" / "val" / "aachen" / "aachen_000000_000019_gtFine_instanceIds.png", ids)
        change(base)
        return ["fog", "--cityscapes", str(base), "--levels", "0.06", "--out", str(tmp / "out"), "--quiet", *flags]
    return build


def _gt_emptied(base: Path) -> None:
    for p in (base / "gtFine" / "val" / "aachen").iterdir():
        p.unlink()


def _gt_groups_big(tmp: Path) -> list[str]:
    """640×320 instanceIds with cargroup (26) on every 3rd pixel of every 3rd row: 22,827
    separate group regions, more than an int32 of 100000·k + class id holds."""
    rng = np.random.default_rng(3)
    base = tmp / "in" / "cs"
    stem = "aachen_000000_000019"
    h, w = 320, 640
    write_image(base / "leftImg8bit" / "val" / "aachen" / f"{stem}_leftImg8bit.png",
                rng.integers(0, 256, (h, w, 3), dtype=np.uint8))
    from fogsim.camera import depth_to_disparity, encode_disparity_png

    disp = encode_disparity_png(depth_to_disparity(np.full((h, w), 30.0, np.float32), 0.209, 400.0))
    write_image(base / "disparity" / "val" / "aachen" / f"{stem}_disparity.png", disp)
    (base / "camera" / "val" / "aachen").mkdir(parents=True)
    (base / "camera" / "val" / "aachen" / f"{stem}_camera.json").write_text(json.dumps(
        {"extrinsic": {"baseline": 0.209}, "intrinsic": {"fx": 400.0, "fy": 400.0, "u0": 319.5, "v0": 159.5}}))
    ids = np.zeros((h, w), np.uint16)
    ids[::3, ::3] = 26
    ids[100:140, 200:300] = 26000
    write_image(base / "gtFine" / "val" / "aachen" / f"{stem}_gtFine_instanceIds.png", ids)
    return ["fog", "--cityscapes", str(base), "--levels", "0.06", "--out", str(tmp / "out"), "--quiet"]


# ----------------------------------------------------------------------------- presets, bench, depth score
def _preset(change: Callable[[dict], None], *flags: str):
    """``fogsim render`` of the bundled default preset changed by ``change`` (refused before Blender)."""
    def build(tmp: Path) -> list[str]:
        from fogsim.presets import preset_path

        doc = json.loads(preset_path("default").read_text())
        doc.pop("$schema", None)
        change(doc)
        path = tmp / "in" / "p.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(doc))
        return ["render", "--preset", str(path), "--frames", "1", "--resolution", "32x24", "--samples", "1",
                "--out", str(tmp / "out"), "--quiet", *flags]
    return build


def _set(path: str, value):
    def change(doc: dict) -> None:
        *parents, last = path.split(".")
        for k in parents:
            doc = doc.setdefault(k, {})
        doc[last] = value
    return change


def _bench(*flags: str):
    def build(tmp: Path) -> list[str]:
        (tmp / "in").mkdir(parents=True, exist_ok=True)
        return ["bench", "fog-physics", "--frames", "1", "--samples", "2", "--out", str(tmp / "out"), "--quiet",
                *flags]
    return build


def _score(*flags: str, holdout: bool = True):
    """``fogsim depth score`` of a folder of ray-distance predictions against hold-out files."""
    def build(tmp: Path) -> list[str]:
        from fogsim.depth.lidar_source import write_holdout

        key = f"{lfx.CONTEXT}/1000000_FRONT"
        write_depth(tmp / "in" / "pred" / f"{key}.exr", np.full((24, 32), 20.0, np.float32))
        uv = np.array([[3.5, 4.5], [10.5, 12.5]])
        if holdout:
            write_holdout(tmp / "in" / "h" / "lidar_holdout" / f"{key}.npz", uv, np.array([20.0, 21.0]), 32, 24)
        else:
            (tmp / "in" / "h").mkdir(parents=True)
        argv = ["depth", "score", "--pred", str(tmp / "in" / "pred"), "--pred-kind", "ray", "--holdout",
                str(tmp / "in" / "h"), "--out", str(tmp / "out"), "--quiet"]
        return [a.replace("{tmp}", str(tmp)) for a in argv + list(flags)]
    return build


def _score_pred(write: Callable[[Path], None]):
    def build(tmp: Path) -> list[str]:
        argv = _score()(tmp)
        write(tmp / "in" / "pred" / f"{lfx.CONTEXT}" / "1000000_FRONT.exr")
        return argv
    return build


def _big_image(tmp: Path) -> list[str]:
    base = good_folder(tmp)
    return fog(base, tmp / "out", "--max-pixels", "700")


# ----------------------------------------------------------------------------- KITTI, STF, --points (issue 29 item 6)
def _kitti(change: Callable[[Path], None] | None = None, *flags: str):
    """``fogsim fog --kitti`` of the fixture tree (three frames) changed by ``change``, with --lidar (the KITTI
    trees off: their empty ImageSets/test.txt would read as a partial file here)."""
    def build(tmp: Path) -> list[str]:
        root = kt.write_kitti(tmp / "in" / "kitti")
        if change:
            change(root)
        return ["fog", "--kitti", str(root), "--levels", "0,0.06", "--lidar", "--no-kitti-trees", "--out",
                str(tmp / "out"), "--quiet", *flags]
    return build


def _scan(fid: str, edit: Callable[[np.ndarray], np.ndarray | bytes]):
    """Rewrite frame ``fid``'s velodyne file: ``edit`` gets its N×4 float32 records."""
    def change(root: Path) -> None:
        path = root / "training" / "velodyne" / f"{fid}.bin"
        rec = np.frombuffer(path.read_bytes(), "<f4").reshape(-1, 4).copy()
        got = edit(rec)
        path.write_bytes(got if isinstance(got, bytes) else got.astype("<f4").tobytes())
    return change


def _put(rec: np.ndarray, row: int, col: int, value: float) -> np.ndarray:
    rec[row, col] = value
    return rec


def _text(rel: str, edit: Callable[[str], str]):
    def change(root: Path) -> None:
        path = root / rel
        path.write_text(edit(path.read_text()))
    return change


def _unlink(rel: str):
    def change(root: Path) -> None:
        (root / rel).unlink()
    return change


def _restore_scan(argv: list[str], tmp: Path) -> list[str]:
    fresh = kt.write_kitti(tmp / "fresh")
    name = "training/velodyne/000001.bin"
    (tmp / "in" / "kitti" / name).write_bytes((fresh / name).read_bytes())
    return argv


def _stf(*flags: str, calib: bool = True, edit: Callable[[Path], None] | None = None):
    def build(tmp: Path) -> list[str]:
        root = tmp / "in" / "stf"
        path = kt.write_stf(root)
        if edit:
            edit(root)
        return ["fog", "--stf", str(root), *(["--stf-calib", str(path)] if calib else []), "--levels", "0.06",
                "--lidar", "--no-kitti-trees", "--out", str(tmp / "out"), "--quiet", *flags]
    return build


def _stf_fractional(root: Path) -> None:
    path = next((root / "lidar_hdl64_strongest").glob("*.bin"))
    rec = np.frombuffer(path.read_bytes(), "<f4").reshape(-1, 5).copy()
    rec[:, 3] = np.linspace(0.01, 0.99, len(rec))  # KITTI-like 0–1 data in a 0–255 format
    path.write_bytes(rec.astype("<f4").tobytes())


def _points(blob: Callable[[], bytes], fmt: str = "nuscenes", *flags: str, out_inside: bool = False):
    """``fogsim fog --points`` of a folder with a good scan and ``blob`` as a second one."""
    def build(tmp: Path) -> list[str]:
        suffix = {"nuscenes": ".pcd.bin", "kitti": ".bin"}[fmt]
        folder = tmp / "in" / "scans"
        folder.mkdir(parents=True)
        xyz, rho, *_ = lf.surfaces_scan([lf.Surface(10.0, 0.5), lf.Surface(30.0, 0.2)])
        good = (lf.stf_bin(xyz, 100 * rho, np.arange(len(xyz)) % 32) if fmt == "nuscenes"
                else lf.kitti_bin(xyz, rho / 2.55))
        (folder / f"good{suffix}").write_bytes(good)
        (folder / f"bad{suffix}").write_bytes(blob())
        out = folder / "out" if out_inside else tmp / "out"
        return ["fog", "--points", str(folder), "--point-format", fmt, "--levels", "0.06", "--out", str(out),
                "--quiet", *flags]
    return build


def _sensor_file(tmp_doc: dict):
    def build(tmp: Path) -> list[str]:
        argv = _kitti()(tmp)
        path = tmp / "in" / "s.json"
        path.write_text(json.dumps(tmp_doc))
        return argv + ["--lidar-sensor", str(path)]
    return build


_FIVE = np.array([[10.0, 0.0, 0.0, 40.0, 3.0]] * 4)


# ----------------------------------------------------------------------------- the cases
def _retry(first: Callable[[Path], list[str]], second: Callable[[list[str], Path], list[str]]):
    """``first``'s argv, then the corrected rerun ``second(first argv, tmp)`` into the same --out."""
    def build(tmp: Path) -> list[str]:
        argv = first(tmp)
        code = main(argv)
        assert code == 2, f"the first run should be refused before it claims --out, exit {code}"
        return second(argv, tmp)
    return build


def _empty_lasers(with_returns: bool) -> bytes:
    """``lasers`` entries without range images, as real camera-only v1 frames carry them: each laser's
    name, and (``with_returns``) empty ri_return1 / ri_return2 messages."""
    empty = pw.bytes_field(2, b"") + pw.bytes_field(3, b"") if with_returns else b""
    return b"".join(pw.bytes_field(5, pw.varint_field(1, la.name) + empty) for la in lfx.wall_scene().lasers)


def _swap_lidar_for_depth_dir(argv: list[str], tmp: Path) -> list[str]:
    i = argv.index("--depth-from")
    return argv[:i] + argv[i + 2:] + ["--depth-dir", str(_depth_dir(tmp))]


CASES = [
    # --- Waymo v1: mistyped fields (T4), labels of another camera (T14), LiDAR (T6, T7, T9)
    Case("w1-labels-varint", _v1(pw.varint_field(8, 7)), 2, ("seg.tfrecord#record 0", "field 8")),
    Case("w1-labels-name-string", _v1(_labels_bytes_name), 2, ("seg.tfrecord#record 0", "field 1")),
    Case("w1-labels-other-camera", _v1(_labels(FRONT_LEFT)), 0, ("seg.tfrecord#record 0", "no camera_labels",
                                                                 "images only")),
    Case("w1-labels-none", _v1(b""), 0, ("seg.tfrecord#record 0", "no camera_labels", "images only")),
    Case("w1-lidar-absent", _v1(_labels(), "--depth-from", "lidar", lasers=False), 2,
         ("seg.tfrecord", "no LiDAR", "--depth-from lidar")),
    Case("w1-lidar-absent-retry", _retry(_v1(_labels(), "--depth-from", "lidar", lasers=False),
                                         _swap_lidar_for_depth_dir), 0, ()),
    # U13: a real camera-only frame has lasers entries, but no range image in them
    Case("w1-lidar-empty-returns", _v1(_labels() + _empty_lasers(True), "--depth-from", "lidar", "--lidar-holdout",
                                       "0.1", lasers=False), 2, ("seg.tfrecord", "no LiDAR", "--depth-from lidar")),
    Case("w1-lidar-laser-names-only", _v1(_labels() + _empty_lasers(False), "--depth-from", "lidar", lasers=False), 2,
         ("seg.tfrecord", "no LiDAR")),
    Case("w1-lidar-empty-returns-retry", _retry(_v1(_labels() + _empty_lasers(True), "--depth-from", "lidar",
                                                    lasers=False), _swap_lidar_for_depth_dir), 0, ()),
    Case("w1-lidar-zipbomb", _bomb("--depth-from", "lidar"), 1, ("seg_bomb.tfrecord#record 0", "range_image_compressed",
                                                                  "declares")),
    Case("w1-lidar-zipbomb-depth-dir", _bomb(), 1, ("seg_bomb.tfrecord#record 0", "range_image_compressed")),
    Case("w1-box-huge", _v1(_labels(boxes=[_car(cx=1.7e308, length=1.7e308)])), 1,
         ("seg.tfrecord#record 0", "2D box", "1.7e+308")),
    Case("w1-extrinsic-singular", _v1(_labels(), scene=_singular_extrinsic), 1,
         ("seg.tfrecord#record 0", "extrinsic", "bottom row")),
    Case("w1-holdout-all", _v1(_labels(), "--depth-from", "lidar", "--lidar-holdout", "0.999"), 1,
         ("seg.tfrecord#record 0", "--lidar-holdout 0.999", "held out")),
    Case("w1-lidar-range-huge", _v1(_labels(), "--depth-from", "lidar", scene=_ranges(1e30)), 1,
         ("seg.tfrecord#record 0", "range", "1e+30")),
    Case("w1-lidar-range-tiny", _v1(_labels(), "--depth-from", "lidar", scene=_ranges(1e-30)), 1,
         ("seg.tfrecord#record 0", "range", "1e-30")),
    # --- Waymo v2: key types (T4, T10), no LiDAR tables (T6), a NaN box type (T9)
    Case("v2-camera-name-list", _v2(_v2_change("camera_image", "key.camera_name", _pa_list_int)), 2,
         ("camera_image", f"{lfx.CONTEXT}.parquet", "key.camera_name")),
    Case("v2-calibration-camera-name-list", _v2(_v2_change("camera_calibration", "key.camera_name", _pa_list_int)),
         2, ("camera_calibration", "key.camera_name")),
    Case("v2-camera-box-camera-name-list", _v2(_v2_change("camera_box", "key.camera_name", _pa_list_int)),
         1, ("camera_box", "key.camera_name")),  # label tables are read per frame
    Case("v2-camera-name-string", _v2(_v2_change("camera_image", "key.camera_name", _pa_str("FRONT"))), 0, ()),
    Case("v2-timestamp-string", _v2(_v2_change("camera_image", "key.frame_timestamp_micros", _pa_str("soon"))), 2,
         ("camera_image", "key.frame_timestamp_micros")),
    Case("v2-lidar-absent", _v2(None, "--depth-from", "lidar"), 2, ("v2", "no LiDAR", "--depth-from lidar")),
    Case("v2-lidar-absent-retry", _retry(_v2(None, "--depth-from", "lidar"), _swap_lidar_for_depth_dir), 0, ()),
    Case("v2-box-type-nan", _v2(_v2_change("camera_box", "[CameraBoxComponent].type", _pa_float(math.nan))), 1,
         ("camera_box", "#row 0", "[CameraBoxComponent].type")),
    Case("v2-box-center-string", _v2(_v2_change("camera_box", "[CameraBoxComponent].box.center.x", _pa_str("mid"))),
         1, ("camera_box", "[CameraBoxComponent].box.center.x")),
    # --- Cityscapes gtFine (T6, T8)
    Case("cs-gt-split-empty", _cs_gt(_gt_emptied), 2, ("gtFine", "val", "--no-labels")),
    Case("cs-gt-split-empty-retry", _retry(_cs_gt(_gt_emptied), lambda argv, tmp: argv + ["--no-labels"]), 0, ()),
    Case("cs-gt-groups-big", _gt_groups_big, 0, ()),
    # --- fogsim fog --max-pixels (also seen: render's bound, same default and message)
    Case("fog-max-pixels-exceeded", _big_image, 1, ("a.png", "32×24", "--max-pixels 700", "raise --max-pixels")),
    Case("fog-max-pixels-zero", lambda t: fog(good_folder(t), t / "out", "--max-pixels", "0"), 2, ("--max-pixels",)),
    # --- bench fog-physics: every flag checked before the first render (T11)
    Case("bench-levels-without-clear", _bench("--levels", "0.03", "--resolution", "32x24"), 2,
         ("--levels 0.03", "must include 0")),
    Case("bench-levels-unknown", _bench("--levels", "thick", "--resolution", "32x24"), 2, ("--levels thick",)),
    Case("bench-resolution-malformed", _bench("--resolution", "big"), 2, ("--resolution",)),
    Case("bench-resolution-huge", _bench("--resolution", "20000x20000"), 2, ("--resolution", "--max-pixels")),
    Case("bench-preset-unknown", _bench("--preset", "nope", "--resolution", "32x24"), 2, ("nope.json",)),
    # --- volumetric and night presets: refused naming the file and the key, before Blender starts
    Case("vol-medium-unknown", _preset(_set("fog_model.volumetric.medium", "smoke")), 2,
         ("p.json", "fog_model.volumetric.medium")),
    Case("vol-g-out-of-range", _preset(_set("fog_model.volumetric.g", 1.5)), 2, ("p.json", "fog_model.volumetric.g")),
    Case("vol-extent-negative", _preset(_set("fog_model.volumetric.extent_m", -5)), 2,
         ("p.json", "fog_model.volumetric.extent_m")),
    Case("vol-medium-flag-with-koschmieder", _preset(lambda d: None, "--fog", "koschmieder", "--fog-medium", "ea"), 2,
         ("--fog-medium", "--fog volumetric")),
    Case("night-day-with-night-keys", _preset(_set("lighting", {"time_of_day": "day", "headlight_power_w": 5})),
         2, ("p.json", "lighting")),
    Case("night-windows-reversed", _preset(_set("lighting", {"time_of_day": "night",
                                                             "lit_window_fraction": [0.5, 0.1]})), 2,
         ("p.json", "lighting.lit_window_fraction")),
    Case("night-lamp-power-string", _preset(_set("lighting", {"time_of_day": "night",
                                                              "street_lamp_power_w": "bright"})), 2,
         ("p.json", "lighting.street_lamp_power_w")),
    # --- fogsim depth score: its inputs (the hold-out files' own fields are test_hostile_documents');
    # one unusable prediction makes the whole score meaningless: exit 2, nothing written
    Case("score-pred-missing", _score("--pred", "{tmp}/in/nopred"), 2, ("nopred",)),
    Case("score-holdout-empty", _score(holdout=False), 2, ("lidar_holdout",)),
    Case("score-pred-wrong-size", _score_pred(lambda p: write_depth(p, np.full((12, 16), 20.0, np.float32))), 2,
         ("1000000_FRONT.exr",)),
    Case("score-pred-nan", _score_pred(lambda p: write_depth(p, np.full((24, 32), np.nan, np.float32))), 2,
         ("1000000_FRONT.exr",)),
    Case("score-pred-truncated", _score_pred(lambda p: p.write_bytes(p.read_bytes()[:200])), 2,
         ("1000000_FRONT.exr",)),
    # --- KITTI: a bad file fails its frame (exit 1), a set or calibration that does not hold exits 2
    Case("kitti-bin-size", _kitti(_scan("000001", lambda r: r.tobytes()[:-6])), 1,
         ("velodyne/000001.bin", "not a whole number of 16-byte kitti records")),
    Case("kitti-bin-nan", _kitti(_scan("000001", lambda r: _put(r, 3, 1, math.nan))), 1,
         ("velodyne/000001.bin", "NaN or infinite coordinates", "row 3")),
    Case("kitti-bin-inf", _kitti(_scan("000001", lambda r: _put(r, 0, 0, math.inf))), 1,
         ("velodyne/000001.bin", "NaN or infinite coordinates")),
    Case("kitti-intensity-255", _kitti(_scan("000001", lambda r: _put(r, 0, 3, 200.0))), 1,
         ("velodyne/000001.bin", "outside the declared 0-1 scale", "0–255 data?")),
    Case("kitti-scan-empty", _kitti(_scan("000001", lambda r: b"")), 1, ("velodyne/000001.bin", "empty scan")),
    Case("kitti-scan-mismatch-retry", _retry(_kitti(_unlink("training/velodyne/000001.bin")), _restore_scan), 0, ()),
    Case("kitti-set-mismatch", _kitti(_unlink("training/velodyne/000001.bin")), 2,
         ("frame 000001: no scan training/velodyne/000001.bin", "do not match")),
    Case("kitti-label-missing", _kitti(_unlink("training/label_2/000002.txt")), 2,
         ("frame 000002: no label file",)),
    Case("kitti-split-unknown-id", _kitti(_text("ImageSets/val.txt", lambda t: "000009\n"), "--split", "val"), 2,
         ("frame 000009: no image",)),
    Case("kitti-calib-missing-key", _kitti(_text("training/calib/000001.txt",
                                                 lambda t: kt.calib_text(drop="Tr_velo_to_cam"))), 2,
         ("calib/000001.txt", "missing calibration key Tr_velo_to_cam")),
    Case("kitti-calib-singular", _kitti(_text("training/calib/000001.txt", lambda t: t.replace(
        " ".join(f"{v:.12e}" for v in kt.R0.ravel()), " ".join(["0"] * 9)))), 2, ("calib/000001.txt", "singular")),
    Case("kitti-label-fields", _kitti(_text("training/label_2/000001.txt",
                                            lambda t: " ".join(t.split("\n")[0].split()[:14]) + "\n")), 1,
         ("label_2/000001.txt", "line 1: 14 fields, expected 15")),
    Case("kitti-label-type", _kitti(_text("training/label_2/000001.txt", lambda t: t.replace("Car", "Bus", 1))), 1,
         ("label_2/000001.txt", "unknown object type 'Bus'")),
    Case("kitti-lidar-without-scans", lambda t: fog(good_folder(t), t / "out", "--lidar"), 2,
         ("--lidar", "--kitti, --stf or --waymo")),
    Case("kitti-sensor-unknown", _kitti(None, "--lidar-sensor", "vlp99"), 2, ("vlp99", "hdl64e")),
    Case("kitti-sensor-file-bad", _sensor_file({"beams": 64, "vertical_fov_deg": [-24.9, 2.0],
                                                "horizontal_resolution_deg": 0.18, "intensity_scale": "0-1"}), 2,
         ("s.json", "max_range_m")),
    # --- STF
    Case("stf-no-calibration", _stf(calib=False), 2, ("in/stf", "no calibration", "--stf-calib")),
    Case("stf-intensity-fractional", _stf(edit=_stf_fractional), 1, ("lidar_hdl64_strongest", "0–1 data")),
    # --- --points: a bad scan fails alone; setup problems exit 2
    Case("points-bin-size", _points(lambda: _FIVE.astype("<f4").tobytes()[:-3]), 1,
         ("bad.pcd.bin", "not a whole number of 20-byte nuscenes records")),
    Case("points-intensity-300", _points(lambda: np.where(np.arange(5) == 3, 300.0, _FIVE).astype("<f4").tobytes()),
         1, ("bad.pcd.bin", "outside the declared 0-255 scale")),
    Case("points-nan", _points(lambda: np.where(np.arange(5) == 0, math.nan, _FIVE).astype("<f4").tobytes()), 1,
         ("bad.pcd.bin", "NaN or infinite")),
    Case("points-empty", _points(lambda: b"", "kitti"), 1, ("bad.bin", "empty scan")),
    Case("points-out-inside-input", _points(lambda: b"", out_inside=True), 2, ("lies inside --points",)),
]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_hostile_input(case: Case, tmp_path, capsys, monkeypatch):
    if case.id.startswith(("v2-",)):
        pytest.importorskip("pyarrow")
    monkeypatch.chdir(tmp_path)
    out_before = (tmp_path / "out").exists()
    err = run_hostile_case(case, tmp_path, capsys)
    if case.code:
        lines = [ln for ln in err.splitlines() if ln.startswith(("fogsim: error", "  failed:"))]
        assert lines and all(len(ln) < 600 for ln in lines), err
    if case.code == 2 and not out_before:
        assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir()), "a usage error wrote output"


def test_at_least_thirty_cases():
    ids = [c.id for c in CASES]
    assert len(ids) >= 30 and len(set(ids)) == len(ids)


# ----------------------------------------------------------------------------- below the command line
def _stream(head: bytes, zeros: int) -> bytes:
    c = zlib.compressobj(9)
    out = c.compress(head)
    for _ in range(zeros >> 20):
        out += c.compress(bytes(1 << 20))
    return out + c.flush()


@pytest.mark.parametrize("head, says", [
    (b"\x0a" + pw.encode_varint(3 << 30), "declares"),  # the values field declares 3 GiB
    (b"\x12\x02\x08\x01", "inflates to more than"),  # shape first, then 300 MiB that declare nothing
])
def test_a_zlib_bomb_is_refused_before_it_is_inflated(head, says):
    """T7: a range image inflates to at most what its largest possible shape holds (memory bound)."""
    import tracemalloc

    from fogsim.errors import InputError
    from fogsim.readers.waymo.matrix import MAX_BYTES, decode_matrix

    bomb = _stream(head, 300 << 20)
    assert len(bomb) < 1 << 20
    tracemalloc.start()
    try:
        with pytest.raises(InputError, match=says) as err:
            decode_matrix(bomb, "float", "seg#record 0 TOP range_image_compressed")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert "seg#record 0 TOP range_image_compressed" in str(err.value)
    assert peak < MAX_BYTES["float"] + (16 << 20), f"peak {peak / 1e6:.0f} MB"


def test_a_real_size_range_image_still_decodes():
    from fogsim.readers.waymo.matrix import decode_matrix, encode_matrix

    ri = np.random.default_rng(0).uniform(1, 75, (64, 2650, 4)).astype(np.float32)
    assert np.array_equal(decode_matrix(encode_matrix(ri), "float", "x"), ri)
    proj = np.random.default_rng(1).integers(-1, 1920, (64, 2650, 6)).astype(np.int32)
    assert np.array_equal(decode_matrix(encode_matrix(proj), "int32", "x"), proj)


def test_write_tfrecord_follows_the_umask(tmp_path):
    """also seen: the helper wrote 0600 files (mkstemp's mode)."""
    import os

    old = os.umask(0o022)
    try:
        write_tfrecord(tmp_path / "a.tfrecord", [b"x"])
    finally:
        os.umask(old)
    assert (tmp_path / "a.tfrecord").stat().st_mode & 0o777 == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["a.tfrecord"]


@pytest.fixture
def small_disk(tmp_path):
    """A 300 KiB tmpfs (root only; skipped elsewhere), unmounted afterwards."""
    import subprocess

    where = tmp_path / "small"
    where.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=300k", "tmpfs", str(where)],
                      capture_output=True).returncode:
        pytest.skip("cannot mount a small tmpfs here (needs root)")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], capture_output=True)


@pytest.mark.blender
@pytest.mark.slow
def test_disk_full_during_render_is_reported_as_disk_full(small_disk, tmp_path, capsys):
    """T13: every frame that hits the full disk says so (Blender's short EXR write was read as a
    corrupt temp file); after space is freed the resumed dataset equals a run on a roomy disk."""
    import subprocess

    pytest.importorskip("bpy")
    argv = ["render", "--frames", "3", "--resolution", "96x64", "--samples", "2", "--quiet", "--out"]
    assert main(argv + [str(small_disk / "ds")]) == 1
    failed = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("  failed:")]
    assert len(failed) == 3 and all("No space left on device" in ln for ln in failed), failed
    assert all(str(small_disk / "ds") in ln for ln in failed), "each names the file it could not write"
    assert not any("EXR" in ln for ln in failed), failed
    subprocess.run(["mount", "-o", "remount,size=64m", str(small_disk)], check=True)
    assert main(argv + [str(small_disk / "ds")]) == 0, capsys.readouterr().err
    assert main(argv + [str(tmp_path / "roomy")]) == 0
    for name in ("images", "labels", "masks", "depth"):
        assert tree_digest(small_disk / "ds" / name) == tree_digest(tmp_path / "roomy" / name), name


def test_a_v2_range_image_larger_than_any_lidar_is_refused_unread(tmp_path):
    """T7 for v2: a lidar row whose values list holds more than 256 × 8192 × 6 values (run-length
    encoded zeros: a small file) is refused from the parquet metadata, before it is read."""
    pytest.importorskip("pyarrow")
    import pyarrow as pa
    import pyarrow.parquet as pq

    from fogsim.errors import InputError
    from fogsim.readers.waymo.lidar import LidarPoints

    root = tmp_path / "v2"
    lfx.write_v2(root, lfx.wall_scene())
    path = root / "lidar" / f"{lfx.CONTEXT}.parquet"
    table = pq.read_table(path)
    name = "[LiDARComponent].range_image_return1.values"
    n = 256 * 8192 * 6 + 1
    huge = pa.ListArray.from_arrays(pa.array([0, n], pa.int32()), pa.array(np.zeros(n, np.float32)))
    table = table.set_column(table.schema.get_field_index(name), name, huge)
    pq.write_table(table, path)
    assert path.stat().st_size < 1 << 20
    with pytest.raises(InputError, match="more than range images hold") as err:
        LidarPoints.v2(root, lfx.CONTEXT, lfx.TIMESTAMP)("FRONT")
    assert str(path) in str(err.value) and name in str(err.value)


def test_more_group_regions_than_an_int32_label_holds():
    """T8: 100000·k + class id passes 2³¹ at k ≈ 21,475; every group region is still one record."""
    from fogsim.readers.cityscapes_labels import instance_records

    ids = np.zeros((320, 640), np.uint16)
    ids[::3, ::3] = 26  # cargroup, every pixel its own 8-connected region
    ids[100:140, 200:300] = 26000  # one car over some of them
    records = instance_records(ids, None)
    groups = [r for r in records if r["reason"] == "group (cargroup)"]
    expected = int((ids == 26).sum())
    assert expected > 21_475 and len(groups) == expected
    assert [r for r in records if r["kept"]] == [records[0]] and records[0]["bbox"] == [200, 100, 300, 140]
    assert all(r["pixels"] == 1 and r["id"] == 26 for r in groups)


def test_unlabelled_images_say_why_in_their_sidecars(tmp_path, capsys):
    """T14: a segment labelled only for FRONT_LEFT, fogged for FRONT: images only, a warning, and
    every sidecar records labels_missing."""
    argv = _v1(_labels(FRONT_LEFT))(tmp_path)
    assert main(argv) == 0
    assert "no camera_labels entry for FRONT" in capsys.readouterr().err
    sidecars = sorted((tmp_path / "out").rglob("*_FRONT.json"))
    assert len(sidecars) == 4 and not (tmp_path / "out" / "labels").exists()  # 2 frames × 2 levels
    for path in sidecars:
        assert "no camera_labels entry for FRONT" in json.loads(path.read_text())["labels_missing"]
