"""Real Blender: the bpy module (5.0) and Debian's blender binary (3.4), each end to end.

Every render here is tiny (96×64, 2 samples). Blender runs in subprocesses so each test gets
a fresh Blender and the exit code of the real entry points is what is checked. A test skips
when what it runs is not installed (the bpy module, the blender binary), except under CI.
"""
import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import expected_yolo_lines, signal_mid_run
from fogsim.boxes import parse_yolo_line
from fogsim.io.depth_files import read_depth_file, read_uint16_map
from fogsim.io.images import read_image

pytestmark = pytest.mark.blender
slow = pytest.mark.slow  # over ~10 s on 2 cores: several render runs, or building the add-on zips

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "tests" / "blender_scripts"
BLENDER = shutil.which("blender")
TINY = ["--resolution", "96x64", "--samples", "2", "--levels", "clear,0.06,0.12", "--quiet"]


def _need_binary():
    if BLENDER is None:
        if os.environ.get("CI"):
            pytest.fail("Debian's blender is not installed (scripts/test.sh installs it)")
        pytest.skip("Debian's blender binary is not installed")


def _need_bpy():
    if importlib.util.find_spec("bpy") is None:  # not imported here: the tests run it in subprocesses
        if os.environ.get("CI"):
            pytest.fail("the bpy module is not installed (pip install 'fogsim[blender]')")
        pytest.skip("the bpy module is not installed (the 'blender' extra)")


def runner(kind):
    """Command prefix that runs a Python file under the bpy module or the blender binary."""
    if kind == "bpy":
        _need_bpy()
        return lambda script, *args: [sys.executable, str(script), *args]
    _need_binary()
    return lambda script, *args: [BLENDER, "-b", "--factory-startup", "-noaudio", "-P", str(script), "--", *args]


def run(cmd, timeout=600, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT, **kw)


KINDS = ["bpy", "blender"]


@pytest.mark.parametrize("kind", KINDS)
def test_plane_at_known_distance_gives_exact_depth(kind, tmp_path):
    res = run(runner(kind)(SCRIPTS / "plane_depth.py", str(tmp_path / "r.json")))
    assert res.returncode == 0, res.stderr[-3000:]
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["wall_pixels"] > 1000
    assert r["wall_depth_min"] == pytest.approx(10.0, abs=1e-4) and r["wall_depth_max"] == pytest.approx(10.0, abs=1e-4)
    assert r["wall_ray_max_abs_err"] < 1e-3
    assert r["ground_depth_max_rel_err"] < 1e-3 and r["sky_rows_inf"]
    assert r["leftover"] == [0, 0, 0]  # clear() removed every mesh, material and object


def render_dataset(kind, out, *extra, timeout=900):
    frames = [] if "--frames" in extra else ["--frames", "2"]
    return run(runner(kind)(ROOT / "scripts" / "render_batch.py", "--out", str(out), *frames, *TINY, *extra),
               timeout=timeout)


def check_dataset(out: Path, preset: str = "default"):
    """Boxes equal the tight boxes of the mask; the clear YOLO file equals the labels recomputed
    from the mask by brute force (the preset's filters); every level has the same labels; files all there."""
    from fogsim.render.preset import load_render_preset

    filters = load_render_preset(preset).labels
    levels = ["clear", "beta0.06", "beta0.12"]
    metas = sorted((out / "meta").glob("*.json"))
    assert len(metas) == 2
    n_boxes = n_ignored = 0
    for m in metas:
        meta = json.loads(m.read_text())
        frame = meta["frame"]
        mask = read_uint16_map(out / "masks" / f"{frame}.png")
        depth = read_depth_file(out / "depth" / f"{frame}.exr")
        assert mask.shape == depth.shape == (64, 96)
        assert np.isinf(depth).any() and np.isfinite(depth).any()
        clear = (out / "labels" / "clear" / f"{frame}.txt").read_text()
        lines = [line for line in clear.split("\n") if line.strip()]
        kept = [r for r in meta["objects"] if r["kept"]]
        assert len(lines) == len(kept)
        n_ignored += len(meta["objects"]) - len(kept)
        for rec, line in zip(kept, lines):
            v, u = np.nonzero(mask == rec["id"])
            assert rec["bbox"] == [int(u.min()), int(v.min()), int(u.max()) + 1, int(v.max()) + 1]
            assert rec["pixels"] == len(u)
            cls, box = parse_yolo_line(line, 96, 64)
            assert cls == rec["class_id"] and list(box) == rec["bbox"]
            n_boxes += 1
        # independent of the records: which objects are labels, and their lines, from the mask alone
        # (only the visible fraction, which needs the meshes' silhouettes, comes from the meta)
        visible = {r["id"]: r["visible_fraction"] for r in meta["objects"]}
        expected = expected_yolo_lines(mask, meta["scene"]["objects"], visible, int(filters["min_pixels"]),
                                       float(filters["min_visible_fraction"]))
        assert lines == expected and clear == "".join(line + "\n" for line in expected)
        for lv in levels:
            img = read_image(out / "images" / lv / f"{frame}.png")
            assert img.shape == (64, 96, 3)
            if lv != "clear":
                assert (out / "labels" / lv / f"{frame}.txt").read_text() == clear
        sky = np.isinf(depth)
        if sky.any():  # sky turns white with fog
            assert read_image(out / "images" / "beta0.12" / f"{frame}.png")[sky].min() == 255
    for lv in levels:
        coco = json.loads((out / "coco" / f"{lv}.json").read_text())
        assert len(coco["images"]) == 2 and len(coco["annotations"]) == n_boxes + n_ignored
        assert sum(a["iscrowd"] for a in coco["annotations"]) == n_ignored  # filtered: ignore regions
        assert (out / "data" / f"{lv}.yaml").is_file()
    assert (out / "data" / "all.yaml").is_file() and (out / "contact_sheet.png").is_file()
    manifest = json.loads((out / "dataset.json").read_text())
    assert manifest["frames"] == 2
    return n_boxes


@pytest.mark.parametrize("kind", KINDS)
def test_render_batch_end_to_end(kind, tmp_path):
    out = tmp_path / "ds"
    res = render_dataset(kind, out)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    assert "rendered 2 frames" in res.stdout
    check_dataset(out)


def dataset_digest(out: Path) -> dict:
    """Labels, depth and masks (the deterministic parts) by relative path."""
    files = {}
    for sub in ("labels", "masks", "depth"):
        for p in sorted((out / sub).rglob("*")):
            if p.is_file():
                files[str(p.relative_to(out))] = (read_depth_file(p).tobytes() if p.suffix == ".exr"
                                                  else p.read_bytes())
    return files


@slow
def test_same_seed_same_dataset_and_resume_after_kill(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    frames = ["--frames", "3", "--seed", "5"]
    assert render_dataset("bpy", a, *frames).returncode == 0
    # start the same run, kill it hard once the first frame is committed, then resume it
    cmd = runner("bpy")(ROOT / "scripts" / "render_batch.py", "--out", str(b), *TINY, *frames)
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    signal_mid_run(proc, (b / "meta" / "000000.json").exists, lambda: not (b / "meta" / "000002.json").exists(),
                   signal.SIGKILL, "frame 0 was committed")
    proc.wait()
    assert len(list((b / "meta").glob("*.json"))) < 3, "the kill came too late to interrupt the run"
    res = render_dataset("bpy", b, *frames)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "already done" in res.stdout and "(0 already done" not in res.stdout
    assert dataset_digest(a) == dataset_digest(b)
    assert not list(b.rglob("*.part"))
    c = tmp_path / "c"
    assert render_dataset("bpy", c, "--frames", "3", "--seed", "6").returncode == 0
    assert dataset_digest(c) != dataset_digest(a)


@slow
def test_shards_cover_the_dataset(tmp_path):
    out = tmp_path / "s"
    for i in (0, 1):
        assert render_dataset("bpy", out, "--shard", f"{i}/2").returncode == 0
    assert sorted(p.stem for p in (out / "meta").glob("*.json")) == ["000000", "000001"]
    assert not (out / "coco").exists()  # shards leave the dataset files to one finalize run
    res = render_dataset("bpy", out, "--finalize-only")
    assert res.returncode == 0, res.stderr[-2000:]
    check_dataset(out)
    assert json.loads((out / "dataset.json").read_text())["split"]["train_fraction"] == 0.8
    res = render_dataset("bpy", out, "--finalize-only", "--train-fraction", "0.5")  # re-split, no render
    assert res.returncode == 0, res.stderr[-2000:]
    assert json.loads((out / "dataset.json").read_text())["split"]["train_fraction"] == 0.5
    res = run(runner("bpy")(ROOT / "scripts" / "render_batch.py", "--out", str(tmp_path / "empty"), "--finalize-only"))
    assert res.returncode == 2 and "not a dataset to finalize" in res.stderr


@pytest.mark.parametrize("args, message", [
    (["--preset", "no-such-preset"], "preset not found"),
    (["--resolution", "big"], "--resolution"),
    (["--shard", "3/2"], "shard"),
])
def test_bad_arguments_exit_2(tmp_path, args, message):
    res = run(runner("bpy")(ROOT / "scripts" / "render_batch.py", "--out", str(tmp_path / "o"), *args))
    assert res.returncode == 2 and message in res.stderr


def test_bad_preset_file_and_unwritable_output(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"style": "urban-canyon", "camera": "nope", "quality": "draft"}))
    res = run(runner("bpy")(ROOT / "scripts" / "render_batch.py", "--out", str(tmp_path / "o"), "--preset", str(bad)))
    assert res.returncode == 2 and "bad.json: unknown camera 'nope'" in res.stderr
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    res = run(runner("bpy")(ROOT / "scripts" / "render_batch.py", "--out", str(blocker / "sub")))
    assert res.returncode == 2 and "file" in res.stderr


def test_setup_error_claims_nothing_and_the_corrected_rerun_works(tmp_path):
    """#11: a bad inline style is a setup error found before the dataset folder is claimed
    (exit 2 naming the preset, no render_run.json), so the corrected preset renders into it."""
    preset = tmp_path / "mine.json"
    default = json.loads((ROOT / "fogsim" / "presets" / "default.json").read_text())
    style = json.loads((ROOT / "fogsim" / "presets" / "styles" / "urban-canyon.json").read_text())
    out = tmp_path / "ds"
    for bad in ({"lanes_per_direction": "two"}, style | {"lanes_per_direction": "two"}, "../cameras/waymo-front"):
        preset.write_text(json.dumps(default | {"style": bad}))
        res = render_dataset("bpy", out, "--frames", "1", "--preset", str(preset))
        assert res.returncode == 2, res.stdout[-2000:] + res.stderr[-2000:]
        assert f"{preset}: " in res.stderr and "Traceback" not in res.stderr
        assert not (out / "render_run.json").exists()
    preset.write_text(json.dumps(default | {"style": style | {"lanes_per_direction": 3}}))
    res = render_dataset("bpy", out, "--frames", "1", "--preset", str(preset))
    assert res.returncode == 0, res.stderr[-3000:]
    assert "rendered 1 frames" in res.stdout and (out / "meta" / "000000.json").is_file()
    assert json.loads((out / "meta" / "000000.json").read_text())["scene"]["street"]["lanes"] == 3


@slow
def test_killed_render_leaves_no_temp_files(tmp_path):
    """#18: Cycles' EXR is written inside OUT (never the system temp folder), and a resumed run
    removes what a kill left there: the hidden .part files of unfinished writes (labels/, images/,
    meta/ …) and the temporary EXR; none of them ever counts as an output."""
    systmp = tmp_path / "systmp"
    systmp.mkdir()
    out = tmp_path / "ds"
    env = dict(os.environ, TMPDIR=str(systmp))
    cmd = runner("bpy")(ROOT / "scripts" / "render_batch.py", "--out", str(out), *TINY, "--frames", "3")
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:  # kill during frame 1: once Cycles' file for it exists, in the system temp folder or in OUT
        signal_mid_run(proc, lambda: (out / "meta" / "000000.json").exists() and (
                           list(systmp.glob("fogsim_render_*")) or (out / ".fogsim_tmp").is_dir()),
                       lambda: not (out / "meta" / "000002.json").exists(), signal.SIGKILL, "frame 1 began",
                       poll_s=0.002)
    finally:
        proc.wait()
    assert not (out / "meta" / "000002.json").exists(), "the kill came too late to interrupt the run"
    assert not list(systmp.glob("fogsim_render_*")), "Cycles' EXR was written to the system temp folder"
    # what a kill at an unlucky moment leaves: a part file of each kind of output (named after the
    # killed writer, as fogsim.io names them), a temporary EXR
    from fogsim.io.parts import _HOST

    w = f"{_HOST}-{proc.pid}"
    stale = [out / "labels" / "clear" / f".000001.txt.{w}.k1ll3d_a.part",
             out / "images" / "beta0.06" / f".000001.png.{w}.k1ll3d_b.part",
             out / "depth" / f".000001.exr.{w}.k1ll3d_c.part", out / "meta" / f".000001.json.{w}.k1ll3d_d.part",
             out / "coco" / f".clear.json.{w}.k1ll3d_e.part", out / ".fogsim_tmp" / "000001.left.exr"]
    for p in stale:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"half written")
    res = run(cmd, env=env)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "rendered" in res.stdout and "(0 already done" not in res.stdout
    assert sorted(p.stem for p in (out / "meta").glob("*.json")) == ["000000", "000001", "000002"]
    assert not list(out.rglob("*.part")) and not (out / ".fogsim_tmp").exists()
    assert not list(systmp.glob("fogsim_render_*"))
    coco = json.loads((out / "coco" / "clear.json").read_text())
    assert len(coco["images"]) == 3  # the dataset files list real frames only


@pytest.mark.parametrize("kind", KINDS)
def test_addon_registers_builds_and_renders_through_ops(kind, tmp_path):
    res = run(runner(kind)(SCRIPTS / "addon_ops.py", str(tmp_path / "ds")))
    assert res.returncode == 0, res.stderr[-3000:]
    line = next(ln for ln in res.stdout.splitlines() if ln.startswith("RESULT "))
    r = json.loads(line[len("RESULT "):])
    assert r["build"] == ["FINISHED"] and r["built_objects"] > 20 and r["left_after_clear"] == 0
    assert r["render"] == ["FINISHED"] and r["status"].startswith("done: 1 frames")
    assert "Saved:" not in res.stdout + res.stderr and "Fra:" not in res.stdout  # Blender's output captured
    assert r["unregistered"]
    assert (tmp_path / "ds" / "meta" / "000000.json").is_file()


@pytest.mark.parametrize("kind", KINDS)
def test_addon_preview_fog_class_assignment_and_reported_errors(kind, tmp_path):
    """The panel's new operators through bpy.ops: *Preview fog* shows the clear render fogged at
    one β (Koschmieder, airlight 255, sRGB: the default preset) within 1 LSB outside the drawn
    boxes, and volumetric fog at that β when asked; *Assign* sets fogsim_class on the selection
    only; bad β / visibility lists are reported errors with the reason in the status line, no
    traceback, nothing written."""
    res = run(runner(kind)(SCRIPTS / "addon_preview.py", str(tmp_path)))
    assert res.returncode == 0, res.stderr[-3000:]
    assert "Traceback" not in res.stdout + res.stderr
    line = next(ln for ln in res.stdout.splitlines() if ln.startswith("RESULT "))
    r = json.loads(line[len("RESULT "):])
    assert r["assign"] == [["FINISHED"], None] and r["classes"] == {"a": "pedestrian", "b": "pedestrian", "c": None}
    assert r["classes_after_unassign"] == {"a": "pedestrian", "b": None}  # "(background)" removes it
    assert "no object selected" in r["assign_none_selected"][1] and r["status_none_selected"].startswith("error:")
    for key in ("bad_levels_render", "bad_levels_preview"):
        assert r[key][0] is None and "'fog' is not a number" in r[key][1]
    assert r["bad_levels_status"] == "error: β 'fog' is not a number" and not r["bad_output_written"]
    assert "visibility must be > 0" in r["bad_visibility"][1]
    assert r["config_levels"] == ["vis50m", "vis100m"] and r["config_night"] == "night"
    assert r["preview"] == [["FINISHED"], None] and r["image"] == [96, 64]
    assert r["status"].startswith(f"frame 0: koschmieder, β 0.06/m, V 50 m, {len(r['records'])} boxes")
    assert r["scenes_after"] == r["scenes_before"] and r["objects_after"] == r["objects_before"]
    assert r["unregistered"]

    clear = read_image(tmp_path / "clear.png").astype(np.float64)
    shown = read_image(tmp_path / "preview.png").astype(np.float64)
    z = np.load(tmp_path / "depth.npy").astype(np.float64)
    k = json.loads((tmp_path / "intrinsics.json").read_text())
    v, u = np.mgrid[0:64, 0:96]
    ray = z * np.sqrt(1 + ((u - k["cx"]) / k["fx"]) ** 2 + ((v - k["cy"]) / k["fy"]) ** 2)
    t = np.exp(-0.06 * ray)[..., None]  # sky: ray = inf → t = 0 → the airlight
    expected = clear * t + 255.0 * (1 - t)
    drawn = np.zeros((64, 96), bool)  # box outlines and the class names above them
    for rec in r["records"]:
        x0, y0, x1, y1 = rec["bbox"]
        drawn[max(0, y0 - 12):y1 + 1, max(0, x0 - 1):x0 + 40] = True
        drawn[y0:y1 + 1, max(0, x0 - 1):x1 + 1] = True
    assert r["records"] and (~drawn).mean() > 0.4
    assert np.abs(shown - expected)[~drawn].max() <= 1.0
    assert np.abs(shown - expected)[drawn].max() > 20  # the boxes are drawn
    assert np.isinf(z).any() and np.abs(clear - expected)[~drawn].max() > 20  # fog that shows
    # volumetric (emission-absorption medium): a render of its own, no boxes drawn this time
    assert r["volumetric"] == [["FINISHED"], None]
    assert r["volumetric_status"].startswith("frame 0: volumetric, β 0.06/m, V 50 m")
    vol, vol_clear = read_image(tmp_path / "volumetric.png"), read_image(tmp_path / "volumetric_clear.png")
    assert np.array_equal(vol_clear, clear)  # the same clear render (same seed and samples)
    near, far = ray < 10, ray > 200  # little fog close by, all fog far away: the grey of the medium
    assert np.abs(vol.astype(float) - clear)[near].mean() < np.abs(vol.astype(float) - clear)[far].mean()
    assert vol[far].std() < 12 and np.abs(vol.astype(float) - clear)[far].mean() > 20


@pytest.fixture(scope="module")
def addon_zips(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    res = run([sys.executable, str(ROOT / "scripts" / "build_addon.py"), "--out", str(out)])
    if res.returncode != 0 and "pip download" in res.stderr + res.stdout and not os.environ.get("CI"):
        pytest.skip("cannot download the wheels to bundle (offline?)")
    assert res.returncode == 0, res.stderr[-3000:]
    return {kind: next(out.glob(f"fogsim-*-{kind}.zip")) for kind in ("legacy", "extension")}


@slow
@pytest.mark.parametrize("kind, package", [("blender", "legacy"), ("bpy", "extension")])
def test_packaged_addon_installs_and_builds(kind, package, request, tmp_path):
    """The zip alone is enough: installed into an empty Blender user folder, it builds a scene."""
    if kind == "blender":
        _need_binary()
    else:
        _need_bpy()
    addon_zips = request.getfixturevalue("addon_zips")  # built only once a test can use them
    env = dict(os.environ, **{f"BLENDER_USER_{k}": str(tmp_path / k.lower())
                              for k in ("RESOURCES", "SCRIPTS", "CONFIG", "EXTENSIONS")})
    script = SCRIPTS / "install_zip.py"
    cmd = ([BLENDER, "-b", "--factory-startup", "-noaudio", "-P", str(script), "--"] if kind == "blender"
           else [sys.executable, str(script)]) + [str(addon_zips[package]), package]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=tmp_path, env=env)
    line = next((ln for ln in res.stdout.splitlines() if ln.startswith("RESULT ")), None)
    assert line, res.stdout[-2000:] + res.stderr[-3000:]
    r = json.loads(line[len("RESULT "):])
    assert r["build"] == ["FINISHED"] and r["objects"] > 20
    assert str(tmp_path) in r["fogsim"]  # the library came from the installed zip, not the checkout
    if package == "legacy":
        assert str(tmp_path) in r["cv2"]  # and so did OpenCV


def test_stereo_pair_in_cityscapes_layout(tmp_path):
    """--stereo: SGBM disparity agrees with the exact disparity where valid, has real holes,
    and the Cityscapes tree goes through ``fogsim fog --cityscapes``."""
    from fogsim.camera import decode_disparity_png, depth_to_disparity
    from fogsim.cli import main

    out = tmp_path / "st"
    res = run(runner("bpy")(ROOT / "scripts" / "render_batch.py", "--out", str(out), "--preset", "cityscapes-stereo",
                            "--frames", "1", "--resolution", "256x128", "--samples", "2", "--levels", "clear",
                            "--quiet"))
    assert res.returncode == 0, res.stderr[-3000:]
    meta = json.loads((out / "meta" / "000000.json").read_text())
    split = meta["stereo"]["split"]
    cs = out / "cityscapes"
    cam = json.loads((cs / "camera" / split / "fogsim" / "000000_camera.json").read_text())
    assert cam["extrinsic"]["baseline"] == 0.209 and cam["intrinsic"]["fx"] == pytest.approx(2262.0 * 256 / 2048)
    sgbm = decode_disparity_png(read_uint16_map(cs / "disparity" / split / "fogsim" / "000000_disparity.png"))
    exact = depth_to_disparity(read_depth_file(out / "depth" / "000000.exr"), 0.209, cam["intrinsic"]["fx"])
    valid = sgbm > 0
    assert 0.05 < 1 - valid.mean() < 0.8
    assert meta["stereo"]["hole_fraction"] == pytest.approx(1 - valid.mean(), abs=1e-5)
    assert np.median(np.abs(sgbm[valid] - exact[valid])) < 0.5
    assert (cs / "rightImg8bit" / split / "fogsim" / "000000_rightImg8bit.png").is_file()
    assert main(["fog", "--cityscapes", str(cs), "--split", split, "--levels", "0.06", "--out", str(tmp_path / "fog"),
                 "--quiet"]) == 0
    # the depth benchmark on this frame: classical completions scored against exact depth
    from fogsim.bench.depth import CLASSICAL, complete, evaluate_frame
    from fogsim.dataset.layout import DatasetLayout
    from fogsim.dataset.reader import read_stereo_frame
    from fogsim.depth.stereo import wls_disparity
    from fogsim.fog.levels import load_preset

    frame = read_stereo_frame(DatasetLayout(out), "000000")
    done = {m: complete(frame, m) for m in CLASSICAL}
    assert np.array_equal(done["sgbm"] == 0, sgbm == 0)
    for m in ("inpaint", "ipbasic", "wls"):
        assert not (done[m] == 0).any()
        if m != "wls":
            assert np.array_equal(done[m][valid], frame.sgbm[valid])  # fills change only holes
    # WLS is not a hole fill: it re-estimates every pixel (edge-aware smoothing of SGBM, guided by
    # the left image), defines more pixels than SGBM, stays close to SGBM where SGBM is valid and
    # close to the exact disparity everywhere (ipbasic fills only what WLS leaves undefined)
    fx, b = cam["intrinsic"]["fx"], cam["extrinsic"]["baseline"]
    raw = wls_disparity(frame.left, frame.right, frame.camera)
    assert (raw > 0).mean() > valid.mean() and (raw > 0)[valid].mean() > 0.95
    wls = depth_to_disparity(done["wls"], b, fx)
    assert not np.array_equal(done["wls"][valid], frame.sgbm[valid])
    assert np.median(np.abs(wls[valid] - sgbm[valid])) < 0.5
    assert np.median(np.abs(wls - exact)) < 1.0
    res = evaluate_frame(frame, done, load_preset("paper"))
    assert res["methods"]["sgbm"]["holes"]["pixels"] == 0 and "fog" not in res["methods"]["sgbm"]
    inpaint = res["methods"]["inpaint"]
    assert inpaint["holes"]["pixels"] > 0 and 0 < inpaint["holes"]["abs_rel"] < 1
    assert set(inpaint["fog"]) == {"beta0.03", "beta0.06", "beta0.09", "beta0.12"}
    assert all(v["psnr"] > 10 for v in inpaint["fog"].values())


@pytest.mark.parametrize("kind", KINDS)
def test_a_script_that_used_tqdm_exits_cleanly(kind):
    res = run(runner(kind)(SCRIPTS / "tqdm_exit.py"))
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-2000:]  # Blender 3.4: -11 without the fix
    assert "written above the bar" in res.stdout + res.stderr


def test_no_api_blender_5_deprecates(tmp_path):
    """Materials, the fog's material and an HDRI world are made without what Blender 5.0 deprecates
    (``use_nodes``, removed in 6.0): a render with every warning shown prints none of them (issue 47)."""
    env = dict(os.environ, PYTHONWARNINGS="always::DeprecationWarning")
    res = run(runner("bpy")(ROOT / "scripts" / "render_batch.py", "--out", str(tmp_path / "d"), "--frames", "1",
                            "--resolution", "96x64", "--samples", "1", "--levels", "clear,0.06", "--preset", "hdri",
                            "--fog", "volumetric", "--quiet"), env=env)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "expected to be removed in Blender 6.0" not in res.stderr, res.stderr[-2000:]
