"""The add-on's *Source* (procedural preset | current scene), *Sky* / *HDRI* and *Assets* controls,
with the real bpy module (tests/blender_scripts/addon_sources.py): the properties reach the
RenderConfig and the scene job, a current-scene render through ``bpy.ops.fogsim.render_dataset``
writes a labelled dataset and leaves the user's scene and .blend as they were, and every
refusal is a panel message (status line + report), never a traceback. Tiny: 96×64, 2 samples."""
import json
from pathlib import Path

import pytest

pytestmark = pytest.mark.blender

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "tests" / "blender_scripts"

SPEC = {"resolution": [96, 64], "frames": [1, 3],
        "camera": {"location": [0, -14, 5], "rotation_deg": [75, 0, 0], "lens": 32, "sensor_width": 36,
                   "sensor_height": 24, "sensor_fit": "AUTO", "shift_x": 0, "shift_y": 0},
        "boxes": [{"name": "Ground", "size": [60, 80, 0.2], "location": [0, 20, -0.1], "color": [0.25, 0.25, 0.27]},
                  {"name": "Car", "size": [4, 1.8, 1.5], "location": [-3, 0, 0.75], "class": "car",
                   "color": [0.8, 0.1, 0.1], "keys": {"1": [-3, 0, 0.75], "3": [3, 0, 0.75]}},
                  {"name": "Truck", "size": [3, 2.4, 2.2], "location": [-6, 25, 1.1], "class": "truck",
                   "color": [0.1, 0.3, 0.8]}]}


def test_addon_sources_sky_assets_and_panel_errors(tmp_path):
    pytest.importorskip("trimesh")
    from asset_models import make_library
    from test_blender import run, runner
    from test_scene_mode import _build

    blend = _build("bpy", tmp_path, SPEC)
    spec = json.loads(json.dumps(SPEC))
    for b in spec["boxes"]:
        b.pop("class", None)
    unlabelled = _build("bpy", tmp_path, spec, "unlabelled.blend")
    make_library(tmp_path / "library")
    res = run(runner("bpy")(SCRIPTS / "addon_sources.py", str(tmp_path / "out"), str(blend), str(unlabelled),
                            str(tmp_path / "library")))
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    assert "Traceback" not in res.stdout + res.stderr
    r = json.loads(next(ln for ln in res.stdout.splitlines() if ln.startswith("RESULT "))[len("RESULT "):])

    # Sky / HDRI / Assets → the preset's lighting and assets
    assert r["hdri_name"] == {"time_of_day": "day", "sky": "hdri", "hdri": "sunset"}
    assert r["hdri_file"]["hdri"] == str((tmp_path / "out" / "sky.hdr").resolve())
    assert r["overcast"] == {"time_of_day": "day", "overcast": True}
    assert r["procedural_over_hdri_preset"] == {} and r["hdri_preset"] == "hdri"  # {}: the default day sky
    beams, choices = r["lidar"]
    assert beams == 64 and r["no_lidar"] == {}
    assert choices[:2] == ["PRESET", "NONE"] and "hdl64e" in choices and "waymo-top" not in choices  # beams known
    assert r["assets"] == {"car": ["estate.glb", "hatch.glb"], "pedestrian": ["walker.obj"]}
    name, choices = r["radar"]
    assert name == "ars408-lr" and r["no_radar"] == {} and choices == ["PRESET", "NONE", "ars408-lr", "srr-corner"]

    # refusals: Blender's report (a RuntimeError for a script caller) and the panel's status line
    for key, text in (("missing_hdri", "HDRI file: no such file"), ("night_sky", "is a day sky"),
                      ("bad_assets", "--assets: not a folder"), ("no_camera", "no camera object named 'NoSuchCamera'"),
                      ("unlabelled", "no labelled object in scene 'Scene' at frame 1"),
                      ("built_street", "press Clear scene first")):
        (result, report), status = r[key]
        assert result is None and text in report, (key, report)
        assert status.startswith("error: ") and text in status, (key, status)
    assert "HDRI file: must be .exr or .hdr" in r["hdri_not_exr"]
    assert "are not classes" in r["odd_assets"][1] and "spaceship" in r["odd_assets"][1]
    assert not r["bad_assets_written"] and not r["unlabelled_written"]

    # Current scene: the panel's options reach the scene job
    job = r["job"]
    assert job["frames"] == [1, 3] and job["camera"] == "Camera" and job["levels"] == ["vis100m", "vis50m"]
    assert job["resolution"] == [96, 64] and job["seed"] == 1 and job["fog"] == "koschmieder"
    assert "labelled car 1 objects + 0 instances, truck 1 objects + 0 instances" in job["summary"]

    # … and its render writes a labelled dataset, the user's scene and .blend untouched
    assert r["render"] == [["FINISHED"], None] and r["render_status"] == "done: 2 frames"
    assert r["same_state"], json.dumps(r["diff"])
    assert r["blend_untouched"]
    ds = tmp_path / "out" / "scene_ds"
    for name in ("000000", "000001"):
        meta = json.loads((ds / "meta" / f"{name}.json").read_text())
        assert sorted(o["class"] for o in meta["objects"]) == ["car", "truck"]
        lines = (ds / "labels" / "beta0.06" / f"{name}.txt").read_text().split("\n")
        assert len([ln for ln in lines if ln.strip()]) == 2
    assert (ds / "contact_sheet.png").is_file() and (ds / "coco" / "clear.json").is_file()


@pytest.mark.slow
def test_addon_current_scene_runs_modal_in_a_window(tmp_path):
    """Debian's Blender 3.4 with a window (Xvfb): *Render dataset* invoked as a click runs the
    scene job on the window manager's timer, one frame per event, progress 50 → 100 %, and leaves
    the user's scene as it was."""
    import os
    import shutil
    import subprocess

    from test_blender import BLENDER, _need_binary, run, runner

    _need_binary()
    if shutil.which("Xvfb") is None:
        pytest.skip("Xvfb is not installed (apt-get install xvfb)")
    blend = tmp_path / "user" / "scene.blend"
    blend.parent.mkdir()
    (tmp_path / "spec.json").write_text(json.dumps(SPEC))
    res = run(runner("blender")(SCRIPTS / "make_scene_blend.py", str(tmp_path / "spec.json"), str(blend)))
    assert res.returncode == 0, res.stderr[-3000:]
    read, write = os.pipe()
    xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(write), "-screen", "0", "1280x800x24", "-nolisten", "tcp"],
                            pass_fds=(write,), stderr=subprocess.DEVNULL)
    try:
        os.close(write)
        display = os.read(read, 16).decode().strip()
        env = dict(os.environ, DISPLAY=f":{display}")
        res = run([BLENDER, "--factory-startup", "-noaudio", str(blend), "-P", str(SCRIPTS / "addon_modal.py"), "--",
                   str(tmp_path / "ds"), str(tmp_path / "r.json")], timeout=300, env=env)
    finally:
        os.close(read)
        xvfb.terminate()
        xvfb.wait(10)
    assert res.returncode == 0 and (tmp_path / "r.json").is_file(), res.stderr[-3000:]
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["invoke"] == ["RUNNING_MODAL"] and r["modal"]
    assert r["status"][-1] == "done: 2 frames" and "frame 0 done (1/2)" in r["status"] and 50 in r["progress"]
    assert r["same_state"]
    assert sorted(p.name for p in (tmp_path / "ds" / "meta").iterdir()) == ["000000.json", "000001.json"]
