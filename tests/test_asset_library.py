"""The asset library's pure half (fogsim.scene.library): files, normalisation, size rules, the
layout's sampling and the preset key — without Blender (the imports are in test_asset_render.py)."""
import json

import numpy as np
import pytest
import trimesh

from asset_models import make_library
from fogsim.camera import Intrinsics
from fogsim.errors import InputError
from fogsim.render.frame import scene_meshes
from fogsim.render.preset import load_render_preset
from fogsim.render.silhouette import silhouette_areas
from fogsim.scene.layout import sample_scene
from fogsim.scene.library import (
    AssetLibrary,
    LibraryModel,
    assets_dir,
    extent,
    fit_size,
    library_files,
    model_files,
    normalise,
)


def apply(M, v):
    return np.asarray(v, float) @ M[:3, :3].T + M[:3, 3]


def test_normalise_turns_the_front_to_plus_y_centres_and_grounds():
    # a 4 × 2 × 1.5 block, its front (a marker point) toward −y, floating at z = 3, off centre
    v = trimesh.creation.box(extents=[2, 4, 1.5]).vertices + [10, 5, 3.75]
    v = np.vstack([v, [10, 3.0, 4.5]])  # the marker: front face (y = 3), top
    M = normalise(v, "-y", "m")
    out = apply(M, v)
    assert out[:, 2].min() == pytest.approx(0.0) and out[:, 2].max() == pytest.approx(1.5)
    assert out[:, :2].min(axis=0) == pytest.approx([-1, -2]) and out[:, :2].max(axis=0) == pytest.approx([1, 2])
    assert out[-1, 1] == pytest.approx(2.0)  # the front is at +y now
    # a model facing +x turns a quarter; units scale it
    M = normalise(np.array([[0, 0, 0], [400, 0, 0], [400, 180, 150]], float), "+x", "cm")
    out = apply(M, [[400, 90, 0]])[0]
    assert extent(apply(M, [[0, 0, 0], [400, 0, 0], [400, 180, 150]])) == pytest.approx((1.8, 4.0, 1.5))
    assert out[1] == pytest.approx(2.0)  # the +x front is now +y


def test_a_model_outside_its_real_size_is_refused_naming_file_and_size():
    assert fit_size("ok.glb", "car", (1.8, 4.4, 1.5)) == 1.0
    with pytest.raises(InputError) as err:
        fit_size("/lib/car/giant.glb", "car", (18.0, 45.0, 15.0))
    msg = str(err.value)
    assert msg.startswith("/lib/car/giant.glb: ") and "45 m" in msg and "3–6 m in length" in msg
    with pytest.raises(InputError, match="pedestrian model must be 1.4–2.1 m in height, this one is 0.018 m"):
        fit_size("tiny.obj", "pedestrian", (0.004, 0.003, 0.018))
    # or scaled to the nearest end of the range when the preset says so
    assert fit_size("giant.glb", "car", (18.0, 45.0, 15.0), "scale") == pytest.approx(6.0 / 45.0)
    assert fit_size("tiny.obj", "pedestrian", (0.004, 0.003, 0.018), "scale") == pytest.approx(1.4 / 0.018)


def test_files_from_folders_globs_and_the_assets_folder(tmp_path):
    make_library(tmp_path / "lib")
    (tmp_path / "lib" / "car" / "notes.txt").write_text("not a model")
    cars = model_files(str(tmp_path / "lib" / "car"))
    assert [p.name for p in cars] == ["estate.glb", "hatch.glb"]  # recursive, models only, sorted
    assert [p.name for p in model_files("lib/car/*.glb", tmp_path)] == ["hatch.glb"]  # a glob, relative to base
    dirs = assets_dir(tmp_path / "lib")
    assert set(dirs) == {"car", "pedestrian"}
    files = library_files(dirs, "--assets")
    assert [p.rsplit("/", 1)[1] for p in files["pedestrian"]] == ["walker.obj"]
    (tmp_path / "lib" / "boats").mkdir()
    with pytest.raises(InputError, match=r"sub-folder\(s\) \['boats'\] are not classes"):
        assets_dir(tmp_path / "lib")
    with pytest.raises(InputError, match="assets.bus: no model file"):
        library_files({"bus": str(tmp_path / "lib" / "boats")}, "preset.json")


def test_preset_key_and_assets_flag(tmp_path):
    make_library(tmp_path / "models")
    preset = tmp_path / "p.json"
    preset.write_text(json.dumps({"style": "urban-canyon", "camera": "waymo-front", "quality": "draft",
                                  "assets": {"car": "models/car", "mix": {"car": 0.25}, "units": "cm"}}))
    cfg = load_render_preset(str(preset))
    a = cfg.assets
    assert set(a["files"]) == {"car"} and all(f.startswith(str(tmp_path / "models")) for f in a["files"]["car"])
    assert (a["mix"], a["units"], a["forward"], a["out_of_range"]) == ({"car": 0.25}, "cm", "-y", "refuse")
    assert cfg.to_dict()["assets"] == a  # in render_run.json: another library does not resume the dataset
    assert "assets" not in load_render_preset("default").to_dict()  # nor does a library appear from nowhere
    # --assets replaces the class entries; mix and units stay; a mix of a class with no library is refused
    flag = load_render_preset(str(preset), assets=str(tmp_path / "models")).assets
    assert set(flag["files"]) == {"car", "pedestrian"} and flag["mix"] == {"car": 0.25, "pedestrian": 1.0}
    preset.write_text(json.dumps({"style": "urban-canyon", "camera": "waymo-front", "quality": "draft",
                                  "assets": {"mix": {"bus": 0.5}}}))
    with pytest.raises(InputError, match=r"assets: mix gives a share to \['bus'\] but no library"):
        load_render_preset(str(preset))
    preset.write_text(json.dumps({"style": "urban-canyon", "camera": "waymo-front", "quality": "draft",
                                  "assets": {"boat": "x"}}))
    with pytest.raises(InputError, match="unknown key"):
        load_render_preset(str(preset))


def _library(mix=1.0) -> AssetLibrary:
    """Two box 'cars' and one 'pedestrian' as if imported (asset frame, metres)."""
    def model(file, cls, size):
        m = trimesh.creation.box(extents=size)
        v = np.asarray(m.vertices) + [0, 0, size[2] / 2]
        return LibraryModel(file, cls, v, np.asarray(m.faces), extent(v))
    return AssetLibrary({"car": [model("a.glb", "car", (1.8, 4.0, 1.4)), model("b.glb", "car", (2.0, 5.0, 1.6))],
                         "pedestrian": [model("p.obj", "pedestrian", (0.5, 0.3, 1.8))]},
                        {"car": mix, "pedestrian": 1.0})


def scene(seed, library=None):
    cfg = load_render_preset("default")
    return sample_scene(np.random.default_rng(seed), cfg.style, cfg.camera, cfg.resolution, seed=seed,
                        library=library)


def test_layout_samples_library_models_with_the_frames_rng():
    lib = _library()
    a, b = scene(3, lib), scene(3, lib)
    assert json.dumps(a) == json.dumps(b)  # same seed → same models at the same places
    cars = [o for o in a["objects"] if o["class"] == "car"]
    assert cars and all(o["asset"]["type"] == "library" for o in cars)
    assert {o["asset"]["params"]["file"] for o in cars} == {"a.glb", "b.glb"}
    assert all(o["asset"]["type"] != "library" for o in a["objects"] if o["class"] in ("van", "cyclist"))
    # an empty library draws nothing: the street is the procedural one, unchanged
    assert json.dumps(scene(3, AssetLibrary())) == json.dumps(scene(3))
    # mix: a share of the cars stays procedural
    mixed = [o["asset"]["type"] for o in scene(3, _library(mix=0.5))["objects"] if o["class"] == "car"]
    assert "library" in mixed and "car" in mixed


def test_silhouettes_use_the_library_mesh():
    lib = _library()
    desc = scene(1, lib)
    meshes = scene_meshes(desc, lib)
    car = next(o for o in desc["objects"] if o["asset"]["type"] == "library" and o["class"] == "car")
    (v, f, slot), = meshes[car["id"]]
    local, faces = lib.mesh(car["asset"]["params"]["file"])
    M = np.asarray(car["transform"])
    assert slot == "library" and np.array_equal(f, faces) and np.allclose(v, apply(M, local))
    K = Intrinsics.from_dict(desc["camera"]["intrinsics"])
    sil = silhouette_areas({car["id"]: [(v, f)]}, K, np.asarray(desc["camera"]["world_to_camera"]))
    assert sil[car["id"]]["pixels_total"] >= 0
    with pytest.raises(ValueError, match="needs the run's asset library"):
        scene_meshes(desc)


def test_night_streets_take_library_vehicles_without_lamps():
    cfg = load_render_preset("night")
    lib = _library()
    desc = sample_scene(np.random.default_rng(2), cfg.style, cfg.camera, cfg.resolution, seed=2,
                        lighting=cfg.lighting, library=lib)
    ids = {o["id"] for o in desc["objects"] if o["asset"]["type"] == "library"}
    assert ids and desc["lighting"]["sources"]  # street lamps, procedural vehicles' lights
    assert not {s.get("object_id") for s in desc["lighting"]["sources"]} & ids
