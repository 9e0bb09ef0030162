import hashlib
import json
import signal
from pathlib import Path

import numpy as np
import pytest

from fogsim.camera import Intrinsics, depth_to_disparity, encode_disparity_png
from fogsim.io.depth_files import write_depth
from fogsim.io.images import write_image
from fogsim.readers.waymo import tfrecord

# A run started in the background of a non-interactive shell (`bash .ci/run &`, nohup) inherits SIGINT
# *ignored*, and so would every process the tests start: the Ctrl-C tests (tests/test_interrupts.py, the
# hostile suites) need it delivered. A Python handler here is reset to the default in each child at exec.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def expected_yolo_lines(mask: np.ndarray, objects: list[dict], visible_fraction: dict, min_pixels: int,
                        min_visible_fraction: float) -> list[str]:
    """A frame's YOLO label lines recomputed from its instance mask by brute force, without the
    label code: every labelled object (scene order) with at least ``min_pixels`` mask pixels and
    ``visible_fraction[id] >= min_visible_fraction``; its tight pixel-edge box [x0, y0, x1, y1)
    as "cls cx cy w h", normalised by the image size, 6 decimals."""
    from fogsim.scene.classes import CLASS_ID, LABELLED

    h, w = mask.shape
    lines = []
    for obj in objects:
        v, u = np.nonzero(mask == obj["id"])
        if obj["class"] not in LABELLED or len(u) < min_pixels or visible_fraction[obj["id"]] < min_visible_fraction:
            continue
        x0, y0, x1, y1 = int(u.min()), int(v.min()), int(u.max()) + 1, int(v.max()) + 1
        lines.append(f"{CLASS_ID[obj['class']]} {(x0 + x1) / 2 / w:.6f} {(y0 + y1) / 2 / h:.6f} "
                     f"{(x1 - x0) / w:.6f} {(y1 - y0) / h:.6f}")
    return lines


def tree_digest(root: Path) -> str:
    """A hash of every file's path and bytes under root (to prove inputs are untouched)."""
    h = hashlib.sha256()
    for p in sorted(root.rglob("*")):
        if p.is_file():
            h.update(str(p.relative_to(root)).encode())
            h.update(p.read_bytes())
    return h.hexdigest()


def run_hostile_case(case, tmp_path: Path, capsys, in_process: bool = True) -> str:
    """Run a hostile case's command line (``case.build(tmp_path)``, ``{tmp}`` = tmp_path) through
    ``fogsim.cli.main`` in ``tmp_path`` (``in_process=False``: ``python -m fogsim`` in a process of its
    own, for commands that load Blender); check its exit code, no traceback, the expected texts and
    that ``tmp_path/in`` (the inputs) is unchanged, and that nothing partial is left. Returns stderr."""
    import subprocess
    import sys

    from fogsim.cli import main
    from fogsim.io.parts import PART_SUFFIX

    argv = [a.replace("{tmp}", str(tmp_path)) for a in case.build(tmp_path)]
    capsys.readouterr()
    before = tree_digest(tmp_path / "in")
    if in_process:
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse's own usage errors
            code = exc.code
        err = capsys.readouterr().err
    else:
        res = subprocess.run([sys.executable, "-m", "fogsim", *argv], capture_output=True, text=True,
                             timeout=HANG_S, cwd=tmp_path)
        code, err = res.returncode, res.stderr
    assert code == case.code, err
    assert "Traceback" not in err
    for text in case.says:
        assert text.replace("{tmp}", str(tmp_path)) in err, err
    assert tree_digest(tmp_path / "in") == before, "an input changed"
    outputs = [p for p in tmp_path.rglob("*") if p.is_file() and p.relative_to(tmp_path).parts[0] != "in"]
    # an empty file is a half-written one, except a YOLO label file: empty is "no object" (visible/labels/ has
    # them wherever the fog hides every object of a frame)
    left = list(tmp_path.rglob(f"*{PART_SUFFIX}")) + [p for p in outputs if p.stat().st_size == 0 and not (
        p.suffix == ".txt" and p.parent.parent.name == "labels")]
    assert not left, f"partial files left: {left}"
    return err


def run_sensor_case(case, tmp_path: Path, capsys, monkeypatch, needs_itur: bool = False) -> str:
    """A hostile case of the sensor surfaces (:func:`run_hostile_case` in ``tmp_path`` with the case's ``env``):
    a refusal is one line each (under 1000 characters) and never a library's raw failure (a MemoryError,
    numpy's wording). ``needs_itur``: skipped without itur (radar sweeps' fog). Returns stderr."""
    if needs_itur:
        pytest.importorskip("itur")
    monkeypatch.chdir(tmp_path)
    for key, value in getattr(case, "env", {}).items():
        monkeypatch.setenv(key, value)
    err = run_hostile_case(case, tmp_path, capsys)
    if case.code:
        lines = [ln for ln in err.splitlines() if ln.startswith(("fogsim: error", "  failed:"))]
        # one line each (a schema error lists the allowed keys)
        assert lines and all(len(ln) < 1000 for ln in lines), err
        assert "MemoryError" not in err and "usecols" not in err and "all input arrays" not in err, err
    return err


@pytest.fixture
def folder_dataset(tmp_path):
    """images/{a,sub/b}.png + depth/{a,sub/b}.exr (planar Z, sky inf) + K.json."""
    rng = np.random.default_rng(5)
    K = Intrinsics(fx=30.0, fy=30.0, cx=15.5, cy=11.5, width=32, height=24)
    for name in ("a", "sub/b"):
        write_image(tmp_path / "images" / f"{name}.png", rng.integers(0, 256, (24, 32, 3), dtype=np.uint8))
        depth = rng.uniform(2, 120, (24, 32)).astype(np.float32)
        depth[:3] = np.inf
        write_depth(tmp_path / "depth" / f"{name}.exr", depth)
    (tmp_path / "K.json").write_text(json.dumps(K.to_dict()))
    return tmp_path


@pytest.fixture
def cityscapes_root(tmp_path):
    """A two-image Cityscapes tree: leftImg8bit, disparity (uint16, with holes), camera."""
    rng = np.random.default_rng(9)
    root = tmp_path / "cityscapes"
    cam = {"extrinsic": {"baseline": 0.209}, "intrinsic": {"fx": 40.0, "fy": 40.0, "u0": 19.5, "v0": 9.5}}
    for base in ("aachen_000000_000019", "aachen_000001_000019"):
        img = rng.integers(0, 256, (20, 40, 3), dtype=np.uint8)
        write_image(root / "leftImg8bit" / "val" / "aachen" / f"{base}_leftImg8bit.png", img)
        depth = rng.uniform(3, 60, (20, 40)).astype(np.float32)
        disp = encode_disparity_png(depth_to_disparity(depth, 0.209, 40.0))
        disp[:2, :4] = 0  # holes
        write_image(root / "disparity" / "val" / "aachen" / f"{base}_disparity.png", disp)
        (root / "camera" / "val" / "aachen").mkdir(parents=True, exist_ok=True)
        (root / "camera" / "val" / "aachen" / f"{base}_camera.json").write_text(json.dumps(cam))
    return root


def _crc_implementations():
    """The numpy fallback always; the compiled module too when one is installed."""
    return ["fallback"] + (["compiled"] if tfrecord._FAST_CRC32C is not None else [])


@pytest.fixture(params=_crc_implementations())
def crc_impl(request, monkeypatch):
    """Each TFRecord CRC32C implementation in turn (Waymo v1 tests that read records)."""
    if request.param == "fallback":  # as if neither google_crc32c nor crc32c were installed
        monkeypatch.setattr(tfrecord, "_FAST_CRC32C", None)
    return request.param


# ----------------------------------------------------------------------------- signals at a known point
#: how long a run may take to reach the point a signal test waits for before the test calls it a hang
#: (never reached on a healthy machine however slow; the wait ends as soon as the point is reached)
HANG_S = 1800


def wait_until(proc, reached, what: str, hang_s: float = HANG_S, poll_s: float = 0.02) -> None:
    """Wait until ``reached()`` (a file the run writes mid-way: a point it reaches by construction,
    not a time); fail if the run ends first, or hangs for ``hang_s``."""
    import time

    start = time.monotonic()
    while not reached():
        if proc.poll() is not None:
            pytest.fail(f"the run ended (exit {proc.returncode}) before {what}")
        if time.monotonic() - start > hang_s:
            proc.kill()
            pytest.fail(f"the run did not reach {what} in {hang_s:.0f} s (hung?)")
        time.sleep(poll_s)


def signal_mid_run(proc, reached, unfinished, sig, what: str, poll_s: float = 0.02) -> None:
    """Send ``sig`` to ``proc``'s process group (started with ``start_new_session=True``, as a
    terminal's Ctrl-C reaches a foreground group) at a point the run reaches by construction: once
    ``reached()``, the group is stopped (SIGSTOP), ``unfinished()`` checks there is work left — a
    stopped run cannot finish meanwhile — and the signal is sent before it continues (SIGCONT), so
    it lands mid-run on any machine, fast or loaded."""
    import os
    import signal

    wait_until(proc, reached, what, poll_s=poll_s)
    os.killpg(proc.pid, signal.SIGSTOP)
    try:
        assert proc.poll() is None and unfinished(), f"the run had no work left at {what}"
        os.killpg(proc.pid, sig)
    finally:
        if sig != signal.SIGKILL:
            os.killpg(proc.pid, signal.SIGCONT)
