"""ILA: masked loss, the fill step, and a tiny end-to-end run (torch, CPU)."""
import numpy as np
import pytest

pytestmark = pytest.mark.torch
torch = pytest.importorskip("torch")

from fogsim.depth.ila import (  # noqa: E402
    ILAConfig,
    build_unet,
    fill_targets,
    load_model,
    load_stereo_set,
    masked_loss,
    predict_depth,
    train_rounds,
)


def test_masked_loss_ignores_holes():
    pred = torch.tensor([[[[0.5, 9.0], [0.2, 7.0]]]])
    target = torch.tensor([[[[0.4, 0.0], [0.2, 0.0]]]])
    valid = (target > 0).float()
    assert float(masked_loss(pred, target, valid)) == pytest.approx((0.1 ** 2 + 0) / 2)
    # whatever the prediction in the holes, the masked loss is the same
    pred2 = pred.clone()
    pred2[0, 0, :, 1] = -3.0
    assert float(masked_loss(pred2, target, valid)) == float(masked_loss(pred, target, valid))
    # the reference's loss regresses holes to 0
    assert float(masked_loss(pred, target, valid, "all")) == pytest.approx((0.01 + 81 + 0 + 49) / 4)


def test_fill_step_changes_only_holes():
    rng = np.random.default_rng(0)
    target = rng.uniform(0.01, 0.1, (2, 1, 8, 8)).astype(np.float32)
    target[:, :, 2:5, 3:6] = 0
    pred = rng.uniform(0.01, 0.1, target.shape).astype(np.float32)
    filled = fill_targets(target, pred)
    holes = target == 0
    assert np.array_equal(filled[~holes], target[~holes]) and np.array_equal(filled[holes], pred[holes])


def test_widths():
    n = lambda w: sum(p.numel() for p in build_unet(ILAConfig(width=w)).parameters())  # noqa: E731
    assert 1e6 < n(16) < 2.5e6  # CPU default
    assert 30e6 < n(64) < 32e6  # the reference's 31 M


def test_tiny_ila_round_end_to_end(cityscapes_root, tmp_path):
    cfg = ILAConfig(size=(32, 16), width=4, rounds=1, epochs=2, batch=2)
    data = load_stereo_set(cityscapes_root, "val", cfg.size)
    assert data.rgb.shape == (2, 3, 16, 32) and data.camera["baseline_m"] == pytest.approx(0.209)
    assert data.camera["fx_over_w"] == pytest.approx(40.0 / 40)
    assert (data.target == 0).any() and (data.target > 0).any()
    log = train_rounds(data, cfg, tmp_path / "ck", progress=False)
    assert log[0]["holes_before"] > 0 and log[0]["holes_after"] == 0
    model, config, camera = load_model(log[0]["checkpoint"])
    assert config == cfg
    depth = predict_depth(model, config, camera, np.zeros((20, 40, 3), np.uint8))
    assert depth.shape == (20, 40) and np.all(np.isfinite(depth)) and np.all(depth > 0)
    # same seed → same weights
    log2 = train_rounds(data, cfg, tmp_path / "ck2", progress=False)
    a = torch.load(log[0]["checkpoint"], weights_only=True)["state_dict"]
    b = torch.load(log2[0]["checkpoint"], weights_only=True)["state_dict"]
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_cli_train_predict_and_fog_with_predicted_depth(cityscapes_root, folder_dataset, tmp_path, capsys):
    import json

    from fogsim.cli import main
    from fogsim.io.depth_files import read_depth_file

    ck = tmp_path / "ila"
    assert main(["ila", "train", "--data", str(cityscapes_root), "--split", "val", "--out", str(ck), "--rounds", "1",
                 "--epochs", "1", "--width", "4", "--size", "32x16", "--sparse", "--quiet"]) == 0
    assert json.loads((ck / "ila_log.json").read_text())["rounds"][0]["holes_after"] == 0
    assert main(["ila", "predict", "--checkpoint", str(ck / "round_0.pt"), "--input", str(folder_dataset / "images"),
                 "--out", str(tmp_path / "pred"), "--quiet"]) == 0
    d = read_depth_file(tmp_path / "pred" / "sub" / "b.exr")
    assert d.shape == (24, 32) and np.all(d > 0)
    out = tmp_path / "fog"
    assert main(["fog", "--input", str(folder_dataset / "images"), "--depth-from", f"ila:{ck / 'round_0.pt'}",
                 "--hfov", "60", "--levels", "0.06", "--out", str(out), "--quiet"]) == 0
    meta = json.loads((out / "beta0.06" / "a.json").read_text())
    assert meta["encoding"] == "ila" and meta["distance"] == "planar→ray"
    assert main(["fog", "--input", str(folder_dataset / "images"), "--depth-from", "ila:/nope.pt", "--hfov", "60",
                 "--out", str(tmp_path / "f2"), "--quiet"]) == 2
    assert "nope.pt: ILA checkpoint not found" in capsys.readouterr().err


def test_log_l1_loss_is_relative_and_masked():
    target = torch.tensor([[[[0.02, 0.0], [0.04, 0.01]]]])
    pred = torch.tensor([[[[0.04, 5.0], [0.02, 0.01]]]])
    valid = (target > 0).float()
    import math
    assert float(masked_loss(pred, target, valid, kind="log_l1")) == pytest.approx(2 * math.log(2) / 3, rel=1e-5)


def test_ila_fill_cli_changes_only_holes(cityscapes_root, tmp_path):
    from fogsim.camera import decode_disparity_png
    from fogsim.cli import main
    from fogsim.io.depth_files import read_uint16_map

    ck = tmp_path / "ila"
    assert main(["ila", "train", "--data", str(cityscapes_root), "--split", "val", "--out", str(ck), "--rounds", "1",
                 "--epochs", "1", "--width", "4", "--size", "32x16", "--quiet"]) == 0
    out = tmp_path / "filled"
    assert main(["ila", "fill", "--checkpoint", str(ck / "round_0.pt"), "--data", str(cityscapes_root),
                 "--split", "val", "--out", str(out), "--quiet"]) == 0
    rel = "disparity/val/aachen/aachen_000000_000019_disparity.png"
    before, after = read_uint16_map(cityscapes_root / rel), read_uint16_map(out / rel)
    holes = before == 0
    assert holes.any() and (after[holes] > 0).all()
    assert np.abs(decode_disparity_png(after)[~holes] - decode_disparity_png(before)[~holes]).max() < 1 / 256 + 1e-6


def test_predicted_depth_conversion_to_metres():
    """depth = baseline · (fx/W) / (d/W): a model that predicts d/W = 0.02 everywhere."""
    class Constant(torch.nn.Module):
        def forward(self, x):
            return torch.full((x.shape[0], 1, x.shape[2], x.shape[3]), 0.02)

    camera = {"baseline_m": 0.209, "fx_over_w": 1.1}
    depth = predict_depth(Constant(), ILAConfig(size=(32, 16)), camera, np.zeros((50, 100, 3), np.uint8))
    assert depth.shape == (50, 100) and np.allclose(depth, 0.209 * 1.1 / 0.02)
