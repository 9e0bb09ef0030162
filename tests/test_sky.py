"""Outdoor light: procedural sky, HDRI, overcast (fogsim.scene.sky, fogsim.render.blender.sky).

Fast tier: the sky is drawn per frame from the seed after the layout (same objects as the
default day frame), HDRIs come from the preset's list, overcast follows its probability, a
preset without sky keys is the description it always was, bad lighting is refused naming the
preset, a user HDRI path is resolved against the preset's folder.
Blender: the hdri and overcast presets render (bpy module and Debian's 3.4 binary, tiny) with the
default preset's labels, masks and depth; the image differs; meta records the sky.
"""
import json
from pathlib import Path

import numpy as np
import pytest

from fogsim.errors import InputError
from fogsim.presets import presets_dir
from fogsim.render.frame import describe_frame
from fogsim.render.preset import load_render_preset
from fogsim.scene.sky import WORLD_HDRIS, hdri_file

DEFAULT = json.loads((presets_dir() / "default.json").read_text())


def _preset(tmp_path, lighting, name="p.json"):
    path = tmp_path / name
    path.write_text(json.dumps(DEFAULT | {"lighting": lighting}))
    return load_render_preset(str(path))


def test_bundled_presets_and_the_default_is_unchanged():
    assert load_render_preset("hdri").lighting["sky"] == "hdri"
    assert load_render_preset("overcast").lighting == {"overcast": True}
    day = describe_frame(load_render_preset("default"), 0)["lighting"]
    assert set(day) == {"sun_elevation_deg", "sun_azimuth_deg", "sun_strength", "sky_strength"}


def test_same_objects_as_the_default_day_and_deterministic():
    base = load_render_preset("default")
    for name in ("hdri", "overcast"):
        cfg = load_render_preset(name)
        for i in (0, 1):
            a, b = describe_frame(base, i), describe_frame(cfg, i)
            assert a["objects"] == b["objects"] and a["camera"] == b["camera"]
            assert json.dumps(describe_frame(cfg, i)) == json.dumps(b)


def test_hdri_is_chosen_per_frame_from_the_list(tmp_path):
    cfg = _preset(tmp_path, {"sky": "hdri", "hdri": ["city", "forest", "sunset"], "strength": [0.5, 2],
                             "rotation_deg": [10, 20]})
    lights = [describe_frame(cfg, i)["lighting"] for i in range(24)]
    assert {x["hdri"] for x in lights} == {"city", "forest", "sunset"}
    assert all(x["sky"] == "hdri" and x["sun_strength"] == 0 and not x["overcast"] for x in lights)
    assert all(0.5 <= x["sky_strength"] <= 2 and 10 <= x["hdri_rotation_deg"] <= 20 for x in lights)
    assert len({x["sky_strength"] for x in lights}) == 24  # drawn per frame


def test_overcast_probability_and_sun_ranges(tmp_path):
    cfg = _preset(tmp_path, {"overcast": 0.5, "sun_elevation_deg": [30, 40], "sun_azimuth_deg": [90, 100]})
    lights = [describe_frame(cfg, i)["lighting"] for i in range(40)]
    over = [x for x in lights if x["overcast"]]
    assert 8 <= len(over) <= 32  # binomial(40, 0.5): outside this range p < 1e-4
    assert all(x["sky"] == "overcast" and x["sun_strength"] == 0 and 1.0 <= x["sky_strength"] <= 1.6 for x in over)
    clear = [x for x in lights if not x["overcast"]]
    assert all(x["sky"] == "procedural" and x["sky_strength"] == 0.3 and x["sun_strength"] > 4 for x in clear)
    assert all(30 <= x["sun_elevation_deg"] <= 40 and 90 <= x["sun_azimuth_deg"] <= 100 for x in lights)
    assert all(describe_frame(_preset(tmp_path, {"overcast": True}), i)["lighting"]["overcast"] for i in range(5))
    assert not any(describe_frame(_preset(tmp_path, {"overcast": 0}), i)["lighting"]["overcast"] for i in range(5))


#: a 2×1 Radiance HDR of white (RGBE 128,128,128,129 = 1.0; no run-length coding below 8 pixels)
TINY_HDR = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n" + bytes([128, 128, 128, 129]) * 2


def test_user_hdri_path_is_relative_to_the_preset(tmp_path):
    (tmp_path / "skies").mkdir()
    (tmp_path / "skies" / "mine.hdr").write_bytes(TINY_HDR)
    cfg = _preset(tmp_path, {"sky": "hdri", "hdri": ["skies/mine.hdr", "city"]})
    assert cfg.lighting["hdri"] == [str((tmp_path / "skies" / "mine.hdr").resolve()), "city"]
    assert hdri_file(cfg.lighting["hdri"][0], "/nowhere") == tmp_path / "skies" / "mine.hdr"
    assert hdri_file("city", "/b/datafiles") == Path("/b/datafiles/studiolights/world/city.exr")


@pytest.mark.parametrize("lighting, message", [
    ({"sky": "hdri", "hdri": "moon"}, "lighting.hdri: must be a Blender world HDRI (city, courtyard"),
    ({"sky": "hdri", "hdri": []}, "lighting.hdri"),
    ({"sky": "hdri", "hdri": "missing.exr"}, "lighting.hdri: no such file"),
    ({"hdri": "city"}, 'lighting.hdri needs "sky": "hdri"'),
    ({"sky": "hdr"}, "lighting.sky: must be one of procedural, hdri"),
    ({"overcast": 1.5}, "lighting.overcast"),
    ({"strength": [2, 1]}, "lighting.strength: must be [low, high]"),
    ({"time_of_day": "night", "sky": "hdri"}, "apply only to \"time_of_day\": \"day\""),
])
def test_bad_sky_is_refused_naming_the_preset(tmp_path, lighting, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(DEFAULT | {"lighting": lighting}))
    with pytest.raises(InputError) as err:
        load_render_preset(str(path))
    assert str(path) in str(err.value) and message in str(err.value)


def test_world_hdris_ship_with_the_bpy_module():
    import importlib.util

    spec = importlib.util.find_spec("bpy")
    if spec is None:
        pytest.skip("the bpy module is not installed")
    found = list(Path(spec.origin).parent.glob("*/datafiles/studiolights/world"))
    assert found and {p.stem for p in found[0].glob("*.exr")} == set(WORLD_HDRIS)


# ----------------------------------------------------------------------------- Blender
@pytest.mark.blender
@pytest.mark.parametrize("kind", ["bpy", "blender"])
def test_hdri_and_overcast_presets_render(kind, tmp_path):
    """Tiny renders of default, hdri and overcast, same seed: identical labels, masks, depth;
    the sky pixels differ (procedural blue vs HDRI vs grey-white overcast); meta names the sky."""
    from fogsim.io.images import read_image
    from test_blender import dataset_digest, render_dataset

    out = {p: tmp_path / p for p in ("default", "hdri", "overcast")}
    for preset, folder in out.items():
        res = render_dataset(kind, folder, "--preset", preset, "--frames", "1", "--seed", "1", timeout=300)
        assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    digests = {p: dataset_digest(f) for p, f in out.items()}
    assert digests["default"] == digests["hdri"] == digests["overcast"]
    mask = read_image(out["default"] / "masks" / "000000.png")
    img = {p: read_image(f / "images" / "clear" / "000000.png").astype(float) for p, f in out.items()}
    for p in ("hdri", "overcast"):
        assert np.abs(img[p] - img["default"]).mean() > 3, f"{p} looks like the procedural sky"
        meta = json.loads((out[p] / "meta" / "000000.json").read_text())
        light = meta["scene"]["lighting"]
        assert light["sky"] == ("hdri" if p == "hdri" else "overcast") and light["sun_strength"] == 0
        if p == "hdri":
            assert light["hdri"] in WORLD_HDRIS and 0 <= light["hdri_rotation_deg"] < 360
    # the overcast sky (mask 0: nothing hit) is grey-white: its colour channels are close
    sky = mask == 0
    assert sky.sum() > 20
    over = img["overcast"][sky].mean(0)
    assert over.max() - over.min() < 0.12 * over.mean()


@pytest.mark.blender
@pytest.mark.slow
def test_bench_render_reports_the_skies_against_the_procedural_one(tmp_path):
    import re
    import subprocess
    import sys

    from test_blender import runner

    runner("bpy")  # skips without the bpy module
    res = subprocess.run([sys.executable, "-m", "fogsim", "bench", "render", "--frames", "1", "--baseline-frames", "1",
                          "--resolution", "48x32", "--out", str(tmp_path / "b"), "--quiet"],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    m = re.search(r"HDRI (\d+\.\d\d)×, overcast (\d+\.\d\d)× the procedural sky", res.stdout)
    assert m, res.stdout
    assert all(0.1 < float(x) < 10 for x in m.groups())


@pytest.mark.blender
def test_volumetric_fog_is_lit_by_the_frame_sky(tmp_path):
    """Path-traced fog (hybrid medium) under the overcast sky: the medium's emission is the frame's
    sky strength and the fog is grey-white like that sky; under an HDRI the fog renders too."""
    import subprocess
    import sys

    from fogsim.io.images import read_image
    from test_blender import runner

    runner("bpy")  # skips without the bpy module
    base = [sys.executable, "-m", "fogsim", "render", "--frames", "1", "--seed", "3", "--resolution", "96x64",
            "--samples", "8", "--levels", "0,0.06", "--fog", "volumetric", "--fog-medium", "hybrid", "--quiet"]
    for preset in ("overcast", "hdri"):
        out = tmp_path / preset
        res = subprocess.run(base + ["--preset", preset, "--out", str(out)], capture_output=True, text=True,
                             timeout=300)
        assert res.returncode == 0, res.stderr[-3000:]
        meta = json.loads((out / "meta" / "000000.json").read_text())
        assert meta["fog"]["model"] == "volumetric"
        assert meta["fog"]["emission"] == pytest.approx(meta["scene"]["lighting"]["sky_strength"])
        fog = read_image(out / "images" / "beta0.06" / "000000.png").astype(float)
        clear = read_image(out / "images" / "clear" / "000000.png").astype(float)
        assert fog.mean() > clear.mean() + 10  # the fog brightens the far street toward the sky
        if preset == "overcast":
            m = fog.reshape(-1, 3).mean(0)
            assert m.max() - m.min() < 0.1 * m.mean()
