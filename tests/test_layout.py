"""Street layouts: deterministic, sensible, serialisable — without Blender."""
import json

import numpy as np
import pytest

from fogsim.render.preset import load_render_preset
from fogsim.scene.classes import LABELLED, STUFF
from fogsim.scene.layout import SIDEWALK_HEIGHT, _footprint, sample_scene


@pytest.fixture(params=["default", "suburban", "arterial"])
def config(request):
    return load_render_preset(request.param)


def scene(config, seed):
    return sample_scene(np.random.default_rng(seed), config.style, config.camera, config.resolution, seed=seed)


def test_same_seed_same_scene(config):
    a, b, c = scene(config, 1), scene(config, 1), scene(config, 2)
    assert json.dumps(a) == json.dumps(b) and json.dumps(a) != json.dumps(c)


def test_layout_makes_sense(config):
    for seed in range(4):
        s = scene(config, seed)
        st = s["street"]
        ids = [o["id"] for o in s["objects"]]
        assert ids == list(range(1, len(ids) + 1))
        assert all(o["class"] in LABELLED + STUFF for o in s["objects"])
        placed = [o for o in s["objects"] if o["class"] in LABELLED + ("pole", "tree")]
        boxes = [_footprint(o["asset"], np.asarray(o["transform"])[0, 3], np.asarray(o["transform"])[1, 3],
                            np.degrees(np.arctan2(np.asarray(o["transform"])[1, 0], np.asarray(o["transform"])[0, 0])))
                 for o in placed]
        for i in range(len(boxes)):  # no two footprints overlap
            for j in range(i + 1, len(boxes)):
                a, b = boxes[i], boxes[j]
                apart = a[1] <= b[0] or b[1] <= a[0] or a[3] <= b[2] or b[3] <= a[2]
                assert apart, (placed[i]["class"], placed[j]["class"])
        for o in s["objects"]:
            M = np.asarray(o["transform"])
            x, z = M[0, 3], M[2, 3]
            heading = np.degrees(np.arctan2(M[1, 0], M[0, 0]))
            if o["class"] in ("car", "van", "truck", "bus") :
                assert abs(x) < st["curb_x"], "vehicles stay on the road"
                assert z == 0.0
                # facing along the street: +y on the right half, −y on the left half
                assert (abs(heading) < 10) if x > 0 else (abs(abs(heading) - 180) < 10)
            if o["class"] == "pedestrian" and z > 0:
                assert z == SIDEWALK_HEIGHT and st["curb_x"] <= abs(x) <= st["curb_x"] + st["sidewalk_width"]
        assert sum(o["class"] in ("car", "van", "truck", "bus") for o in s["objects"]) >= 1


def test_camera_follows_preset(config):
    s = scene(config, 0)
    K = s["camera"]["intrinsics"]
    assert (K["width"], K["height"]) == tuple(config.resolution)
    assert s["camera"]["position"][2] == config.camera["height_m"]
    assert 0 < s["camera"]["position"][0] < s["street"]["lanes"] * s["street"]["lane_width"]


@pytest.mark.parametrize(
    "change, message",
    [
        ({"resolution": [640]}, r"resolution: must be a \[width, height\] list of integers"),
        ({"resolution": [0, 0]}, r"resolution\[0\]: must be an integer ≥ 8"),
        ({"exposure": "abc"}, "exposure: must be a finite number"),
        ({"fog_model": {"extended": True, "kernel": "boxx"}}, "fog_model.kernel: must be one of box, gaussian, guided"),
        ({"fog_model": {"airlight": 300}}, "airlight"),
        ({"labels": {"min_pixels": 0}}, "min_pixels"),
        ({"fog": [0.03, -1]}, r"fog\[1\]: must be a number ≥ 0"),
        ({"camera": "nope"}, "unknown camera"),
    ],
)
def test_bad_presets_fail_at_load_naming_the_file(tmp_path, change, message):
    import json as _json

    from fogsim.errors import InputError
    from fogsim.presets import presets_dir

    d = _json.loads((presets_dir() / "default.json").read_text()) | change
    path = tmp_path / "bad.json"
    path.write_text(_json.dumps(d))
    with pytest.raises(InputError, match=message) as err:
        load_render_preset(str(path))
    assert "bad.json" in str(err.value)


def test_train_fraction_from_preset_or_override(tmp_path):
    import json as _json

    from fogsim.presets import presets_dir

    assert load_render_preset("default").train_fraction == 0.8
    assert load_render_preset("default", train_fraction=0.628).train_fraction == 0.628  # the paper's 8,100/4,800
    with pytest.raises(ValueError, match="--train-fraction"):
        load_render_preset("default", train_fraction=1.0)
    path = tmp_path / "split.json"
    path.write_text(_json.dumps(_json.loads((presets_dir() / "default.json").read_text()) | {"train_fraction": 0.5}))
    assert load_render_preset(str(path)).train_fraction == 0.5
    path.write_text(_json.dumps(_json.loads((presets_dir() / "default.json").read_text()) | {"train_fraction": 2}))
    with pytest.raises(Exception, match="split.json.*train_fraction"):
        load_render_preset(str(path))
