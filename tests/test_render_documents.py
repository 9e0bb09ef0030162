"""A rendered dataset's own documents at finalize time (issue 18, part A), with real Blender (the
bpy module, 96×64, 2 samples): a damaged or stray ``meta/*.json`` is skipped and named (exit 1,
not a traceback or an ``int('notes')`` error), ``dataset.json``'s ``preset.frames`` never shrinks
on a resume with fewer ``--frames``, and ``--finalize-only`` says how many frames it found and,
with ``--shard i/N``, which shards' frames are absent."""
from __future__ import annotations

import json
import shutil

import pytest

from test_blender import render_dataset

pytestmark = [pytest.mark.blender, pytest.mark.slow]


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    out = tmp_path_factory.mktemp("render") / "ds"
    res = render_dataset("bpy", out, "--frames", "3")
    assert res.returncode == 0, res.stderr[-2000:]
    return out


def _copy(rendered, tmp_path):
    ds = tmp_path / "ds"
    shutil.copytree(rendered, ds)
    return ds


def _errors(res) -> list[str]:
    return [ln for ln in res.stderr.splitlines() if ln.strip()]


@pytest.mark.parametrize("name, text, says", [
    ("000001.json", "[]", "must be a JSON object"),
    ("notes.json", json.dumps({"frame": "notes", "width": 96, "height": 64, "objects": []}),
     "not a frame of a render"),
    ("notes.json", "{}", "lacks"),
])
def test_finalize_skips_and_names_a_damaged_or_stray_meta(rendered, tmp_path, name, text, says):
    ds = _copy(rendered, tmp_path)
    (ds / "meta" / name).write_text(text)
    res = render_dataset("bpy", ds, "--frames", "3", "--finalize-only")
    assert res.returncode == 1 and "Traceback" not in res.stderr, res.stderr[-2000:]
    errors = _errors(res)
    assert len(errors) == 1 and errors[0].startswith(f"  skipped: {ds / 'meta' / name}: ") and says in errors[0], errors
    assert (ds / "meta" / name).read_text() == text  # the damaged file is left as it was
    manifest = json.loads((ds / "dataset.json").read_text())
    good = 2 if name == "000001.json" else 3
    assert manifest["frames"] == good and len(manifest["skipped_frames"]) == 1
    assert len(json.loads((ds / "coco" / "clear.json").read_text())["images"]) == good


def test_resume_with_fewer_frames_keeps_preset_frames(rendered, tmp_path):
    ds = _copy(rendered, tmp_path)
    assert json.loads((ds / "dataset.json").read_text())["preset"]["frames"] == 3
    res = render_dataset("bpy", ds, "--frames", "2")  # everything done: resume, then finalize
    assert res.returncode == 0, res.stderr[-2000:]
    manifest = json.loads((ds / "dataset.json").read_text())
    assert manifest["frames"] == 3 and manifest["preset"]["frames"] == 3


def test_finalize_only_says_what_it_found_and_which_shards_are_absent(rendered, tmp_path):
    ds = _copy(rendered, tmp_path)
    (ds / "meta" / "000001.json").unlink()  # frame 1 of 4 (shard 1/2) and frame 3 (never rendered) absent
    res = render_dataset("bpy", ds, "--frames", "4", "--shard", "1/2", "--finalize-only")
    assert res.returncode == 0, res.stderr[-2000:]
    assert "finalize: 2 frames found of the run's 4; 2 absent (frames 1, 3), from shards 1/2" in res.stdout, res.stdout
    res = render_dataset("bpy", ds, "--frames", "2", "--finalize-only")
    assert "finalize: 2 frames found of the run's 2; 1 absent (frames 1)" in res.stdout, res.stdout
