"""Scene mode's whole-run checks (the fourth trial's U2, U3, U4, U10, U14, U18): a scene setting or a flag
that makes no dataset is refused with one line naming it, exit 2, before the output folder is claimed, so
the corrected rerun into the same folder is accepted; a damaged frame record is reported, not dropped."""
from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from fogsim.cli import main
from fogsim.render.job_options import MAX_FRAME, RunOptions, SceneOptions, parse_frame_range
from test_scene_mode import SPEC, _build, _digest, _render

TINY = ["--samples", "1", "--levels", "clear,0.06", "--frame-range", "1:1", "--quiet"]


# ----------------------------------------------------------------------------- before Blender starts
@pytest.mark.parametrize("flags, message", [
    (["--frame-range", "1:2000000000"], f"Blender's frames are -{MAX_FRAME}…{MAX_FRAME}"),           # U2
    (["--frame-range", "1:99999999999999999999"], "Blender's frames are"),                          # U2
    (["--frame-range", "2000000:2000001"], "Blender's frames are"),                                 # U2
    (["--frame-range", "3:1"], "END ≥ START"),
    (["--fog", "volumetric", "--fog-scale", "nan"], "--fog-scale"),                                 # U14
    (["--fog", "volumetric", "--fog-scale", "0"], "--fog-scale"),                                   # U14
    (["--fog-scale", "2"], "--fog-scale"),                                                          # U14
    (["--fog", "koschmieder", "--fog-scale", "0.5"], "--fog-scale needs --fog volumetric"),
    (["--assets", "LIB"], "--assets is not available with --scene"),                               # U14
    (["--resolution", "0x0"], "--resolution"),
])
def test_scene_flags_are_refused_before_the_blend_is_opened(flags, message, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["render", "--scene", str(tmp_path / "absent.blend"), "--out", str(out), *flags]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


def test_a_huge_frame_range_is_refused_at_once_in_bounded_memory(tmp_path):
    """U2: the range is refused where it is parsed; nothing becomes a list of two billion frames."""
    code = ("import resource, sys\n"
            "resource.setrlimit(resource.RLIMIT_AS, (1 << 31, 1 << 31))\n"  # 2 GiB: far below the 12 GB it took
            "from fogsim.cli import main\n"
            f"sys.exit(main(['render', '--scene', {str(tmp_path / 's.blend')!r}, '--frame-range', '1:2000000000', "
            f"'--out', {str(tmp_path / 'out')!r}]))\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and "Blender's frames are" in res.stderr, res.stderr[-2000:]
    assert not (tmp_path / "out").exists()


def test_the_options_records_are_checked_and_shard_lazily():
    assert parse_frame_range("1:10:3") == (1, 10, 3) and parse_frame_range(f"-{MAX_FRAME}:{MAX_FRAME}")
    assert list(RunOptions(shard=(1, 3)).frames(8)) == [1, 4, 7]
    assert len(RunOptions(shard=(0, 2)).frames(10**12)) == 5 * 10**11  # a range: no list is made
    with pytest.raises(ValueError, match="--seed"):
        SceneOptions(seed=-1).check()
    with pytest.raises(ValueError, match="--levels|β"):
        SceneOptions(levels="0.1,x").check()


def test_a_scene_job_takes_four_parameters():
    import ast
    from pathlib import Path

    tree = ast.parse((Path(__file__).parents[1] / "fogsim/render/blender/scene_mode.py").read_text())
    init = next(n for c in ast.walk(tree) if isinstance(c, ast.ClassDef) and c.name == "SceneJob"
                for n in c.body if isinstance(n, ast.FunctionDef) and n.name == "__init__")
    assert len(init.args.args) - 1 <= 4
    job = (Path(__file__).parents[1] / "fogsim/render/blender").glob("*.py")
    refusal = 'fog_model.volumetric.phase \\"MIE\\" needs'  # as written in the source
    assert sum(p.read_text().count(refusal) for p in job) == 1  # the preset's MIE refusal, once


# ----------------------------------------------------------------------------- real Blender
def _refused_then_accepted(blend, tmp_path, message, fix):
    out = tmp_path / "out"
    res = _render("bpy", blend, out, *TINY)
    assert res.returncode == 2 and message in res.stderr, res.stderr[-2000:]
    assert "Traceback" not in res.stderr and not out.exists()
    res = _render("bpy", blend, out, *TINY, *fix)  # the corrected run, into the same folder
    assert res.returncode == 0, res.stderr[-2000:]


@pytest.mark.blender
@pytest.mark.slow
def test_a_render_size_of_zero_is_refused_naming_the_setting_and_the_fix_is_accepted(tmp_path):
    """U3: resolution_percentage 1 makes a 96×64 scene 0×0."""
    blend = _build("bpy", tmp_path, {**SPEC, "resolution_percentage": 1})
    _refused_then_accepted(blend, tmp_path, "renders 0×0 pixels (resolution 96×64 at 1 %)", ["--resolution", "96x64"])


@pytest.mark.blender
@pytest.mark.slow
def test_a_camera_that_is_not_finite_is_refused(tmp_path):
    """U4: a NaN camera location rendered with NaN in meta; now refused, naming the camera."""
    spec = json.loads(json.dumps(SPEC))
    spec["camera"]["location"] = [math.nan, -14, 5]
    blend = _build("bpy", tmp_path, spec)
    before = _digest(blend.parent)
    res = _render("bpy", blend, tmp_path / "out", *TINY)
    assert res.returncode == 2 and "camera 'Camera' at frame 1: its position or rotation is not finite" in res.stderr
    assert not (tmp_path / "out").exists() and _digest(blend.parent) == before


@pytest.mark.blender
@pytest.mark.slow
def test_a_missing_linked_library_is_named(tmp_path):
    """U10: a labelled car linked from lib.blend, which is then deleted."""
    lib_spec = {**SPEC, "boxes": [b for b in SPEC["boxes"] if b["name"] == "Car"], "points": [], "instances": [],
                "collections": {}}
    lib = _build("bpy", tmp_path, lib_spec, "lib.blend")
    scene = {**SPEC, "boxes": [b for b in SPEC["boxes"] if b["name"] == "Ground"], "points": [], "instances": [],
             "collections": {}, "link": [{"library": "lib.blend", "object": "Car"}]}
    blend = _build("bpy", tmp_path, scene)
    lib.unlink()
    res = _render("bpy", blend, tmp_path / "out", *TINY)
    assert res.returncode == 2 and "lib.blend" in res.stderr and "missing" in res.stderr, res.stderr[-2000:]
    assert "no labelled object" not in res.stderr and not (tmp_path / "out").exists()


@pytest.mark.blender
@pytest.mark.slow
def test_fog_scale_implies_volumetric_fog_and_a_damaged_frame_record_is_reported(tmp_path):
    """U14: --fog-scale alone is volumetric fog at that scale (recorded); U18: --finalize-only names a
    damaged frame record (exit 1) instead of leaving the frame out without a word."""
    blend = _build("bpy", tmp_path, SPEC)
    out = tmp_path / "out"
    res = _render("bpy", blend, out, "--samples", "1", "--levels", "clear,0.06", "--frame-range", "1:3:2",
                  "--resolution", "48x32", "--fog-scale", "0.5", "--quiet")
    assert res.returncode == 0, res.stderr[-2000:]
    run = json.loads((out / "render_run.json").read_text())["parameters"]
    assert run["fog_model"]["kind"] == "volumetric" and run["fog_model"]["volumetric"]["resolution_scale"] == 0.5
    meta = json.loads((out / "meta" / "000001.json").read_text())
    assert meta["fog"]["model"] == "volumetric" and meta["fog"]["resolution_scale"] == 0.5
    (out / "meta" / "000001.json").write_text("[]")
    res = _render("bpy", blend, out, "--samples", "1", "--levels", "clear,0.06", "--frame-range", "1:3:2",
                  "--resolution", "48x32", "--fog-scale", "0.5", "--finalize-only")
    assert res.returncode == 1, res.stdout[-1000:] + res.stderr[-2000:]
    assert "skipped:" in res.stderr and "000001.json" in res.stderr and "Traceback" not in res.stderr
