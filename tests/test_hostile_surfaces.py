"""Hostile cases on the surfaces added since round three (issue 31, item 6): fit-fog, the study's
flags, presets' assets, skies and sensor, the asset library, scene mode (Blender cases under the
``blender`` marker) — in the style of :mod:`test_hostile`: each case builds its inputs under
``tmp/in``, runs one ``fogsim`` command and checks the exit code, a one-line message naming the
file or flag, no traceback, every input byte-identical, nothing partial and (exit 2) nothing written.
The Python API of ``fogsim.augment`` has its own table in :mod:`test_augment_hostile`.
"""
from __future__ import annotations

import json
import shutil
import tempfile
from pathlib import Path

import pytest

from conftest import run_hostile_case
from test_hostile import Case

_CACHE = Path(tempfile.mkdtemp(prefix="fogsim-hostile-surfaces-"))


# ----------------------------------------------------------------------------- inputs
def fog_physics_run(tmp: Path) -> Path:
    """tmp/in/fp: a fog-physics folder (a committed clear frame, two stand-in volumetric runs), built once."""
    from test_fog_physics_bench import make_bench_dir

    cached = _CACHE / "fp"
    if not cached.is_dir():
        make_bench_dir(_CACHE / "fp.part")
        (_CACHE / "fp.part").rename(cached)
    dest = tmp / "in" / "fp"
    shutil.copytree(cached, dest)
    return dest


def _fit(*argv: str, prepare=None):
    """``fogsim fit-fog`` on tmp/in/fp; ``{fp}`` in an argument is that folder; ``prepare(tmp, fp)`` first."""
    def build(tmp: Path) -> list[str]:
        fp = fog_physics_run(tmp)
        if prepare:
            prepare(tmp, fp)
        return ["fit-fog", *[a.replace("{fp}", str(fp)) for a in argv], "--quiet"]
    return build


def _start_file(tmp: Path, fp: Path) -> None:
    from fogsim.fog.scatter import shipped_params_path

    shutil.copy(shipped_params_path(), tmp / "in" / "start.json")


def _existing_folder(tmp: Path, fp: Path) -> None:
    (tmp / "in" / "a_folder").mkdir()


FIT_FOG = [
    Case("fit-fog-out-is-its-run-file", _fit("{fp}", "--out", "{fp}/clear/render_run.json"), 2,
         ("--out lies inside RUN_DIR", "render_run.json")),
    Case("fit-fog-out-inside-its-run", _fit("{fp}", "--out", "{fp}/params.json"), 2, ("--out lies inside RUN_DIR",)),
    Case("fit-fog-out-is-its-run", _fit("{fp}", "--out", "{fp}"), 2, ("{tmp}/in/fp", "--out is a folder")),
    Case("fit-fog-out-is-start", _fit("{fp}", "--start", "{tmp}/in/start.json", "--out", "{tmp}/in/start.json",
                                      prepare=_start_file), 2, ("--out is --start",)),
    Case("fit-fog-out-existing-folder", _fit("{fp}", "--out", "{tmp}/in/a_folder", prepare=_existing_folder), 2,
         ("{tmp}/in/a_folder: --out is a folder",)),
    Case("fit-fog-out-read-only", _fit("{fp}", "--out", "/sys/p.json"), 2, ("/sys/p.json", "cannot be written")),
    Case("fit-fog-out-empty", _fit("{fp}", "--out", ""), 2, ("--out must name a file",)),
    Case("fit-fog-run-missing", _fit("{tmp}/in/nothing", "--out", "{tmp}/p.json"), 2, ("nothing",)),
    Case("fit-fog-start-missing", _fit("{fp}", "--start", "{tmp}/in/none.json", "--out", "{tmp}/p.json"), 2,
         ("none.json", "not found")),
    Case("fit-fog-start-not-params", _fit("{fp}", "--start", "{fp}/clear/render_run.json", "--out", "{tmp}/p.json"),
         2, ("render_run.json",)),
    Case("fit-fog-glow-only-without-night", _fit("{fp}", "--glow-only", "--out", "{tmp}/p.json"), 2,
         ("night",)),
]

CASES = FIT_FOG


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_hostile_surface_case(case: Case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    err = run_hostile_case(case, tmp_path, capsys)
    assert len(err.strip().splitlines()) == 1, err
    if case.code == 2:
        written = [p for p in tmp_path.rglob("*") if p.is_file() and p.relative_to(tmp_path).parts[0] != "in"]
        assert not written, f"a usage error wrote {written}"


def test_fit_fog_into_a_folder_of_its_own_runs(tmp_path, capsys):
    """The corrected command (an --out beside the runs) writes the parameter file, once."""
    from fogsim.cli import main

    fp = fog_physics_run(tmp_path)
    out = tmp_path / "params.json"
    assert main(["fit-fog", str(fp), "--out", str(out), "--quiet"]) == 0
    assert json.loads(out.read_text())["parameters"]
