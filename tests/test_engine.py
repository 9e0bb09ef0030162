"""The fog record (fogsim.fog.engine.FogSettings): one factory for every front end, one word list
in every document, and documents of older fogsims still read."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fogsim.augment import Draw, FogSpec, apply_fog
from fogsim.camera import Intrinsics, planar_to_ray
from fogsim.cli import main
from fogsim.fog.engine import FogSettings, Heterogeneity
from fogsim.fog.model import Fogger, Kernel
from fogsim.fog.scatter import ScatterFogger, load_params
from fogsim.io.depth_files import read_depth_file
from fogsim.io.images import read_image
from fogsim.schema.vocabulary import FOG_KINDS, model_word

BETA = 0.06
#: the models every front end is run with: (name, FogSettings keywords, fogsim fog flags, preset fog_model)
MODELS = {
    "koschmieder": ({}, [], {}),
    "extended": ({"kernel": Kernel("box", 5)}, ["--extended", "--kernel-size", "5"],
                 {"extended": True, "kernel_size": 5}),
    "scatter": ({"kind": "scatter"}, ["--model", "scatter"], {"kind": "scatter"}),
}


def scene(h=24, w=32, seed=3):
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    img[4:8, 5:9] = 255  # a saturated patch (the scatter model's glow)
    ray = rng.uniform(3, 90, (h, w)).astype(np.float32)
    ray[:3] = np.inf
    return img, ray, Intrinsics.from_hfov(60.0, w, h)


@pytest.mark.parametrize("name", MODELS)
def test_the_factory_builds_the_models_fogger(name):
    img, ray, K = scene()
    fs = FogSettings(**MODELS[name][0])
    got = fs.fogger(img, ray, K)(BETA)
    if fs.kind == "scatter":
        ref = ScatterFogger(img, ray, 255.0, "linear", load_params(), K)(BETA)
    else:
        ref = Fogger(img, ray, 255.0, "srgb", fs.kernel)(BETA)
    assert np.array_equal(got, ref) and not np.array_equal(got, img)


@pytest.mark.parametrize("name", MODELS)
def test_numpy_and_albumentations_front_ends_are_the_factory(name):
    img, ray, K = scene()
    kw = MODELS[name][0]
    spec = FogSpec(beta=BETA, model=kw.get("kind", "koschmieder"), kernel=kw.get("kernel"), intrinsics=K)
    ref = FogSettings(**kw).fogger(img, ray, K)(BETA)
    assert np.array_equal(apply_fog(img, ray, Draw(BETA, (255.0,) * 3), spec), ref)
    A = pytest.importorskip("albumentations")
    import fogsim.augment

    aug = A.Compose([fogsim.augment.Fog(beta=BETA, model=spec.model, kernel=spec.kernel, intrinsics=K)],
                    additional_targets={"depth": "mask"}, seed=0)
    assert np.array_equal(aug(image=img, depth=ray)["image"], ref)


@pytest.mark.torch
@pytest.mark.parametrize("name", ["koschmieder", "extended"])
def test_the_torch_batch_matches_the_factory_to_one_level(name):
    torch = pytest.importorskip("torch")
    from fogsim.augment.torch_fog import fog_batch

    img, ray, K = scene()
    kw = MODELS[name][0]
    finite = np.where(np.isfinite(ray), ray, 1e6).astype(np.float32)  # inf → no transmission either way
    ref = FogSettings(**kw).fogger(img, finite, K)(BETA)
    out = fog_batch(torch.from_numpy(img).permute(2, 0, 1)[None], torch.from_numpy(finite)[None, None], BETA,
                    spec=FogSpec(beta=BETA, kernel=kw.get("kernel")))[0].permute(1, 2, 0).numpy()
    assert np.abs(out.astype(int) - ref.astype(int)).max() <= 1


def test_albumentations_fog_takes_the_scatter_model():
    A = pytest.importorskip("albumentations")
    import fogsim.augment

    img, ray, K = scene()
    t = fogsim.augment.Fog(beta=(0.03, 0.12), model="scatter", hfov=60.0)  # a TypeError before the record
    assert t.spec.model == "scatter" and t.spec.space == "linear"
    out = A.Compose([t], additional_targets={"depth": "mask"}, seed=1)(image=img, depth=ray)["image"]
    beta = t.get_applied_params()["beta"]
    assert np.array_equal(out, FogSettings("scatter").fogger(img, ray, K)(beta))


@pytest.mark.parametrize("name", MODELS)
def test_fogsim_fog_is_the_factory_and_says_the_models_word(name, folder_dataset, tmp_path):
    ds, out = folder_dataset, tmp_path / "out"
    kw, flags, _ = MODELS[name]
    assert main(["fog", "--input", str(ds / "images"), "--depth", str(ds / "depth"), "--intrinsics",
                 str(ds / "K.json"), "--levels", str(BETA), "--quiet", "--out", str(out), *flags]) == 0
    K = Intrinsics.from_dict(json.loads((ds / "K.json").read_text()))
    img = read_image(ds / "images" / "a.png")
    ray = planar_to_ray(read_depth_file(ds / "depth" / "a.exr"), K)
    fs = FogSettings(**kw, airlight=(255.0, 255.0, 255.0))  # --airlight 255 is white in each channel
    assert np.array_equal(read_image(out / f"beta{BETA}" / "a.png"), fs.fogger(img, ray, K)(BETA))
    side = json.loads((out / f"beta{BETA}" / "a.json").read_text())
    run = json.loads((out / "fogsim_run.json").read_text())["parameters"]
    for doc in (side, run):
        assert doc["model"] == fs.kind and doc["blend_space"] == fs.blend_space
        assert {k: doc[k] for k in fs.record()} == json.loads(json.dumps(fs.record()))


@pytest.mark.parametrize("name", MODELS)
def test_a_rendered_frame_is_fogged_by_the_factory(name, tmp_path):
    from fogsim.colour import linear_to_srgb8
    from fogsim.dataset.layout import DatasetLayout
    from fogsim.fog.scatter_optics import up_from_world_to_camera
    from fogsim.render.frame import DescribedFrame, FramePasses, commit_frame
    from fogsim.render.preset import load_render_preset

    preset = tmp_path / "p.json"
    preset.write_text(json.dumps({"style": "suburban", "camera": "waymo-front", "quality": "draft",
                                  "resolution": [32, 24], "fog": [0, BETA], "fog_model": MODELS[name][2]}))
    config = load_render_preset(str(preset), frames=1)
    rng = np.random.default_rng(0)
    rgb = np.clip(rng.normal(0.3, 0.1, (24, 32, 3)), 0, 1).astype(np.float32)
    depth = np.vstack([np.full((6, 32), np.inf, np.float32),
                       np.tile(np.geomspace(60, 5, 18)[:, None], (1, 32)).astype(np.float32)])
    frame = DescribedFrame.of(config, 0)
    meta = commit_frame(DatasetLayout(tmp_path / "ds"), config, frame,
                        FramePasses(rgb, depth, np.zeros((24, 32), np.uint16)))
    K = Intrinsics.from_dict(meta["camera"]["intrinsics"])
    fs = FogSettings(**MODELS[name][0])
    up = up_from_world_to_camera(meta["camera"]["world_to_camera"]) if fs.kind == "scatter" else None
    ref = fs.fogger(linear_to_srgb8(rgb, config.exposure), planar_to_ray(depth, K), K, up)(BETA)
    assert np.array_equal(read_image(tmp_path / "ds" / "images" / f"beta{BETA}" / "000000.png"), ref)
    assert meta["fog"]["model"] == fs.kind and meta["fog"]["distance"] == "planar→ray"
    assert {k: meta["fog"][k] for k in fs.record()} == fs.record()


def test_records_use_one_word_list():
    assert {FogSettings(k).record()["model"] for k in ("koschmieder", "scatter")} <= set(FOG_KINDS)
    rec = FogSettings(kernel=Kernel("gaussian", 7, 2.0), heterogeneity=Heterogeneity(0.2, 32)).record()
    assert rec["model"] == "koschmieder" and rec["kernel"]["kind"] == "gaussian"
    assert rec["heterogeneity"] == {"amplitude": 0.2, "scale_px": 32}
    assert "scatter_params" not in rec and "kernel" not in FogSettings("scatter").record()
    assert model_word("standard") == model_word("extended") == "koschmieder" and model_word("scatter") == "scatter"


@pytest.mark.parametrize("kw, message", [
    ({"kind": "fancy"}, "fog model must be one of"),
    ({"kind": "scatter", "kernel": Kernel()}, "no extended kernel"),
    ({"scatter_file": "p.json"}, "scatter parameters need the scatter model"),
    ({"airlight": 300}, "airlight must lie in"),
    ({"space": "cmyk"}, "blend space"),
])
def test_the_record_refuses_what_no_model_does(kw, message):
    with pytest.raises(ValueError, match=message):
        FogSettings(**kw)


def test_volumetric_fog_has_no_fogger():
    img, ray, K = scene()
    with pytest.raises(ValueError, match="rendered"):
        FogSettings("volumetric").fogger(img, ray, K)


@pytest.mark.parametrize("old", [
    {"model": "standard", "kernel": None, "heterogeneity": None},
    {"model": "standard", "kernel": None, "heterogeneity": None, "fog_model": "scatter"},
])
def test_a_run_written_in_older_words_resumes(old, folder_dataset, tmp_path, capsys):
    ds, out = folder_dataset, tmp_path / "out"
    args = ["fog", "--input", str(ds / "images"), "--depth", str(ds / "depth"), "--intrinsics", str(ds / "K.json"),
            "--levels", str(BETA), "--quiet", "--out", str(out)]
    if "fog_model" in old:
        args += ["--model", "scatter"]
    assert main(args) == 0
    run_file = out / "fogsim_run.json"
    run = json.loads(run_file.read_text())
    params = run["parameters"]
    if "fog_model" in old:  # before 0.4: "standard" beside "fog_model", kernel and heterogeneity None
        params.pop("model")
    run["parameters"] = {**params, **old}
    run_file.write_text(json.dumps(run))
    capsys.readouterr()
    assert main(args) == 0 and "2 already done" in capsys.readouterr().out
    assert json.loads(run_file.read_text()) == run  # the old file is read, not rewritten
    run["parameters"]["blend_space"] = "linear" if "fog_model" not in old else "srgb"
    run_file.write_text(json.dumps(run))
    assert main(args) == 2  # other parameters are still refused


def test_the_lidar_reads_the_same_record():
    """One fog, two sensors: the record's LiDAR fogger is the LiDAR fog model with the record's spec, and
    its per-point β is the camera's β times the density field at the point's pixel."""
    from fogsim.lidar.fog import LidarFogger
    from fogsim.lidar.points import PointCloud

    rng = np.random.default_rng(4)
    r = rng.uniform(2, 80, 500)
    az = rng.uniform(-np.pi, np.pi, 500)
    xyz = np.stack([r * np.cos(az), r * np.sin(az), np.full(500, -1.0)], 1).astype(np.float32)
    scan = PointCloud.from_raw(xyz, rng.uniform(0, 1, 500).astype(np.float32), "0-1", "scan.bin")
    fs = FogSettings(lidar={"model": "attenuation", "extinction_ratio": 1.2})
    got = fs.lidar_fogger(scan, "hdl64e")(0.06, np.random.default_rng(1))
    ref = LidarFogger(scan, "hdl64e", {"model": "attenuation", "extinction_ratio": 1.2})(0.06, np.random.default_rng(1))
    assert np.array_equal(got.outcome, ref.outcome) and got.cloud.same_as(ref.cloud)
    assert fs.record()["lidar_fog"]["extinction_ratio"] == 1.2 and "lidar_fog" not in FogSettings().record()
    field = np.ones((10, 20), np.float32)
    field[2, 3] = 1.3
    betas = fs.point_betas(0.05, field, np.array([[3.5, 2.5], [3.0, 2.99], [25.0, 2.0], [-1.0, 4.0]]))
    assert np.allclose(betas, [0.065, 0.065, 0.05, 0.05])  # pixel (row 2, col 3); outside the image: β
    assert fs.point_betas(0.05, None, None) == 0.05
    with pytest.raises(ValueError, match="lidar_fog|model"):
        FogSettings(lidar={"model": "magic"})
