"""One front door: every ``fogsim`` subcommand's --help works without Blender, torch or
Ultralytics, and a command that needs a missing extra exits 2 with one line naming the fix."""
import json
import subprocess
import sys

import pytest

SUBCOMMANDS = (["render"], ["fog"], ["demo"], ["levels"], ["ila"], ["ila", "train"], ["ila", "fill"],
               ["ila", "predict"], ["study"], ["bench"], ["bench", "fog"], ["bench", "render"], ["bench", "ila"],
               ["lidar-fit"], ["lidar-compare"])


def run_without_extras(*argv: str, cwd=None) -> subprocess.CompletedProcess:
    """``fogsim ARGV`` in a fresh Python in which bpy, torch and Ultralytics cannot be imported."""
    code = ("import sys\n"
            "for m in ('bpy', 'torch', 'ultralytics', 'mathutils'): sys.modules[m] = None\n"
            "from fogsim.cli import main\n"
            f"code = main({list(argv)!r})\n"
            "loaded = [m for m in ('bpy', 'torch', 'ultralytics') if sys.modules.get(m) is not None]\n"
            "print('LOADED ' + repr(loaded))\n"
            "sys.exit(code)\n")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=cwd)


@pytest.mark.parametrize("argv", SUBCOMMANDS, ids=" ".join)
def test_help_works_without_optional_extras(argv):
    res = run_without_extras(*argv, "--help")
    assert res.returncode == 0, res.stderr
    assert "usage: fogsim " + " ".join(argv) in res.stdout
    assert "Traceback" not in res.stderr


def test_render_without_blender_is_a_setup_error(tmp_path):
    res = run_without_extras("render", "--out", str(tmp_path / "o"), "--frames", "1")
    assert res.returncode == 2, res.stderr
    assert "rendering needs Blender" in res.stderr and "fogsim[blender]" in res.stderr
    assert "Traceback" not in res.stderr and not (tmp_path / "o").exists()


def test_bad_preset_is_refused_before_blender_is_needed(tmp_path):
    res = run_without_extras("render", "--out", str(tmp_path / "o"), "--preset", "nope")
    assert res.returncode == 2 and "nope.json: preset not found" in res.stderr, res.stderr


def test_fog_runs_without_optional_extras(tmp_path):
    res = run_without_extras("demo", "--out", str(tmp_path / "d"), "--frames", "1", "--quiet")
    assert res.returncode == 0, res.stderr
    assert "LOADED []" in res.stdout
    assert (tmp_path / "d" / "fog_strip.png").is_file()


def test_python_m_fogsim_is_the_cli(tmp_path):
    res = subprocess.run([sys.executable, "-m", "fogsim", "levels"], capture_output=True, text=True, timeout=60,
                         cwd=tmp_path)
    assert res.returncode == 0 and "paper" in res.stdout and "beta0.12" in res.stdout, res.stderr


def test_import_fogsim_loads_no_heavy_extras():
    code = ("import sys, json, fogsim, fogsim.cli; fogsim.cli.build_parser(); "
            "print(json.dumps([m for m in ('bpy', 'torch', 'ultralytics') if m in sys.modules]))")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and json.loads(res.stdout) == [], res.stdout + res.stderr
