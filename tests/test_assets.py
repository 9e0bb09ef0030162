"""The procedural asset library: valid meshes, honest extents, determinism, the catalogue."""
import json

import numpy as np
import pytest

from fogsim.scene.assets import ASSET_TYPES, asset_extent, build_asset, sample_asset
from fogsim.scene.materials import MATERIALS, TEXTURES, material

SEEDS = range(5)
VEHICLES = {  # (width, length, height) ranges, metres
    "car": ((1.75, 1.9), (4.2, 4.9), (1.4, 1.55)),
    "van": ((1.95, 2.05), (5.0, 5.5), (2.0, 2.4)),
    "truck": ((2.45, 2.55), (7.0, 9.0), (3.0, 3.6)),
    "bus": ((2.5, 2.55), (10.0, 12.0), (3.0, 3.2)),
}
WHEELS = {"car": 4, "van": 4, "truck": 6, "bus": 6, "cyclist": 2}
MAX_FACES = {"car": 3000, "van": 3000, "truck": 3000, "bus": 3000, "pedestrian": 2000, "cyclist": 3000,
             "building": 5000}
REQUIRED = ("body_paint glass tyre rim headlight taillight plastic_black skin hair cloth_top cloth_bottom shoe "
            "bike_frame asphalt lane_paint sidewalk curb facade_brick facade_concrete facade_plaster window door "
            "roof pole_metal signal_housing signal_red signal_amber signal_green sign_face sign_back "
            "bark foliage").split()


def spec_of(asset_type: str, seed: int, **constraints) -> dict:
    return sample_asset(asset_type, np.random.default_rng(seed), **constraints)


def bounds(parts) -> tuple[np.ndarray, np.ndarray]:
    v = np.concatenate([np.asarray(m.vertices) for m, _ in parts])
    return v.min(0), v.max(0)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("asset_type", ASSET_TYPES)
def test_build_is_valid_and_extent_is_honest(asset_type, seed):
    spec = spec_of(asset_type, seed)
    parts = build_asset(spec)
    slots = [slot for _, slot in parts]
    assert parts and len(set(slots)) == len(slots), "one mesh per material slot"
    for mesh, slot in parts:
        assert slot in MATERIALS
        assert len(mesh.faces) > 0 and np.isfinite(mesh.vertices).all()
        assert mesh.is_winding_consistent and mesh.volume > 0, f"{slot}: normals must point outward"
    assert sum(len(m.faces) for m, _ in parts) <= MAX_FACES.get(asset_type, 3000)
    lo, hi = bounds(parts)
    assert abs(lo[2]) <= 0.01, "stands on the ground"
    ext = np.array(asset_extent(spec))
    assert (ext >= hi - lo - 1e-9).all() and (ext - (hi - lo) <= 0.02).all(), (ext, hi - lo)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("asset_type", list(VEHICLES))
def test_vehicle_dimensions_and_footprint(asset_type, seed):
    lo, hi = bounds(build_asset(spec_of(asset_type, seed)))
    assert np.abs(lo[:2] + hi[:2]).max() <= 0.02, "footprint centred on the origin"
    for size, (a, b) in zip(hi - lo, VEHICLES[asset_type]):
        assert a - 1e-6 <= size <= b + 1e-6


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("asset_type", list(WHEELS))
def test_wheels_touch_the_ground(asset_type, seed):
    tyres = [m for m, slot in build_asset(spec_of(asset_type, seed)) if slot == "tyre"][0]
    v = np.asarray(tyres.vertices)
    assert abs(v[:, 2].min()) <= 0.01
    contacts = v[v[:, 2] < 0.01]
    wheels = {(bool(x > 0) if asset_type != "cyclist" else True, round(y * 2)) for x, y, _ in contacts}
    assert len(wheels) == WHEELS[asset_type]


@pytest.mark.parametrize("asset_type", list(VEHICLES))
def test_vehicles_face_plus_y(asset_type):
    parts = dict((slot, m) for m, slot in build_asset(spec_of(asset_type, 3)))
    assert parts["headlight"].vertices[:, 1].min() > 0 > parts["taillight"].vertices[:, 1].max()


@pytest.mark.parametrize("seed", SEEDS)
def test_people_heights(seed):
    for asset_type in ("pedestrian", "cyclist"):
        spec = spec_of(asset_type, seed)
        assert 1.5 <= spec["params"]["height"] <= 1.95
        assert 1.4 <= asset_extent(spec)[2] <= 1.95


def test_pedestrian_pose_is_a_parameter():
    standing = spec_of("pedestrian", 0, stride=0.0)
    walking = spec_of("pedestrian", 0, stride=20.0)
    size_y = [asset_extent(s)[1] for s in (standing, walking)]
    assert size_y[1] > size_y[0] + 0.3, "a stride spreads the feet along y"


@pytest.mark.parametrize("asset_type", ASSET_TYPES)
def test_deterministic_and_json(asset_type):
    a, b, c = spec_of(asset_type, 11), spec_of(asset_type, 11), spec_of(asset_type, 12)
    assert a == b and a != c
    round_trip = json.loads(json.dumps(a))
    for (m1, s1), (m2, s2) in zip(build_asset(a), build_asset(round_trip), strict=True):
        assert s1 == s2 and np.array_equal(m1.vertices, m2.vertices) and np.array_equal(m1.faces, m2.faces)


def test_only_the_given_rng_is_used():
    np.random.seed(1)
    state = np.random.get_state()
    first = [spec_of(t, 5) for t in ASSET_TYPES]
    assert np.array_equal(np.random.get_state()[1], state[1])
    np.random.seed(2)
    assert [spec_of(t, 5) for t in ASSET_TYPES] == first


def test_building_respects_plot():
    spec = spec_of("building", 3, width=12, depth=10, height=20)
    assert (spec["params"]["width"], spec["params"]["depth"], spec["params"]["height"]) == (12, 10, 20)
    assert np.allclose(asset_extent(spec), (12, 10, 20))
    lo, hi = bounds(build_asset(spec))
    assert np.allclose(lo, (-6, -5, 0), atol=0.02) and np.allclose(hi, (6, 5, 20), atol=0.02)
    slots = {slot for _, slot in build_asset(spec)}
    assert spec["params"]["facade"] in slots and {"window", "roof"} <= slots


def test_building_windows_on_the_street_side():
    parts = dict((slot, m) for m, slot in build_asset(spec_of("building", 4, width=15, depth=12, height=18)))
    assert parts["window"].vertices[:, 1].min() > 5.0


@pytest.mark.parametrize("state", ["red", "amber", "green"])
def test_traffic_light_has_one_lit_lamp(state):
    spec = spec_of("traffic_light", 0, state=state)
    lit = [s for s, m in spec["materials"].items() if material(s, **m).get("emission", 0) > 0]
    assert lit == [f"signal_{state}"]
    assert {"signal_red", "signal_amber", "signal_green"} <= {s for _, s in build_asset(spec)}


@pytest.mark.parametrize("shape", ["circle", "triangle", "rectangle"])
def test_sign_shapes(shape):
    spec = spec_of("traffic_sign", 1, shape=shape)
    slots = {s for _, s in build_asset(spec)}
    assert spec["params"]["shape"] == shape and {"sign_face", "sign_back", "pole_metal"} <= slots


def test_unknown_type_and_constraint():
    with pytest.raises(ValueError, match="car.*building"):
        sample_asset("spaceship", np.random.default_rng(0))
    with pytest.raises(ValueError, match="wingspan"):
        sample_asset("car", np.random.default_rng(0), wingspan=3.0)
    with pytest.raises(ValueError, match="state"):
        sample_asset("traffic_light", np.random.default_rng(0), state="blue")


def test_material_catalogue():
    assert set(REQUIRED) <= set(MATERIALS)
    untextured = {"glass", "headlight", "taillight", "lane_paint", "street_lamp", "signal_red", "signal_amber",
                  "signal_green"}
    for name, m in MATERIALS.items():
        assert m["texture"] in TEXTURES and m["texture_scale"] > 0
        assert len(m["color"]) == 3 and all(0.0 <= c <= 1.0 for c in m["color"])
        assert 0 <= m["roughness"] <= 1 and 0 <= m["metallic"] <= 1
        assert m["texture"] != "none" or name in untextured, name


def test_material_overrides_copy():
    red = material("body_paint", color=[0.5, 0.0, 0.0])
    assert red["color"] == [0.5, 0.0, 0.0] and MATERIALS["body_paint"]["color"] != red["color"]
    material("tyre")["color"][0] = 9.0
    assert MATERIALS["tyre"]["color"][0] != 9.0
    with pytest.raises(KeyError, match="body_paint"):
        material("unobtainium")
