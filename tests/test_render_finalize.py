"""``fogsim render --out OUT --finalize-only`` after shards rendered with any flags (issue 47, point 1): the
configuration comes from ``render_run.json``; a flag that disagrees with it is refused naming the
parameter and both values (never "use another --out"). The first tests need no Blender (the run file is
written as a render writes it); the last renders real shards with the bpy module."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from fogsim.cli import main
from fogsim.render.finalize import RUN_FILE, check_flags, dataset_parameters, recorded_config
from fogsim.render.preset import load_render_preset
from fogsim.runs import claim_output, describe_difference

ROOT = Path(__file__).resolve().parents[1]
FLAGS = dict(resolution="96x64", samples=1, levels="clear,0.06", lidar="hdl64e", seed=3)


def _claimed(out: Path, preset: str = "suburban", **flags):
    """A folder claimed as ``fogsim render`` claims it (RenderJob.claim), no frame rendered."""
    config = load_render_preset(preset, **flags)
    out.mkdir(parents=True)
    claim_output(out / RUN_FILE, dataset_parameters(config), {"blender": "5.0.1", "config": config.to_dict()},
                 what="dataset")
    return config


def test_the_record_gives_back_the_configuration(tmp_path):
    config = _claimed(tmp_path / "ds", **FLAGS)
    back, blender = recorded_config(tmp_path / "ds")
    assert back.to_dict() == json.loads(json.dumps(config.to_dict())) and blender == "5.0.1"
    assert [lv.key for lv in back.levels] == ["clear", "beta0.06"] and back.lidar_sensor.beams == 64


@pytest.mark.parametrize("flag, value, says", [
    ("--resolution", "640x426", "resolution: [96, 64] recorded, [640, 426] with --resolution"),
    ("--lidar", "hdl32e", "lidar.beams: 64 recorded, 32 with --lidar"),
    ("--levels", "clear,0.06,0.12", 'levels: ["clear", "beta0.06"] recorded, ["clear", "beta0.06", "beta0.12"] with'),
    ("--seed", 4, "seed: 3 recorded, 4 with --seed"),
    ("--samples", 4, "quality.samples: 1 recorded, 4 with --samples"),
    ("--preset", "default", 'name: "suburban" recorded, "default" with --preset'),
    ("--fog", "volumetric", 'fog_model.kind: absent recorded, "volumetric" with --fog'),
    ("--camera", "Cam", "rendered from the preset 'suburban', not from a scene"),
])
def test_a_flag_that_disagrees_names_the_parameter_and_both_values(tmp_path, flag, value, says):
    config = _claimed(tmp_path / "ds", **FLAGS)
    with pytest.raises(Exception) as err:
        check_flags(config, {flag: value}, tmp_path / "ds" / RUN_FILE)
    text = str(err.value)
    assert says in text and "leave " + flag + " out" in text, text
    assert "another --out" not in text and "delete" not in text


def test_flags_that_agree_with_the_record_pass(tmp_path):
    config = _claimed(tmp_path / "ds", **FLAGS)
    check_flags(config, {"--preset": "suburban", "--resolution": "96x64", "--samples": 1, "--levels": "clear,0.06",
                         "--lidar": "hdl64e", "--seed": 3, "--radar": None, "--stereo": False}, "run file")


def test_the_command_refuses_a_disagreeing_flag_before_writing_anything(tmp_path, capsys):
    out = tmp_path / "ds"
    _claimed(out, **FLAGS)
    before = sorted(p.name for p in out.iterdir())
    assert main(["render", "--out", str(out), "--finalize-only", "--resolution", "640x426"]) == 2
    err = capsys.readouterr().err
    assert f"{out / RUN_FILE}: --resolution 640x426 disagrees" in err and "[96, 64] recorded" in err, err
    assert sorted(p.name for p in out.iterdir()) == before  # nothing written
    # only --out: the record is enough (here it has no frame yet: exit 2, said so)
    assert main(["render", "--out", str(out), "--finalize-only"]) == 2
    assert "no committed frames to finalize" in capsys.readouterr().err
    assert main(["render", "--out", str(tmp_path / "none"), "--finalize-only"]) == 2
    assert "not a dataset to finalize" in capsys.readouterr().err


def test_finalize_needs_no_blender(tmp_path, capsys, monkeypatch):
    """Frames committed (the synthetic dataset's, written by the renderer's writer) and the render's claim:
    ``--finalize-only --out`` writes the dataset files with bpy made unimportable."""
    import sys

    from synthetic_dataset import make_dataset

    out = tmp_path / "ds"
    make_dataset(out, frames=3)
    config = load_render_preset("default", levels="paper", frames=3, seed=0)
    claim_output(out / RUN_FILE, dataset_parameters(config), {"blender": "5.0.1", "config": config.to_dict()},
                 what="dataset")
    (out / "dataset.json").unlink()
    monkeypatch.setitem(sys.modules, "bpy", None)  # import bpy now fails
    assert main(["render", "--out", str(out), "--finalize-only", "--train-fraction", "0.5"]) == 0
    assert "finalize: 3 frames found of the run's 3" in capsys.readouterr().out
    manifest = json.loads((out / "dataset.json").read_text())
    assert manifest["blender"] == "5.0.1" and manifest["preset"]["name"] == "default"
    assert manifest["split"]["train_fraction"] == 0.5 and manifest["frames"] == 3


def test_a_resumed_render_with_other_flags_names_the_difference(tmp_path):
    _claimed(tmp_path / "ds", **FLAGS)
    other = load_render_preset("suburban", **{**FLAGS, "resolution": "640x426"})
    with pytest.raises(Exception, match=r"resolution: \[96, 64\] there, \[640, 426\] now"):
        claim_output(tmp_path / "ds" / RUN_FILE, dataset_parameters(other), what="dataset")


def test_describe_difference():
    assert describe_difference({"a": [1, 2]}, {"a": [1, 2]}) == ""
    assert describe_difference({"a": {"b": 1}}, {"a": {"b": 2}}) == "a.b: 1 recorded, 2 given"
    assert describe_difference({"a": [{"k": 1}]}, {"a": [{"k": 2}]}) == "a[0].k: 1 recorded, 2 given"
    assert describe_difference({}, {"x": "y" * 200}).endswith("… given")


@pytest.mark.blender
@pytest.mark.slow
def test_shards_with_flags_then_finalize_with_only_out(tmp_path):
    """Two shards rendered with --preset suburban --lidar hdl64e --resolution … --levels …; then
    ``fogsim render --out OUT --finalize-only`` and nothing else: the dataset files of the record's levels,
    the same COCO as one run over both frames."""
    pytest.importorskip("bpy")
    flags = ["--preset", "suburban", "--frames", "2", "--resolution", "96x64", "--samples", "1", "--levels",
             "clear,0.06", "--lidar", "hdl64e", "--quiet"]

    def render(out, *extra):
        return subprocess.run([sys.executable, "-m", "fogsim", "render", "--out", str(out), *extra],
                              capture_output=True, text=True, timeout=600, cwd=ROOT)

    sharded, whole = tmp_path / "sharded", tmp_path / "whole"
    for i in (0, 1):
        res = render(sharded, *flags, "--shard", f"{i}/2")
        assert res.returncode == 0, res.stderr[-2000:]
        assert f"fogsim render --out {sharded} --finalize-only" in res.stdout  # the reminder, exact
    res = render(sharded, "--finalize-only", "--resolution", "640x426")
    assert res.returncode == 2 and "resolution: [96, 64] recorded, [640, 426] with --resolution" in res.stderr
    assert not (sharded / "dataset.json").exists()
    res = render(sharded, "--finalize-only")
    assert res.returncode == 0, res.stderr[-2000:]
    assert "finalize: 2 frames found of the run's 2" in res.stdout
    assert render(whole, *flags).returncode == 0
    manifest = json.loads((sharded / "dataset.json").read_text())
    assert [lv["key"] for lv in manifest["levels"]] == ["clear", "beta0.06"] and "lidar" in manifest
    assert manifest["preset"]["name"] == "suburban" and manifest["blender"]
    for level in ("clear", "beta0.06"):
        a, b = (json.loads((d / "coco" / f"{level}.json").read_text()) for d in (sharded, whole))
        assert a["annotations"] == b["annotations"]
