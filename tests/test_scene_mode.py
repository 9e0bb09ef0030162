"""Scene mode: a user's own .blend → a labelled fog dataset (fogsim.render.blender.scene_mode).

The pure parts (Blender's camera → K, the class map) run everywhere. The Blender tests build a
.blend from trimesh boxes (tests/blender_scripts/make_scene_blend.py): a vertically fitted camera
with a shifted principal point, an animated car and a linked duplicate of it, a labelled truck with
an unlabelled child, a collection instanced twice (its class from the collection), a labelled sign
instanced on two points by geometry nodes, a hidden labelled object, and objects hidden in the
viewport only (the eye, the monitor: Blender renders them, so does fogsim); then render it with
``fogsim render --scene`` (bpy module) and ``blender -b FILE -P render_batch.py -- --scene current``
(Debian's 3.4), and check every box against the corners projected here by hand.
"""
import hashlib
import itertools
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fogsim.cli import main
from fogsim.errors import InputError
from fogsim.io.depth_files import read_uint16_map
from fogsim.io.images import read_image
from fogsim.render.scene_classes import ClassMap, load_class_map
from fogsim.scene.pose import blender_intrinsics, blender_lens

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "tests" / "blender_scripts"

SPEC = {
    "resolution": [96, 64], "frames": [1, 3],
    "camera": {"location": [0, -14, 5], "rotation_deg": [75, 0, 0], "lens": 32, "sensor_width": 36,
               "sensor_height": 18, "sensor_fit": "VERTICAL", "shift_x": 0.06, "shift_y": -0.05},
    "collections": {"People": "pedestrian", "Props": None},
    "boxes": [
        {"name": "Ground", "size": [60, 80, 0.2], "location": [0, 20, -0.1], "color": [0.25, 0.25, 0.27]},
        {"name": "Car", "size": [4, 1.8, 1.5], "location": [-3, 0, 0.75], "class": "car", "color": [0.8, 0.1, 0.1],
         "keys": {"1": [-3, 0, 0.75], "3": [3, 0, 0.75]}},
        {"name": "Truck", "size": [3, 2.4, 2.2], "location": [-6, 25, 1.1], "class": "truck", "color": [0.1, 0.3, 0.8]},
        {"name": "TruckBox", "size": [5, 2.4, 3], "location": [4, 0, 0.4], "parent": "Truck",
         "color": [0.9, 0.8, 0.2], "hide_eye": True},
        {"name": "Van", "data_of": "Car", "location": [7, 28, 0.75], "class": "van"},
        {"name": "Ghost", "size": [2, 2, 2], "location": [0, 4, 1], "class": "car", "hidden": True, "hide_eye": True,
         "color": [0, 1, 0]},
        {"name": "Person", "size": [0.6, 0.5, 1.8], "location": [0, 0, 0.9], "collection": "People",
         "color": [0.2, 0.6, 0.2]},
        {"name": "Sign", "size": [0.9, 0.1, 0.9], "location": [0, 0, 0], "class": "traffic_sign",
         "collection": "Props", "color": [0.9, 0.9, 0.9]}],
    "points": [{"name": "Signs", "object": "Sign", "points": [[6, 10, 2.2], [9, 20, 2.2]]}],
    "instances": [{"name": "PedA", "collection": "People", "location": [-1, 8, 0]},
                  {"name": "PedB", "collection": "People", "location": [2, 14, 0], "viewport_off": True}]}
TINY = ["--samples", "2", "--levels", "clear,0.06", "--frame-range", "1:3:2", "--quiet"]


# ----------------------------------------------------------------------------- by hand
def hand_K(spec) -> tuple[float, float, float, float]:
    """Vertical fit: the sensor height spans the image height; shifts are fractions of that height."""
    c, (w, h) = spec["camera"], spec["resolution"]
    f = c["lens"] * h / c["sensor_height"]
    return f, f, (w - 1) / 2 - c["shift_x"] * h, (h - 1) / 2 + c["shift_y"] * h


def hand_project(spec, points) -> np.ndarray:
    """Pixel-centre coordinates of world points through the camera (a rotation about x only)."""
    c = spec["camera"]
    a = math.radians(c["rotation_deg"][0])
    R = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    p = (np.asarray(points, float) - c["location"]) @ R  # Blender camera axes: x right, y up, looking along −z
    fx, fy, cx, cy = hand_K(spec)
    return np.stack([fx * p[:, 0] / -p[:, 2] + cx, fy * -p[:, 1] / -p[:, 2] + cy], axis=1)


def corners(size, centre) -> list:
    return [np.add(centre, np.multiply(s, size) / 2) for s in itertools.product((-1, 1), repeat=3)]


def expected_boxes(spec, frame: int) -> dict:
    """Pixel-edge boxes [x0, y0, x1, y1] of the projected corners, by object."""
    b = {x["name"]: x for x in spec["boxes"]}
    truck = np.add(b["Truck"]["location"], b["TruckBox"]["location"])
    person = b["Person"]
    pts = {"Car": corners(b["Car"]["size"], b["Car"]["keys"][str(frame)]),
           "Truck": corners(b["Truck"]["size"], b["Truck"]["location"]) + corners(b["TruckBox"]["size"], truck),
           "Van": corners(b["Car"]["size"], b["Van"]["location"])}
    for inst in spec["instances"]:
        pts[inst["name"]] = corners(person["size"], np.add(inst["location"], person["location"]))
    for i, point in enumerate(spec["points"][0]["points"]):  # geometry-nodes instances of the sign
        pts[f"Sign{i}"] = corners(b["Sign"]["size"], point)
    out = {}
    for name, p in pts.items():
        uv = hand_project(spec, p)
        out[name] = [*(uv.min(axis=0) + 0.5), *(uv.max(axis=0) + 0.5)]
    return out


# ----------------------------------------------------------------------------- pure
def test_blender_intrinsics_inverts_blender_lens_and_fits_by_hand():
    lens = blender_lens(500.0, 500.0, 300.2, 210.7, 640, 426)
    K = blender_intrinsics(lens["lens"], lens["sensor_width"], 24.0, lens["sensor_fit"], lens["shift_x"],
                           lens["shift_y"], 640, 426)
    assert (K["fx"], K["fy"], K["cx"], K["cy"]) == pytest.approx((500.0, 500.0, 300.2, 210.7))
    assert tuple(blender_intrinsics(32, 36, 18, "VERTICAL", 0.06, -0.05, 96, 64)[k] for k in ("fx", "fy", "cx", "cy")) \
        == pytest.approx(hand_K(SPEC))
    # AUTO fits the sensor width to the larger side: a portrait image is fitted vertically, with sensor_width
    portrait = blender_intrinsics(30, 36, 24, "AUTO", 0.1, 0.0, 60, 90)
    assert portrait["fy"] == pytest.approx(30 * 90 / 36) and portrait["cx"] == pytest.approx(29.5 - 0.1 * 90)
    # pixels twice as tall as wide: fy is half fx
    tall = blender_intrinsics(30, 36, 24, "HORIZONTAL", 0, 0, 96, 64, 1.0, 2.0)
    assert tall["fx"] == pytest.approx(80.0) and tall["fy"] == pytest.approx(40.0)


def test_class_map_globs_property_and_refusals(tmp_path):
    cmap = load_class_map('{"Car*": "car", "*": "background"}')
    assert cmap.match("Car.001") == "car" and cmap.match("Tree") == "background"
    assert cmap.direct("Car.001", "pedestrian", "obj") == "pedestrian"  # the property wins
    assert ClassMap().direct("x", None, "obj") is None
    bad = tmp_path / "map.json"
    bad.write_text('{"Car*": "car",')
    with pytest.raises(InputError, match=r"map\.json: not readable as JSON"):
        load_class_map(str(bad))
    with pytest.raises(InputError, match="unknown class 'spaceship'"):
        load_class_map('{"Car*": "spaceship"}')
    with pytest.raises(InputError, match="non-empty JSON object"):
        load_class_map("{}")
    with pytest.raises(InputError, match=r"absent\.json: file not found"):
        load_class_map(str(tmp_path / "absent.json"))
    with pytest.raises(InputError, match="unknown class"):
        cmap.direct("Car", "spaceship", "object 'Car'")


@pytest.mark.parametrize("args, message", [
    (["--scene", "x.blend", "--preset", "default"], "--preset is not available with --scene"),
    (["--scene", "x.blend", "--frames", "3"], "--frames is not available with --scene"),
    (["--class-map", '{"a": "car"}'], "need --scene"),
    (["--scene", "x.blend", "--class-map", "{oops"], "not readable as JSON"),
])
def test_scene_usage_errors_exit_2_before_writing(tmp_path, capsys, args, message):
    out = tmp_path / "out"
    assert main(["render", "--out", str(out), *args]) == 2
    assert message in capsys.readouterr().err and not out.exists()


# ----------------------------------------------------------------------------- real Blender
def _build(kind: str, tmp_path: Path, spec: dict, name: str = "scene.blend") -> Path:
    from test_blender import run, runner

    (tmp_path / "spec.json").write_text(json.dumps(spec))
    blend = tmp_path / "user" / name
    blend.parent.mkdir(exist_ok=True)
    res = run(runner(kind)(SCRIPTS / "make_scene_blend.py", str(tmp_path / "spec.json"), str(blend)))
    assert res.returncode == 0 and blend.is_file(), res.stderr[-3000:]
    return blend


def _render(kind: str, blend: Path, out: Path, *extra) -> subprocess.CompletedProcess:
    from test_blender import BLENDER, run

    if kind == "bpy":
        cmd = [sys.executable, "-m", "fogsim", "render", "--scene", str(blend), "--out", str(out), *extra]
    else:
        cmd = [BLENDER, "-b", str(blend), "-noaudio", "-P", str(ROOT / "scripts" / "render_batch.py"), "--",
               "--scene", "current", "--out", str(out), *extra]
    return run(cmd)


def _digest(folder: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


@pytest.mark.blender
@pytest.mark.slow
@pytest.mark.parametrize("kind", ["bpy", "blender"])
def test_scene_mode_boxes_match_hand_projection(kind, tmp_path):
    blend = _build(kind, tmp_path, SPEC)
    before = _digest(blend.parent)
    out = tmp_path / "out"
    res = _render(kind, blend, out, *TINY)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    assert _digest(blend.parent) == before  # the .blend byte-identical, nothing written beside it
    fx, fy, cx, cy = hand_K(SPEC)
    car_x0 = {}
    for name, frame in (("000000", 1), ("000001", 3)):
        meta = json.loads((out / "meta" / f"{name}.json").read_text())
        K = meta["camera"]["intrinsics"]
        assert (K["fx"], K["fy"], K["cx"], K["cy"]) == pytest.approx((fx, fy, cx, cy), abs=1e-4)
        assert (K["width"], K["height"]) == (96, 64) and meta["scene"]["source"]["blender_frame"] == frame
        owners = {o["id"]: o for o in meta["scene"]["objects"]}
        # one label per visible instance; the hidden car is not one; the truck is the union of its meshes
        by_key = {owners[r["id"]]["key"]: r for r in meta["objects"]}
        signs = sorted((k for k in by_key if k.startswith("instance/Signs/")), key=lambda k: by_key[k]["bbox"][0])
        assert sorted(set(by_key) - set(signs)) == ["instance/PedA", "instance/PedB", "object/Car", "object/Truck",
                                                     "object/Van"]
        assert len(signs) == 2 and all(by_key[k]["class"] == "traffic_sign" for k in signs)
        assert [r["class"] for r in meta["objects"]].count("pedestrian") == 2
        for i, k in enumerate(signs):
            by_key[f"instance/Sign{i}"] = by_key.pop(k)
        truck = next(o for o in owners.values() if o["key"] == "object/Truck")
        assert sorted(truck["blender_objects"]) == ["Truck", "TruckBox"]
        expected = expected_boxes(SPEC, frame)
        for key, rec in by_key.items():
            assert rec["visible_fraction"] == pytest.approx(1.0, abs=0.02), key
            assert np.abs(np.subtract(rec["bbox"], expected[key.split("/")[1]])).max() <= 1.0, (key, rec["bbox"])
        car_x0[frame] = by_key["object/Car"]["bbox"][0]
        mask = np.unique(read_uint16_map(out / "masks" / f"{name}.png"))
        assert set(mask) == {0, *owners}  # background 0, every labelled object its own id
    assert car_x0[3] - car_x0[1] > 40  # the animated car moved right (49 px by hand)
    for f in ("contact_sheet.png", "coco", "data"):
        assert (out / f).exists()
    assert len(list((out / "images").rglob("*.png"))) == 4  # 2 frames × 2 levels


@pytest.mark.blender
@pytest.mark.slow
def test_scene_mode_refusals_exit_2_before_writing_and_class_map(tmp_path):
    spec = json.loads(json.dumps(SPEC))
    for b in spec["boxes"]:
        b.pop("class", None)
    spec["collections"] = dict.fromkeys(spec["collections"])
    spec["cameras"] = [{"name": "Ortho", "type": "ORTHO"}, {"name": "Pano", "type": "PANO"}]
    blend = _build("bpy", tmp_path, spec)
    before = _digest(blend.parent)
    cmap = '{"Car": "car", "Peo*": "pedestrian"}'
    for extra, message in ((), "no labelled object in scene 'Scene' at frame 1"),\
                          (("--class-map", cmap, "--camera", "Ortho"), "camera 'Ortho' is orthographic"), \
                          (("--class-map", cmap, "--camera", "Pano"), "camera 'Pano' is panoramic"), \
                          (("--class-map", cmap, "--camera", "Sun"), "no camera object named 'Sun'"):
        out = tmp_path / "refused"
        res = _render("bpy", blend, out, *TINY, *extra)
        assert res.returncode == 2 and message in res.stderr, (extra, res.stderr[-2000:])
        assert not out.exists() and "Traceback" not in res.stderr
    out = tmp_path / "mapped"
    res = _render("bpy", blend, out, "--samples", "1", "--levels", "clear", "--frame-range", "1:1", "--class-map", cmap)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "labelled car 1 objects + 0 instances, pedestrian 0 objects + 2 instances" in res.stdout
    meta = json.loads((out / "meta" / "000000.json").read_text())
    assert sorted(r["class"] for r in meta["objects"]) == ["car", "pedestrian", "pedestrian"]
    assert _digest(blend.parent) == before


@pytest.mark.blender
@pytest.mark.parametrize("kind", ["bpy", "blender"])
def test_blender_camera_intrinsics_agree_with_blenders_projection(kind, tmp_path):
    """fogsim's K and pose against bpy_extras' world_to_camera_view: every sensor fit, pixel aspect,
    shift, landscape and portrait."""
    from test_blender import run, runner

    res = run(runner(kind)(SCRIPTS / "camera_intrinsics.py", str(tmp_path / "k.json")))
    assert res.returncode == 0, res.stderr[-3000:]
    results = json.loads((tmp_path / "k.json").read_text())
    assert len(results) == 36 and max(r["max_err_px"] for r in results) < 1e-3


@pytest.mark.blender
@pytest.mark.slow
def test_add_on_entry_leaves_the_users_scene_as_it_was(tmp_path):
    """scene_job() on the open scene with volumetric fog, stepped by FrameLoop as the add-on does:
    afterwards no data-block is left over, every visibility flag (eye, monitor, render), pass index,
    camera setting (the fog renders move clip_start), the frame and the render settings are as before."""
    from test_blender import run, runner

    blend = _build("bpy", tmp_path, SPEC)
    res = run(runner("bpy")(SCRIPTS / "scene_job_api.py", str(blend), str(tmp_path / "out"), str(tmp_path / "r.json")))
    assert res.returncode == 0, res.stderr[-3000:]
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["done"] == 2 and not r["failed"]
    assert r["before"] == r["after"]
    assert r["before"]["objects"]["TruckBox"][2] is True and r["before"]["objects"]["PedB"][1] is True
    assert (tmp_path / "out" / "contact_sheet.png").is_file()
    meta = json.loads((tmp_path / "out" / "meta" / "000001.json").read_text())
    assert meta["fog"]["model"] == "volumetric" and meta["render"]["samples"] == 1
    clear, foggy = (read_image(tmp_path / "out" / "images" / lv / "000001.png").astype(float)
                    for lv in ("clear", "beta0.06"))
    assert foggy.std() < 0.8 * clear.std()  # the fog layer lowers the contrast


@pytest.mark.blender
@pytest.mark.slow
def test_scene_mode_shards_finalize_and_resume(tmp_path):
    """--shard 0/2 and 1/2 render one frame each and no dataset files; --finalize-only writes them over
    both; a rerun renders nothing (resume); another class map into the same folder is refused."""
    blend = _build("bpy", tmp_path, SPEC)
    out = tmp_path / "out"
    for shard in ("0/2", "1/2"):
        res = _render("bpy", blend, out, *TINY, "--shard", shard)
        assert res.returncode == 0, res.stderr[-3000:]
    assert sorted(p.name for p in (out / "meta").iterdir()) == ["000000.json", "000001.json"]
    assert not (out / "contact_sheet.png").exists()  # a shard leaves the dataset files to --finalize-only
    res = _render("bpy", blend, out, *TINY, "--finalize-only")
    assert res.returncode == 0 and (out / "contact_sheet.png").is_file(), res.stderr[-3000:]
    coco = json.loads((out / "coco" / "clear.json").read_text())
    assert len(coco["images"]) == 2
    # --out alone finalizes it too (the scene's parameters come from render_run.json; no .blend opened)
    res = subprocess.run([sys.executable, "-m", "fogsim", "render", "--out", str(out), "--finalize-only"],
                         capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert res.returncode == 0 and "finalize: 2 frames found of the run's 2" in res.stdout, res.stderr[-2000:]
    assert json.loads((out / "coco" / "clear.json").read_text())["annotations"] == coco["annotations"]
    res = _render("bpy", blend, out, "--finalize-only", "--frame-range", "1:4")
    assert res.returncode == 2 and "style.scene_mode.frame_range: [1, 3, 2] recorded, [1, 4, 1]" in res.stderr
    res = _render("bpy", blend, out, *TINY[:-1])
    assert res.returncode == 0 and "rendered 0 frames (2 already done, 0 failed)" in res.stdout, res.stdout[-2000:]
    res = _render("bpy", blend, out, *TINY, "--class-map", '{"Ground": "road"}')
    assert res.returncode == 2 and "other parameters" in res.stderr
