"""Volumetric fog: the preset block, the pure helpers, and real Cycles renders.

The Blender tests are tiny (96×64, 8–16 samples): the volumetric and the Koschmieder run of one
preset and seed write the same labels, depth and masks and different foggy images; the
camera-only emission–absorption medium reproduces Koschmieder's law in linear light per distance
bin, in the bpy module (5.0) and in Debian's Blender (3.4); the fog renders' Cycles settings are
raised and then restored for the next clear render.
"""
import json
import math
import sys

import numpy as np
import pytest

from fogsim.camera import Intrinsics, planar_to_ray
from fogsim.colour import linear_to_srgb8
from fogsim.dataset.layout import DatasetLayout
from fogsim.errors import InputError
from fogsim.fog.model import koschmieder
from fogsim.fog.physics import far_luminance, interior_mask
from fogsim.io.depth_files import read_depth_file, read_uint16_map
from fogsim.io.exr import read_rgb_exr
from fogsim.io.images import read_image
from fogsim.render.fog_settings import frame_volumetric, volumetric_settings
from fogsim.render.preset import load_render_preset
from fogsim.render.volumetric import auto_exposure
from test_blender import KINDS, ROOT, SCRIPTS, dataset_digest, run, runner

LEVELS = ["beta0.03", "beta0.06", "beta0.09", "beta0.12"]


# the law the camera-only emission–absorption medium must reproduce, and its per-bin bias
def koschmieder_linear(clear_linear: np.ndarray, ray: np.ndarray, beta: float, airlight: float) -> np.ndarray:
    """Koschmieder's law on a scene-linear image: I·t + A·(1 − t), t = e^(−βℓ) (ℓ: ray distance, m;
    +inf = sky, t = 0). ``airlight`` A is scene-linear (1.0 = white), at most 1."""
    # a float image blended in its own values ("srgb" = no transfer applied): linear light here
    return koschmieder(np.asarray(clear_linear, dtype=np.float32), ray, beta, airlight=255.0 * airlight,
                       space="srgb")


def bin_bias(diff: np.ndarray, ray: np.ndarray, mask: np.ndarray,
             edges=(0.0, 10.0, 20.0, 40.0, 80.0, 160.0, math.inf)) -> list[dict]:
    """Mean of ``diff`` (H×W or H×W×3) per ray-distance bin over ``mask``; sky (+inf) is its own bin."""
    d = diff.mean(axis=-1) if diff.ndim == 3 else diff
    out = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = mask & (ray >= lo) & (ray < hi)
        if sel.any():
            out.append({"from_m": lo, "to_m": hi, "pixels": int(sel.sum()), "bias": float(d[sel].mean())})
    sky = mask & np.isinf(ray)
    if sky.any():
        out.append({"from_m": math.inf, "to_m": math.inf, "pixels": int(sky.sum()), "bias": float(d[sky].mean())})
    return out



def preset_file(tmp_path, fog_model: dict, **extra) -> str:
    d = json.loads((ROOT / "fogsim" / "presets" / "default.json").read_text())
    d["fog_model"] = fog_model
    d.update(extra)
    p = tmp_path / "vol.json"
    p.write_text(json.dumps(d))
    return str(p)


# ----------------------------------------------------------------------------- preset (fast)
def test_defaults_and_overrides():
    cfg = load_render_preset("default")
    assert volumetric_settings(cfg) is None  # Koschmieder stays the default
    v = volumetric_settings(load_render_preset("default", fog="volumetric"))
    assert v["medium"] == "full" and v["g"] == 0.85 and v["volume_bounces"] == 64 and v["layer_height_m"] == 100
    assert v["extent_m"] == 400.0  # max(400, 12/β_min) with β_min = 0.03
    v = volumetric_settings(load_render_preset("default", fog_medium="hybrid", levels="clear,0.005"))
    assert v["medium"] == "hybrid" and v["extent_m"] == 1400.0  # 12/0.005 = 2400, capped inside clip_end
    assert v["emission"] == "sky"  # resolved per frame: the frame's sky strength
    assert frame_volumetric(v, {"lighting": {"sky_strength": 0.01}})["emission"] == 0.01
    assert frame_volumetric({**v, "emission": 0.8}, {"lighting": {"sky_strength": 0.01}})["emission"] == 0.8
    with pytest.raises(ValueError, match="--fog: must be one of"):
        load_render_preset("default", fog="mie")
    with pytest.raises(ValueError, match="--fog-medium needs --fog volumetric"):
        load_render_preset("default", fog="koschmieder", fog_medium="ea")


@pytest.mark.parametrize("volumetric, message", [
    ({"medium": "fast"}, "fog_model.volumetric.medium: must be one of full, hybrid, ea"),
    ({"g": 1.0}, "fog_model.volumetric.g: must be a number in [-0.99, 0.99]"),
    ({"layer_height_m": 0}, "fog_model.volumetric.layer_height_m: must be a number in [1, 1000]"),
    ({"extent_m": 3000}, "fog_model.volumetric.extent_m: must be a number in [10, 1400]"),
    ({"volume_bounces": 6.5}, "fog_model.volumetric.volume_bounces: must be an integer"),
    ({"scatter_fraction": 2}, "fog_model.volumetric.scatter_fraction: must be a number in [0, 1]"),
    ({"emission": "moon"}, 'fog_model.volumetric.emission: must be "sky" or a number'),
    ({"exposure": "horizon"}, "fog_model.volumetric.exposure: must be one of none, auto"),
    ({"keep_linear": 1}, "fog_model.volumetric.keep_linear: must be true or false"),
    ({"bounces": 64}, "fog_model.volumetric: unknown key ['bounces']"),
    ({"domain": "world"}, "a world volume cannot be used for fog"),
])
def test_bad_volumetric_blocks_name_the_preset_and_key(tmp_path, volumetric, message):
    path = preset_file(tmp_path, {"kind": "volumetric", "volumetric": volumetric})
    with pytest.raises(InputError) as err:
        load_render_preset(path)
    assert str(err.value).startswith(f"{path}: ") and message in str(err.value)


def test_bad_kind_refused(tmp_path):
    with pytest.raises(InputError, match="fog_model.kind: must be one of koschmieder, volumetric"):
        load_render_preset(preset_file(tmp_path, {"kind": "pathtraced"}))


def test_world_volume_preset_refused_before_anything_is_written(tmp_path, capsys):
    from fogsim.cli import main

    path = preset_file(tmp_path, {"kind": "volumetric", "volumetric": {"domain": "world"}})
    out = tmp_path / "out"
    assert main(["render", "--preset", path, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "world volume cannot be used" in err and "sun" in err and "Traceback" not in err
    assert not out.exists()


def test_render_fog_bench_and_fog_flags_have_help_without_extras():
    from test_front_door import run_without_extras

    res = run_without_extras("bench", "render-fog", "--help")
    assert res.returncode == 0 and "--fog-samples" in res.stdout, res.stderr
    res = run_without_extras("render", "--help")
    assert res.returncode == 0, res.stderr
    assert "--fog {koschmieder,volumetric,scatter}" in res.stdout and "--fog-medium" in res.stdout


# ----------------------------------------------------------------------------- pure helpers (fast)
def test_auto_exposure_matches_the_median_luminance():
    rng = np.random.default_rng(1)
    clear = rng.uniform(0.05, 1.0, (20, 30, 3)).astype(np.float32)
    assert auto_exposure(clear, clear * 0.25) == pytest.approx(4.0, rel=1e-5)
    assert auto_exposure(clear, clear * 1e-6) == 64.0  # clipped
    assert auto_exposure(clear, np.zeros_like(clear)) == 1.0


def test_horizon_radiance_is_the_far_luminance_beyond_the_visibility():
    fog = np.full((4, 5, 3), 0.2, np.float32)
    fog[0] = 0.6
    ray = np.full((4, 5), 10.0, np.float32)
    ray[0] = np.inf
    ray[1, :2] = 60.0  # beyond ln(20)/0.06 = 49.9 m: counts, with value 0.2
    assert far_luminance(fog, ray, 0.06) == pytest.approx(0.6)
    assert far_luminance(fog, np.full((4, 5), 10.0, np.float32), 0.06) is None


def test_koschmieder_linear_and_bins_against_the_formula():
    clear = np.full((3, 4, 3), 0.1, np.float32)
    ray = np.array([[5.0, 10, 20, np.inf]] * 3, np.float32)
    k = koschmieder_linear(clear, ray, 0.1, 0.8)
    t = np.exp(-0.1 * ray)
    assert np.allclose(k[..., 0], 0.1 * t + 0.8 * (1 - t), atol=1e-6)
    bins = bin_bias(k - 0.5, ray, np.ones(ray.shape, bool))
    assert [b["pixels"] for b in bins] == [3, 3, 3, 3] and math.isinf(bins[-1]["from_m"])
    assert bins[-1]["bias"] == pytest.approx(0.3)


def test_linear_path_in_the_layout(tmp_path):
    assert DatasetLayout(tmp_path).linear("beta0.06", "000003") == tmp_path / "linear" / "beta0.06" / "000003.exr"


# ----------------------------------------------------------------------------- real Cycles

@pytest.mark.blender
def test_volumetric_run_keeps_labels_and_changes_images(tmp_path):
    runner("bpy")  # skips without the bpy module
    cmd = [sys.executable, "-m", "fogsim", "render", "--preset", "default", "--frames", "1", "--seed", "3",
           "--resolution", "96x64", "--samples", "8", "--quiet"]
    a, b = tmp_path / "A", tmp_path / "B"
    ra = run(cmd + ["--fog", "volumetric", "--out", str(a)])
    assert ra.returncode == 0, ra.stderr[-3000:]
    rb = run(cmd + ["--out", str(b)])
    assert rb.returncode == 0, rb.stderr[-3000:]
    da, db = dataset_digest(a), dataset_digest(b)
    assert da == db and any(k.startswith("labels/") for k in da) and "depth/000000.exr" in da
    clear = read_image(a / "images" / "clear" / "000000.png")
    assert np.array_equal(clear, read_image(b / "images" / "clear" / "000000.png"))
    for lv in LEVELS:
        va, kb = read_image(a / "images" / lv / "000000.png"), read_image(b / "images" / lv / "000000.png")
        assert np.abs(va.astype(int) - kb).mean() > 5 and np.abs(va.astype(int) - clear).mean() > 5
    meta = json.loads((a / "meta" / "000000.json").read_text())
    fog = meta["fog"]
    assert fog["model"] == "volumetric" and fog["medium"] == "full" and fog["g"] == 0.85 and fog["phase"] == "HG"
    assert fog["layer_height_m"] == 100 and fog["volume_bounces"] == 64 and fog["samples"] == 8
    assert fog["cycles"]["max_bounces"] >= 64 and fog["cycles"]["sample_clamp_indirect"] == 0
    assert fog["cycles"]["adaptive_sampling"] is False and fog["seed"] == meta["render"]["seed"]
    assert set(fog["exposure_factor"]) == set(LEVELS) and set(fog["horizon_radiance"]) == set(LEVELS)
    h = [fog["horizon_radiance"][lv] for lv in LEVELS]
    assert all(0 < x < 2 for x in h) and h[0] > h[-1]  # denser fog lit from above is darker
    assert meta["render"]["max_bounces"] == 2  # the clear render kept the draft quality
    assert json.loads((b / "meta" / "000000.json").read_text())["fog"]["model"] == "koschmieder"
    assert "fog_render" in meta["timings_s"] and not (a / "linear").exists()
    # per-object visibility per level, measured in each model's own foggy images
    kosch = json.loads((b / "meta" / "000000.json").read_text())["objects"]
    assert meta["objects"] and len(meta["objects"]) == len(kosch)
    for va, vb in zip((o["visibility"] for o in meta["objects"]), (o["visibility"] for o in kosch)):
        assert set(va) == {"clear", *LEVELS}
        assert all(va[lv]["transmission"] == vb[lv]["transmission"] for lv in LEVELS)  # same distance
    assert any(o["visibility"][lv]["contrast"] != k["visibility"][lv]["contrast"]
               for o, k in zip(meta["objects"], kosch) for lv in LEVELS)


EA_PRESET = {"style": "urban-canyon", "camera": "waymo-front", "resolution": [96, 64], "seed": 3,
             "fog": [0, 0.03, 0.12],
             "quality": {"samples": 16, "denoise": False, "adaptive_threshold": 0,
                         "bounces": {"total": 4, "diffuse": 2, "glossy": 2, "transmission": 0, "transparent": 0}},
             "fog_model": {"kind": "volumetric",
                           "volumetric": {"medium": "ea", "emission": 0.8, "denoise": False, "keep_linear": True,
                                          "exposure": "auto"}}}


@pytest.mark.blender
@pytest.mark.parametrize("kind", KINDS)
def test_ea_medium_equals_koschmieder_in_linear_light(kind, tmp_path):
    """Camera-only emission–absorption fog = I·t + A·(1 − t) with the clear render's I, the exact
    ray distance and A = the emission value, to ≤ 0.005 in every distance bin (interior pixels);
    and the fog renders' Cycles settings do not outlive them."""
    preset = tmp_path / "ea.json"
    preset.write_text(json.dumps(EA_PRESET))
    out = tmp_path / "ea"
    res = run(runner(kind)(SCRIPTS / "volumetric_job.py", str(out), str(preset)))
    line = next((ln for ln in res.stdout.splitlines() if ln.startswith("RESULT ")), None)
    assert res.returncode == 0 and line, res.stdout[-2000:] + res.stderr[-3000:]
    r = json.loads(line[len("RESULT "):])
    assert r["fog_cycles"]["volume_bounces"] == 64 and r["fog_cycles"]["max_bounces"] == 68
    assert r["fog_cycles"]["sample_clamp_indirect"] == 0 and r["fog_cycles"]["transparent_max_bounces"] == 8
    assert r["after"] == {"volume_bounces": 0, "max_bounces": 4, "sample_clamp_indirect": 10.0, "z": True,
                          "index": True, "persistent": False}  # the next clear render's settings
    meta = json.loads((out / "meta" / "000000.json").read_text())
    assert meta["fog"]["medium"] == "ea" and meta["fog"]["emission"] == 0.8
    K = Intrinsics.from_dict(meta["camera"]["intrinsics"])
    depth = read_depth_file(out / "depth" / "000000.exr")
    ray = planar_to_ray(depth, K)
    inner = interior_mask(depth, read_uint16_map(out / "masks" / "000000.png"))
    assert inner.mean() > 0.3
    clear = read_rgb_exr(out / "linear" / "clear" / "000000.exr")
    for key, beta in (("beta0.03", 0.03), ("beta0.12", 0.12)):
        fog = read_rgb_exr(out / "linear" / key / "000000.exr")
        assert np.abs(fog - clear).mean() > 0.05  # the fog is there
        bins = bin_bias(fog - koschmieder_linear(clear, ray, beta, 0.8), ray, inner)
        assert sum(b["pixels"] for b in bins) == inner.sum() and len(bins) >= 4
        worst = max(bins, key=lambda b: abs(b["bias"]))
        assert abs(worst["bias"]) <= 0.005, (r["blender"], key, bins)
        # exposure "auto": the 8-bit image is the linear render scaled to the clear render's median luminance
        factor = meta["fog"]["exposure_factor"][key]
        assert factor == pytest.approx(auto_exposure(clear, fog)) and factor != 1.0
        assert np.array_equal(read_image(out / "images" / key / "000000.png"), linear_to_srgb8(fog, factor))
    assert np.array_equal(read_image(out / "images" / "clear" / "000000.png"), linear_to_srgb8(clear))


@pytest.mark.blender
def test_addon_panel_renders_volumetric_fog(tmp_path):
    res = run(runner("bpy")(SCRIPTS / "addon_ops.py", str(tmp_path / "ds"), "volumetric", "hybrid"))
    assert res.returncode == 0, res.stderr[-3000:]
    line = next(ln for ln in res.stdout.splitlines() if ln.startswith("RESULT "))
    assert json.loads(line[len("RESULT "):])["status"].startswith("done: 1 frames")
    fog = json.loads((tmp_path / "ds" / "meta" / "000000.json").read_text())["fog"]
    assert fog["model"] == "volumetric" and fog["medium"] == "hybrid" and fog["scatter_fraction"] == 0.5
