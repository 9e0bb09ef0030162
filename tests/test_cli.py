"""The ``fogsim`` command end to end on datasets the tests build."""
import json
import os

import numpy as np
import pytest

from conftest import tree_digest
from fogsim.camera import Intrinsics, decode_disparity_png, disparity_to_depth, planar_to_ray
from fogsim.cli import main
from fogsim.fog.fill import fill_holes
from fogsim.io.depth_files import read_depth_file, read_uint16_map, write_depth
from fogsim.io.images import read_image, write_image


def fog_args(ds, out, *extra):
    return ["fog", "--input", str(ds / "images"), "--depth", str(ds / "depth"),
            "--intrinsics", str(ds / "K.json"), "--out", str(out), "--quiet", *extra]


def test_folder_dataset_numbers_and_sidecars(folder_dataset, tmp_path):
    ds, out = folder_dataset, tmp_path / "out"
    before = tree_digest(ds / "images") + tree_digest(ds / "depth")
    assert main(fog_args(ds, out, "--levels", "clear,0.05")) == 0
    assert tree_digest(ds / "images") + tree_digest(ds / "depth") == before  # inputs untouched
    img = read_image(ds / "images" / "sub" / "b.png")
    K = Intrinsics.from_dict(json.loads((ds / "K.json").read_text()))
    ray = planar_to_ray(read_depth_file(ds / "depth" / "sub" / "b.exr"), K).astype(np.float64)
    t = np.exp(-0.05 * ray)[..., None]
    ref = np.floor(img * t + 255 * (1 - t) + 0.5)
    got = read_image(out / "beta0.05" / "sub" / "b.png")
    assert np.abs(got - ref).max() <= 1 and np.mean(got == ref) > 0.99
    assert np.array_equal(read_image(out / "clear" / "sub" / "b.png"), img)
    meta = json.loads((out / "beta0.05" / "sub" / "b.json").read_text())
    assert meta["level"]["beta"] == 0.05 and meta["level"]["visibility_m"] == pytest.approx(59.915, abs=1e-3)
    assert meta["airlight_rgb"] == [255, 255, 255] and meta["blend_space"] == "srgb"
    assert meta["distance"] == "planar→ray" and meta["model"] == "koschmieder" and meta["kernel"] is None
    assert meta["fill"] == "none" and meta["fogsim_version"]
    run = json.loads((out / "fogsim_run.json").read_text())
    assert run["parameters"]["seed"] == 0 and run["numpy"]


def test_extended_and_linear_options_are_recorded(folder_dataset, tmp_path):
    out = tmp_path / "out"
    assert main(fog_args(folder_dataset, out, "--levels", "0.1", "--extended", "--kernel", "gaussian",
                         "--space", "linear", "--airlight", "240,240,250", "--heterogeneity", "0.3",
                         "--seed", "4")) == 0
    meta = json.loads((out / "beta0.1" / "a.json").read_text())
    assert meta["kernel"] == {"kind": "gaussian", "size": 19, "sigma": 5.0}
    assert meta["blend_space"] == "linear" and meta["airlight_rgb"] == [240, 240, 250]
    assert meta["heterogeneity"]["amplitude"] == 0.3 and isinstance(meta["sample_seed"], int)
    # same seed → same pixels; another seed → other pixels
    out2, out3 = tmp_path / "o2", tmp_path / "o3"
    main(fog_args(folder_dataset, out2, "--levels", "0.1", "--heterogeneity", "0.3", "--seed", "4"))
    main(fog_args(folder_dataset, out3, "--levels", "0.1", "--heterogeneity", "0.3", "--seed", "5"))
    a2, a3 = read_image(out2 / "beta0.1" / "a.png"), read_image(out3 / "beta0.1" / "a.png")
    main(fog_args(folder_dataset, tmp_path / "o4", "--levels", "0.1", "--heterogeneity", "0.3", "--seed", "4"))
    assert np.array_equal(a2, read_image(tmp_path / "o4" / "beta0.1" / "a.png"))
    assert not np.array_equal(a2, a3)


def test_resume_shards_and_workers(folder_dataset, tmp_path, capsys):
    ds, out = folder_dataset, tmp_path / "out"
    assert main(fog_args(ds, out, "--levels", "0.03", "--shard", "0/2")) == 0
    assert (out / "beta0.03" / "a.png").exists() and not (out / "beta0.03" / "sub" / "b.png").exists()
    assert main(fog_args(ds, out, "--levels", "0.03", "--shard", "1/2")) == 0
    assert (out / "beta0.03" / "sub" / "b.png").exists()
    mtime = os.path.getmtime(out / "beta0.03" / "a.png")
    capsys.readouterr()
    assert main(fog_args(ds, out, "--levels", "0.03")) == 0
    assert "fogged 0 of 2" in capsys.readouterr().out and os.path.getmtime(out / "beta0.03" / "a.png") == mtime
    (out / "beta0.03" / "a.json").unlink()  # an interrupted sample: image written, sidecar not
    assert main(fog_args(ds, out, "--levels", "0.03")) == 0
    assert "fogged 1 of 2" in capsys.readouterr().out
    par = tmp_path / "par"
    assert main(fog_args(ds, par, "--levels", "0.03", "--workers", "2")) == 0
    for name in ("a", "sub/b"):
        single, sharded = (read_image(d / "beta0.03" / f"{name}.png") for d in (par, out))
        assert single.tobytes() == sharded.tobytes()
    assert not list(out.rglob("*.part"))


def test_other_parameters_into_same_out_are_refused(folder_dataset, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(fog_args(folder_dataset, out, "--levels", "0.03")) == 0
    assert main(fog_args(folder_dataset, out, "--levels", "0.06")) == 2
    assert "fogsim_run.json" in capsys.readouterr().err


def test_bad_inputs_fail_clearly_without_partial_output(folder_dataset, tmp_path, capsys):
    ds = folder_dataset
    write_depth(ds / "depth" / "a.exr", np.ones((10, 10), np.float32))  # wrong size
    nan = np.full((24, 32), 5.0, np.float32)
    nan[3, 3] = np.nan
    write_depth(ds / "depth" / "sub" / "b.exr", nan)
    (ds / "images" / "c.png").write_bytes(b"not a png at all")
    write_image(ds / "images" / "d.png", np.zeros((24, 32, 3), np.uint8))  # no depth for it
    out = tmp_path / "out"
    assert main(fog_args(ds, out, "--levels", "0.03")) == 1
    err = capsys.readouterr().err
    assert "a.exr: depth is 10×10 but the image" in err
    assert "b.exr: depth has 1 NaN pixels" in err
    assert "c.png: not a readable image" in err
    assert "d.exr: depth file not found" in err
    assert not list(out.rglob("*.png")) and not list(out.rglob("*.part"))


@pytest.mark.parametrize("args, message", [
    (["--levels", "-0.1"], "≥ 0"),
    (["--levels", "0.1", "--airlight", "300"], "airlight"),
    (["--levels", "0.1", "--shard", "2/2"], "shard"),
    (["--levels", "0.1", "--fill", "magic"], "fill"),
])
def test_usage_errors_exit_2(folder_dataset, tmp_path, capsys, args, message):
    assert main(fog_args(folder_dataset, tmp_path / "out", *args)) == 2
    assert message in capsys.readouterr().err


def test_missing_dataset_and_missing_intrinsics(tmp_path, folder_dataset, capsys):
    assert main(["fog", "--input", str(tmp_path / "nope"), "--depth", str(tmp_path / "depth"), "--out",
                 str(tmp_path / "o"), "--quiet"]) == 2
    assert "nope: image folder not found" in capsys.readouterr().err
    # a run-wide setup error: exit 2 before the folder is claimed, so the corrected rerun works
    assert main(["fog", "--input", str(folder_dataset / "images"), "--depth", str(folder_dataset / "depth"),
                 "--out", str(tmp_path / "o2"), "--quiet", "--levels", "0.1"]) == 2
    assert "needs the camera intrinsics" in capsys.readouterr().err
    assert not (tmp_path / "o2").exists()
    assert main(["fog", "--input", str(folder_dataset / "images"), "--depth", str(folder_dataset / "depth"),
                 "--out", str(tmp_path / "o2"), "--quiet", "--levels", "0.1", "--hfov", "60"]) == 0


def test_cityscapes_tree(cityscapes_root, tmp_path, capsys):
    root, out = cityscapes_root, tmp_path / "out"
    before = tree_digest(root)
    assert main(["fog", "--cityscapes", str(root), "--split", "val", "--levels", "foggy-cityscapes",
                 "--out", str(out), "--quiet"]) == 0
    assert tree_digest(root) == before
    base = "aachen_000000_000019"
    rel = f"leftImg8bit/val/aachen/{base}_leftImg8bit"
    meta = json.loads((out / "beta0.02" / f"{rel}.json").read_text())
    assert meta["fill"] == "inpaint" and meta["hole_fraction"] == pytest.approx(8 / 800)
    raw = read_uint16_map(root / "disparity" / "val" / "aachen" / f"{base}_disparity.png")
    depth = fill_holes(disparity_to_depth(decode_disparity_png(raw), 0.209, 40.0), "inpaint")
    ray = planar_to_ray(depth, Intrinsics(40.0, 40.0, 19.5, 9.5, 40, 20)).astype(np.float64)
    img = read_image(root / "leftImg8bit" / "val" / "aachen" / f"{base}_leftImg8bit.png")
    t = np.exp(-0.02 * ray)[..., None]
    got = read_image(out / "beta0.02" / f"{rel}.png")
    assert np.abs(got - (img * t + 255 * (1 - t))).max() <= 0.5 + 1e-2


def test_cityscapes_bad_camera_and_8bit_disparity(cityscapes_root, tmp_path, capsys):
    root = cityscapes_root
    (root / "camera" / "val" / "aachen" / "aachen_000000_000019_camera.json").unlink()
    write_image(root / "disparity" / "val" / "aachen" / "aachen_000001_000019_disparity.png",
                np.zeros((20, 40, 3), np.uint8))
    assert main(["fog", "--cityscapes", str(root), "--levels", "0.01", "--out", str(tmp_path / "o"),
                 "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "aachen_000000_000019_disparity.png: disparity needs its camera JSON" in err
    assert "aachen_000000_000019_camera.json" in err
    assert "aachen_000001_000019_disparity.png: expected a single-channel 16-bit map" in err


def test_paper_8bit_depth_reproduces_reference(tmp_path):
    rng = np.random.default_rng(2)
    img = rng.integers(0, 256, (8, 10, 3), dtype=np.uint8)
    raw = rng.integers(0, 127, (8, 10), dtype=np.uint8)
    write_image(tmp_path / "img" / "x.png", img)
    write_image(tmp_path / "dep" / "x.png", raw)
    assert main(["fog", "--input", str(tmp_path / "img"), "--depth", str(tmp_path / "dep"),
                 "--depth-encoding", "paper-8bit", "--levels", "0.06", "--out", str(tmp_path / "o"),
                 "--quiet"]) == 0
    p = raw.astype(np.float64)
    dist = np.where(p < 2, 320.0, 22 * 5.6 / ((p - 1) / 256) / 100)
    t = np.exp(-0.06 * dist)[..., None]
    got = read_image(tmp_path / "o" / "beta0.06" / "x.png")
    assert np.abs(got - (img * t + 255 * (1 - t))).max() <= 0.5 + 1e-2


def test_demo_writes_strip(tmp_path):
    assert main(["demo", "--out", str(tmp_path / "d"), "--frames", "1", "--quiet"]) == 0
    strip = read_image(tmp_path / "d" / "fog_strip.png")
    assert strip.shape[1] > 5 * 320
    for key in ("clear", "beta0.03", "beta0.12"):
        assert (tmp_path / "d" / "fog" / key / "street_000.png").is_file()
    far = read_image(tmp_path / "d" / "fog" / "beta0.12" / "street_000.png")[:20].mean()
    near = read_image(tmp_path / "d" / "fog" / "clear" / "street_000.png")[:20].mean()
    assert far > near  # the sky row turns white in fog


def test_bad_hfov_scale_intrinsics_changed_inputs_and_name_clashes_exit_2(folder_dataset, tmp_path, capsys):
    """Usage errors naming their cause: --hfov 0, --heterogeneity-scale 0, a resumed run with
    another field of view, intrinsics with fx = 0, two images whose outputs would collide."""
    ds = folder_dataset
    base = ["fog", "--input", str(ds / "images"), "--depth", str(ds / "depth"), "--levels", "0.1", "--quiet"]
    assert main(base + ["--hfov", "0", "--out", str(tmp_path / "h0")]) == 2
    assert "--hfov" in capsys.readouterr().err
    assert main(base + ["--hfov", "50", "--heterogeneity", "0.2", "--heterogeneity-scale", "0",
                        "--out", str(tmp_path / "hs")]) == 2
    assert "--heterogeneity-scale" in capsys.readouterr().err
    # a resumed run with other inputs (another field of view) is refused, not skipped
    assert main(base + ["--hfov", "50", "--out", str(tmp_path / "o")]) == 0
    assert main(base + ["--hfov", "70", "--out", str(tmp_path / "o")]) == 2
    assert "fogsim_run.json" in capsys.readouterr().err
    # intrinsics with fx = 0 name their file
    bad_k = tmp_path / "badK.json"
    bad_k.write_text(json.dumps({"fx": 0, "fy": 30, "cx": 15.5, "cy": 11.5, "width": 32, "height": 24}))
    assert main(base + ["--intrinsics", str(bad_k), "--out", str(tmp_path / "k")]) == 2
    assert "badK.json" in capsys.readouterr().err
    # two images whose names differ only by extension would overwrite each other's outputs
    write_image(ds / "images" / "a.jpg", np.zeros((24, 32, 3), np.uint8))
    assert main(base + ["--hfov", "50", "--out", str(tmp_path / "dup")]) == 2
    assert "a.png: has the same name as" in capsys.readouterr().err


def test_demo_refuses_another_run_before_touching_its_inputs(tmp_path, capsys):
    out = tmp_path / "d"
    assert main(["demo", "--out", str(out), "--frames", "1", "--quiet"]) == 0
    before = (out / "input" / "images" / "street_000.png").read_bytes()
    assert main(["demo", "--out", str(out), "--frames", "1", "--seed", "5", "--quiet"]) == 2
    assert (out / "input" / "images" / "street_000.png").read_bytes() == before


# ----------------------------------------------------------------------------- reliability regressions
@pytest.mark.parametrize("args, message", [
    (["--levels", "0.1", "--airlight", "white"], "--airlight takes a value in [0, 255], R,G,B or 'estimate', "
                                                 "got 'white'"),
    (["--levels", "1e308"], "--levels: β 1e308 is out of range: at most 1000 1/m"),
    (["--visibility", "1e-9"], "--visibility: 1e-9 m is out of range"),
])
def test_bad_values_name_their_flag(folder_dataset, tmp_path, capsys, args, message):
    """#22: the message names the flag and the real problem (not float() or the level key)."""
    assert main(fog_args(folder_dataset, tmp_path / "out", *args)) == 2
    err = capsys.readouterr().err
    assert message in err and "could not convert" not in err and "key" not in err
    assert not (tmp_path / "out").exists()


def test_large_visibility_gets_a_valid_level_key(folder_dataset, tmp_path):
    assert main(fog_args(folder_dataset, tmp_path / "out", "--visibility", "1e7")) == 0
    assert (tmp_path / "out" / "vis1e07m" / "a.png").is_file()


@pytest.mark.parametrize("source", ["input", "waymo"])
def test_disparity_encoding_without_cityscapes_is_a_setup_error(folder_dataset, tmp_path, capsys, source):
    """#12: --depth-encoding disparity cannot get its camera JSON outside --cityscapes."""
    ds = folder_dataset
    if source == "input":
        args = ["--input", str(ds / "images"), "--depth", str(ds / "depth")]
    else:
        (tmp_path / "seg.tfrecord").write_bytes(b"")
        args = ["--waymo", str(tmp_path / "seg.tfrecord"), "--depth-dir", str(ds / "depth")]
    assert main(["fog", *args, "--depth-encoding", "disparity", "--levels", "0.1",
                 "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--depth-encoding disparity" in err and "--cityscapes" in err
    assert not (tmp_path / "out").exists()


def test_16_bit_input_to_jpg_is_scaled_not_saturated(tmp_path):
    """#17: JPEG is 8-bit: a 16-bit image is scaled by 255/65535 (and recorded), never clipped."""
    rng = np.random.default_rng(6)
    img16 = (rng.integers(20, 236, (24, 32, 3)) * 257).astype(np.uint16)
    write_image(tmp_path / "img" / "x.png", img16)
    write_depth(tmp_path / "dep" / "x.exr", np.full((24, 32), 10.0, np.float32))
    base = ["fog", "--input", str(tmp_path / "img"), "--depth", str(tmp_path / "dep"), "--depth-kind", "ray",
            "--levels", "clear,0.05", "--quiet"]
    assert main(base + ["--format", "jpg", "--out", str(tmp_path / "j")]) == 0
    clear = read_image(tmp_path / "j" / "clear" / "x.jpg")
    assert clear.dtype == np.uint8
    assert abs(clear.mean() - img16.mean() / 257) < 2  # not near-white
    meta = json.loads((tmp_path / "j" / "beta0.05" / "x.json").read_text())
    assert meta["bit_depth"] == {"input": 16, "output": 8, "conversion": "round(v * 255 / 65535)"}
    assert main(base + ["--out", str(tmp_path / "p")]) == 0  # PNG keeps the 16 bits
    assert np.array_equal(read_image(tmp_path / "p" / "clear" / "x.png"), img16)
    assert json.loads((tmp_path / "p" / "beta0.05" / "x.json").read_text())["bit_depth"] == \
        {"input": 16, "output": 16}
    from fogsim.io.images import encode_image

    with pytest.raises(ValueError, match="JPEG holds 8-bit"):
        encode_image(img16, ".jpg")
