"""ILA on bad input: unsafe or unreadable checkpoints, bad training flags, bad images.

Every bad input ends with one line naming the file (or flag) and the problem — no traceback —
and the documented exit code; a checkpoint is never unpickled beyond tensors and plain data,
and nothing is written before the checkpoint and the flags have been checked.
"""
import ast
import json
import os
import pickle
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.torch
torch = pytest.importorskip("torch")

from fogsim.camera import depth_to_disparity, encode_disparity_png  # noqa: E402
from fogsim.cli import main  # noqa: E402
from fogsim.io.images import write_image  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
TRAIN = ["--rounds", "1", "--epochs", "1", "--width", "2", "--size", "64x32", "--quiet"]


def _cityscapes(root: Path) -> Path:
    """Two 40×20 Cityscapes frames with disparity holes (as the conftest's ``cityscapes_root``)."""
    rng = np.random.default_rng(9)
    cam = {"extrinsic": {"baseline": 0.209}, "intrinsic": {"fx": 40.0, "fy": 40.0, "u0": 19.5, "v0": 9.5}}
    for base in ("aachen_000000_000019", "aachen_000001_000019"):
        write_image(root / "leftImg8bit" / "val" / "aachen" / f"{base}_leftImg8bit.png",
                    rng.integers(0, 256, (20, 40, 3), dtype=np.uint8))
        disp = encode_disparity_png(depth_to_disparity(rng.uniform(3, 60, (20, 40)).astype(np.float32), 0.209, 40.0))
        disp[:2, :4] = 0
        write_image(root / "disparity" / "val" / "aachen" / f"{base}_disparity.png", disp)
        (root / "camera" / "val" / "aachen").mkdir(parents=True, exist_ok=True)
        (root / "camera" / "val" / "aachen" / f"{base}_camera.json").write_text(json.dumps(cam))
    return root


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """(Cityscapes root, a real round_0.pt) trained once for the module: width 2, 64×32, 1 epoch."""
    base = tmp_path_factory.mktemp("ila_trained")
    root = _cityscapes(base / "cityscapes")
    assert main(["ila", "train", "--data", str(root), "--split", "val", "--out", str(base / "ck"), *TRAIN]) == 0
    return root, base / "ck" / "round_0.pt"


@pytest.fixture
def images(tmp_path):
    rng = np.random.default_rng(1)
    for name in ("a", "b", "c"):
        write_image(tmp_path / "images" / f"{name}.png", rng.integers(0, 256, (24, 32, 3), dtype=np.uint8))
    return tmp_path / "images"


def _one_line_error(capsys, *names) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for name in names:
        assert str(name) in lines[0], err
    return lines[0]


def _commands(kind, ck, trained, images, out):
    """The three commands that read a checkpoint, each into ``out``."""
    root = trained[0]
    return {
        "predict": ["ila", "predict", "--checkpoint", str(ck), "--input", str(images), "--out", str(out), "--quiet"],
        "fill": ["ila", "fill", "--checkpoint", str(ck), "--data", str(root), "--split", "val", "--out", str(out),
                 "--quiet"],
        "fog": ["fog", "--input", str(images), "--depth-from", f"ila:{ck}", "--hfov", "60", "--levels", "0.06",
                "--out", str(out), "--quiet"],
    }[kind]


COMMANDS = ("predict", "fill", "fog")


# ----------------------------------------------------------------------------- #2 checkpoints run no code

class _Payload:
    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


@pytest.mark.parametrize("container", ["pickle", "torch.save"])
@pytest.mark.parametrize("kind", COMMANDS)
def test_crafted_checkpoint_never_runs_its_payload(kind, container, trained, images, tmp_path, capsys):
    marker = tmp_path / "PWNED"
    evil = tmp_path / "evil.pt"
    if container == "pickle":  # the reliability note's reproduction
        with open(evil, "wb") as f:
            pickle.dump(_Payload(marker), f)
    else:  # the same payload inside a real torch zip archive, under the expected keys
        torch.save({"fogsim_ila_format": 2, "state_dict": _Payload(marker), "config": {}}, evil)
    out = tmp_path / "out"
    assert main(_commands(kind, evil, trained, images, out)) == 2
    assert not marker.exists(), "the checkpoint's payload ran"
    _one_line_error(capsys, evil)
    assert not out.exists()


def test_checkpoint_holds_only_tensors_and_plain_data(trained):
    from fogsim.depth.ila import CHECKPOINT_FORMAT, ILAConfig

    ck = torch.load(trained[1], map_location="cpu", weights_only=True)  # nothing but tensors and plain data
    assert ck["fogsim_ila_format"] == CHECKPOINT_FORMAT == 2
    assert ck["config"] == {**asdict(ILAConfig(width=2, size=(64, 32), rounds=1, epochs=1)), "size": [64, 32]}
    assert set(ck["camera"]) == {"baseline_m", "fx_over_w"} and ck["round"] == 0
    assert all(isinstance(v, torch.Tensor) for v in ck["state_dict"].values())
    assert not list(trained[1].parent.glob(".*.part"))


@pytest.mark.parametrize("kind", COMMANDS)
def test_checkpoint_of_fogsim_0_1_asks_to_retrain(kind, trained, images, tmp_path, capsys):
    """fogsim 0.1 saved {state_dict, config, camera, round, output} with no format number."""
    ck = torch.load(trained[1], map_location="cpu", weights_only=True)
    old = tmp_path / "round_0.pt"
    torch.save({"state_dict": ck["state_dict"], "config": {**ck["config"], "size": tuple(ck["config"]["size"])},
                "camera": ck["camera"], "round": 0, "output": "disparity / image width"}, old)
    out = tmp_path / "out"
    assert main(_commands(kind, old, trained, images, out)) == 2
    line = _one_line_error(capsys, old)
    assert "written by an older fogsim (format 1); retrain with fogsim ila train" in line
    assert not out.exists()


def test_no_unsafe_unpickling_in_fogsim():
    """No torch.load without weights_only=True, no pickle.load/loads/Unpickler on files.

    fogsim/detection is left out: yolo.py reads Ultralytics' own training checkpoint (a pickled
    model, which weights_only=True cannot load) — reported separately, not ILA code.
    """
    offenders = []
    for path in sorted((REPO / "fogsim").rglob("*.py")) + sorted((REPO / "scripts").rglob("*.py")):
        if "detection" in path.relative_to(REPO).parts:
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, ast.Call):
                continue
            name = ast.unparse(node.func)
            safe = any(k.arg == "weights_only" and isinstance(k.value, ast.Constant) and k.value.value is True
                       for k in node.keywords)
            if (name.endswith("torch.load") and not safe) or name in ("pickle.load", "pickle.loads",
                                                                          "pickle.Unpickler"):
                offenders.append(f"{path.relative_to(REPO)}:{node.lineno}: {ast.unparse(node)}")
    assert not offenders, offenders


# ----------------------------------------------------------------------------- #6 unreadable checkpoints

def _bad_checkpoint(case: str, trained, tmp_path: Path) -> Path:
    path = tmp_path / f"{case}.pt"
    if case == "random":
        path.write_bytes(np.random.default_rng(0).integers(0, 256, 100_000, dtype=np.uint8).tobytes())
    elif case == "truncated":
        data = trained[1].read_bytes()
        path.write_bytes(data[:len(data) // 2])
    elif case == "empty":
        path.write_bytes(b"")
    elif case == "list":
        torch.save([1, 2, 3], path)
    elif case == "foreign_dict":
        torch.save({"weights": torch.zeros(3)}, path)
    elif case == "newer":
        ck = torch.load(trained[1], map_location="cpu", weights_only=True)
        torch.save({**ck, "fogsim_ila_format": 99}, path)
    elif case == "wrong_weights":
        ck = torch.load(trained[1], map_location="cpu", weights_only=True)
        torch.save({**ck, "config": {**ck["config"], "width": 3}}, path)
    elif case == "bad_config":
        ck = torch.load(trained[1], map_location="cpu", weights_only=True)
        torch.save({**ck, "config": {**ck["config"], "size": "big"}}, path)
    elif case == "folder":
        path.mkdir()
    return path


BAD = ("random", "truncated", "empty", "list", "foreign_dict", "newer", "wrong_weights", "bad_config", "folder")


@pytest.mark.parametrize("case", BAD)
@pytest.mark.parametrize("kind", COMMANDS)
def test_unreadable_checkpoint_is_one_line_at_setup(kind, case, trained, images, tmp_path, capsys):
    ck = _bad_checkpoint(case, trained, tmp_path)
    out = tmp_path / "out"
    assert main(_commands(kind, ck, trained, images, out)) == 2
    line = _one_line_error(capsys, ck)
    if case == "newer":
        assert "written by a newer fogsim (format 99;" in line
    assert not out.exists(), "output written or claimed before the checkpoint was checked"


def test_load_model_names_the_checkpoint(trained, tmp_path):
    from fogsim.depth.ila import load_model
    from fogsim.errors import InputError

    ck = _bad_checkpoint("random", trained, tmp_path)
    with pytest.raises(InputError, match="random.pt: "):
        load_model(ck)


# ----------------------------------------------------------------------------- #7 training flags

@pytest.mark.parametrize("flag,value", [("--epochs", "0"), ("--epochs", "-2"), ("--rounds", "0"), ("--width", "0"),
                                        ("--size", "60x32"), ("--size", "0x0"), ("--size", "abc"),
                                        ("--size", "64x-16"), ("--seed", "-1")])
def test_train_refuses_bad_flags_up_front(flag, value, trained, tmp_path, capsys):
    args = dict(zip(TRAIN[:-1:2], TRAIN[1::2]))
    args[flag] = value
    out = tmp_path / "ck"
    argv = ["ila", "train", "--data", str(trained[0]), "--split", "val", "--out", str(out), "--quiet"]
    assert main(argv + [x for kv in args.items() for x in kv]) == 2
    line = _one_line_error(capsys, flag)
    assert "--resolution" not in line
    assert not out.exists()


def test_config_refuses_empty_training():
    from fogsim.depth.ila import ILAConfig

    for bad in ({"epochs": 0}, {"rounds": 0}, {"width": 0}, {"batch": 0}, {"size": (0, 0)}, {"size": (-16, 32)}):
        with pytest.raises(ValueError):
            ILAConfig(**bad)


# ----------------------------------------------------------------------------- #27 predict skips bad images

def test_predict_skips_an_unreadable_image_and_goes_on(trained, images, tmp_path, capsys):
    bad = images / "b.png"
    bad.write_bytes(bad.read_bytes()[:40])  # truncated PNG
    out = tmp_path / "pred"
    assert main(["ila", "predict", "--checkpoint", str(trained[1]), "--input", str(images), "--out", str(out),
                 "--quiet"]) == 1
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and str(bad) in captured.err
    assert sorted(p.name for p in out.iterdir()) == ["a.exr", "c.exr"]  # no b.exr, no .part left
    assert "2 of 3" in captured.out


def test_fill_skips_an_unreadable_frame_and_goes_on(trained, tmp_path, capsys):
    import shutil

    root = tmp_path / "cs"
    shutil.copytree(trained[0], root)
    bad = root / "disparity" / "val" / "aachen" / "aachen_000000_000019_disparity.png"
    bad.write_bytes(b"not a png")
    out = tmp_path / "filled"
    assert main(["ila", "fill", "--checkpoint", str(trained[1]), "--data", str(root), "--split", "val",
                 "--out", str(out), "--quiet"]) == 1
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and str(bad) in captured.err
    done = sorted(p.name for p in (out / "disparity" / "val" / "aachen").iterdir())
    assert done == ["aachen_000001_000019_disparity.png"]


# ----------------------------------------------------------------------------- image scales

def test_predicted_depth_does_not_depend_on_the_image_bit_depth():
    """A 16-bit (or float) image is the same picture as its 8-bit version: the same input."""
    from fogsim.depth.ila import ILAConfig, predict_depth

    class Brightness(torch.nn.Module):
        def forward(self, x):
            return x[:, :1] * 0.01 + 0.001

    camera = {"baseline_m": 0.2, "fx_over_w": 1.0}
    img8 = np.full((16, 32, 3), 128, np.uint8)
    cfg = ILAConfig(size=(32, 16))
    d8 = predict_depth(Brightness(), cfg, camera, img8)
    d16 = predict_depth(Brightness(), cfg, camera, img8.astype(np.uint16) * 257)
    dfl = predict_depth(Brightness(), cfg, camera, img8.astype(np.float32) / 255)
    assert np.allclose(d16, d8, rtol=1e-5) and np.allclose(dfl, d8, rtol=1e-5)
