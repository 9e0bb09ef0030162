"""``--quiet`` prints errors and the summary line only; Blender's own output never reaches the terminal.

The capture itself (file descriptors 1 and 2, C's stdio buffer, restored on error) is tested
here without Blender; the commands run as real subprocesses and every byte they print to
stdout and stderr is counted. The Blender tier renders tiny frames with the bpy module and
Debian's ``blender -b -P`` and checks the output and the device recorded for ``--gpu``.
"""
import ctypes
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fogsim.console import captured_fds, last_segment
from fogsim.io.depth_files import write_depth
from fogsim.io.documents import write_json
from fogsim.render.blender.output import blender_output, classify

ROOT = Path(__file__).resolve().parents[1]
BLENDER = shutil.which("blender")
TINY = ["--frames", "1", "--resolution", "96x64", "--samples", "2", "--levels", "clear,0.06"]
LIBC = ctypes.CDLL(None)


def fogsim(*args, timeout=600):
    return subprocess.run([sys.executable, "-m", "fogsim", *map(str, args)], cwd=ROOT, capture_output=True,
                          text=True, timeout=timeout)


def printed(res) -> list[str]:
    """Every non-empty line the process printed, stdout then stderr."""
    return [ln for ln in (res.stdout + res.stderr).splitlines() if ln.strip()]


# --- the capture ---------------------------------------------------------------------------------

def test_captured_fds_holds_back_c_output_and_restores_the_descriptors(capfd):
    before = os.fstat(1).st_ino, os.fstat(2).st_ino
    with captured_fds() as lines:
        os.write(1, b"Fra:1 Mem:1M | Sample 1/2\n")
        LIBC.printf(b"Saved: '/tmp/x.exr'\n")  # C's buffered stdout: must be flushed inside
        os.write(2, b"from C on stderr\n")
    assert (os.fstat(1).st_ino, os.fstat(2).st_ino) == before
    out, err = capfd.readouterr()
    assert out == "" and err == ""
    assert lines["stdout"] == ["Fra:1 Mem:1M | Sample 1/2", "Saved: '/tmp/x.exr'"]
    assert lines["stderr"] == ["from C on stderr"]


def test_captured_fds_restores_on_error(capfd):
    before = os.fstat(1).st_ino
    with pytest.raises(RuntimeError):
        with captured_fds() as lines:
            os.write(1, b"half\n")
            raise RuntimeError("boom")
    assert os.fstat(1).st_ino == before and lines["stdout"] == ["half"]
    os.write(1, b"after\n")
    assert capfd.readouterr().out == "after\n"


@pytest.mark.parametrize("line, kind", [
    ("Fra:1 Mem:66.88M (Peak 66.88M) | Time:00:00.11 | Mem:0.00M | fogsim, ViewLayer | Sample 1/2", "progress"),
    ("Saved: '/tmp/ds/.fogsim_tmp/000000.left.exr'", "progress"),
    (" Time: 00:00.51 (Saving: 00:00.00)", "progress"),
    ("00:05.101  render           | Saved: '/tmp/x.exr'", "progress"),
    ("", "progress"),
    ("render:  50%|█████     | 1/2 [00:05<00:05,  5.0s/frame]", "progress"),
    ("00:00.744  cycles           | WARNING CUEW initialization failed: Error opening the library", "other"),
    ("Warning: texture not found", "other"),
    ("Error: Not freed memory blocks: 2", "error"),
    ("00:01.000  cycles           | ERROR out of memory", "error"),
    ("RuntimeError: Error: cannot render", "error"),
])
def test_blender_lines_are_sorted(line, kind):
    assert classify(line) == kind


@pytest.mark.parametrize("quiet", [True, False])
def test_blender_output_drops_progress_keeps_errors(capfd, quiet):
    with blender_output(quiet=quiet):
        LIBC.printf(b"Fra:1 Mem:1M | Sample 1/2\nSaved: '/tmp/a.exr'\n Time: 00:00.51 (Saving: 00:00.00)\n")
        os.write(1, b"Warning: a texture is missing\n")
        os.write(2, b"Error: the render failed\n")
    out, err = capfd.readouterr()
    assert "Saved" not in out + err and "Fra:" not in out + err and "Time:" not in out + err
    assert err.splitlines() == ["Error: the render failed"]
    assert out.splitlines() == ([] if quiet else ["Warning: a texture is missing"])


def test_blender_output_shows_errors_when_the_block_raises(capfd):
    with pytest.raises(KeyboardInterrupt):
        with blender_output(quiet=True):
            os.write(2, b"Error: interrupted\n")
            raise KeyboardInterrupt
    assert capfd.readouterr().err == "Error: interrupted\n"


SUMMARY_ONLY = """
import os, subprocess, sys
from fogsim.console import summary_only
with summary_only({quiet}):
    print("a table\\nof figures")
    os.write(2, b"\\rbench:  50%|#####     | 1/2 [00:01<00:01]\\n")
    os.write(2, b"error: one item failed\\n")
    subprocess.run([sys.executable, "-c", "print('a child process line')"])
    print("bench x: 3.1x faster")
"""


def test_summary_only_prints_the_last_line_and_errors():
    """In a process of its own: Python's print must go to file descriptor 1 as it does outside pytest."""
    run = lambda quiet: subprocess.run([sys.executable, "-c", SUMMARY_ONLY.format(quiet=quiet)], cwd=ROOT,  # noqa: E731
                                       capture_output=True, text=True, timeout=60)
    res = run(True)
    assert res.returncode == 0, res.stderr
    assert res.stdout == "bench x: 3.1x faster\n" and res.stderr == "error: one item failed\n"
    res = run(False)
    assert res.stdout == "a table\nof figures\na child process line\nbench x: 3.1x faster\n"


# --- the commands --------------------------------------------------------------------------------

def test_demo_quiet_prints_one_line(tmp_path):
    res = fogsim("demo", "--out", tmp_path / "d", "--frames", "1", "--quiet")
    assert res.returncode == 0, res.stderr
    assert len(printed(res)) == 1, printed(res)
    loud = fogsim("demo", "--out", tmp_path / "e", "--frames", "1")
    assert loud.stdout.splitlines()[-1].startswith("fog strip: ") and "100%|" in loud.stderr  # the bar


def test_fog_quiet_prints_one_line(folder_dataset, tmp_path):
    ds = folder_dataset
    res = fogsim("fog", "--input", ds / "images", "--depth", ds / "depth", "--intrinsics", ds / "K.json",
                 "--out", tmp_path / "o", "--levels", "clear,0.05", "--quiet")
    assert res.returncode == 0, res.stderr
    assert len(printed(res)) == 1, printed(res)


def on_terminal(*args, size: tuple[int, int] | None = None) -> tuple[int, str]:
    """``fogsim ARGS`` with stdout and stderr on a pseudo-terminal (``size``: columns × lines set on it; None:
    left at 0 × 0, as ``script`` or a CI runner opens one); returns (exit code, everything it printed)."""
    import fcntl
    import pty
    import struct
    import termios

    master, slave = pty.openpty()
    if size is not None:
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", size[1], size[0], 0, 0))
    proc = subprocess.Popen([sys.executable, "-m", "fogsim", *map(str, args)], cwd=ROOT, stdin=subprocess.DEVNULL,
                            stdout=slave, stderr=slave)
    os.close(slave)
    chunks = []
    while True:  # read while it runs (a full pseudo-terminal would block it), until its side closes
        try:
            data = os.read(master, 65536)
        except OSError:  # EIO: every writer has exited
            break
        if not data:
            break
        chunks.append(data)
    os.close(master)
    return proc.wait(timeout=600), b"".join(chunks).decode("utf-8", "replace").replace("\r\n", "\n")  # the tty's


@pytest.mark.parametrize("size", [None, (100, 30)])
def test_fog_draws_its_progress_bar_on_a_terminal_and_nothing_with_quiet(folder_dataset, tmp_path, size):
    ds = folder_dataset
    args = ["fog", "--input", ds / "images", "--depth", ds / "depth", "--intrinsics", ds / "K.json", "--levels",
            "clear,0.05"]
    rc, text = on_terminal(*args, "--out", tmp_path / "loud", size=size)
    assert rc == 0, text
    shown = [last_segment(ln) for ln in text.split("\n") if last_segment(ln)]  # what the terminal keeps
    bar = [seg for ln in text.split("\n") for seg in ln.split("\r") if seg.startswith("fog: ")]
    assert bar and bar[-1].startswith("fog: 100%|") and "| 2/2 [" in bar[-1], text  # the bar, as render's
    assert len(bar[-1].rstrip()) <= (size or (80, 24))[0]  # drawn within the terminal (0 columns: 80)
    assert shown[-2].startswith("fog: 100%|") and shown[-1].startswith("fogged 2 of 2 images"), shown
    rc, text = on_terminal(*args, "--out", tmp_path / "quiet", "--quiet", size=size)
    assert rc == 0, text
    assert "%|" not in text and [ln for ln in text.splitlines() if ln.strip()] == \
        [ln for ln in text.splitlines() if ln.startswith("fogged 2 of 2 images")]  # the summary line alone
    res = fogsim(*args, "--out", tmp_path / "piped")  # no terminal: the bar's lines still reach stderr
    assert res.returncode == 0 and "fog: 100%|" in res.stderr and "%|" not in res.stdout


def test_a_one_frame_dataset_is_one_warning_line_or_said_in_the_quiet_summary(tmp_path):
    import kitti_tree as kt

    root = kt.write_kitti(tmp_path / "in" / "kitti")
    args = ["fog", "--kitti", root, "--split", "val", "--levels", "0.06"]  # ImageSets/val.txt: one frame
    res = fogsim(*args, "--out", tmp_path / "loud")
    assert res.returncode == 0, res.stderr
    warnings = [ln for ln in res.stderr.splitlines() if "warning" in ln]
    assert warnings == ["fogsim: warning: a one-frame dataset: frame training__image_2__000002 is in both train and "
                        "val, so nothing is held out for validation (add frames for a real split)"]
    assert "dataset: 1 frame, in both train and val" in res.stdout
    assert json.loads((tmp_path / "loud" / "dataset.json").read_text())["split"]["in_both"] == [
        "training__image_2__000002"]
    res = fogsim(*args, "--out", tmp_path / "quiet", "--quiet")
    assert res.returncode == 0 and len(printed(res)) == 1 and "in both train and val" in res.stdout, printed(res)
    res = fogsim("fog", "--finalize-only", "--out", tmp_path / "quiet")
    assert res.returncode == 0 and res.stderr.count("fogsim: warning: a one-frame dataset") == 1


def test_labelled_fog_shards_and_finalize_quiet(tmp_path):
    from cityscapes_tree import make_tree

    root = make_tree(tmp_path / "cs")
    out = tmp_path / "o"
    for i in (0, 1):
        res = fogsim("fog", "--cityscapes", root, "--out", out, "--levels", "clear,0.06", "--shard", f"{i}/2",
                     "--quiet")
        assert res.returncode == 0, res.stderr
        assert len(printed(res)) == 1, printed(res)
    res = fogsim("fog", "--finalize-only", "--out", out, "--quiet")
    assert res.returncode == 0, res.stderr
    assert len(printed(res)) == 1 and printed(res)[0].startswith("dataset: 2 frames")
    whole = fogsim("fog", "--cityscapes", root, "--out", tmp_path / "w", "--levels", "clear,0.06", "--quiet")
    assert whole.returncode == 0 and len(printed(whole)) == 1, printed(whole)
    assert "; dataset: 2 frames" in printed(whole)[0]  # the run's line and the dataset's, joined
    assert (tmp_path / "w" / "dataset.json").is_file()  # quiet finalizes all the same


def test_depth_score_quiet_prints_one_line(tmp_path):
    ds, pred = tmp_path / "ds", tmp_path / "pred"
    depth = np.full((8, 12), 10.0, np.float32)
    write_json(ds / "meta" / "000000.json", {"frame": "000000"})
    write_depth(ds / "depth" / "000000.exr", depth)
    write_depth(pred / "000000.exr", depth * 1.1)
    res = fogsim("depth", "score", "--pred", pred, "--dataset", ds, "--out", tmp_path / "r", "--quiet")
    assert res.returncode == 0, res.stderr
    assert len(printed(res)) == 1 and "AbsRel 0.1000" in res.stdout, printed(res)
    assert len(printed(fogsim("depth", "score", "--pred", pred, "--dataset", ds, "--out", tmp_path / "s"))) > 3


def test_every_command_has_quiet():
    """--quiet exists on every command that does work (levels only lists presets)."""
    from fogsim.cli import build_parser

    def leaves(parser, path=()):
        subs = [a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction"]
        if not subs:
            yield path, parser
            return
        for name, p in subs[0].choices.items():
            yield from leaves(p, path + (name,))

    missing = [" ".join(path) for path, p in leaves(build_parser())
               if path != ("levels",) and "--quiet" not in p._option_string_actions]
    assert missing == []


@pytest.mark.slow
@pytest.mark.parametrize("bench", [["fog", "--repeat", "1"], ["lidar", "--repeat", "1"]])
def test_bench_quiet_prints_its_summary_line(bench):
    res = fogsim("bench", *bench, "--quiet")
    assert res.returncode == 0, res.stderr
    assert len(printed(res)) == 1 and printed(res)[0].startswith(f"bench {bench[0]}: "), printed(res)


# --- Blender -------------------------------------------------------------------------------------

def _need_bpy():
    import importlib.util

    if importlib.util.find_spec("bpy") is None:
        pytest.skip("the bpy module is not installed (the 'blender' extra)")


def _need_binary():
    if BLENDER is None:
        pytest.skip("Debian's blender binary is not installed")


def render_batch_binary(*args):
    """``blender -b -P scripts/render_batch.py -- …``, started as fogsim's tests start Blender."""
    cmd = [BLENDER, "-b", "--factory-startup", "-noaudio", *blender_quiet_flags(), "-P",
           str(ROOT / "scripts" / "render_batch.py"), "--", *map(str, args)]
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)


def blender_quiet_flags() -> list[str]:
    """Blender 4.2+ has ``-q`` (no start-up banner); 3.4 has none."""
    help_text = subprocess.run([BLENDER, "--help"], capture_output=True, text=True, timeout=60).stdout
    return ["-q"] if "\n-q, --quiet" in help_text or "\n--quiet" in help_text else []


BANNER = "Blender "  # 3.4 prints "Blender 3.4.1" before any script runs, and has no flag to stop it


def render_meta(out: Path) -> dict:
    return json.loads((out / "meta" / "000000.json").read_text())


@pytest.mark.blender
def test_render_quiet_bpy_prints_the_summary_line_only(tmp_path):
    _need_bpy()
    res = fogsim("render", "--out", tmp_path / "ds", *TINY, "--quiet")
    assert res.returncode == 0, res.stderr
    assert printed(res) == [res.stdout.strip()] and res.stdout.startswith("rendered 1 frames"), printed(res)


@pytest.mark.blender
def test_render_bpy_without_quiet_keeps_blender_off_the_bar_and_gpu_falls_back(tmp_path):
    _need_bpy()
    res = fogsim("render", "--out", tmp_path / "ds", *TINY, "--gpu")
    assert res.returncode == 0, res.stderr
    text = res.stdout + res.stderr
    assert "Saved:" not in text and "Fra:" not in text and "CUEW" not in text
    assert "frame 000000:" in res.stdout and "rendered 1 frames" in res.stdout
    assert res.stderr.count("--gpu: no OptiX or CUDA device found") == 1  # said once, on stderr
    record = render_meta(tmp_path / "ds")["render"]
    assert record["device"] == "CPU" and record["gpu_requested"] and "no OptiX or CUDA" in record["gpu_fallback"]


@pytest.mark.blender
def test_render_batch_binary_quiet_prints_the_summary_line_only(tmp_path):
    _need_binary()
    res = render_batch_binary("--out", tmp_path / "ds", *TINY, "--quiet")
    assert res.returncode == 0, res.stderr
    lines = printed(res)
    if lines and lines[0].startswith(BANNER) and not blender_quiet_flags():
        lines = lines[1:]
    assert len(lines) == 1 and lines[0].startswith("rendered 1 frames"), printed(res)


@pytest.mark.blender
def test_render_batch_binary_gpu_falls_back_to_the_cpu(tmp_path):
    _need_binary()
    res = render_batch_binary("--out", tmp_path / "ds", *TINY, "--gpu")
    assert res.returncode == 0, res.stderr
    assert "Saved:" not in res.stdout + res.stderr and "Fra:" not in res.stdout + res.stderr
    assert "--gpu: no OptiX or CUDA device found" in res.stderr
    record = render_meta(tmp_path / "ds")["render"]
    assert record["device"] == "CPU" and record["blender"].startswith("3.") and record["gpu_devices"] == []


@pytest.mark.blender
@pytest.mark.parametrize("kind", ["bpy", "blender"])
def test_gpu_backends_of_each_blender(kind, tmp_path):
    """Both Blender APIs: the backends this build has (3.4: no OptiX, assigning it raises TypeError),
    the device lists (refresh_devices + get_devices_for_type), and the CPU when none has a device."""
    script = ROOT / "tests" / "blender_scripts" / "gpu_backends.py"
    if kind == "bpy":
        _need_bpy()
        cmd = [sys.executable, str(script), str(tmp_path / "r.json")]
    else:
        _need_binary()
        cmd = [BLENDER, "-b", "--factory-startup", "-noaudio", "-P", str(script), "--", str(tmp_path / "r.json")]
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["backends"]["CUDA"] == []  # CUDA is in both builds; no device on this machine
    assert r["backends"]["OPTIX"] == (None if r["version"][0] == 3 else [])  # Debian's 3.4: no OptiX
    assert r["find_gpu"][0] is None and "no OptiX or CUDA device" in r["find_gpu"][2]
    assert r["record"] == {"device": "CPU", "gpu_requested": True, "gpu_devices": [],
                           "gpu_fallback": r["find_gpu"][2]}
    assert r["scene_device"] == "CPU" and r["no_gpu_record"] == {"device": "CPU", "gpu_requested": False}


@pytest.mark.detect
@pytest.mark.slow
def test_study_quiet_prints_the_report_line_only(tmp_path):
    """Ultralytics' log and progress bars off (YOLO_VERBOSE), no table: one line naming the report."""
    import importlib.util

    if importlib.util.find_spec("ultralytics") is None or importlib.util.find_spec("pycocotools") is None:
        pytest.skip("the 'detect' extra (Ultralytics, pycocotools) is not installed")
    from synthetic_dataset import make_dataset

    ds = make_dataset(tmp_path / "ds", frames=4)
    res = fogsim("study", "--out", tmp_path / "s", "--dataset", ds, "--epochs", "1", "--imgsz", "64", "--batch", "4",
                 "--workers", "0", "--device", "cpu", "--no-plots", "--quiet", timeout=1500)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    assert len(printed(res)) == 1 and printed(res)[0].startswith("report: "), printed(res)[:20]
