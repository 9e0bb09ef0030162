"""The asset library in real Blender: every importer (bpy 5.0 module and Blender 3.4), a render
with ``--assets`` whose meta names each library object's file, a wrong-size model refused, and
flat memory over a long run. The library is made by trimesh here (tests/asset_models.py), the FBX
and .blend by Blender's own exporters; no model file lives in the repository."""
import json

import numpy as np
import pytest

from asset_models import MODELS, make_library
from fogsim.io.depth_files import read_uint16_map
from test_blender import KINDS, SCRIPTS, render_dataset, run, runner

pytestmark = pytest.mark.blender


@pytest.fixture
def library(tmp_path):
    make_library(tmp_path / "lib")
    return tmp_path / "lib"


@pytest.mark.parametrize("kind", KINDS)
def test_every_format_imports_normalised_and_leaves_nothing_behind(kind, library, tmp_path):
    res = run(runner(kind)(SCRIPTS / "asset_import.py", str(library), str(tmp_path / "r.json")))
    assert res.returncode == 0, res.stderr[-3000:]
    r = json.loads((tmp_path / "r.json").read_text())
    models = r["models"]
    assert set(models) == {"car/hatch.glb", "car/estate/estate.glb", "car/fbx/hatch.fbx", "car/blend/hatch.blend",
                           "pedestrian/walker/walker.obj"}
    size = {rel: s for rel, _, s in MODELS}
    for rel, m in models.items():
        expected = size.get(rel, size["car/hatch.glb"])  # the FBX and .blend are the hatchback
        length_or_height = m["extent"][1] if m["class"] == "car" else m["extent"][2]
        assert length_or_height == pytest.approx(expected, abs=1e-3), rel  # metres, front along y
        assert m["min_z"] == pytest.approx(0.0, abs=1e-5) and m["centre_xy"] == pytest.approx([0, 0], abs=1e-5)
        assert m["scale"] == 1.0 and m["blender_matches"], rel
        if m["class"] == "car":
            assert m["parts"] == 6 and m["faces"] == 280  # body, cabin, 4 wheels, all triangles
            assert m["cabin_y"] < -0.3, rel  # the cabin is behind the middle: the front faces +y
            assert len(m["materials"]) == 3, rel  # body, cabin, tyres came along
    assert models["pedestrian/walker/walker.obj"]["materials"] == ["skin"]  # from the .mtl
    assert r["after_load"]["objects"] == r["start"]["objects"]  # the imports' objects are gone
    assert r["after_load"]["meshes"] == r["start"]["meshes"] + 4 * 6 + 1  # only the kept meshes
    assert r["after_remove"] == r["start"]


def check_library_dataset(out, library, frames):
    files = {str(p) for p in library.rglob("*") if p.suffix in (".glb", ".obj")}
    library_records = 0
    for f in range(frames):
        meta = json.loads((out / "meta" / f"{f:06d}.json").read_text())
        scene = {o["id"]: o for o in meta["scene"]["objects"]}
        used = [o for o in scene.values() if o["asset"]["type"] == "library"]
        assert used and {o["asset"]["params"]["file"] for o in used} <= files
        assert {o["class"] for o in used} <= {"car", "pedestrian"}
        mask = read_uint16_map(out / "masks" / f"{f:06d}.png")
        for rec in meta["objects"]:
            asset = scene[rec["id"]]["asset"]
            assert rec["asset_file"] == (asset["params"]["file"] if asset["type"] == "library" else None)
            assert rec["pixels"] == int((mask == rec["id"]).sum())
            library_records += rec["asset_file"] is not None
    return library_records


@pytest.mark.slow
def test_render_with_an_asset_library_names_every_library_file(library, tmp_path):
    out = tmp_path / "out"
    res = render_dataset("bpy", out, "--assets", str(library), "--levels", "clear", "--resolution", "128x80")
    assert res.returncode == 0, res.stderr[-3000:]
    assert check_library_dataset(out, library, 2) >= 3
    records = [r for f in range(2) for r in json.loads((out / "meta" / f"{f:06d}.json").read_text())["objects"]
               if r["asset_file"] and r["pixels"] >= 40 and not r["truncated"]]
    # silhouettes are the imported meshes': an unoccluded library car covers all of its silhouette
    assert records and max(r["visible_fraction"] for r in records) > 0.95
    run_file = json.loads((out / "render_run.json").read_text())
    assert set(run_file["parameters"]["assets"]["files"]) == {"car", "pedestrian"}


def test_blender_34_renders_with_the_library(library, tmp_path):
    out = tmp_path / "out"
    res = render_dataset("blender", out, "--assets", str(library), "--frames", "1", "--levels", "clear")
    assert res.returncode == 0, res.stderr[-3000:]
    assert check_library_dataset(out, library, 1) >= 1


def test_a_wrong_size_model_is_refused_naming_it(tmp_path):
    make_library(tmp_path / "lib", giant=True)
    out = tmp_path / "out"
    res = render_dataset("bpy", out, "--assets", str(tmp_path / "lib"))
    assert res.returncode == 2, res.stderr[-3000:]
    line = [x for x in res.stderr.splitlines() if "giant.glb" in x]
    assert line and "a car model must be 3–6 m in length, this one is 45 m" in line[0], res.stderr[-2000:]
    assert not (out / "render_run.json").exists() and not (out / "meta").exists()  # nothing claimed


@pytest.mark.slow
def test_memory_stays_flat_over_many_library_frames(library, tmp_path):
    """40 frames in one process: Blender's datablocks are the same after every frame (nothing
    imported per frame, nothing left behind) and RSS grows by well under 1 MiB a frame."""
    res = run(runner("bpy")(SCRIPTS / "asset_rss.py", str(library), str(tmp_path / "out"), "40",
                            str(tmp_path / "rss.json")), timeout=1200)
    assert res.returncode == 0, res.stderr[-3000:]
    r = json.loads((tmp_path / "rss.json").read_text())
    rows = r["frames"]
    assert r["library_objects"] > 100  # the library was used throughout
    assert len({(x["objects"], x["meshes"], x["materials"], x["images"]) for x in rows}) == 1
    rss = np.array([x["rss_mib"] for x in rows])
    slope = np.polyfit(np.arange(5, len(rss)), rss[5:], 1)[0]
    assert slope < 1.0, rss.tolist()  # MiB per frame
