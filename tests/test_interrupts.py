"""Ctrl-C means stop in every mode (issue 31, item 3; U15): ``fogsim fog`` (tests/test_run_safety.py),
scene mode and volumetric fog with the bpy module, the Blender binary, the add-on's batch, the study.

Each run is interrupted at a point it reaches by construction: inside a render (a ``render_pre``
handler sends SIGINT, tests/blender_scripts/sigint_at_render.py) or, for the study, once an epoch's
checkpoint is written (the run stopped while the signal is sent: conftest.signal_mid_run). Each must
exit 130 with one line, no traceback, nothing partial, and resume when run again.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import HANG_S, signal_mid_run
from test_blender import BLENDER, ROOT, SCRIPTS, runner

pytestmark = [pytest.mark.blender, pytest.mark.slow]
HOOK = SCRIPTS / "sigint_at_render.py"
RENDER = ["--samples", "2", "--levels", "clear,0.06", "--quiet"]


def _interrupted(res: subprocess.CompletedProcess, out: Path, committed: int) -> None:
    err = res.stdout[-2000:] + res.stderr[-3000:]
    assert res.returncode == 130, err
    assert "Traceback" not in res.stderr and "KeyboardInterrupt" not in res.stderr, err
    assert [ln for ln in res.stderr.splitlines() if ln.strip()] == ["fogsim: error: interrupted"], err
    assert len(list((out / "meta").glob("*.json"))) == committed, err
    assert not list(out.rglob("*.part")), "a partial file was left"


def _run(cmd, at: int, **kw) -> subprocess.CompletedProcess:
    env = dict(os.environ, SIGINT_AT_RENDER=str(at))
    return subprocess.run(cmd, capture_output=True, text=True, timeout=HANG_S, cwd=ROOT, env=env, **kw)


def test_scene_mode_stops_on_ctrl_c_during_cycles(tmp_path):
    """U15: Cycles' engine callback swallowed the KeyboardInterrupt: 'rendered 3 frames', exit 0."""
    from test_scene_mode import SPEC, _build

    blend = _build("bpy", tmp_path, SPEC)
    out = tmp_path / "out"
    argv = ["render", "--scene", str(blend), "--frame-range", "1:3", "--resolution", "48x32", "--out", str(out),
            *RENDER]
    res = _run([sys.executable, str(HOOK), *argv], at=2)  # inside frame 2's Cycles render
    _interrupted(res, out, committed=1)
    res = subprocess.run([sys.executable, "-m", "fogsim", *argv], capture_output=True, text=True, timeout=HANG_S)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "2 frames (1 already done" in res.stdout and len(list((out / "meta").glob("*.json"))) == 3


def test_volumetric_fog_stops_on_ctrl_c_during_a_fog_render(tmp_path):
    out = tmp_path / "out"
    argv = ["render", "--preset", "default", "--frames", "2", "--resolution", "48x32", "--fog", "volumetric",
            "--out", str(out), *RENDER]
    res = _run([sys.executable, str(HOOK), *argv], at=2)  # frame 0: the clear render, then this fog render
    _interrupted(res, out, committed=0)
    res = subprocess.run([sys.executable, "-m", "fogsim", *argv], capture_output=True, text=True, timeout=HANG_S)
    assert res.returncode == 0, res.stderr[-3000:]
    assert len(list((out / "meta").glob("*.json"))) == 2


def test_the_blender_binary_stops_on_ctrl_c(tmp_path):
    """Blender's own SIGINT handler broke the render in progress and went on (the frame lost)."""
    runner("blender")  # skips without Debian's blender
    out = tmp_path / "out"
    args = ["--preset", "default", "--frames", "2", "--resolution", "48x32", "--out", str(out), *RENDER]
    cmd = [BLENDER, "-b", "--factory-startup", "-noaudio", "--python", str(HOOK), "-P",
           str(ROOT / "scripts" / "render_batch.py"), "--", *args]
    res = _run(cmd, at=2)  # frame 1's render
    _interrupted(res, out, committed=1)
    res = subprocess.run(cmd[:5] + cmd[7:], capture_output=True, text=True, timeout=HANG_S, cwd=ROOT)
    assert res.returncode == 0, res.stderr[-3000:]
    assert len(list((out / "meta").glob("*.json"))) == 2


def test_the_addon_batch_stops_on_ctrl_c(tmp_path):
    """An operator cannot raise: Blender catches its exceptions, so the calling script went on."""
    runner("bpy")
    out = tmp_path / "out"
    res = _run([sys.executable, str(SCRIPTS / "addon_interrupt.py"), str(out)], at=2)
    assert "AFTER" not in res.stdout, res.stdout[-2000:]
    err = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 130 and err == ["fogsim: error: interrupted"], res.stderr[-3000:]
    assert len(list((out / "meta").glob("*.json"))) == 1 and not list(out.rglob("*.part"))


@pytest.mark.detect
def test_the_study_stops_on_ctrl_c_and_resumes(tmp_path):
    """Ctrl-C once the first model is finished and before the last is (the run stopped while it is
    sent): exit 130, one line; the rerun keeps the finished model and trains the rest."""
    from study_driver import TINY, need_detect_extra
    from synthetic_dataset import make_dataset

    need_detect_extra()
    ds = make_dataset(tmp_path / "ds", frames=8, train_fraction=0.5)
    out = tmp_path / "study"
    argv = [sys.executable, "-m", "fogsim", "study", "--out", str(out), "--dataset", str(ds), *TINY, "--quiet"]
    first, last = out / "runs" / "clear" / "fogsim_done.json", out / "runs" / "mixed" / "fogsim_done.json"
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                            start_new_session=True)
    signal_mid_run(proc, first.is_file, lambda: not last.exists(), signal.SIGINT, "the first model was done")
    _, err = proc.communicate(timeout=HANG_S)
    assert proc.returncode == 130, err[-3000:]
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert "Traceback" not in err and lines[-1] == "fogsim: error: interrupted", err[-3000:]
    assert not (out / "report" / "report.md").exists() and not list(out.rglob("*.part"))
    done = first.read_bytes()
    res = subprocess.run(argv, capture_output=True, text=True, timeout=HANG_S, cwd=ROOT)
    assert res.returncode == 0, res.stderr[-3000:]
    assert first.read_bytes() == done and last.is_file() and (out / "report" / "report.md").is_file()
