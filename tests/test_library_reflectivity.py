"""A library model's materials reach the LiDAR by name and kind, as a user's scene's do: a car made by trimesh
with materials named "car_paint_red", "glass" and "tire_rubber" returns each part's 905 nm reflectivity from
the table (red paint's family, glass, tyre rubber, each drawn per object), not the 0.3 fallback; its points'
intensities are the sensor's for ρ·cos θ. Pure (a model as the importer hands it over) and in a real render
with ``--assets`` (bpy)."""
from __future__ import annotations

import json
import math
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from fogsim.scene.library import LibraryModel
from fogsim.scene.reflectivity import FALLBACK, PAINT_FAMILIES, SURFACES, instance_reflectivity, material_entry

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

#: the car's materials: name → the table entry its name (or kind) must map to
CAR_MATERIALS = {"car_paint_red": PAINT_FAMILIES["red"], "glass": SURFACES["glass"], "tire_rubber": SURFACES["tyre"]}


def test_names_and_kinds_map_to_the_table():
    assert material_entry("car_paint_red")[0] is PAINT_FAMILIES["red"]
    assert material_entry("Body paint", colour=[0.8, 0.8, 0.8])[0] is PAINT_FAMILIES["white"]  # its base colour
    assert material_entry("CarPaint.001", colour=[0.004, 0.004, 0.004])[0] is PAINT_FAMILIES["black"]
    assert material_entry("paint")[0] is SURFACES["body_paint"]  # nothing else known: the catalogue's own
    assert material_entry("tire_rubber")[0] is SURFACES["tyre"]
    assert material_entry("Material.004", transmission=1.0)[0] is SURFACES["glass"]
    assert material_entry("Material.004")[0] is FALLBACK
    own = material_entry("car_paint_red", reflectivity=20.0)[0]
    assert own.rho == 20.0 and own.retro and own.spread == 0


def painted_car() -> LibraryModel:
    """Body, cabin (glass) and two wheels (tyres) as one model with three materials, as the importer gives it."""
    import trimesh

    parts = [(trimesh.creation.box(extents=[1.8, 4.2, 0.8]), [0.0, 0.0, 0.7], 0),
             (trimesh.creation.box(extents=[1.6, 2.0, 0.6]), [0.0, -0.5, 1.4], 1)]
    for y in (-1.3, 1.3):
        wheel = trimesh.creation.cylinder(radius=0.33, height=0.25, sections=16)
        wheel.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))
        parts.append((wheel, [1.0, y, 0.33], 2))
    vs, fs, ms, n = [], [], [], 0
    for mesh, at, k in parts:
        vs.append(np.asarray(mesh.vertices) + at)
        fs.append(np.asarray(mesh.faces) + n)
        ms.append(np.full(len(mesh.faces), k))
        n += len(mesh.vertices)
    v = np.concatenate(vs)
    materials = ({"name": "car_paint_red", "color": [0.5, 0.02, 0.02], "transmission": 0.0, "reflectivity": None},
                 {"name": "glass", "color": [0.1, 0.1, 0.1], "transmission": 0.0, "reflectivity": None},
                 {"name": "tire_rubber", "color": None, "transmission": 0.0, "reflectivity": None})
    return LibraryModel("car.glb", "car", v, np.concatenate(fs), (1.8, 4.2, 1.7), 1.0, materials, np.concatenate(ms))


def test_a_library_models_faces_take_their_materials_reflectivity():
    from fogsim.render.frame import scene_meshes
    from fogsim.render.lidar_scan import Geometry
    from fogsim.scene.library import AssetLibrary

    model = painted_car()
    library = AssetLibrary({"car": [model]})
    objects = [{"id": i, "class": "car", "asset": model.spec(), "forward": "+y",
                "transform": np.eye(4).tolist()} for i in (4, 5)]
    desc = {"seed": 21, "objects": objects}
    meshes = scene_meshes(desc, library)
    assert sorted(slot for _, _, slot in meshes[4]) == sorted(f"library:{n}" for n in CAR_MATERIALS)
    geo = Geometry.of_frame(desc, meshes)
    faces = {k: int((model.face_material == j).sum()) for j, k in enumerate(CAR_MATERIALS)}
    for oid in (4, 5):
        for name, entry in CAR_MATERIALS.items():
            rho = instance_reflectivity(entry, 21, oid, zlib.crc32(f"library:{name}".encode()))
            assert int(((geo.face_id == oid) & np.isclose(geo.face_rho, rho, rtol=1e-6)).sum()) >= faces[name]
    assert not np.isclose(geo.face_rho, FALLBACK.rho).any()
    red = geo.face_rho[(geo.face_id == 4)].max()
    assert red > 0.25  # red paint is bright at 905 nm however dark it looks


# ----------------------------------------------------------------------------- real Blender
def write_library(root: Path) -> None:
    """A glTF car with the three named materials (trimesh's exporter) and an OBJ walker ("skin")."""
    import trimesh

    from asset_models import pedestrian

    scene = trimesh.Scene()

    def part(mesh, at, name, colour):
        mesh.apply_translation(at)
        mesh.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
            name=name, baseColorFactor=np.array([*colour, 255], np.uint8)))
        return mesh
    # glTF frame: x right, y up, z front
    scene.add_geometry(part(trimesh.creation.box(extents=[1.8, 0.75, 4.3]), [0, 0.7, 0], "car_paint_red",
                            (150, 20, 20)), geom_name="body")
    scene.add_geometry(part(trimesh.creation.box(extents=[1.6, 0.6, 2.0]), [0, 1.37, -0.6], "glass",
                            (30, 40, 50)), geom_name="cabin")
    for i, (sx, sz) in enumerate(((-1, -1), (-1, 1), (1, -1), (1, 1))):
        wheel = trimesh.creation.cylinder(radius=0.33, height=0.25, sections=16)
        wheel.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
        scene.add_geometry(part(wheel, [sx * 0.88, 0.33, sz * 1.4], "tire_rubber", (20, 20, 20)),
                           geom_name=f"wheel{i}")
    (root / "car").mkdir(parents=True)
    scene.export(root / "car" / "painted.glb")
    (root / "pedestrian").mkdir()
    pedestrian(1.78).export(root / "pedestrian" / "walker.obj")


@pytest.mark.blender
@pytest.mark.slow
def test_a_render_with_library_models_sees_their_materials(tmp_path):
    from fogsim.lidar.formats import read_points
    from fogsim.lidar.sensors import LidarSensor
    from test_blender import _need_bpy, run

    _need_bpy()
    write_library(tmp_path / "lib")
    out = tmp_path / "out"
    res = run([sys.executable, "-m", "fogsim", "render", "--assets", str(tmp_path / "lib"), "--lidar", "hdl64e",
               "--frames", "1", "--resolution", "96x64", "--samples", "1", "--levels", "clear", "--quiet",
               "--out", str(out)])
    assert res.returncode == 0, res.stderr[-3000:]
    meta = json.loads((out / "meta" / "000000.json").read_text())
    seed = int(meta["scene"]["seed"])
    cars = [o for o in meta["scene"]["objects"] if o["asset"]["type"] == "library" and o["class"] == "car"]
    walkers = [o for o in meta["scene"]["objects"] if o["asset"]["type"] == "library" and o["class"] == "pedestrian"]
    assert cars
    with np.load(out / meta["lidar"]["sweep"]["attributes"], allow_pickle=False) as f:
        oid, rho, incidence = f["object_id"].astype(int), f["reflectivity"], f["incidence_deg"]
    cloud = read_points(out / meta["lidar"]["input"]["file"], meta["lidar"]["format"])
    sensor = LidarSensor.preset("hdl64e")
    seen = {name: 0 for name in CAR_MATERIALS}
    for car in cars:
        slots = {s: s.split(":", 1)[1] for s in car["asset"]["materials"]}
        assert set(slots.values()) >= set(CAR_MATERIALS)  # the importer kept the names
        table = {slot: instance_reflectivity(CAR_MATERIALS[name], seed, car["id"], zlib.crc32(slot.encode()))
                 for slot, name in slots.items() if name in CAR_MATERIALS}
        mine = oid == car["id"]
        for slot, value in table.items():
            on = mine & np.isclose(rho, value, rtol=1e-6)
            seen[slots[slot]] += int(on.sum())
        # every point on the car carries one of its parts' table values (never the fallback)
        assert np.isclose(rho[mine][:, None], list(table.values()), rtol=1e-6).any(axis=1).all()
    assert seen["car_paint_red"] > 50 and seen["tire_rubber"] > 5, seen
    cos_t = np.cos(np.radians(incidence))
    on_cars = np.isin(oid, [c["id"] for c in cars])
    expected = np.minimum(sensor.intensity_of(rho * cos_t, cloud.range_m), 1.0)
    np.testing.assert_allclose(cloud.intensity[on_cars], expected[on_cars], rtol=1e-4, atol=2e-6)
    if walkers:  # the OBJ's "skin" (its MTL) is skin at 905 nm
        skin = [instance_reflectivity(SURFACES["skin"], seed, w["id"], zlib.crc32(s.encode()))
                for w in walkers for s in w["asset"]["materials"]]
        mine = np.isin(oid, [w["id"] for w in walkers])
        assert np.isclose(rho[mine][:, None], skin, rtol=1e-6).any(axis=1).all()
