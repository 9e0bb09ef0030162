"""Night: light sources described in pure Python (fast tier), and real Cycles renders (blender).

Fast tier: a night frame lists street lamps under the poles' lamp heads and headlights at the
front of every driving vehicle, aimed along its heading; it is deterministic from the seed and
has the same objects and geometry as the day frame; a day frame has no sources and is the
description it always was; a bad ``lighting`` is refused naming the preset file.
Blender: the night render of a seed has the day render's labels, masks and depth, is much
darker, and its Light objects light what they should (lamp pool, headlight beam).
"""
import copy
import json
from pathlib import Path

import numpy as np
import pytest

from fogsim.errors import InputError
from fogsim.presets import names, presets_dir
from fogsim.render.frame import describe_frame
from fogsim.render.preset import load_render_preset
from fogsim.scene.assets import build_asset
from fogsim.scene.geometry import world_parts
from fogsim.scene.lights import NIGHT, VEHICLE_CLASSES, is_driving
from fogsim.scene.materials import material

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = json.loads((presets_dir() / "default.json").read_text())


@pytest.fixture(scope="module")
def frames():
    day, night = load_render_preset("default"), load_render_preset("night")
    return {i: (describe_frame(day, i), describe_frame(night, i)) for i in (0, 1)}


def _local(obj, p):
    """World point ``p`` in the object's local frame (front = +y)."""
    M = np.asarray(obj["transform"])
    return M[:3, :3].T @ (np.asarray(p) - M[:3, 3])


def test_night_preset_is_listed_and_is_default_at_night():
    assert "night" in names()
    night = json.loads((presets_dir() / "night.json").read_text())
    assert night["lighting"] == {"time_of_day": "night"}
    same = {k for k in DEFAULT if DEFAULT[k] == night.get(k)}
    assert set(DEFAULT) - same == {"name", "description", "fog_model"}  # airlight: the night sky, not white
    assert load_render_preset("night").lighting == {"time_of_day": "night"}
    assert load_render_preset("default").lighting == {} and "lighting" not in load_render_preset("default").to_dict()


def test_same_objects_and_geometry_as_day(frames):
    for day, night in frames.values():
        assert [(o["id"], o["class"], o["transform"]) for o in day["objects"]] == \
               [(o["id"], o["class"], o["transform"]) for o in night["objects"]]
        assert day["camera"] == night["camera"] and day["street"] == night["street"]
        for a, b in zip(day["objects"], night["objects"]):
            if a["class"] in ("building", "car", "truck", "van", "bus", "pole"):
                va = np.concatenate([v for v, _, _ in world_parts(a)])
                vb = np.concatenate([v for v, _, _ in world_parts(b)])
                assert sorted(map(tuple, va.round(9))) == sorted(map(tuple, vb.round(9)))
            else:
                assert a == b


def test_day_has_no_lights(frames):
    for day, _ in frames.values():
        assert set(day["lighting"]) == {"sun_elevation_deg", "sun_azimuth_deg", "sun_strength", "sky_strength"}
        assert all("lit_windows" not in o["asset"].get("params", {}) for o in day["objects"])


def test_night_is_deterministic_and_seeded(frames):
    night = load_render_preset("night")
    assert json.dumps(describe_frame(night, 0)) == json.dumps(frames[0][1])
    assert frames[0][1]["lighting"]["sources"] != frames[1][1]["lighting"]["sources"]


def test_night_sky_and_sources(frames):
    for _, night in frames.values():
        light = night["lighting"]
        assert light["time_of_day"] == "night" and light["sky_strength"] == NIGHT["sky_strength"] == 0.01
        assert light["sun_strength"] == NIGHT["moon_strength"]
        kinds = {s["kind"] for s in light["sources"]}
        assert kinds == {"street_lamp", "headlight", "taillight"}
        for s in light["sources"]:
            assert s["power_w"] > 0 and len(s["position"]) == 3 and max(s["color"]) == 1.0
            if s["type"] == "SPOT":
                assert np.linalg.norm(s["direction"]) == pytest.approx(1.0) and 0 < s["spot_angle_deg"] < 180


def test_street_lamps_hang_under_the_lamp_heads(frames):
    for _, night in frames.values():
        by_id = {o["id"]: o for o in night["objects"]}
        poles = [o for o in night["objects"] if o["class"] == "pole"]
        lamps = [s for s in night["lighting"]["sources"] if s["kind"] == "street_lamp"]
        assert poles and len(lamps) == sum(2 if p["asset"]["params"]["double"] else 1 for p in poles)
        for s in lamps:
            pole = by_id[s["object_id"]]
            p = pole["asset"]["params"]
            x, y, z = _local(pole, s["position"])
            assert abs(x) < 0.2 and abs(abs(y) - p["arm"]) < 0.3, "under the end of an arm"
            assert p["height"] - 0.5 < z < p["height"], "at lamp height, just under the head"
            assert s["direction"] == [0.0, 0.0, -1.0] and s["type"] == "SPOT"
            lens = material("street_lamp", **pole["asset"]["materials"]["street_lamp"])
            assert lens["emission"] > 0
            # the arm toward local +y reaches over the road (a double pole's other arm, over the sidewalk)
            assert (abs(s["position"][0]) < abs(pole["transform"][0][3])) == (y > 0)


def test_headlights_at_the_front_pointing_along_the_heading(frames):
    for _, night in frames.values():
        by_id = {o["id"]: o for o in night["objects"]}
        vehicles = [o for o in night["objects"] if o["class"] in VEHICLE_CLASSES]
        driving = {o["id"] for o in vehicles if is_driving(o, night["street"])}
        assert driving and len(driving) < len(vehicles)  # the default street has parked cars too
        src = night["lighting"]["sources"]
        heads = [s for s in src if s["kind"] == "headlight"]
        tails = [s for s in src if s["kind"] == "taillight"]
        assert {s["object_id"] for s in heads} == {s["object_id"] for s in tails} == driving
        for s in heads + tails:
            v = by_id[s["object_id"]]
            p = v["asset"]["params"]
            x, y, z = _local(v, s["position"])
            assert 0.1 < abs(x) < p["width"] / 2 and 0.2 < z < 1.5
            assert (p["length"] / 2 < y < p["length"] / 2 + 0.1) if s["kind"] == "headlight" else \
                   (-p["length"] / 2 - 0.1 < y < -p["length"] / 2)
        for s in heads:
            M = np.asarray(by_id[s["object_id"]]["transform"])
            heading = M[:3, :3] @ [0.0, 1.0, 0.0]
            d = np.asarray(s["direction"])
            assert d @ heading > 0.99 and -0.1 < d[2] < 0, "along the heading, slightly down"
            assert s["type"] == "SPOT" and 30 <= s["spot_angle_deg"] <= 40
        for v in vehicles:  # the lenses glow on driving vehicles only
            mats = v["asset"]["materials"]
            glow = material("headlight", **mats.get("headlight", {}))["emission"]
            assert (glow > 0) == (v["id"] in driving)


def test_a_seeded_fraction_of_windows_is_lit(frames):
    _, night = frames[0]
    fractions = []
    for obj in night["objects"]:
        if obj["class"] != "building":
            continue
        lit = obj["asset"]["params"]["lit_windows"]
        parts = dict((slot, m) for m, slot in build_asset(obj["asset"]))
        n_lit = len(parts["window_lit"].faces) if "window_lit" in parts else 0
        n_dark = len(parts["window"].faces) if "window" in parts else 0
        fractions.append(n_lit / (n_lit + n_dark))
        assert NIGHT["lit_window_fraction"][0] <= lit["fraction"] <= NIGHT["lit_window_fraction"][1]
    assert 0.1 < float(np.mean(fractions)) < 0.5 and len(set(fractions)) > 1
    assert material("window_lit")["emission"] > 0


def test_lighting_overrides_reach_the_sources(tmp_path):
    path = tmp_path / "mine.json"
    path.write_text(json.dumps(DEFAULT | {"lighting": {"time_of_day": "night", "street_lamp_power_w": 900,
                                                       "lit_window_fraction": [0, 0]}}))
    desc = describe_frame(load_render_preset(str(path)), 0)
    assert {s["power_w"] for s in desc["lighting"]["sources"] if s["kind"] == "street_lamp"} == {900.0}
    assert all(o["asset"]["params"]["lit_windows"]["fraction"] == 0 for o in desc["objects"]
               if o["class"] == "building")


@pytest.mark.parametrize("lighting, message", [
    ({"time_of_day": "dusk"}, "lighting.time_of_day: must be one of day, night (got 'dusk')"),
    ({"time_of_day": 1}, "lighting.time_of_day: must be one of day, night"),
    ("night", "lighting: must be a JSON object"),
    ({"time_of_day": "night", "sky_strength": -1}, "lighting.sky_strength: must be a number in [0, 10]"),
    ({"time_of_day": "night", "headlight_power_w": "bright"}, "lighting.headlight_power_w: must be a finite number"),
    ({"time_of_day": "night", "lit_window_fraction": [0.5, 0.2]}, "lighting.lit_window_fraction: must be [low, high]"),
    ({"time_of_day": "night", "lamps": True}, "lighting: unknown key ['lamps']"),
    ({"street_lamp_power_w": 900}, "apply only to \"time_of_day\": \"night\""),
])
def test_bad_lighting_is_refused_naming_the_preset(tmp_path, lighting, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(DEFAULT | {"lighting": lighting}))
    with pytest.raises(InputError) as err:
        load_render_preset(str(path))
    assert str(path) in str(err.value) and message in str(err.value)


def test_explicit_day_is_the_default():
    day = copy.deepcopy(DEFAULT) | {"lighting": {"time_of_day": "day"}}
    from fogsim.render.preset import check_lighting

    assert check_lighting(day["lighting"]) == {} and check_lighting({}) == {}
    assert set(NIGHT) == {"sky_strength", "moon_strength", "street_lamp_power_w", "headlight_power_w",
                          "taillight_power_w", "lit_window_fraction"}


# ----------------------------------------------------------------------------- Blender
@pytest.mark.blender
@pytest.mark.parametrize("kind", ["bpy", "blender"])
def test_lights_light_the_scene_and_leave_the_passes(kind, tmp_path):
    """A lamp, a car driving toward a wall: day, night, night without Light objects."""
    from test_blender import SCRIPTS, run, runner

    res = run(runner(kind)(SCRIPTS / "night_lights.py", str(tmp_path / "r.json")), timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["sources"] == 5 and r["lights"] == {"day": 1, "night": 6, "dark": 1}  # the sun + lamp, 2+2 car lights
    assert r["leftover"] == [0, 0] and r["smooth_faces"] == 0  # flat shading in every version
    assert r["index_equal"] and r["depth_equal"] and r["car_pixels"] > 100 and r["pole_pixels"] > 10
    assert r["patch_ids"] == [1, 1, 4, 4]  # pool and control on the road, beam and outside on the wall
    assert r["mean_night"] < 0.3 * r["mean_day"]
    assert r["pool"] > 4 * r["road"], "the street lamp lights the road under it"
    assert r["beam"] > 20 * r["outside"], "the headlights light the wall ahead, not beside the beam"


@pytest.mark.blender
@pytest.mark.parametrize("kind", ["bpy", "blender"])
def test_night_dataset_has_the_day_labels_masks_and_depth(kind, tmp_path):
    """render_batch with --preset night and with default, same seed: identical labels/, masks/ and
    depth/; a much darker image; the frame's scene lists the lights."""
    from fogsim.io.images import read_image
    from test_blender import dataset_digest, render_dataset

    out = {p: tmp_path / p for p in ("default", "night")}
    for preset, folder in out.items():
        res = render_dataset(kind, folder, "--preset", preset, "--frames", "1", "--seed", "3", timeout=300)
        assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    day, night = dataset_digest(out["default"]), dataset_digest(out["night"])
    assert day == night and any(k.startswith("labels/") for k in day) and "masks/000000.png" in day
    mean = {p: read_image(f / "images" / "clear" / "000000.png").mean() for p, f in out.items()}
    assert mean["night"] < 0.5 * mean["default"]
    meta = json.loads((out["night"] / "meta" / "000000.json").read_text())
    assert meta["scene"]["lighting"]["time_of_day"] == "night" and len(meta["scene"]["lighting"]["sources"]) > 10
    run_file = json.loads((out["night"] / "render_run.json").read_text())
    assert run_file["parameters"]["lighting"] == {"time_of_day": "night"}


@pytest.mark.blender
def test_night_in_volumetric_fog_stays_night(tmp_path):
    """Night + path-traced fog (hybrid medium): the medium's emission follows the frame's sky
    (0.01 at night), so the foggy night is dark with glowing lamps, not a white day fog; labels
    and masks are those of the night render without fog."""
    import subprocess
    import sys

    from fogsim.io.images import read_image
    from test_blender import dataset_digest, runner

    runner("bpy")  # skips without the bpy module
    base = [sys.executable, "-m", "fogsim", "render", "--frames", "1", "--seed", "3", "--resolution", "96x64",
            "--samples", "8", "--levels", "0,0.06", "--quiet"]
    out = {}
    for name, extra in (("night", ["--preset", "night"]),
                        ("night_fog", ["--preset", "night", "--fog", "volumetric", "--fog-medium", "hybrid"]),
                        ("day_fog", ["--preset", "default", "--fog", "volumetric", "--fog-medium", "hybrid"])):
        out[name] = tmp_path / name
        res = subprocess.run(base + extra + ["--out", str(out[name])], capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, res.stderr[-3000:]
    assert dataset_digest(out["night"]) == dataset_digest(out["night_fog"])
    fog = {n: read_image(out[n] / "images" / "beta0.06" / "000000.png").astype(float) for n in ("night_fog", "day_fog")}
    assert fog["night_fog"].mean() < 0.4 * fog["day_fog"].mean()
    assert fog["night_fog"].max() > 3 * np.median(fog["night_fog"])  # the lamps still shine through
    meta = json.loads((out["night_fog"] / "meta" / "000000.json").read_text())
    assert meta["fog"]["emission"] == pytest.approx(NIGHT["sky_strength"])
