"""The scatter fog model (fogsim.fog.scatter): Koschmieder when its terms are off, the PSF's
energy and width, glow only around emitters, the parameter file, and the front doors
(``fogsim fog --model scatter``, presets, ``fogsim fit-fog``, ``bench fog-physics`` columns)."""
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from fogsim.camera import Intrinsics
from fogsim.colour import from_float, full_scale, linear_to_srgb, luminance, srgb_to_linear
from fogsim.errors import InputError
from fogsim.fog.model import Fogger
from fogsim.fog.scatter import (
    EXPOSURE_GAIN_RANGE,
    KOSCHMIEDER,
    ScatterFogger,
    direct_planes,
    exposure_gain,
    load_params,
    load_params_file,
    median_luminance,
    scatter,
    shipped_params_path,
)
from fogsim.fog.scatter_optics import (
    elevation_sine,
    reduce_points,
    smooth_elevation_sine,
    splat,
    up_from_world_to_camera,
)
from fogsim.schema.scatter import TERMS, ScatterParamsFile, fit_space, parameter_table
from test_fog_physics_bench import bench_dir  # noqa: F401  (the fixture: stand-in fog-physics runs)

P = KOSCHMIEDER.with_values  # the model with these parameters (by path), every other term off
#: the parameter file fogsim ≤ 0.3 shipped (version 1: one flat object)
V1_FILE = Path(__file__).parent / "data" / "scatter_params_v1.json"

H, W = 60, 80
K = Intrinsics(fx=70.0, fy=70.0, cx=40.0, cy=30.0, width=W, height=H)


def street(seed=0, dtype=np.float32):
    """Random colours; sky in the top 12 rows, a ground 80 → 3 m below, a box at 15 m."""
    rng = np.random.default_rng(seed)
    img = rng.uniform(0.05, 0.9, (H, W, 3)).astype(np.float32)
    ray = np.full((H, W), np.inf, np.float32)
    ray[12:] = np.geomspace(80, 3, H - 12)[:, None]
    ray[20:35, 30:50] = 15.0
    if dtype == np.uint8:
        img = (img * 255 + 0.5).astype(np.uint8)
    return img, ray


@pytest.mark.parametrize("space", ["srgb", "linear"])
@pytest.mark.parametrize("params", [KOSCHMIEDER, "shipped-without-terms"])
def test_reduces_to_koschmieder_with_the_extra_terms_off(space, params):
    params = load_params().without(*TERMS) if params == "shipped-without-terms" else params
    img, ray = street()
    for beta in (0.0, 0.03, 0.12):
        got = ScatterFogger(img, ray, 200.0, space, params, K)(beta)
        ref = Fogger(img, ray, 200.0, space)(beta)
        assert np.abs(got - ref).max() < 2e-6
    img8, _ = street(dtype=np.uint8)
    got, ref = ScatterFogger(img8, ray, 255, space, params, K)(0.06), Fogger(img8, ray, 255, space)(0.06)
    assert np.abs(got.astype(int) - ref).max() <= 1 and (got == ref).mean() > 0.999  # float rounding only
    # and each term on its own changes the image
    for term, value in (("psf.forward", 0.5), ("direct.illumination", 10.0), ("airlight.level", 0.8),
                        ("airlight.elevation", 1.0), ("direct.exposure_key", 0.3), ("direct.flatten", 0.4),
                        ("airlight.sky_exponent", 0.5)):
        on = ScatterFogger(img, ray, 255, "linear", P({term: value}), K)(0.06)
        assert np.abs(on - Fogger(img, ray, 255, "linear")(0.06)).max() > 0.01, term


def test_psf_conserves_energy_and_has_the_asked_width():
    src = np.zeros((101, 121, 3), np.float32)
    src[50, 60] = (1.0, 2.0, 3.0)
    src[20, 15] = (0.5, 0.5, 0.5)  # near the border: mirrored back, not lost
    for sigma in (1.0, 3.0, 6.0, 12.0):
        out = splat(src, np.full(src.shape[:2], sigma, np.float32))
        assert out.sum(axis=(0, 1)) == pytest.approx(src.sum(axis=(0, 1)), rel=1e-4)
        point = np.zeros_like(src)
        point[50, 60] = 1.0
        one = splat(point, np.full(src.shape[:2], sigma, np.float32))[..., 0]
        x = np.arange(121) - 60
        var = float((one.sum(axis=0) * x ** 2).sum() / one.sum())
        assert math.sqrt(var) == pytest.approx(sigma, rel=0.25)  # layers 2× apart, three boxes ≈ a Gaussian
    # the model's scattered light: exactly the energy taken from the direct beam, m·I·(t_f − t)
    img, ray = street()
    ray[np.isinf(ray)] = 50.0
    p = P({"psf.forward": 0.6, "psf.spread": 0.2})
    f = ScatterFogger(img, ray, 255, "linear", p, K)
    s = f.scattered(0.06)
    lin = f.blend(0.0)  # β = 0: the image itself, in the blend space
    lost = lin * (np.exp(-0.06 * 0.4 * ray) - np.exp(-0.06 * ray))[..., None]
    assert s.sum(axis=(0, 1)) == pytest.approx(lost.sum(axis=(0, 1)), rel=1e-3)
    assert np.abs(s - lost).max() > 1e-3  # but moved


def test_the_exposure_key_makes_the_direct_term_independent_of_the_clear_exposure():
    img, ray = street()
    p = P({"direct.exposure_key": 0.25})
    lin = srgb_to_linear(img)
    darker = linear_to_srgb(0.4 * lin)                     # the same scene, exposed 0.4× in the clear image
    for space in ("linear", "srgb"):
        a, b = (ScatterFogger(x, ray, 255, space, p, K) for x in (img, darker))
        assert a.exposure_gain == pytest.approx(0.25 / float(np.median(luminance(lin)[np.isfinite(ray)])), rel=0.03)
        assert b.exposure_gain == pytest.approx(a.exposure_gain / 0.4, rel=0.03)
    a, b = (ScatterFogger(x, ray, 255, "linear", p, K).blend(0.06) for x in (img, darker))
    assert np.abs(a - b).max() < 0.01 * a.max()             # the fogged images agree (linear blend)
    off = ScatterFogger(darker, ray, 255, "linear", KOSCHMIEDER, K).blend(0.06)
    assert np.abs(off - a).max() > 0.05                     # Koschmieder keeps the darker exposure
    # with the day/night boundary set, a night image keeps its own exposure (lamps light it, not the fog)
    night = linear_to_srgb(0.01 * lin)
    assert ScatterFogger(night, ray, 255, "linear", P({"direct.exposure_key": 0.25}), K).exposure_gain > 4
    with_dark = ScatterFogger(night, ray, 255, "linear", P({"direct.exposure_key": 0.25, "night.luminance": 0.045}), K)
    assert with_dark.exposure_gain == pytest.approx(1.0, abs=1e-3)
    assert ScatterFogger(img, ray, 255, "linear", P({"direct.exposure_key": 0.25, "night.luminance": 0.045}),
                         K).exposure_gain == pytest.approx(ScatterFogger(img, ray, 255, "linear", p, K).exposure_gain,
                                                          rel=1e-3)   # a day image: unchanged
    # bounds: a black clear image is not scaled without limit; no non-sky pixel → no gain
    black = np.zeros_like(img)
    assert median_luminance(black, ray) == 0.0
    assert exposure_gain(0.0, 0.25, (1.0, 1.0, 1.0)) == EXPOSURE_GAIN_RANGE[1]
    sky = np.full(ray.shape, np.inf, np.float32)
    assert median_luminance(img, sky) is None and ScatterFogger(img, sky, 255, "linear", p, K).exposure_gain == 1.0


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize("space", ["linear", "srgb"])
def test_flatten_compresses_the_direct_term_around_its_median(dtype, space):
    img, _ = street()
    img = from_float(img * np.float32(full_scale(dtype)), dtype) if dtype != np.float32 else img
    plain = direct_planes(img, space)
    ref = float(np.median(plain[1]))
    flat = direct_planes(img, space, gain=2.0, flatten=0.5, reference=ref)
    for q, f in zip(plain, flat):
        want = 2.0 * ref * (q / ref) ** 0.5
        assert np.allclose(f, want, rtol=1e-4, atol=1e-6)
    assert np.std(np.log(flat[1])) == pytest.approx(0.5 * np.std(np.log(plain[1])), rel=1e-3)


def test_glow_appears_around_an_emitter_and_nowhere_else():
    img = np.full((90, 120, 3), 0.02, np.float32)
    ray = np.full((90, 120), 30.0, np.float32)
    ray[:20] = np.inf
    lamp = img.copy()
    lamp[44:47, 29:32] = 1.0  # saturated: a lamp
    base = P({"psf.forward": 0.5, "psf.spread": 0.002})  # σ = √(ρβℓ)·f ≈ 6 px: the PSF ends in 20 px
    glow = P({"psf.forward": 0.5, "psf.spread": 0.002, "glow.gain": 50.0})
    def fog(image, params):
        return ScatterFogger(image, ray, 255, "linear", params, K)(0.06)

    diff = fog(lamp, glow) - fog(lamp, base)
    y = diff.mean(axis=2)
    yy, xx = np.mgrid[:90, :120]
    r = np.hypot(xx - 30, yy - 45)
    assert y[(r > 2) & (r < 6)].mean() > 0.05  # a halo around the lamp
    assert np.abs(y[r > 40]).max() < 1e-3      # and nothing far from it (running-sum rounding only)
    assert (y >= -1e-3).all()
    # its own, narrower PSF keeps the same energy closer to the lamp
    def light(params):  # linear light, not clipped at white
        return ScatterFogger(lamp, ray, 255, "linear", params, K).blend(0.06)
    wide = light(glow) - light(base)
    narrow = light(P({"psf.forward": 0.5, "psf.spread": 0.002, "glow.gain": 50.0, "glow.spread": 0.0002})) - light(base)
    ring = (r > 2) & (r < 4)
    assert narrow.mean(axis=2)[ring].mean() > 1.5 * wide.mean(axis=2)[ring].mean()
    assert narrow.sum() == pytest.approx(wide.sum(), rel=0.02)
    # glow_dark: the same lamp glows in a dark image, not in a bright one (by day white saturates too)
    dark_glow = P({"psf.forward": 0.5, "psf.spread": 0.002, "glow.gain": 50.0, "night.luminance": 0.045})
    assert np.allclose(light(dark_glow), light(glow), atol=1e-4)    # median ≈ 0.0015 ≪ 0.045: weight ≈ 1
    day = np.full_like(lamp, 0.8)
    day[44:47, 29:32] = 1.0
    def day_light(params):
        return ScatterFogger(day, ray, 255, "linear", params, K).blend(0.06)
    assert np.abs(day_light(dark_glow) - day_light(base)).max() < 1e-5
    assert np.abs(day_light(glow) - day_light(base)).max() > 0.05
    # no emitter, no glow: the glow term changes nothing
    same = fog(img, glow) - fog(img, base)
    assert np.abs(same).max() < 1e-6
    # a saturated sky is not a lamp
    sky = img.copy()
    sky[:20] = 1.0
    same = fog(sky, glow) - fog(sky, base)
    assert np.abs(same).max() < 1e-6


def test_glow_comes_from_small_sources_and_its_tail_keeps_the_energy():
    img = np.full((90, 120, 3), 0.02, np.float32)
    ray = np.full((90, 120), 30.0, np.float32)
    both = img.copy()
    both[44:47, 29:32] = 1.0          # a lamp: 9 px, 0.08 % of the image
    both[60:90, 60:120] = 1.0         # a lit patch of road: 1800 px, 17 %
    lamp = img.copy()
    lamp[44:47, 29:32] = 1.0
    base = P({"psf.forward": 0.5, "psf.spread": 0.002})

    def light(image, params):
        return ScatterFogger(image, ray, 255, "linear", params, K).blend(0.06)
    capped = P({"psf.forward": 0.5, "psf.spread": 0.002, "glow.gain": 50.0, "glow.max_area": 0.01})
    # the patch does not glow, the lamp does, as it does alone
    assert np.allclose(light(both, capped) - light(both, base), light(lamp, capped) - light(lamp, base), atol=1e-5)
    uncapped = P({"psf.forward": 0.5, "psf.spread": 0.002, "glow.gain": 50.0})
    assert (light(both, uncapped) - light(both, base)).sum() > 10 * (light(both, capped) - light(both, base)).sum()
    # a cap above the patch's size lets it glow again
    assert np.allclose(light(both, capped.with_values({"glow.max_area": 0.5})), light(both, uncapped), atol=1e-6)
    # the tail: a share of the glow by the scene's wide PSF, the same energy, less of it near the lamp
    core = P({"psf.forward": 0.5, "psf.spread": 0.02, "glow.gain": 50.0, "glow.spread": 0.0002})
    tailed = core.with_values({"glow.tail": 0.5})
    g_core, g_tail = light(lamp, core) - light(lamp, base), light(lamp, tailed) - light(lamp, base)
    yy, xx = np.mgrid[:90, :120]
    r = np.hypot(xx - 30, yy - 45)
    assert g_tail.sum() == pytest.approx(g_core.sum(), rel=0.02)
    assert g_tail.mean(axis=2)[r < 3].mean() < 0.7 * g_core.mean(axis=2)[r < 3].mean()
    assert g_tail.mean(axis=2)[(r > 12) & (r < 30)].mean() > 2 * g_core.mean(axis=2)[(r > 12) & (r < 30)].mean()


def test_the_smooth_elevation_map_is_the_exact_one_to_1e5():
    big = Intrinsics.from_hfov(60.0, 1920, 1280)
    for up in (None, (0.0, -math.cos(0.2), math.sin(0.2)), (0.1, -0.99, 0.05)):
        exact = elevation_sine((1280, 1920), big, up)
        smooth = smooth_elevation_sine((1280, 1920), big, up)
        assert np.abs(smooth - exact).max() < 1e-5          # borders included: the grid reaches past them
    small = elevation_sine((H, W), K)                      # small images: the exact map
    assert np.array_equal(smooth_elevation_sine((H, W), K), small)


def test_sparse_points_are_reduced_as_cv2_inter_area_would():
    rng = np.random.default_rng(3)
    for (h, w), small in (((160, 240), (30, 20)), ((61, 97), (32, 20))):   # sizes that divide, and not
        ys, xs = rng.integers(0, h, 300), rng.integers(0, w, 300)
        v = rng.random((300, 3)).astype(np.float32)
        full = np.zeros((h, w, 3), np.float32)
        np.add.at(full, (ys, xs), v)
        want = cv2.resize(full, small, interpolation=cv2.INTER_AREA)
        assert np.allclose(reduce_points(v, ys, xs, (h, w), small), want, atol=1e-6)


def test_elevation_map_and_world_up():
    s = elevation_sine((H, W), K)
    assert abs(s[30, 40]) < 0.01 and s[0, 40] > 0.35 and s[-1, 40] < -0.35
    # integer pixel coordinates are pixel centres (docs/conventions.md): row 0 looks up by atan((0 − cy)/fy)
    assert s[0, 40] == pytest.approx(math.sin(math.atan(30 / 70)), abs=1e-6)
    assert s[30, 40] == pytest.approx(0.0, abs=1e-7)
    pitch = math.radians(10)  # camera pitched up: the centre looks 10° above the horizon
    up = (0.0, -math.cos(pitch), math.sin(pitch))
    assert elevation_sine((H, W), K, up)[30, 40] == pytest.approx(math.sin(pitch), abs=0.01)
    w2c = np.eye(4)
    w2c[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]  # world z up → camera −y (a level camera)
    assert up_from_world_to_camera(w2c) == (0.0, -1.0, 0.0)


def test_shipped_parameters_load_and_malformed_files_are_refused(tmp_path):
    doc = load_params_file()
    assert doc.version == 2 and doc.format == "fogsim-scatter-params"
    assert shipped_params_path().is_file() and load_params() == doc.parameters
    good = json.loads(shipped_params_path().read_text())
    psf = good["parameters"]["psf"]
    v1 = json.loads(V1_FILE.read_text())
    cases = {
        "range": ({**good, "parameters": {**good["parameters"], "psf": {**psf, "forward": 1.5}}},
                  "parameters.psf.forward"),
        "unknown": ({**good, "parameters": {**good["parameters"], "fwd": 0.1}}, "fwd"),
        "unknown in a block": ({**good, "parameters": {**good["parameters"], "psf": {**psf, "fwd": 0.1}}}, "fwd"),
        "version": ({**good, "version": 3}, "version"),
        "missing": ({k: v for k, v in good.items() if k != "parameters"}, "parameters"),
        "type": ({**good, "parameters": {**good["parameters"], "psf": {**psf, "spread": "wide"}}},
                 "parameters.psf.spread"),
        "v1 range": ({**v1, "parameters": {**v1["parameters"], "forward": 1.5}}, "parameters.psf.forward"),
        "v1 unknown": ({**v1, "parameters": {**v1["parameters"], "fwd": 0.1}}, "fwd"),
    }
    for name, (bad, where) in cases.items():
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(bad))
        with pytest.raises(InputError) as exc:
            load_params(path)
        line = str(exc.value)
        assert str(path) in line and where in line and "\n" not in line, line
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(InputError):
        load_params(tmp_path / "broken.json")
    with pytest.raises(ValueError, match="glow"):
        P({"glow.gain": -1.0})


def test_scatter_function_keeps_the_dtype_and_brightens_the_far_field_above_the_horizon():
    img, ray = street(dtype=np.uint8)
    as_float = (img / 255.0).astype(np.float32)
    for dtype, im in ((np.uint8, img), (np.uint16, img.astype(np.uint16) * 257), (np.float32, as_float)):
        out = scatter(im, ray, 0.06, intrinsics=K)
        assert out.dtype == dtype and out.shape == im.shape
    p = P({"airlight.level": 0.8, "airlight.elevation": 2.0})
    out = scatter(img, ray, 0.12, airlight=150, params=p, intrinsics=K).astype(float).mean(axis=2)
    assert out[2].mean() > out[11].mean() + 5  # the sky gets brighter with elevation


def test_fog_cli_with_the_scatter_model(folder_dataset, tmp_path, capsys):
    from fogsim.cli import main
    from fogsim.io.images import read_image

    ds = folder_dataset
    base = ["fog", "--input", str(ds / "images"), "--depth", str(ds / "depth"), "--intrinsics", str(ds / "K.json"),
            "--levels", "0.06", "--quiet"]
    assert main([*base, "--out", str(tmp_path / "k")]) == 0
    assert main([*base, "--model", "scatter", "--out", str(tmp_path / "s")]) == 0
    side = json.loads((tmp_path / "s" / "beta0.06" / "a.json").read_text())
    assert side["model"] == "scatter" and side["blend_space"] == "linear"
    run = json.loads((tmp_path / "s" / "fogsim_run.json").read_text())
    assert run["parameters"]["scatter_params"] == load_params().to_dict()
    a, b = (read_image(tmp_path / d / "beta0.06" / "a.png") for d in ("k", "s"))
    assert np.abs(a.astype(int) - b).mean() > 1
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "fogsim-scatter-params", "version": 1, "parameters": {"forward": 2}}))
    capsys.readouterr()
    assert main([*base, "--model", "scatter", "--scatter-params", str(bad), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.json" in err[0] and "forward" in err[0]
    assert not (tmp_path / "x").exists()
    assert main([*base, "--model", "scatter", "--extended", "--out", str(tmp_path / "y")]) == 2


def test_preset_kind_scatter_is_declared_and_fogs_a_rendered_frame(tmp_path):
    from fogsim.render.fog_settings import fog_settings
    from fogsim.render.preset import load_render_preset

    config = load_render_preset("default", frames=1, resolution="64x48", levels="0,0.06", fog="scatter")
    fs = fog_settings(config)
    assert fs.kind == "scatter" and fs.blend_space == "linear" and fs.scatter_file is None
    from fogsim.dataset.layout import DatasetLayout
    from fogsim.render.frame import DescribedFrame, FramePasses, commit_frame

    rng = np.random.default_rng(0)
    rgb = np.clip(rng.normal(0.25, 0.05, (48, 64, 3)), 0, 1).astype(np.float32)
    depth = np.vstack([np.full((10, 64), np.inf, np.float32),
                       np.tile(np.geomspace(60, 5, 38)[:, None], (1, 64)).astype(np.float32)])
    meta = commit_frame(DatasetLayout(tmp_path / "ds"), config, DescribedFrame.of(config, 0),
                        FramePasses(rgb, depth, np.zeros((48, 64), np.uint16)))
    assert meta["fog"]["model"] == "scatter" and meta["fog"]["scatter_params"] == load_params().to_dict()


def test_fog_physics_on_a_tiny_night_frame_has_every_new_column():
    from fogsim.bench.fog_physics_report import markdown
    from fogsim.fog.physics import (
        BIN_NAMES,
        Comparison,
        default_models,
        koschmieder_linear,
        noisy_render,
        scatter_model,
    )

    img, ray = street()
    img *= 0.1  # night
    img[40:43, 10:13] = 1.0  # a lamp on the ground, 15–20 m away
    mask = np.zeros((H, W), np.uint16)
    mask[20:35, 30:50] = 1
    clear = img ** 2.2
    truth = scatter_model(P({"psf.forward": 0.5, "psf.spread": 0.01, "glow.gain": 20.0}))
    rng = np.random.default_rng(1)
    renders = {b: tuple(noisy_render(0.3 * koschmieder_linear(clear, ray, b, truth, K), 0.05, rng) for _ in range(2))
               for b in (0.03, 0.09)}
    comp = Comparison(models=default_models(scatter=truth.params))
    comp.add_frame("night", clear, ray, mask, renders, camera=K, night=True)
    result = comp.result()
    assert "scatter" in result["models"]
    for key in ("0.03", "0.09"):
        pb = result["per_beta"][key]
        for exposure in ("raw", "normalised", "far"):
            cols = pb["models"]["scatter"][exposure]
            assert {"all", "sky", *BIN_NAMES} <= set(cols) and cols["all"]["rms"] is not None
        assert pb["objects_summary"]["scatter"]["objects"] >= 0
        assert "scatter" in pb["objects"][0]["ratio_pt_k"]
        glow = pb["glow"]
        assert glow["lamps"] == 1 and len(glow["pt"]) == len(glow["rings_px"])
        # the stand-in renders are the scatter model: it matches their glow, Koschmieder does not
        near_pt, near_s, near_k = glow["pt"][1], glow["models"]["scatter"][1], glow["models"]["linear"][1]
        assert abs(near_s - near_pt) < abs(near_k - near_pt)
    md = markdown(result)
    assert "| scatter |" in md and "Glow around the lamps" in md and "| path-traced |" in md
    assert comp.panels["night"].shape[1] > 9 * W  # clear | K lin | K srgb | scatter | PT… | error maps


def test_fit_fog_and_the_bench_column_on_fog_physics_runs(bench_dir, tmp_path, capsys):  # noqa: F811
    """The stand-in "path-traced" runs are linear Koschmieder × 0.35 plus noise: the fit must not
    do worse than Koschmieder, write a file that loads, and record what it was fitted on."""
    from fogsim.bench.fog_physics import analyse
    from fogsim.cli import main

    out = tmp_path / "params.json"
    assert main(["fit-fog", str(bench_dir), "--out", str(out), "--quiet"]) == 0
    said = capsys.readouterr().out.strip().splitlines()
    assert len(said) == 1 and "fit-fog: RMS normalised" in said[0]
    doc = load_params_file(out)
    assert doc.fitted_on.after <= doc.fitted_on.before + 1e-6 and doc.fitted_on.betas == [0.06, 0.12]
    assert doc.fitted_on.frames == 1 and doc.fitted_on.resolution == "96x64"
    assert load_params(out) == doc.parameters
    result = analyse(bench_dir)
    assert "scatter" in result["models"] and "| scatter |" in (bench_dir / "report" / "fog_physics.md").read_text()
    # the bench compares a new fit before it ships: --scatter-params
    def scatter_rms(doc):
        return [b["models"]["scatter"]["normalised"]["all"]["rms"] for b in doc["per_beta"].values()]
    shipped = scatter_rms(result)
    assert main(["bench", "fog-physics", "--out", str(bench_dir), "--analyse-only", "--scatter-params", str(out),
                 "--quiet"]) == 0
    fitted = scatter_rms(json.loads((bench_dir / "report" / "fog_physics.json").read_text()))
    assert fitted != shipped
    assert main(["bench", "fog-physics", "--out", str(bench_dir), "--analyse-only", "--scatter-params",
                 str(tmp_path / "missing.json")]) == 2


def test_shipped_parameters_are_fitted_and_say_on_what():
    """The shipped file is the output of ``fogsim fit-fog`` on rendered frames: every term it fits
    is recorded with the scenes, seeds, β and resolution it was fitted on."""
    doc = load_params_file()
    fit = doc.fitted_on
    assert "PLACEHOLDER" not in shipped_params_path().read_text() and "not fitted" not in doc.note
    assert fit.frames >= 2 and fit.runs and fit.styles and fit.seeds and fit.resolution
    assert set(fit.betas) == {0.03, 0.06, 0.09, 0.12} and fit.samples > 0 and "day" in fit.times_of_day
    for run in fit.runs:
        assert run.style and run.seed is not None and run.frames >= 1 and run.time_of_day in ("day", "night")
    assert fit.after < fit.before  # the fit beats Koschmieder on what it was fitted on
    p = load_params()
    assert p.psf.forward > 0 and p.psf.spread > 0 and p != KOSCHMIEDER


def test_fade_scales_the_airlight_by_exp_minus_lambda_beta():
    img, ray = street()
    base = P({"airlight.level": 0.8})
    for beta in (0.03, 0.12):
        plain = ScatterFogger(img, ray, 255, "linear", base, K).blend(beta)
        faded = ScatterFogger(img, ray, 255, "linear", P({"airlight.level": 0.8, "airlight.fade": 5.0}), K).blend(beta)
        t = np.exp(-beta * ray)[..., None]
        lin = ScatterFogger(img, ray, 255, "linear", base, K).blend(0.0)  # the image in linear light
        air_plain, air_faded = plain - lin * t, faded - lin * t
        assert np.allclose(air_faded, air_plain * math.exp(-5.0 * beta), atol=1e-5)


def test_splat_on_reduced_copies_matches_full_size_layers():
    """Wide PSF layers are blurred on reduced copies: the light's sum is kept exactly and the
    result stays within 2 % of the source's peak of the full-size layers (the tolerance docs/speed.md states)."""
    import fogsim.fog.scatter_optics as S

    rng = np.random.default_rng(3)
    src = rng.uniform(0, 1, (80, 120, 3)).astype(np.float32)
    sigma = np.tile(np.geomspace(1.0, 60.0, 120, dtype=np.float32), (80, 1))
    fast = splat(src, sigma)
    old = S.REDUCE_ABOVE
    try:
        S.REDUCE_ABOVE = 1e9  # every layer at full size
        full = splat(src, sigma)
    finally:
        S.REDUCE_ABOVE = old
    assert fast.sum(axis=(0, 1)) == pytest.approx(full.sum(axis=(0, 1)), rel=1e-4)
    assert np.abs(fast - full).max() < 0.02 * float(src.max())


def test_bench_fog_has_the_scatter_rows_and_their_ratio(capsys):
    from fogsim.cli import main

    assert main(["bench", "fog", "--repeat", "1", "--size", "96x64"]) == 0
    out = capsys.readouterr().out
    assert "scatter, sRGB blend" in out and "scatter, linear blend" in out
    assert "scatter ≤ 3× Koschmieder (sRGB)" in out
    last = out.strip().splitlines()[-1]
    assert last.startswith("bench fog:") and "× Koschmieder per level (sRGB" in last


def test_fog_physics_pools_folders_and_reports_the_targets(bench_dir, tmp_path):  # noqa: F811
    import shutil

    from fogsim.bench.fog_physics import analyse
    from fogsim.bench.fog_physics_report import target_summary

    other = tmp_path / "other"
    shutil.copytree(bench_dir, other, ignore=shutil.ignore_patterns("report"))
    result = analyse(bench_dir, pool=[other])
    assert len(result["frames"]) == 2 and result["frames"][0].startswith(bench_dir.name + "-")
    assert result["pooled_folders"] == [str(bench_dir), str(other)]
    rows = target_summary(result)
    assert [r["beta"] for r in rows] == [0.06, 0.12] and result["targets"] == rows
    assert all({"normalised", "far", "contrast", "rms_met", "contrast_met"} <= set(r) for r in rows)
    assert "Scatter against Koschmieder" in (bench_dir / "report" / "fog_physics.md").read_text()


@pytest.mark.slow  # the glow's grid search: about 20 s
def test_glow_only_refit_finds_the_lamps_glow_and_keeps_the_rest():
    """Stand-in night renders made by the scatter model with a known glow (small lamps glow, a lit patch
    of road does not): the glow fit lowers the night objective, turns the glow on, caps the lamps'
    size, and keeps every day parameter."""
    from fogsim.bench.fit_fog import fit_glow, frame_levels
    from fogsim.fog.physics import koschmieder_linear, noisy_render, scatter_model

    img, ray = street()
    img *= 0.05
    img[40:43, 10:13] = 1.0          # a lamp
    img[50:60, 40:80] = 1.0          # a lit patch of road (8 % of the image)
    clear = img ** 2.2
    day = P({"psf.forward": 0.4, "psf.spread": 1.0, "airlight.level": 0.9})
    truth = scatter_model(day.with_values({"glow.gain": 30.0, "glow.spread": 0.003, "glow.max_area": 0.02,
                                           "night.luminance": 0.045}))
    rng = np.random.default_rng(2)
    renders = {b: tuple(noisy_render(0.3 * koschmieder_linear(clear, ray, b, truth, K), 0.02, rng) for _ in range(2))
               for b in (0.06, 0.12)}
    data = {"clear_linear": clear, "distance": ray, "mask": np.zeros((H, W), np.uint16), "renders": renders,
            "camera": K, "up": None, "night": True}
    params, glow = fit_glow(day, [data], frame_levels(data), log=lambda *a: None)
    assert glow["after"] < glow["before"]
    assert params.glow.gain > 1 and 0 < params.glow.max_area < 0.08
    off = {"glow.gain": 0.0, "glow.spread": 0.0, "glow.max_area": 0.0, "glow.tail": 0.0, "night.luminance": 0.0}
    assert params.with_values(off) == day


def test_glow_only_refit_needs_night_runs(bench_dir, tmp_path, capsys):  # noqa: F811
    from fogsim.cli import main

    out = tmp_path / "glow.json"
    capsys.readouterr()
    assert main(["fit-fog", str(bench_dir), "--glow-only", "--out", str(out)]) == 2
    assert "no night frame" in capsys.readouterr().err and not out.exists()


def test_every_parameter_is_declared_once_in_blocks():
    p = load_params()
    assert set(p.model_dump()) == {"psf", "direct", "airlight", "glow", "night"}
    assert len(TERMS) == 9 and all(KOSCHMIEDER.without(t) == KOSCHMIEDER for t in TERMS)
    assert p.without(*TERMS).glow.gain == 0 and p.without(*TERMS).airlight.level == 1.0
    with pytest.raises(ValueError, match="not model terms"):
        p.without("glow.threshold")
    day = list(fit_space("day"))
    assert day[0] == "direct.exposure_key" and "psf.spread" in day and "glow.gain" not in day
    assert set(fit_space("night")) == {"glow.gain", "glow.tail", "glow.spread", "glow.max_area"}
    import fogsim.fog.scatter as module
    from fogsim.schema.scatter import leaves

    for path, _ in leaves():  # the module's formula names every parameter by its path
        assert f"``{path}``" in module.__doc__, path


def test_the_version_1_file_still_loads_into_the_blocks(tmp_path):
    doc = ScatterParamsFile.model_validate(json.loads(V1_FILE.read_text()))
    assert doc.version == 2 and doc.parameters == load_params()  # the shipped v2 file holds the same values
    flat = json.loads(V1_FILE.read_text())["parameters"]
    assert doc.parameters.glow.gain == flat["glow"] and doc.parameters.night.luminance == flat["glow_dark"]
    assert load_params(V1_FILE) == load_params()


def test_the_docs_table_is_the_declaration():
    page = (Path(__file__).parents[1] / "docs" / "fog-physics.md").read_text()
    assert parameter_table() in page, "docs/fog-physics.md: paste fogsim.schema.scatter.parameter_table()"
