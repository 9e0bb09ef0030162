"""Render presets are checked in full when loaded — before any output folder is touched — and a
killed render's leftovers are found and removed by frame. No Blender: the checks are pure, and
``fogsim render`` loads the preset before it needs bpy."""
import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from fogsim.dataset.layout import DatasetLayout
from fogsim.errors import InputError
from fogsim.presets import presets_dir
from fogsim.render.preset import load_render_preset

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = json.loads((presets_dir() / "default.json").read_text())
STYLE = json.loads((presets_dir() / "styles" / "urban-canyon.json").read_text())
CAMERA = json.loads((presets_dir() / "cameras" / "waymo-front.json").read_text())


def preset_file(tmp_path, change: dict, name: str = "bad.json"):
    path = tmp_path / name
    path.write_text(json.dumps(DEFAULT | change))
    return path


@pytest.mark.parametrize("change, key", [
    # the trial's cases (#20, #11): inline components with wrong types, names that are paths
    ({"style": {"lanes_per_direction": "two"}}, "style.lanes_per_direction: must be an integer (got 'two')"),
    ({"style": {"lanes_per_direction": 2}}, "style: lacks 'name', 'lane_width'"),
    ({"style": STYLE | {"lanes_per_direction": "two"}}, "style.lanes_per_direction: must be an integer (got 'two')"),
    ({"quality": {"samples": -4}}, "quality.samples: must be an integer in [1, 16777216] (got -4)"),
    ({"seed": 1.7}, "seed: must be an integer (got 1.7)"),
    ({"frames": 2.9}, "frames: must be an integer (got 2.9)"),
    ({"resolution": "640x426"}, "resolution: must be a list (got '640x426')"),
    # more wrong types and ranges in style / camera / quality values
    ({"style": STYLE | {"lane_width": "3.4"}}, "style.lane_width: must be a finite number (got '3.4')"),
    ({"style": STYLE | {"driving": [12, 4]}}, "style.driving: must be [low, high] with low ≤ high (got [12, 4])"),
    ({"style": STYLE | {"pedestrians": [1.5, 3]}}, "style.pedestrians[0]: must be an integer (got 1.5)"),
    ({"style": STYLE | {"vehicle_mix": {"tank": 1.0}}}, "style.vehicle_mix: unknown key ['tank'] (allowed: ['bus',"),
    ({"style": STYLE | {"crosswalk_probability": 2}}, "style.crosswalk_probability: must be a number in [0, 1]"),
    ({"style": STYLE | {"street_length": 1e9}}, "street_length: must be a number in [1, 1000] (got 1000000000.0)"),
    ({"style": STYLE | {"lane_widht": 3.0}}, "style: unknown key ['lane_widht'] (allowed: ["),
    ({"camera": CAMERA | {"height_m": "2.1"}}, "camera.height_m: must be a finite number (got '2.1')"),
    ({"camera": CAMERA | {"hfov_deg": 0}}, "camera.hfov_deg: must be a number in (0, 179] (got 0)"),
    ({"camera": CAMERA | {"fx": 2000.0}}, "camera: needs exactly one of 'fx'"),
    ({"camera": CAMERA | {"width": 1920.5}}, "camera.width: must be an integer (got 1920.5)"),
    ({"quality": {"samples": 8, "denoise": "yes"}}, "quality.denoise: must be true or false (got 'yes')"),
    ({"quality": {"bounces": {"total": -1}}}, "quality.bounces.total: must be an integer in [0, 1024] (got -1)"),
    ({"quality": 5}, "quality: must be a bundled quality name or an inline JSON object (got 5)"),
    ({"resolution": [640.5, 426]}, "resolution[0]: must be an integer (got 640.5)"),
    ({"stereo": "yes"}, "stereo: must be true, false or {\"baseline_m\": …} (got 'yes')"),
    ({"stereo": {"baseline_m": -1}}, "stereo.baseline_m: must be a number > 0 (got -1)"),
    ({"fog_model": {"extended": True, "kernel_size": 19.5}}, "fog_model.kernel_size: must be an integer (got 19.5)"),
    ({"fog_model": {"extended": "yes"}}, "fog_model.extended: must be true or false (got 'yes')"),
    ({"labels": {"min_pixels": 2.5}}, "labels.min_pixels: must be an integer (got 2.5)"),
    ({"exposure": True}, "exposure: must be a finite number (got True)"),
    ({"fog": ["0.03"]}, "fog[0]: must be a β ≥ 0 (1/m, a number) or \"clear\" (got '0.03')"),
    ({"frames": 0}, "frames: must be an integer in [1, 1000000] (got 0)"),
    ({"seed": -1}, "seed: must be an integer ≥ 0 (got -1)"),
])
def test_wrong_types_and_ranges_name_the_preset_and_the_key(tmp_path, change, key):
    with pytest.raises(InputError) as err:
        load_render_preset(str(preset_file(tmp_path, change)))
    assert str(err.value).startswith(f"{tmp_path / 'bad.json'}: ")
    assert key in str(err.value)


@pytest.mark.parametrize("key, name", [
    ("style", "../cameras/waymo-front"), ("camera", "waymo-front/../../styles/arterial"),
    ("quality", "draft.json"), ("fog", "../fog/paper"), ("fog", "/etc/passwd.json"),
])
def test_component_names_are_never_paths(tmp_path, key, name):
    with pytest.raises(InputError, match="may hold only letters, digits, '-' and '_'") as err:
        load_render_preset(str(preset_file(tmp_path, {key: name})))
    assert "bad.json" in str(err.value)


def test_integers_are_integers_not_truncated(tmp_path):
    cfg = load_render_preset(str(preset_file(tmp_path, {"frames": 3.0, "seed": 7.0})))
    assert (cfg.frames, cfg.seed) == (3, 7) and type(cfg.frames) is int and type(cfg.seed) is int
    for flag, kw in (("--frames", {"frames": 2.9}), ("--frames", {"frames": 0}), ("--seed", {"seed": 1.7}),
                     ("--seed", {"seed": -1}), ("--samples", {"samples": 0}), ("--samples", {"samples": -4})):
        with pytest.raises(ValueError, match=flag):
            load_render_preset("default", **kw)


def test_validation_keeps_the_bundled_presets_as_written():
    """The checked components equal the files: a dataset rendered before keeps its parameters."""
    for name in ("default", "suburban", "arterial", "cityscapes-stereo", "night"):
        raw = json.loads((presets_dir() / f"{name}.json").read_text())
        cfg = load_render_preset(name)
        assert cfg.style == json.loads((presets_dir() / "styles" / f"{raw['style']}.json").read_text())
        assert cfg.camera == json.loads((presets_dir() / "cameras" / f"{raw['camera']}.json").read_text())
        assert cfg.quality == json.loads((presets_dir() / "quality" / f"{raw['quality']}.json").read_text())
        assert cfg.resolution == tuple(raw["resolution"])


# --- #21: an upper bound on the render size ------------------------------------------------------
def test_resolution_above_the_bound_is_refused_naming_the_flag(tmp_path):
    from fogsim.render.preset import MAX_PIXELS

    assert MAX_PIXELS == 40_000_000
    with pytest.raises(ValueError, match=r"--resolution 9000×9000 = 81.0 MP is above the limit of 40 MP.*--max-pixels"):
        load_render_preset("default", resolution="9000x9000")
    with pytest.raises(ValueError, match="--resolution 100000×100000 is larger than Blender renders"):
        load_render_preset("default", resolution="100000x100000", max_pixels=10**12)
    assert load_render_preset("default", resolution="9000x9000", max_pixels=90_000_000).resolution == (9000, 9000)
    with pytest.raises(InputError, match=r"bad.json: resolution 9000×9000 .*raise --max-pixels"):
        load_render_preset(str(preset_file(tmp_path, {"resolution": [9000, 9000]})))
    with pytest.raises(ValueError, match="--max-pixels"):
        load_render_preset("default", max_pixels=0)


def fogsim(*args, timeout=120):
    """``fogsim …`` in a process of its own (a render that is not refused would take minutes)."""
    try:
        return subprocess.run([sys.executable, "-m", "fogsim", *map(str, args)], capture_output=True, text=True,
                              timeout=timeout, cwd=ROOT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"fogsim {' '.join(map(str, args))} was not refused: still running after {timeout} s")


def test_render_refuses_before_anything_is_written(tmp_path):
    """``fogsim render`` with a setup error: exit 2, one line naming the flag or preset, no
    folder (#21, #11). The preset is loaded before bpy is needed, so this runs without Blender."""
    out = tmp_path / "o"
    r = fogsim("render", "--out", out, "--frames", "1", "--resolution", "100000x100000", "--samples", "1")
    assert r.returncode == 2 and "--resolution 100000×100000" in r.stderr, r.stderr[-2000:]
    assert len(r.stderr.strip().splitlines()) == 1
    r = fogsim("render", "--out", out, "--frames", "1", "--resolution", "9000x9000", "--samples", "1")
    assert r.returncode == 2 and "--max-pixels" in r.stderr, r.stderr[-2000:]
    bad = preset_file(tmp_path, {"style": {"lanes_per_direction": "two"}})
    r = fogsim("render", "--out", out, "--frames", "1", "--preset", bad)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert f"{bad}: style.lanes_per_direction: must be an integer" in r.stderr
    assert not out.exists()


# --- #11: the scene of the first frame is described before the folder is claimed ---------------
def test_check_scene_names_the_preset_when_the_layout_fails():
    from fogsim.render.frame import check_scene

    cfg = load_render_preset("default")
    check_scene(cfg)
    broken = dataclasses.replace(cfg, style={k: v for k, v in cfg.style.items() if k != "lane_width"})
    with pytest.raises(InputError, match=r"default.json: cannot build a scene from this preset \(KeyError"):
        check_scene(broken)


# --- #18: leftovers of a killed render ------------------------------------------------------------
def test_leftovers_of_a_killed_render_are_removed(tmp_path):
    import subprocess
    import sys

    from fogsim.io.parts import _HOST, remove_stale_parts
    from fogsim.render.leftovers import TMP_DIR, remove_render_tmp

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()  # a writer that is gone
    gone, running = f"{_HOST}-{dead.pid}", f"{_HOST}-{os.getpid()}"
    layout = DatasetLayout(tmp_path / "ds")
    real = [layout.image("clear", "000001"), layout.label("beta0.06", "000001"), layout.depth("000001"),
            layout.meta("000000"), layout.coco("clear")]
    stale = [layout.labels_dir("clear") / f".000001.txt.{gone}.ab12.part",
             layout.images_dir("beta0.06") / f".000001.png.{gone}.q9w8.part",
             layout.root / "depth" / f".000001.exr.{gone}.zzzz.part",
             layout.meta_dir() / f".000001.json.{gone}.a1b2.part",
             layout.cityscapes("disparity", "000001", "train").with_name(f".000001_disparity.png.{gone}.k2j3.part"),
             layout.root / "coco" / f".clear.json.{gone}.abcd.part", layout.root / f".dataset.json.{gone}.abcd.part",
             layout.root / "splits" / f".all_val.txt.{gone}.abcd.part"]
    in_flight = [layout.labels_dir("clear") / f".000002.txt.{running}.ab12.part"]  # a live writer's
    renders = [layout.root / TMP_DIR / "000001.left.exr", layout.root / TMP_DIR / "000002.left.exr"]
    for p in real + stale + in_flight + renders:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"x")
    assert layout.done_frames() == ["000000"]  # a part file never counts as an output
    assert remove_stale_parts(layout.root) == len(stale)
    assert all(p.exists() for p in real + in_flight + renders) and not any(p.exists() for p in stale)
    remove_render_tmp(layout, {"000001"})
    assert not renders[0].exists() and renders[1].exists()  # another shard's render is still in it
    remove_render_tmp(layout, {"000002"})
    assert not (layout.root / TMP_DIR).exists()
    assert all(p.exists() for p in real)
    assert os.listdir(layout.root / "meta") == ["000000.json"]
