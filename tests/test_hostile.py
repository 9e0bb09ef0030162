"""Hostile inputs through the command line, as the reliability trial ran them.

Every case builds its inputs, runs one ``fogsim`` command and checks what a user relies on:
the exit code (2 usage or setup error, 1 some items failed), a message that names the file or
the flag, no traceback, every input byte-identical afterwards, and no partial file left
anywhere (no hidden ``*.part``, no zero-byte output).
"""
from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from conftest import run_hostile_case, tree_digest
from fogsim.camera import Intrinsics, depth_to_disparity, encode_disparity_png
from fogsim.cli import main
from fogsim.io.depth_files import write_depth
from fogsim.io.images import write_image


# ----------------------------------------------------------------------------- inputs
def good_folder(root: Path) -> Path:
    """root/in: images/{a,b}.png, depth/{a,b}.exr (planar Z, sky inf), K.json (32×24)."""
    rng = np.random.default_rng(11)
    base = root / "in"
    for name in ("a", "b"):
        write_image(base / "images" / f"{name}.png", rng.integers(0, 256, (24, 32, 3), dtype=np.uint8))
        depth = rng.uniform(2, 120, (24, 32)).astype(np.float32)
        depth[:3] = np.inf
        write_depth(base / "depth" / f"{name}.exr", depth)
    (base / "K.json").write_text(json.dumps(Intrinsics(30.0, 30.0, 15.5, 11.5, 32, 24).to_dict()))
    return base


def good_cityscapes(root: Path, camera: dict | None = None) -> Path:
    rng = np.random.default_rng(9)
    base = root / "in" / "cs"
    cam = camera or {"extrinsic": {"baseline": 0.209}, "intrinsic": {"fx": 40.0, "fy": 40.0, "u0": 19.5, "v0": 9.5}}
    stem = "aachen_000000_000019"
    write_image(base / "leftImg8bit" / "val" / "aachen" / f"{stem}_leftImg8bit.png",
                rng.integers(0, 256, (20, 40, 3), dtype=np.uint8))
    disp = encode_disparity_png(depth_to_disparity(rng.uniform(3, 60, (20, 40)).astype(np.float32), 0.209, 40.0))
    write_image(base / "disparity" / "val" / "aachen" / f"{stem}_disparity.png", disp)
    (base / "camera" / "val" / "aachen").mkdir(parents=True, exist_ok=True)
    (base / "camera" / "val" / "aachen" / f"{stem}_camera.json").write_text(json.dumps(cam))
    return base


def fog(base: Path, out: Path | str, *extra: str) -> list[str]:
    return ["fog", "--input", str(base / "images"), "--depth", str(base / "depth"), "--intrinsics",
            str(base / "K.json"), "--levels", "0.06", "--out", str(out), "--quiet", *extra]


@dataclass
class Case:
    """``build(tmp) -> argv``; the run must exit ``code`` and print every string of ``says``
    (``{tmp}`` is replaced by the case's folder). Inputs live under ``tmp/in``."""

    id: str
    build: Callable[[Path], list[str]]
    code: int
    says: tuple[str, ...]


def _with(change: Callable[[Path], None], *extra: str):
    def build(tmp: Path) -> list[str]:
        base = good_folder(tmp)
        change(base)
        return fog(base, tmp / "out", *extra)
    return build


def _flags(*extra: str):
    return _with(lambda base: None, *extra)


def _write(rel: str, data: bytes):
    return _with(lambda base: (base / rel).write_bytes(data))


def _truncate(rel: str, keep: float = 0.5):
    def change(base: Path):
        data = (base / rel).read_bytes()
        (base / rel).write_bytes(data[: int(len(data) * keep)])
    return _with(change)


def _depth(rel: str, array):
    return _with(lambda base: (base / rel).unlink() if array is None else write_depth(base / rel, array))


def _npy(name: str, array: np.ndarray):
    def change(base: Path):
        (base / "depth" / f"{name}.exr").unlink()
        np.save(base / "depth" / f"{name}.npy", array)
    return _with(change)


def _jpeg_truncated(base: Path):
    from fogsim.io.images import encode_image, read_image

    for name in ("a", "b"):
        img = read_image(base / "images" / f"{name}.png")
        (base / "images" / f"{name}.png").unlink()
        data = encode_image(img, ".jpg")
        (base / "images" / f"{name}.jpg").write_bytes(data[: len(data) // 2] if name == "a" else data)


def _k(values: dict):
    return _with(lambda base: (base / "K.json").write_text(json.dumps(values)))


def _out(where: Callable[[Path, Path], Path], *extra: str):
    def build(tmp: Path) -> list[str]:
        base = good_folder(tmp)
        return fog(base, where(tmp, base), *extra)
    return build


def _file_out(tmp: Path, base: Path) -> Path:
    (tmp / "in" / "afile").write_text("x")
    return tmp / "in" / "afile"


def _two_runs(tmp: Path) -> list[str]:
    base = good_folder(tmp)
    assert main(fog(base, tmp / "out")) == 0
    return fog(base, tmp / "out", "--airlight", "200")


def _cs(camera: dict | None = None, *extra: str):
    def build(tmp: Path) -> list[str]:
        base = good_cityscapes(tmp, camera)
        return ["fog", "--cityscapes", str(base), "--levels", "0.06", "--out", str(tmp / "out"), "--quiet", *extra]
    return build


def _cmd(*argv: str):
    def build(tmp: Path) -> list[str]:
        good_folder(tmp)
        return [a.replace("{tmp}", str(tmp)) for a in argv]
    return build


H, W = 24, 32
CASES = [
    # --- usage errors (exit 2): nothing is written
    Case("levels-negative", _flags("--levels", "-0.1"), 2, ("≥ 0",)),
    Case("levels-unknown-preset", _flags("--levels", "heavy"), 2, ("heavy", "unknown fog preset")),
    Case("levels-duplicate", _flags("--levels", "0.1,0.1"), 2, ("duplicate",)),
    Case("levels-and-visibility", _flags("--visibility", "50"), 2, ("--levels", "--visibility")),
    Case("visibility-zero", lambda t: fog(good_folder(t), t / "out")[:-5] + ["--visibility", "0", "--out",
                                                                              str(t / "out")], 2, ("visibility",)),
    Case("airlight-out-of-range", _flags("--airlight", "300"), 2, ("--airlight",)),
    Case("airlight-two-values", _flags("--airlight", "1,2"), 2, ("--airlight",)),
    Case("shard-out-of-range", _flags("--shard", "2/2"), 2, ("--shard",)),
    Case("shard-malformed", _flags("--shard", "x"), 2, ("--shard",)),
    Case("fill-unknown", _flags("--fill", "magic"), 2, ("--fill",)),
    Case("workers-zero", _flags("--workers", "0"), 2, ("--workers",)),
    Case("heterogeneity-too-large", _flags("--heterogeneity", "1.5"), 2, ("--heterogeneity",)),
    Case("kernel-size-even", _flags("--extended", "--kernel-size", "18"), 2, ("kernel",)),
    Case("hfov-zero", lambda t: ["fog", "--input", str(good_folder(t) / "images"), "--depth",
                                 str(t / "in" / "depth"), "--hfov", "0", "--out", str(t / "out")], 2, ("--hfov",)),
    Case("depth-from-not-ila", _flags("--depth-from", "midas:x.pt"), 2, ("--depth-from",)),
    Case("depth-from-missing-checkpoint", _flags("--depth-from", "ila:{tmp}/none.pt"), 2, ("none.pt",)),
    # --- output folders
    Case("out-is-input", _out(lambda t, b: b / "images"), 2, ("--out", "--input")),
    Case("out-contains-input", _out(lambda t, b: b), 2, ("--out", "contains")),
    Case("out-inside-input", _out(lambda t, b: b / "images" / "fogged"), 2, ("--out", "lies inside")),
    Case("out-inside-depth", _out(lambda t, b: b / "depth" / "o"), 2, ("--out", "--depth")),
    Case("out-empty", _out(lambda t, b: ""), 2, ("--out must name a folder",)),
    Case("out-is-a-file", _out(_file_out), 2, ("afile", "not a folder")),
    Case("out-under-a-file", _out(lambda t, b: _file_out(t, b) / "sub"), 2, ("afile",)),
    Case("out-holds-another-run", _two_runs, 2, ("fogsim_run.json", "other parameters")),
    # --- setup errors of the whole run (exit 2, found before OUT is claimed)
    Case("input-missing", _cmd("fog", "--input", "{tmp}/nope", "--depth", "{tmp}/in/depth", "--hfov", "50",
                               "--out", "{tmp}/out"), 2, ("nope", "not found")),
    Case("input-empty", lambda t: (good_folder(t), (t / "in" / "empty").mkdir(),
                                   ["fog", "--input", str(t / "in" / "empty"), "--depth", str(t / "in" / "depth"),
                                    "--hfov", "50", "--out", str(t / "out")])[-1], 2, ("empty", "no images")),
    Case("intrinsics-missing-file", _with(lambda b: (b / "K.json").unlink()), 2, ("K.json",)),
    Case("intrinsics-not-json", _write("K.json", b"{fx: 3"), 2, ("K.json",)),
    Case("intrinsics-other-aspect", _k(Intrinsics(30.0, 30.0, 15.5, 15.5, 32, 32).to_dict()), 2,
         ("another aspect ratio",)),
    Case("no-intrinsics-for-planar-depth", _cmd("fog", "--input", "{tmp}/in/images", "--depth", "{tmp}/in/depth",
                                                "--out", "{tmp}/out"), 2, ("needs the camera intrinsics",)),
    Case("depth-forgotten", _cmd("fog", "--input", "{tmp}/in/images", "--hfov", "50", "--out", "{tmp}/out"), 2,
         ("has no depth",)),
    Case("cityscapes-root-missing", _cmd("fog", "--cityscapes", "{tmp}/nocs", "--out", "{tmp}/out"), 2, ("nocs",)),
    # --- bad items (exit 1): each named, the others done, no partial file
    Case("image-not-an-image", _write("images/a.png", b"not a png at all"), 1, ("a.png", "not a readable image")),
    Case("image-empty-file", _write("images/a.png", b""), 1, ("a.png",)),
    Case("depth-missing-for-one", _depth("depth/a.exr", None), 1, ("a.exr", "depth file not found")),
    Case("depth-wrong-size", _depth("depth/a.exr", np.ones((10, 10), np.float32)), 1, ("a.exr", "10×10")),
    Case("depth-nan", _depth("depth/a.exr", np.where(np.eye(H, W, dtype=bool), np.nan, 5.0).astype(np.float32)),
         1, ("a.exr", "NaN")),
    Case("depth-negative", _depth("depth/a.exr", np.full((H, W), -1.0, np.float32)), 1, ("a.exr", "negative")),
    Case("depth-holes-unfilled", _depth("depth/a.exr", np.zeros((H, W), np.float32)), 1, ("a.exr",)),
    Case("depth-exr-corrupt", _write("depth/a.exr", b"v/1\x01garbage" * 10), 1, ("a.exr", "EXR")),
    Case("depth-exr-truncated", _truncate("depth/a.exr", 0.6), 1, ("a.exr",)),
    Case("depth-npy-3d", _npy("a", np.ones((H, W, 3), np.float32)), 1, ("a.npy", "single-channel")),
    Case("depth-npy-object", _npy("a", np.array([{"x": 1}], dtype=object)), 1, ("a.npy",)),
    Case("image-png-truncated", _truncate("images/a.png", 0.6), 1, ("a.png",)),
    Case("image-jpeg-truncated", _with(_jpeg_truncated), 1, ("a.jpg", "JPEG")),
    Case("depth-npy-complex", _npy("a", np.ones((H, W), np.complex64)), 1, ("a.npy",)),
    Case("airlight-word", _flags("--airlight", "white"), 2, ("--airlight",)),
    Case("levels-huge-beta", _flags("--levels", "1e308"), 2, ("--levels",)),
    Case("intrinsics-infinite-fx", _k({"fx": "Infinity", "fy": 30.0, "cx": 15.5, "cy": 11.5, "width": 32,
                                       "height": 24}), 2, ("K.json",)),
    Case("intrinsics-nan-cx", _write("K.json", b'{"fx": 30, "fy": 30, "cx": NaN, "cy": 11.5, "width": 32, '
                                                b'"height": 24}'), 2, ("K.json",)),
    Case("disparity-encoding-without-cityscapes", _flags("--depth-encoding", "disparity"), 2, ("--cityscapes",)),
    Case("waymo-empty-tfrecord", lambda t: (good_folder(t), (t / "in" / "e.tfrecord").write_bytes(b""),
                                            ["fog", "--waymo", str(t / "in" / "e.tfrecord"), "--depth-dir",
                                             str(t / "in" / "depth"), "--out", str(t / "out")])[-1], 2,
         ("e.tfrecord", "no frames")),
    Case("waymo-garbage-tfrecord", lambda t: (good_folder(t), (t / "in" / "g.tfrecord").write_bytes(b"\x07" * 999),
                                              ["fog", "--waymo", str(t / "in" / "g.tfrecord"), "--depth-dir",
                                               str(t / "in" / "depth"), "--out", str(t / "out")])[-1], 2,
         ("g.tfrecord",)),
    Case("render-preset-unknown", _cmd("render", "--preset", "nope", "--out", "{tmp}/out"), 2, ("nope.json",)),
    Case("render-resolution-malformed", _cmd("render", "--resolution", "abc", "--out", "{tmp}/out"), 2,
         ("--resolution",)),
    Case("study-dataset-missing", _cmd("study", "--dataset", "{tmp}/nods", "--out", "{tmp}/out"), 2,
         ("nods", "dataset.json")),
    Case("study-epochs-zero", _cmd("study", "--dataset", "{tmp}/in", "--epochs", "0", "--out", "{tmp}/out"), 2,
         ("--epochs",)),
    Case("demo-frames-zero", _cmd("demo", "--frames", "0", "--out", "{tmp}/out"), 2, ("--frames",)),
    Case("cityscapes-camera-missing-key", _cs({"intrinsic": {"fx": 40.0, "fy": 40.0, "u0": 19.5, "v0": 9.5}}), 1,
         ("_camera.json", "extrinsic")),
]


def _ila_checkpoint(kind: str):
    def build(tmp: Path) -> list[str]:
        base = good_folder(tmp)
        ckpt = tmp / "in" / "ila.pt"
        if kind == "random":
            ckpt.write_bytes(np.random.default_rng(0).bytes(5000))
        else:  # a pickle whose loading would run a command
            ckpt.write_bytes(b"cos\nsystem\n(S'touch " + str(tmp / "PWNED").encode() + b"'\ntR.")
        return ["ila", "predict", "--checkpoint", str(ckpt), "--input", str(base / "images"),
                "--out", str(tmp / "out")]
    return build


ILA_CASES = [
    Case("ila-checkpoint-random", _ila_checkpoint("random"), 2, ("ila.pt",)),
    Case("ila-checkpoint-pickle-payload", _ila_checkpoint("payload"), 2, ("ila.pt",)),
    Case("ila-train-epochs-zero", _cmd("ila", "train", "--data", "{tmp}/in", "--epochs", "0", "--out", "{tmp}/out"),
         2, ("--epochs",)),
    Case("ila-train-size-malformed", _cmd("ila", "train", "--data", "{tmp}/in", "--size", "abc", "--out",
                                          "{tmp}/out"), 2, ("--size",)),
]
CASES += [pytest.param(c, id=c.id, marks=pytest.mark.torch) for c in ILA_CASES]


@pytest.mark.parametrize("case", CASES, ids=[c.id if isinstance(c, Case) else None for c in CASES])
def test_hostile_case(case: Case, tmp_path, capsys, monkeypatch):
    if case.id.startswith("ila-"):
        pytest.importorskip("torch")
    monkeypatch.chdir(tmp_path)  # a relative or empty --out lands here, never in the checkout
    run_hostile_case(case, tmp_path, capsys)
    assert not (tmp_path / "PWNED").exists(), "a checkpoint ran code"
    if case.code == 2 and case.id != "out-holds-another-run":
        assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir()), "a usage error wrote output"


def test_at_least_forty_cases():
    ids = [c.id if isinstance(c, Case) else c.id for c in CASES]
    assert len(ids) >= 40 and len(set(ids)) == len(ids)


def test_a_good_run_passes_the_same_checks(tmp_path):
    """The harness itself: the good inputs fog cleanly (so a case fails for its own defect)."""
    base = good_folder(tmp_path)
    before = tree_digest(base)
    assert main(fog(base, tmp_path / "out")) == 0
    assert tree_digest(base) == before
    assert len(list((tmp_path / "out").rglob("*.png"))) == 2
    shutil.rmtree(tmp_path / "out")
