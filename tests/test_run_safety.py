"""Output folders, run claims, workers, signals, permissions and leftovers of ``fogsim fog``
(the reliability trial's defects #1, #5, #8, #9, #10, #11, #18, #24, #26)."""
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import HANG_S, signal_mid_run, tree_digest, wait_until
from fogsim.camera import Intrinsics
from fogsim.cli import main
from fogsim.errors import InputError
from fogsim.fog.batch import FogJob, check_run_file
from fogsim.fog.engine import FogSettings
from fogsim.fog.levels import parse_levels
from fogsim.io.depth_files import write_depth
from fogsim.io.images import write_image
from fogsim.io.parts import PART_SUFFIX


def fog_cli(images, depth, out, *extra):
    return ["fog", "--input", str(images), "--depth", str(depth), "--hfov", "50", "--levels", "0.06",
            "--out", str(out), "--quiet", *extra]


# ----------------------------------------------------------------------------- #1, #24: output vs input
@pytest.mark.parametrize("where", ["parent", "same", "inside", "depth_inside", "symlink"])
def test_output_overlapping_an_input_is_refused_and_nothing_changes(folder_dataset, tmp_path, capsys, where):
    x = tmp_path / "X"
    shutil.copytree(folder_dataset / "images", x / "beta0.06")
    shutil.copytree(folder_dataset / "depth", x / "depth")
    images, depth = x / "beta0.06", x / "depth"
    out = {"parent": x, "same": images, "inside": images / "fogged", "depth_inside": depth / "o",
           "symlink": tmp_path / "link"}[where]
    if where == "symlink":
        os.symlink(images, out)  # the same folder under another name
    before = tree_digest(x)
    assert main(fog_cli(images, depth, out)) == 2
    err = capsys.readouterr().err
    assert "--out" in err and ("--input" in err or "--depth" in err) and "Traceback" not in err
    assert tree_digest(x) == before
    assert not (x / "fogsim_run.json").exists() and not (images / "fogsim_run.json").exists()


def test_empty_out_is_refused(folder_dataset, tmp_path, capsys, monkeypatch):
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    assert main(fog_cli(folder_dataset / "images", folder_dataset / "depth", "")) == 2
    assert "--out must name a folder" in capsys.readouterr().err
    assert list(cwd.iterdir()) == []


# ----------------------------------------------------------------------------- #5: unwritable output
@pytest.mark.parametrize("kind", ["under_a_file", "is_a_file", "read_only"])
def test_unwritable_output_is_one_line_exit_2(folder_dataset, tmp_path, kind):
    blocker = tmp_path / "f"
    blocker.write_text("x")
    out = {"under_a_file": blocker / "sub", "is_a_file": blocker, "read_only": tmp_path / "ro" / "o"}[kind]
    if kind == "read_only":
        (tmp_path / "ro").mkdir()
        os.chmod(tmp_path / "ro", 0o555)
        if os.access(tmp_path / "ro", os.W_OK):
            pytest.skip("running as a user who can write into a read-only folder (root)")
    res = subprocess.run([sys.executable, "-m", "fogsim", *fog_cli(folder_dataset / "images",
                                                                     folder_dataset / "depth", out)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 2, res.stderr
    assert "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert str(blocker if kind != "read_only" else tmp_path / "ro") in res.stderr
    assert blocker.read_text() == "x"


# ----------------------------------------------------------------------------- #8: atomic claims
def test_claim_has_no_check_then_write_race(folder_dataset, tmp_path, monkeypatch):
    """Run B claims the folder while run A is writing its claim (a slow file system): exactly one
    of them may be accepted, and the run file must hold the winner's parameters."""
    levels = tuple(parse_levels("0.06"))
    a = FogJob(levels, str(tmp_path / "out"), FogSettings(airlight=(255.0,) * 3))
    b = FogJob(levels, str(tmp_path / "out"), FogSettings(airlight=(200.0,) * 3))
    real_mkstemp = tempfile.mkstemp
    results = {}

    def mkstemp_then_let_b_claim(*args, **kw):
        out = real_mkstemp(*args, **kw)
        if "b" not in results:
            results["b"] = "running"
            try:
                check_run_file(b, {})
                results["b"] = "accepted"
            except InputError:
                results["b"] = "refused"
        return out

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp_then_let_b_claim)
    try:
        check_run_file(a, {})
        results["a"] = "accepted"
    except InputError:
        results["a"] = "refused"
    assert sorted(results.values()) == ["accepted", "refused"], results
    stored = json.loads((tmp_path / "out" / "fogsim_run.json").read_text())["parameters"]
    winner = a if results["a"] == "accepted" else b
    assert stored["airlight"] == list(winner.parameters()["airlight"])


# ----------------------------------------------------------------------------- #10: permissions
def test_outputs_honour_the_umask(folder_dataset, tmp_path):
    old = os.umask(0o022)
    try:
        assert main(fog_cli(folder_dataset / "images", folder_dataset / "depth", tmp_path / "o")) == 0
    finally:
        os.umask(old)
    files = [p for p in (tmp_path / "o").rglob("*") if p.is_file()]
    assert files and {oct(p.stat().st_mode & 0o777) for p in files} == {"0o644"}


# ----------------------------------------------------------------------------- #11: setup errors first
def test_run_wide_errors_exit_2_before_the_folder_is_claimed(folder_dataset, tmp_path, capsys):
    images, depth = folder_dataset / "images", folder_dataset / "depth"
    wrong = tmp_path / "K_wrong.json"
    wrong.write_text(json.dumps(Intrinsics(30.0, 30.0, 15.5, 15.5, 32, 32).to_dict()))  # 1:1, images are 4:3
    cases = [(["--intrinsics", str(wrong)], "another aspect ratio"),  # wrong-aspect K.json
             (["--depth-kind", "planar"], "needs the camera intrinsics")]  # no --hfov
    for extra, message in cases:
        args = ["fog", "--input", str(images), "--depth", str(depth), "--levels", "0.06", "--out",
                str(tmp_path / "o"), "--quiet", *extra]
        assert main(args) == 2
        assert message in capsys.readouterr().err
        assert not (tmp_path / "o").exists()
    # forgotten --depth: also a setup error
    assert main(["fog", "--input", str(images), "--hfov", "50", "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "has no depth" in capsys.readouterr().err and not (tmp_path / "o").exists()
    # the corrected rerun into the same folder is accepted
    assert main(fog_cli(images, depth, tmp_path / "o")) == 0


# ----------------------------------------------------------------------------- #18: leftovers
def test_stale_temporary_files_are_removed_on_resume(folder_dataset, tmp_path):
    from fogsim.io.parts import _HOST

    out = tmp_path / "o"
    args = fog_cli(folder_dataset / "images", folder_dataset / "depth", out)
    assert main(args) == 0
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()  # a pid that is gone
    stale = out / "beta0.06" / f".a.png.{_HOST}-{dead.pid}.x1y2.part"
    old_style = out / "beta0.06" / f".b.png.abcd1234{PART_SUFFIX}"  # fogsim 0.1's naming, a day old
    alive = out / "beta0.06" / f".c.png.{_HOST}-{os.getpid()}.x1y2.part"  # a writer still running
    for p in (stale, old_style, alive):
        p.write_bytes(b"half")
    day_ago = time.time() - 2 * 24 * 3600
    os.utime(old_style, (day_ago, day_ago))
    assert main(args) == 0
    assert not stale.exists() and not old_style.exists() and alive.exists()
    assert not [p for p in out.rglob("*.png") if p.name.startswith(".")]


# ----------------------------------------------------------------------------- #9, #26: workers, signals
@pytest.fixture
def medium_dataset(tmp_path):
    """64 images of 640×480 with depth: ten seconds or more of fog with the extended form, so a signal
    sent once the first frames are written always lands mid-run (24 images raced a fast machine: the
    run had finished, exit 0, before the Ctrl-C arrived)."""
    rng = np.random.default_rng(2)
    for i in range(64):
        write_image(tmp_path / "images" / f"f{i:03d}.png", rng.integers(0, 256, (480, 640, 3), dtype=np.uint8))
        write_depth(tmp_path / "depth" / f"f{i:03d}.exr", rng.uniform(2, 150, (480, 640)).astype(np.float32))
    return tmp_path


def _children(pid: int) -> set[int]:
    out = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.add(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _start(medium, out, workers):
    args = fog_cli(medium / "images", medium / "depth", out, "--extended", "--levels", "paper",
                   "--workers", str(workers))
    return subprocess.Popen([sys.executable, "-m", "fogsim", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def _mid_run(out: Path):
    """(reached, unfinished) of a fog run into ``out``: two images fogged (their sidecars beside the
    run file), and fewer than all 64 × 5 level images written."""
    return (lambda: len(list(out.rglob("*.json"))) >= 3,
            lambda: len([p for p in out.rglob("*.png") if not p.name.startswith(".")]) < 64 * 5)


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc (Linux)")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_workers_never_outlive_their_parent(medium_dataset, tmp_path, sig):
    proc = _start(medium_dataset, tmp_path / "o", 2)
    reached, unfinished = _mid_run(tmp_path / "o")
    wait_until(proc, reached, "two images were fogged")
    workers = _children(proc.pid)  # the pool's workers (and multiprocessing's resource tracker)
    assert workers, "no worker processes seen"
    signal_mid_run(proc, reached, unfinished, sig, "two images were fogged")
    proc.wait(timeout=300)
    deadline = time.time() + 60
    while time.time() < deadline and any(_alive(p) for p in workers):
        time.sleep(0.1)
    assert not [p for p in workers if _alive(p)], "workers outlived the parent"
    time.sleep(1.0)
    files = sorted(p.name for p in (tmp_path / "o").rglob("*"))
    time.sleep(1.5)
    assert sorted(p.name for p in (tmp_path / "o").rglob("*")) == files, "something still writes"


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_ctrl_c_prints_one_line_and_exits_130(medium_dataset, tmp_path, workers):
    """Ctrl-C once two images are fogged, with the run stopped while the signal is sent: it lands
    mid-run by construction (not after a time), however fast or loaded the machine."""
    proc = _start(medium_dataset, tmp_path / "o", workers)
    signal_mid_run(proc, *_mid_run(tmp_path / "o"), signal.SIGINT, "two images were fogged")
    _, err = proc.communicate(timeout=HANG_S)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted" in err and len(err.strip().splitlines()) == 1, err
    assert not list((tmp_path / "o").rglob(f"*{PART_SUFFIX}"))
    # and the resumed run finishes the job
    args = fog_cli(medium_dataset / "images", medium_dataset / "depth", tmp_path / "o", "--extended",
                   "--levels", "paper")
    assert main(args) == 0


def test_render_and_study_refuse_an_output_over_their_input(tmp_path, capsys):
    preset = tmp_path / "mine.json"
    preset.write_text("{}")
    assert main(["render", "--preset", str(preset), "--out", str(tmp_path)]) == 2
    assert "--out contains --preset" in capsys.readouterr().err
    (tmp_path / "ds").mkdir()
    assert main(["study", "--dataset", str(tmp_path / "ds"), "--out", str(tmp_path / "ds" / "study")]) == 2
    assert "--out lies inside --dataset" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds", "mine.json"] and not list((tmp_path / "ds").iterdir())


@pytest.mark.parametrize("command", ["train", "fill", "predict"])
def test_ila_refuses_an_output_over_its_input(cityscapes_root, tmp_path, capsys, command):
    ckpt = tmp_path / "ila" / "round_0.pt"
    ckpt.parent.mkdir()
    ckpt.write_bytes(b"x")
    argv = {"train": ["ila", "train", "--data", str(cityscapes_root), "--out", str(cityscapes_root / "ila")],
            "fill": ["ila", "fill", "--checkpoint", str(ckpt), "--data", str(cityscapes_root),
                     "--out", str(cityscapes_root)],
            "predict": ["ila", "predict", "--checkpoint", str(ckpt), "--input", str(tmp_path / "ila"),
                        "--out", str(tmp_path)]}[command]
    before = tree_digest(tmp_path)
    assert main(argv) == 2
    assert "--out" in capsys.readouterr().err
    assert tree_digest(tmp_path) == before
