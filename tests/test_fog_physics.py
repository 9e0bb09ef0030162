"""The Koschmieder-vs-path-traced comparison on synthetic "path-traced" renders whose answer is known."""
import json
import math

import numpy as np
import pytest

from fogsim.bench.fog_physics_report import markdown, write_report
from fogsim.fog.physics import (
    BIN_NAMES,
    Comparison,
    horizon_radiance,
    interior_mask,
    koschmieder_linear,
    koschmieder_model,
    noisy_render,
)

H, W, SKY = 100, 90, 15
BETA = 0.06


def srgb(x):
    x = np.clip(np.asarray(x, np.float64), 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def lin(x):
    x = np.asarray(x, np.float64)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def scene(seed=0):
    """Sky rows 0–14 (inf); a ground whose distance falls from 100 m at row 15 to 3 m at the bottom
    (exponentially: neighbouring rows 4.3 % apart); three boxes: black at 9.5 m, light at 30 m, red at 60 m."""
    rng = np.random.default_rng(seed)
    rgb = np.clip(rng.normal(0.2, 0.03, (H, W, 3)), 0, 1).astype(np.float32)
    ray = np.full((H, W), np.inf, np.float32)
    rows = np.arange(SKY, H)
    ray[SKY:] = (3 * (100 / 3) ** ((H - 1 - rows) / (H - 1 - SKY)))[:, None]
    rgb[:SKY] = 1.0
    mask = np.zeros((H, W), np.uint16)
    for oid, (x0, d, colour) in enumerate(((5, 9.5, (0.02,) * 3), (35, 30.0, (0.6,) * 3),
                                          (65, 60.0, (0.5, 0.05, 0.05))), start=1):
        mask[20:40, x0:x0 + 20] = oid
        ray[20:40, x0:x0 + 20] = d
        rgb[20:40, x0:x0 + 20] = colour
    return rgb, ray, mask


def test_interior_mask_by_hand():
    ray = np.full((30, 30), 50.0, np.float32)
    mask = np.zeros((30, 30), np.uint16)
    ray[10:20, 10:20], mask[10:20, 10:20] = 10.0, 4
    inner = interior_mask(ray, mask)
    assert (~inner).sum() == (12 * 12 - 8 * 8)  # the object's edge ring inside (36) and outside (44)
    assert inner[11:19, 11:19].all() and not inner[10, 10:20].any() and not inner[9, 9:21].any()
    ramp = np.tile(np.array([10.0, 10.4, 10.8, 11.5, 11.5], np.float32), (5, 1))  # +4 %, +3.8 %, +6.5 %
    keep = interior_mask(ramp, np.zeros((5, 5), np.uint16))
    assert keep[:, 1].all() and not keep[:, 2].any() and not keep[:, 3].any() and keep[:, 4].all()
    sky = interior_mask(np.full((4, 4), np.inf), np.zeros((4, 4), np.uint16))
    assert sky.all()


def test_koschmieder_exact_plus_independent_noise_has_no_bias_and_no_noise_free_error():
    rgb, ray, mask = scene()
    model = koschmieder_model("linear")
    k = koschmieder_linear(rgb, ray, BETA, model)
    f1, f2 = (noisy_render(k, 0.1, np.random.default_rng(s)) for s in (1, 2))
    comp = Comparison(models=(model,))
    comp.add_frame("f", rgb, ray, mask, {BETA: (f1, f2)})
    res = comp.result()["per_beta"]["0.06"]["models"]["linear"]
    for exposure in ("raw", "normalised"):
        for key in ("all", *BIN_NAMES):
            cell = res[exposure][key]
            assert cell["values"] > 0, key
            assert abs(cell["bias"]) < 0.01, (exposure, key, cell)
            assert cell["rms"] < 0.3 * cell["rms_with_noise"], (exposure, key, cell)
            assert cell["noise"] == pytest.approx(cell["rms_with_noise"] * math.sqrt(2), rel=0.2)
    assert res["raw"]["all"]["rms_with_noise"] > 0.02  # the noise is there, and not counted as error


def test_a_known_exposure_factor_is_recovered_by_normalisation():
    rgb, ray, mask = scene()
    model = koschmieder_model("linear")
    k = koschmieder_linear(rgb, ray, BETA, model)
    comp = Comparison(models=(model,))
    comp.add_frame("f", rgb, ray, mask, {BETA: (0.3 * k, 0.3 * k)})
    out = comp.result()["per_beta"]["0.06"]
    assert out["horizon"]["luminance_mean"] == pytest.approx(0.3, rel=1e-5)
    norm, raw = out["models"]["linear"]["normalised"], out["models"]["linear"]["raw"]
    for key in ("all", "sky", *BIN_NAMES):
        assert abs(norm[key]["bias"]) < 1e-5 and norm[key]["rms"] < 1e-3, key
    inner = interior_mask(ray, mask) & np.isfinite(ray)
    assert raw["all"]["bias"] == pytest.approx(-0.7 * k[inner].mean(), rel=1e-4)
    assert raw["all"]["rms"] == pytest.approx(0.7 * np.sqrt((k[inner] ** 2).mean()), rel=1e-4)
    assert raw["sky"]["bias"] == pytest.approx(-0.7, rel=1e-5)
    # "far": the median beyond the visibility (sky and fogged-out ground, K ≈ A there) becomes A
    assert out["far_luminance_mean"] == pytest.approx(0.3, rel=0.03)
    assert out["models"]["linear"]["far"]["all"]["rms"] < 0.03


def test_constant_offset_and_the_srgb_model_by_hand():
    """A uniform grey wall at 15 m under a sky: PT = linear Koschmieder + 0.02 on the wall. The linear
    model errs by +0.02 exactly; the sRGB model by K_lin + 0.02 − lin(srgb(I)·t + 1 − t)."""
    rgb = np.full((40, 40, 3), 0.2, np.float32)
    ray = np.full((40, 40), 15.0, np.float32)
    rgb[:10], ray[:10] = 1.0, np.inf
    mask = np.zeros((40, 40), np.uint16)
    t = math.exp(-BETA * 15.0)
    k_lin = 0.2 * t + (1 - t)
    pt = np.full((40, 40, 3), k_lin + 0.02, np.float32)
    pt[:10] = 1.0
    comp = Comparison(models=(koschmieder_model("linear"), koschmieder_model("srgb")))
    comp.add_frame("wall", rgb, ray, mask, {BETA: (pt, pt)})
    m = comp.result()["per_beta"]["0.06"]["models"]
    assert m["linear"]["raw"]["10-20 m"]["bias"] == pytest.approx(0.02, abs=1e-5)
    assert m["linear"]["raw"]["10-20 m"]["rms"] == pytest.approx(0.02, abs=1e-5)
    assert m["linear"]["raw"]["sky"]["bias"] == pytest.approx(0.0, abs=1e-6)
    k_srgb = float(lin(srgb(0.2) * t + (1 - t)))
    assert m["srgb"]["raw"]["10-20 m"]["bias"] == pytest.approx(k_lin + 0.02 - k_srgb, abs=1e-5)
    assert m["linear"]["raw"]["0-10 m"]["values"] == 0 and m["linear"]["raw"]["0-10 m"]["bias"] is None


def test_per_object_contrast_against_transmission():
    """PT = linear Koschmieder: every object's C_PT / C_K = 1 and, for the black box against the white
    sky, C_PT / C0 = t; the sRGB model keeps more contrast, so PT/K(srgb) < 1."""
    rgb, ray, mask = scene()
    k = koschmieder_linear(rgb, ray, 0.12, koschmieder_model("linear"))
    comp = Comparison(models=(koschmieder_model("linear"), koschmieder_model("srgb")))
    comp.add_frame("f", rgb, ray, mask, {0.12: (k, k)}, classes={1: "car", 2: "van", 3: "bus"})
    objs = {o["id"]: o for o in comp.result()["per_beta"]["0.12"]["objects"]}
    assert set(objs) == {1, 2, 3} and objs[1]["class"] == "car"
    for o in objs.values():
        assert o["transmission"] == pytest.approx(math.exp(-0.12 * o["distance_m"]), rel=1e-6)
        assert o["contrast_pt"] / o["contrast_clear"] == pytest.approx(o["transmission"], rel=1e-3, abs=1e-5)
    for o in (objs[1], objs[2]):
        assert o["ratio_pt_k"]["linear"] == pytest.approx(1.0, abs=1e-4)
    assert objs[3]["ratio_pt_k"]["linear"] is None  # 60 m at 0.12/m: no contrast left to divide by
    black = objs[1]
    assert black["distance_m"] == pytest.approx(9.5) and black["contrast_clear"] == pytest.approx(0.98, abs=1e-3)
    assert black["ratio_pt_k"]["srgb"] < 1.0
    summary = comp.result()["per_beta"]["0.12"]["objects_summary"]
    assert summary["linear"]["objects"] == 1 and summary["linear"]["median_ratio_pt_k"] == pytest.approx(1.0, abs=1e-4)
    only = Comparison(models=(koschmieder_model("linear"),))  # classes name the objects of the table
    only.add_frame("f", rgb, ray, mask, {0.12: (k, k)}, classes={2: "van"})
    assert [o["id"] for o in only.result()["per_beta"]["0.12"]["objects"]] == [2]


def test_horizon_is_the_lowest_sky_and_its_profile():
    img = np.zeros((20, 10, 3), np.float32)
    img[:10] = np.linspace(2.0, 1.0, 10)[:, None, None]  # brighter higher up
    ray = np.full((20, 10), 5.0, np.float32)
    ray[:10] = np.inf
    hz = horizon_radiance(img, ray, np.zeros((20, 10), np.uint16))
    assert hz["rows"] == [9, 9] and hz["luminance"] == pytest.approx(1.0, rel=1e-5)
    assert hz["mean_sky_over_horizon"] == pytest.approx(1.5, rel=1e-5)
    assert hz["profile_top_to_bottom"][0] > hz["profile_top_to_bottom"][-1]
    assert horizon_radiance(img, np.full((20, 10), 5.0), np.zeros((20, 10), np.uint16)) is None


def test_report_files(tmp_path):
    rgb, ray, mask = scene()
    comp = Comparison()
    for beta in (0.03, 0.12):
        k = koschmieder_linear(rgb, ray, beta, koschmieder_model("linear"))
        comp.add_frame(f"b{beta}", rgb, ray, mask, {beta: (noisy_render(0.4 * k, 0.05, np.random.default_rng(1)),
                                                           noisy_render(0.4 * k, 0.05, np.random.default_rng(2)))})
    result = write_report(comp, tmp_path)
    assert [m for m in result["models"]] == ["srgb", "linear", "srgb+box19", "linear+box19", "scatter"]
    stored = json.loads((tmp_path / "fog_physics.json").read_text())
    assert set(stored["per_beta"]) == {"0.03", "0.12"} and 0.5 < stored["interior_fraction"] < 1
    md = (tmp_path / "fog_physics.md").read_text()
    a_h = stored["per_beta"]["0.12"]["horizon"]["luminance_mean"]
    assert a_h == pytest.approx(0.4, rel=0.01)  # the exposure of the stand-in renders
    assert md == markdown(result) and f"| 0.12 | {a_h:.3f} | 1.00 | linear+box19 |" in md
    for frame in ("b0.03", "b0.12"):
        assert (tmp_path / f"panels_{frame}.png").stat().st_size > 0
