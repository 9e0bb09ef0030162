"""Cheap volumetric fog: fog levels rendered at a fraction of the size, rebuilt from the clear render.

The pure rebuild (:mod:`fogsim.render.fog_rebuild`) is checked against images made by its own
model (F = α·C·t + A·(1 − t), reduced by area averaging as Cycles' pixel filter does) and against
plain bilinear upsampling; the Blender test renders the camera-only emission–absorption medium
(Koschmieder in linear light, ``test_volumetric.py``) at ``resolution_scale`` 0.5 and checks the
rebuilt full-size image against the law per distance bin.
"""
import json

import cv2
import numpy as np
import pytest

from fogsim.camera import Intrinsics, planar_to_ray
from fogsim.errors import InputError
from fogsim.fog.model import transmission
from fogsim.fog.physics import interior_mask
from fogsim.io.depth_files import read_depth_file, read_uint16_map
from fogsim.io.exr import read_rgb_exr
from fogsim.render.fog_rebuild import fit_fog_terms, low_size, rebuild
from fogsim.render.fog_settings import volumetric_settings
from fogsim.render.preset import load_render_preset
from test_blender import SCRIPTS, run, runner
from test_volumetric import EA_PRESET, bin_bias, koschmieder_linear


def scene(H=96, W=144, beta=0.06, alpha=1.0, seed=0):
    """A clear image with texture and an object in front of a receding ground and sky; its fog
    image by the model with a row-dependent airlight; the ray distance."""
    rng = np.random.default_rng(seed)
    clear = cv2.GaussianBlur(rng.uniform(0, 1, (H, W, 3)).astype(np.float32), (0, 0), 1.0)
    ray = np.full((H, W), np.inf, np.float32)
    ray[H // 3:] = np.linspace(4, 90, H - H // 3)[:, None]
    ray[H // 2:H - 10, W // 3:W // 2] = 11.0  # a box 11 m away, sharp edges
    t = transmission(ray, beta)[..., None]
    airlight = (0.7 + 0.25 * np.linspace(1, 0, H)[:, None, None]) * np.ones((1, W, 3), np.float32)
    return clear, ray, (alpha * clear * t + airlight * (1 - t)).astype(np.float32)


def test_transmittance_and_sizes():
    ray = np.array([[0.0, 10.0, np.inf]], np.float32)
    assert np.allclose(transmission(ray, 0.1), [[1.0, np.exp(-1.0), 0.0]])
    assert low_size(640, 426, 0.5) == (320, 213) and low_size(96, 64, 0.25) == (24, 16)


def test_fit_recovers_alpha_and_airlight_of_uniform_windows():
    rng = np.random.default_rng(1)
    clear = rng.uniform(0.1, 1, (20, 30, 3)).astype(np.float32)
    t = rng.uniform(0.2, 0.9, (20, 30)).astype(np.float32)
    fog = 1.4 * clear * t[..., None] + 0.6 * (1 - t[..., None])
    alpha, airlight = fit_fog_terms(clear, t, fog)
    inner = (slice(3, -3), slice(3, -3))
    assert np.allclose(alpha[inner], 1.4, atol=0.02) and np.allclose(airlight[inner], 0.6, atol=0.02)


@pytest.mark.parametrize("scale", [0.5, 0.25])
@pytest.mark.parametrize("alpha", [1.0, 1.3])
def test_rebuild_beats_bilinear_upsampling(scale, alpha):
    clear, ray, full = scene(alpha=alpha)
    w, h = low_size(full.shape[1], full.shape[0], scale)
    low = cv2.resize(full, (w, h), interpolation=cv2.INTER_AREA)
    got = rebuild(clear, low, ray, 0.06)
    bilinear = cv2.resize(low, (full.shape[1], full.shape[0]), interpolation=cv2.INTER_LINEAR)
    err, base = np.sqrt(np.mean((got - full) ** 2)), np.sqrt(np.mean((bilinear - full) ** 2))
    assert got.shape == full.shape and got.dtype == np.float32
    assert err < 0.006 and err < base / 3, (err, base)


def test_rebuild_of_a_full_size_render_is_the_render():
    clear, ray, full = scene()
    assert np.array_equal(rebuild(clear, full, ray, 0.06), full)


def test_resolution_scale_is_a_checked_preset_key(tmp_path):
    assert volumetric_settings(load_render_preset("default", fog="volumetric"))["resolution_scale"] == 1.0
    p = tmp_path / "bad.json"
    p.write_text(json.dumps({**EA_PRESET, "fog_model": {"kind": "volumetric", "volumetric": {"resolution_scale": 2}}}))
    with pytest.raises(InputError, match="resolution_scale"):
        load_render_preset(str(p))


@pytest.mark.blender
def test_half_size_ea_fog_rebuilt_equals_koschmieder(tmp_path):
    """The EA medium rendered at half width and height, rebuilt: Koschmieder in linear light to
    ≤ 0.01 in every distance bin of the interior pixels, at full size; meta records the scale."""
    preset = tmp_path / "ea_half.json"
    vol = {**EA_PRESET["fog_model"]["volumetric"], "resolution_scale": 0.5}
    preset.write_text(json.dumps({**EA_PRESET, "fog_model": {"kind": "volumetric", "volumetric": vol}}))
    out = tmp_path / "ea"
    res = run(runner("bpy")(SCRIPTS / "volumetric_job.py", str(out), str(preset)))
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    meta = json.loads((out / "meta" / "000000.json").read_text())
    assert meta["fog"]["resolution_scale"] == 0.5 and meta["fog"]["rebuild_rule"].startswith("F = α·C·t")
    assert meta["fog"]["cycles"]["resolution_percentage"] == 50
    depth = read_depth_file(out / "depth" / "000000.exr")
    ray = planar_to_ray(depth, Intrinsics.from_dict(meta["camera"]["intrinsics"]))
    inner = interior_mask(depth, read_uint16_map(out / "masks" / "000000.png"))
    clear = read_rgb_exr(out / "linear" / "clear" / "000000.exr")
    for key, beta in (("beta0.03", 0.03), ("beta0.12", 0.12)):
        fog = read_rgb_exr(out / "linear" / key / "000000.exr")
        assert fog.shape == clear.shape
        bins = bin_bias(fog - koschmieder_linear(clear, ray, beta, 0.8), ray, inner)
        worst = max(bins, key=lambda b: abs(b["bias"]))
        assert abs(worst["bias"]) <= 0.01, (key, bins)


def test_fog_scale_flag_sets_the_key_and_implies_volumetric():
    cfg = load_render_preset("default", fog_scale=0.5)
    assert cfg.fog_model["kind"] == "volumetric" and volumetric_settings(cfg)["resolution_scale"] == 0.5
    with pytest.raises(ValueError, match="--fog-scale needs --fog volumetric"):
        load_render_preset("default", fog="koschmieder", fog_scale=0.5)
    with pytest.raises(ValueError, match="--fog-scale"):
        load_render_preset("default", fog_scale=0.05)
