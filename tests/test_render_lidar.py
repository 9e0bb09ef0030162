"""Synthetic LiDAR in a render (fogsim.render.lidar_*): the sweep lies on what the camera rendered, the
labelled points lie in their objects' 3D boxes, the boxes project onto the masks' boxes, each level's scan
is the LiDAR fog model's, and the KITTI tree reads back by the format's spec.

The pure parts (rays, the caster, the rig, boxes) run everywhere with geometry built here; the render
tests run real Blender (the bpy module) on a tiny frame.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from fogsim.lidar.boxes import Box3D
from fogsim.lidar.sensors import LidarSensor
from fogsim.render.boxes3d import box_record, object_box
from fogsim.render.lidar_rig import camera_offset_pose, ego_to_world, mounted_pose
from fogsim.render.lidar_scan import Geometry, RayCaster, sweep, sweep_directions
from fogsim.scene.pose import camera_to_world, world_to_camera

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
pytest.importorskip("embreex", reason="the LiDAR ray caster needs embreex (the 'blender' extra)")


def box_mesh(centre, size, yaw=0.0):
    import trimesh

    m = trimesh.creation.box(extents=size)
    c, s = math.cos(yaw), math.sin(yaw)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    T[:3, 3] = centre
    m.apply_transform(T)
    return np.asarray(m.vertices), np.asarray(m.faces), T


def sensor(**kw) -> LidarSensor:
    return LidarSensor.from_dict({"name": "test", "beams": 16, "vertical_fov_deg": [-15, 15],
                                  "horizontal_resolution_deg": 1.0, "max_range_m": 100.0, "intensity_scale": "0-1",
                                  "reflectivity_per_intensity": 1.0, **kw})


# ----------------------------------------------------------------------------- pure
def test_rays_hit_a_wall_at_its_distance_with_the_lidar_equation():
    """A wall 20 m ahead (x = 20, ρ 0.6): every ray hitting it reports range 20 / cos(angle to the normal),
    the apparent reflectivity ρ·cos θ; the intensity is the sensor's for that ρ at that range."""
    v, f, _ = box_mesh([20.5, 0, 0], [1, 80, 80])
    geo = Geometry.from_parts([(v, f, 7, 0.6)])
    s = sensor()
    scan = sweep(RayCaster(geo), np.eye(4), s, "wall")
    d, beam, _ = sweep_directions(s)
    with np.errstate(divide="ignore"):
        t = np.where(d[:, 0] > 0, 20.0 / d[:, 0], np.inf)
    hits = np.flatnonzero(np.isfinite(t) & (np.abs(t * d[:, 1]) <= 40) & (np.abs(t * d[:, 2]) <= 40))
    rows = scan.cloud.index
    np.testing.assert_array_equal(rows, hits)  # exactly the rays that meet the wall (its face at x = 20)
    assert (scan.object_id == 7).all()
    cos_t = d[rows, 0]  # the wall's normal is −x: cos θ is the ray's x component
    np.testing.assert_allclose(scan.cloud.range_m, 20.0 / cos_t, rtol=1e-5)
    np.testing.assert_allclose(np.cos(np.radians(scan.incidence_deg)), cos_t, atol=1e-4)
    expected = s.intensity_of(0.6 * cos_t, 20.0 / cos_t)
    np.testing.assert_allclose(scan.cloud.raw_intensity, np.minimum(expected, 1.0), rtol=1e-5)
    np.testing.assert_array_equal(scan.cloud.ring, beam[rows])


def test_the_threshold_drops_dark_far_and_grazing_returns():
    """Two walls at 60 m: ρ 0.9 is reported, ρ 0.02 is not (its clear-air signal is below the threshold);
    exactly as (ρ cos θ/ρ_ref)(R_max/R)² ≥ 1 says."""
    s = sensor(max_range_m=80.0, reference_reflectivity=0.8)
    bright = box_mesh([60.5, -20, 0], [1, 40, 80])
    dark = box_mesh([60.5, 20, 0], [1, 40, 80])
    geo = Geometry.from_parts([(*bright[:2], 1, 0.9), (*dark[:2], 2, 0.02)])
    scan = sweep(RayCaster(geo), np.eye(4), s, "walls")
    assert (scan.object_id == 1).sum() > 100 and not (scan.object_id == 2).any()
    r = scan.cloud.range_m
    assert (s.clear_signal(scan.reflectivity * np.cos(np.radians(scan.incidence_deg)), r) >= 1).all()


def test_the_rig_puts_the_lidar_on_the_ego_vehicle_and_the_camera_offset():
    c2w = camera_to_world([3.0, 1.0, 1.6], yaw_deg=30.0, pitch_deg=-4.0)
    w2c = world_to_camera(c2w)
    ego = ego_to_world(w2c)
    assert np.allclose(ego[:3, 3], [3.0, 1.0, 0.0]) and np.allclose(ego[:3, 2], [0, 0, 1])
    # yaw 30° turns the camera's +y view left: the ego's forward is (−sin 30°, cos 30°, 0)
    assert np.allclose(ego[:3, 0], [-0.5, math.cos(math.radians(30)), 0], atol=1e-9)
    kitti = LidarSensor.preset("hdl64e")
    pose = mounted_pose(w2c, kitti.mount_pose)
    assert np.allclose(pose[:3, 3], [3.0, 1.0, 1.73])
    off = camera_offset_pose(w2c)
    assert np.allclose(off[:3, 3], [3.0, 1.0, 1.6] + (-0.27) * ego[:3, 0] + [0, 0, 0.08])


def test_object_boxes_are_tight_and_kitti_in_the_camera():
    """A 4.5 × 1.8 × 1.5 car (procedural frame: forward +y) turned 20°, 15 m ahead of a level camera."""
    v, f, T = box_mesh([0, 15, 0.75], [1.8, 4.5, 1.5], math.radians(20))
    box = object_box([(v, f, "body")], T, "+y")
    np.testing.assert_allclose(2 * box.half, [4.5, 1.8, 1.5], atol=1e-9)
    np.testing.assert_allclose(box.centre, [0, 15, 0.75], atol=1e-9)
    w2c = world_to_camera(camera_to_world([0, 0, 1.5]))
    rec = box_record(box, w2c, np.linalg.inv(np.eye(4)))
    cam = rec["camera"]
    np.testing.assert_allclose(cam["location_m"], [0, 1.5, 15], atol=1e-9)  # bottom centre: 1.5 m below the camera
    assert cam["dimensions_hwl_m"] == pytest.approx([1.5, 1.8, 4.5])
    # heading +y turned 20° left (towards −x): in the camera, x right, z forward → rotation_y = −(90° + 20°)
    assert cam["rotation_y"] == pytest.approx(-math.radians(110)) and cam["alpha"] == pytest.approx(cam["rotation_y"])
    assert rec["lidar"]["yaw"] == pytest.approx(math.radians(110))


def test_slots_take_their_905nm_reflectivity_not_their_colour():
    """Glass returns little, foliage is bright and carbon-black paint dark at 905 nm whatever they look like;
    a body's paint family comes from its colour, its spread is drawn per object (same object, same value)."""
    from fogsim.render.lidar_scan import slot_reflectivity, surface_reflectivity
    from fogsim.scene.reflectivity import PAINT_FAMILIES, SURFACES

    car = {"id": 3, "asset": {"materials": {"body_paint": {"color": [0.006, 0.006, 0.007]}}}}  # "#101112"
    assert slot_reflectivity({"id": 1, "asset": {}}, "glass") == SURFACES["glass"].rho < 0.01
    assert slot_reflectivity({"id": 1, "asset": {}}, "foliage", 5) > 0.25  # dark green, bright in the NIR
    black = [slot_reflectivity({**car, "id": i}, "body_paint", 7) for i in range(200)]
    assert slot_reflectivity(car, "body_paint", 7) == slot_reflectivity(car, "body_paint", 7)
    assert np.median(black) == pytest.approx(PAINT_FAMILIES["black"].rho, rel=0.2) and np.std(np.log(black)) > 0.3
    red = {"id": 4, "asset": {"materials": {"body_paint": {"color": [0.25, 0.01, 0.01]}}}}
    assert slot_reflectivity(red, "body_paint") > 2 * PAINT_FAMILIES["black"].rho * 3  # red looks dark, is not
    assert surface_reflectivity("Windshield_glass")[1] == "glass"
    assert surface_reflectivity("Material.001")[1] == "fallback"
    assert surface_reflectivity("Car Paint", transmission=1.0)[0] == SURFACES["glass"].rho


def test_painted_cars_at_10_to_100_m_follow_the_lidar_equation_with_the_table():
    """Procedural cars (the renderer's own meshes) in black, grey and white paint at 10–100 m around
    hdl64e, side-on, each on its own bearing: every ray that meets a car is reported exactly when
    (ρ·cos θ/ρ_ref)(R_max/R)²ξ(R) ≥ 1 with ρ the 905 nm table's value for that car's slot (its spread
    drawn per object), its intensity the sensor's for ρ·cos θ; a black car at 60 m is still seen, and
    each car's point count is what the equation predicts over the rays the geometry gives it."""
    from fogsim.render.frame import scene_meshes
    from fogsim.render.lidar_scan import slot_reflectivity
    from fogsim.scene.assets_vehicles import sample_car
    from fogsim.scene.pose import transform
    from fogsim.scene.reflectivity import paint_family

    paints = {"black": [0.006, 0.006, 0.007], "grey": [0.1, 0.11, 0.12], "white": [0.89, 0.89, 0.87]}
    objects, k = [], 0
    for x in (10.0, 20.0, 30.0, 45.0, 60.0, 80.0, 100.0):
        for name, colour in paints.items():
            k += 1
            a = math.radians(-70.0 + 140.0 * (k - 1) / 20)  # each car on its own bearing: none hides another
            params, mats = sample_car(np.random.default_rng(k), {})
            asset = {"type": "car", "params": params, "materials": {**mats, "body_paint": {"color": colour}}}
            objects.append({"id": k, "class": "car", "paint": name, "asset": asset, "forward": "+y",
                            "x": x, "transform": transform([x * math.cos(a), x * math.sin(a), 0.0], 90.0).tolist()})
    desc = {"seed": 11, "objects": objects}
    meshes = scene_meshes(desc)
    assert {paint_family(c) for c in paints.values()} == set(paints)
    geo = Geometry.of_frame(desc, meshes)
    s = LidarSensor.preset("hdl64e")
    pose = np.eye(4)
    pose[2, 3] = 1.73
    caster = RayCaster(geo)
    scan = sweep(caster, pose, s, "street")
    d, beam, az = sweep_directions(s)
    origins = s.beam_origins(beam, az) + pose[:3, 3]  # each ray from its laser (KITTI's vertical offsets)
    assert np.abs(origins[:, 2] - 1.73).max() > 0.1
    t, prim, normal = caster.cast(origins, d, s.max_range_m)
    hit = np.flatnonzero(np.isfinite(t) & (t >= s.min_range_m))
    cos_t = np.abs(np.einsum("ij,ij->i", normal[hit], d[hit]))
    rho = geo.face_rho[prim[hit]].astype(np.float64)
    by_id = {o["id"]: o for o in objects}
    for i, f in zip(hit[:50], prim[hit][:50]):  # each face's ρ is its slot's table value for that object
        oid = int(geo.face_id[f])
        assert any(math.isclose(geo.face_rho[f], slot_reflectivity(by_id[oid], slot, 11), rel_tol=1e-6)
                   for _, _, slot in meshes[oid])
    q = s.clear_signal(rho * cos_t, t[hit])
    np.testing.assert_array_equal(scan.cloud.index, hit[q >= 1])  # reported exactly where q ≥ 1
    np.testing.assert_allclose(scan.cloud.raw_intensity, np.minimum(s.intensity_of((rho * cos_t)[q >= 1],
                                                                                    t[hit][q >= 1]), 1.0), rtol=1e-5)
    points = {o["id"]: int((scan.object_id == o["id"]).sum()) for o in objects}
    rays = {o["id"]: int((geo.face_id[prim[hit]] == o["id"]).sum()) for o in objects}
    for o in objects:
        x = o["x"]
        assert 0 < points[o["id"]] <= rays[o["id"]], (o["paint"], x, points[o["id"]], rays[o["id"]])
        if x <= 60:  # the body's paint is seen to 60 m even when black; glass and tyres may drop out
            assert points[o["id"]] >= 0.5 * rays[o["id"]], (o["paint"], x, points[o["id"]], rays[o["id"]])
    black60 = next(o["id"] for o in objects if o["paint"] == "black" and o["x"] == 60.0)
    assert points[black60] >= 5
    white100 = next(o["id"] for o in objects if o["paint"] == "white" and o["x"] == 100.0)
    assert points[white100] >= 5


# ----------------------------------------------------------------------------- real Blender
def _project(points_world: np.ndarray, K: dict, w2c: np.ndarray):
    cam = points_world @ w2c[:3, :3].T + w2c[:3, 3]
    z = cam[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u, v = K["fx"] * cam[:, 0] / z + K["cx"], K["fy"] * cam[:, 1] / z + K["cy"]
    return u, v, z, np.linalg.norm(cam, axis=1)


def check_points_on_depth(out: Path, frame: str, caster=None, min_points: int = 200, convex: bool = False) -> dict:
    """Every LiDAR point the camera also sees lies on the rendered depth within 2 cm; labelled points lie in
    their object's box. "Seen": its pixel's 4×4 neighbourhood shows the object it hit, on one plane, and —
    with ``caster`` (the frame's geometry, rebuilt here) — the ray from the camera to the point meets nothing
    before it (an object can hide its own far side); ``convex`` (every object is a box, as the user scene of
    these tests): the surface the point lies on faces the camera. Returns counts."""
    from fogsim.io.depth_files import read_depth_file, read_uint16_map
    from fogsim.lidar.formats import read_points

    meta = json.loads((out / "meta" / f"{frame}.json").read_text())
    K, w2c = meta["camera"]["intrinsics"], np.asarray(meta["camera"]["world_to_camera"])
    l2w = np.asarray(meta["lidar"]["lidar_to_world"])
    cloud = read_points(out / meta["lidar"]["levels"]["clear"]["file"], meta["lidar"]["format"])
    labels = np.fromfile(out / meta["lidar"]["levels"]["clear"]["labels"], "<u4")
    with np.load(out / meta["lidar"]["sweep"]["attributes"], allow_pickle=False) as f:
        hit = f["object_id"].astype(np.int64)
        normal = f["normal"].astype(np.float64) @ l2w[:3, :3].T
        np.testing.assert_allclose(f["range_m"], cloud.range_m, rtol=1e-6)
    assert len(labels) == len(cloud) == len(hit)
    instance = (labels >> 16).astype(np.int64)
    assert ((instance == 0) | (instance == hit)).all()  # a labelled object's points carry its mask id
    world = cloud.xyz.astype(np.float64) @ l2w[:3, :3].T + l2w[:3, 3]
    u, v, z, ray = _project(world, K, w2c)
    depth, mask = read_depth_file(out / meta["depth"]["file"]), read_uint16_map(out / "masks" / f"{frame}.png")
    h, w = depth.shape
    inside = (z > 0.5) & (u >= 1) & (v >= 1) & (u < w - 2) & (v < h - 2)
    if convex:  # a box's face that faces the camera is seen where the mask shows that box
        inside &= np.einsum("ij,ij->i", normal, np.linalg.inv(w2c)[:3, 3] - world) > 0
    if caster is not None:  # the camera's own line of sight to each point, and the surface around it
        c2w = np.linalg.inv(w2c)
        centre = c2w[:3, 3]
        to_point = world - centre
        dist = np.linalg.norm(to_point, axis=1)
        first, prim, _ = caster.cast(np.broadcast_to(centre, world.shape), to_point / dist[:, None])
        inside &= first >= dist - 0.005  # nothing hides the point from the camera
        normal = caster.normals(np.maximum(prim, 0))
        for du, dv in ((0, 0), (1, 0), (0, 1), (1, 1)):  # the pixel centres the depth is interpolated from
            pu, pv = np.floor(u) + du, np.floor(v) + dv
            d = np.stack([(pu - K["cx"]) / K["fx"], (pv - K["cy"]) / K["fy"], np.ones_like(pu)], 1) @ c2w[:3, :3].T
            d /= np.linalg.norm(d, axis=1)[:, None]
            t, _, _ = caster.cast(np.broadcast_to(centre, d.shape), d)
            q = centre + d * np.where(np.isfinite(t), t, 1e9)[:, None]
            inside &= np.abs(np.einsum("ij,ij->i", q - world, normal)) < 1e-3  # on the point's plane
    ui, vi = np.floor(u[inside]).astype(int), np.floor(v[inside]).astype(int)
    idx = np.flatnonzero(inside)
    errs = []
    for k, x0, y0 in zip(idx, ui, vi):
        ids = mask[y0 - 1:y0 + 3, x0 - 1:x0 + 3]
        if hit[k] == 0 or not (ids == hit[k]).all():
            continue  # the camera sees another object there (occlusion from another viewpoint)
        inv = 1.0 / depth[y0 - 1:y0 + 3, x0 - 1:x0 + 3].astype(np.float64)
        flat = 1e-4 * inv[1, 1]  # 1/Z is linear in the image on a plane: second differences vanish
        if np.abs(np.diff(inv, 2, axis=0)).max() > flat or np.abs(np.diff(inv, 2, axis=1)).max() > flat:
            continue  # the 4×4 neighbourhood is not one plane (an edge between two faces)
        fx, fy = u[k] - x0, v[k] - y0  # 1/Z is bilinear on a plane: interpolate between pixel centres
        iz = (inv[1, 1] * (1 - fx) * (1 - fy) + inv[1, 2] * fx * (1 - fy) + inv[2, 1] * (1 - fx) * fy
              + inv[2, 2] * fx * fy)
        zc = 1.0 / iz
        xn, yn = (u[k] - K["cx"]) / K["fx"], (v[k] - K["cy"]) / K["fy"]
        errs.append(abs(zc * math.sqrt(1 + xn * xn + yn * yn) - ray[k]))
    assert len(errs) >= min_points, len(errs)
    assert max(errs) <= 0.02, max(errs)
    # labelled points lie in their object's box (1 cm of tolerance on the faces)
    boxes = {r["id"]: r["box3d"]["lidar"] for r in meta["lidar"]["objects"] if "box3d" in r}
    labelled = np.flatnonzero(instance > 0)
    assert len(labelled) > 50
    for oid in np.unique(instance[labelled]):
        b = boxes[int(oid)]
        box = Box3D.from_yaw(b["centre_m"], *(np.add(b["size_lwh_m"], 0.02)), b["yaw"])
        assert box.contains(cloud.xyz[instance == oid]).all(), oid
    return {"on_depth": len(errs), "labelled": len(labelled), "max_error_m": max(errs)}


def check_boxes_project_onto_masks(out: Path, frame: str, tolerance_px: float = 3.0) -> int:
    """For every unoccluded, untruncated object the 3D box's corners project onto the mask's 2D box."""
    meta = json.loads((out / "meta" / f"{frame}.json").read_text())
    K = meta["camera"]["intrinsics"]
    n = 0
    for r in meta["objects"]:
        if "box3d" not in r or r["visible_fraction"] < 0.99 or r["truncated"] or r["pixels"] < 40:
            continue
        b = r["box3d"]["world"]  # the camera may pitch: project the world box, not KITTI's yaw-only form
        box = Box3D.from_yaw(b["centre_m"], *b["size_lwh_m"], b["yaw"])
        w2c = np.asarray(meta["camera"]["world_to_camera"])
        u, v, _, _ = _project(box.corners(), K, w2c)
        projected = [u.min() + 0.5, v.min() + 0.5, u.max() + 0.5, v.max() + 0.5]  # pixel centres → edges
        assert np.abs(np.subtract(projected, r["bbox"])).max() <= tolerance_px, (r["class"], projected, r["bbox"])
        n += 1
    return n


RENDER = {"lidar": "hdl64e", "resolution": "240x160", "levels": "clear,0.06", "seed": 3}


@pytest.fixture(scope="module")
def lidar_render(tmp_path_factory):
    from test_blender import _need_bpy, run

    _need_bpy()
    out = tmp_path_factory.mktemp("lidar") / "out"
    res = run([sys.executable, "-m", "fogsim", "render", "--lidar", RENDER["lidar"], "--frames", "2", "--resolution",
               RENDER["resolution"], "--samples", "1", "--levels", RENDER["levels"], "--seed", str(RENDER["seed"]),
               "--quiet", "--out", str(out)])
    assert res.returncode == 0, res.stderr[-3000:]
    return out


@pytest.mark.blender
@pytest.mark.slow
def test_a_render_sweeps_what_the_camera_rendered(lidar_render):
    from fogsim.render.frame import DescribedFrame
    from fogsim.render.preset import load_render_preset

    config = load_render_preset("default", **RENDER)  # the scenes are functions of the preset and the seed
    counts = []
    for index, f in enumerate(("000000", "000001")):
        frame = DescribedFrame.of(config, index)
        counts.append(check_points_on_depth(lidar_render, f, RayCaster(Geometry.of_frame(frame.desc, frame.meshes))))
    assert sum(c["on_depth"] for c in counts) >= 500
    assert sum(check_boxes_project_onto_masks(lidar_render, f) for f in ("000000", "000001")) >= 1


@pytest.mark.blender
@pytest.mark.slow
def test_each_level_is_the_fog_models_scan_and_the_kitti_tree_reads_back(lidar_render):
    from fogsim.lidar.fog import LidarFogger
    from fogsim.lidar.formats import read_points
    from fogsim.lidar.outcome_file import read_outcomes
    from fogsim.readers.kitti import kitti_samples, read_kitti_calib
    from fogsim.render.lidar_frame import LIDAR_STREAM
    from test_kitti import spec_read_frame

    out = lidar_render
    meta = json.loads((out / "meta" / "000000.json").read_text())
    lv = meta["lidar"]["levels"]
    clear = read_points(out / lv["clear"]["file"], "kitti")
    fogged = read_points(out / lv["beta0.06"]["file"], "kitti")
    assert clear.same_as(read_points(out / meta["lidar"]["input"]["file"], "kitti"))  # the clear level is the sweep
    again = LidarFogger(clear, LidarSensor.from_dict(meta["lidar"]["sensor_spec"]))
    ref = again(0.06, np.random.default_rng([meta["seed"], 1, LIDAR_STREAM]))
    shown = len(ref.cloud)  # the sweep's points (the fogger here has no empty rays: their draws come after)
    np.testing.assert_array_equal(fogged.xyz[:shown], ref.cloud.xyz)
    assert len(fogged) == shown + lv["beta0.06"]["empty_ray_clutter"] and lv["beta0.06"]["empty_rays"] > 0
    outcome, index = read_outcomes(out / lv["beta0.06"]["outcome_file"])
    np.testing.assert_array_equal(outcome, ref.outcome)
    assert lv["beta0.06"]["outcomes"]["clutter"] > 0 and lv["clear"]["outcomes"]["kept"] == len(clear)
    # every labelled object has its points per level, fewer in fog
    pts = [r["lidar_points"] for r in meta["objects"] if "lidar_points" in r]
    assert pts and all(p["beta0.06"] <= p["clear"] for p in pts)
    # the KITTI tree: the spec reader, and fogsim's own KITTI reader (P2·R0·Tr reproduces the render's K and pose)
    for level in ("clear", "beta0.06"):
        points, calib, labels, size = spec_read_frame(out / "kitti" / level, "000000")
        assert size == (240, 160) and len(points) == len(read_points(out / lv[level]["file"], "kitti"))
    cal = read_kitti_calib(out / "kitti" / "clear" / "training" / "calib" / "000000.txt")
    K = meta["camera"]["intrinsics"]
    assert cal.intrinsics(240, 160).to_dict()["fx"] == pytest.approx(K["fx"])
    uv, _, ray = cal.project_velo(clear.xyz)
    w2c, l2w = np.asarray(meta["camera"]["world_to_camera"]), np.asarray(meta["lidar"]["lidar_to_world"])
    u, v, _, ray2 = _project(clear.xyz.astype(np.float64) @ l2w[:3, :3].T + l2w[:3, 3], K, w2c)
    ok = np.isfinite(uv[:, 0])
    np.testing.assert_allclose(uv[ok], np.stack([u, v], 1)[ok] + 0.5, atol=1e-3)
    np.testing.assert_allclose(ray[ok], ray2[ok], rtol=1e-6)
    samples = kitti_samples(out / "kitti" / "clear")
    objs = samples[0].labels().objects
    cars = [o for o in objs if o["kept"]]
    written = [r for r in meta["objects"] if r["kept"] and r["class"] in ("car", "van", "truck", "pedestrian",
                                                                          "cyclist", "bus") and "box3d" in r]
    assert len(cars) == len(written)


@pytest.mark.blender
@pytest.mark.slow
def test_scene_mode_sweeps_the_users_scene_and_leaves_the_blend(tmp_path):
    """A user's scene of boxes (tests/test_scene_mode.py's, the parented truck box left out so that every
    object is convex): the same checks; the .blend is untouched; the LiDAR sits at the camera + KITTI's offset."""
    from test_scene_mode import SPEC, _build, _digest, _render

    spec = {**SPEC, "boxes": [b for b in SPEC["boxes"] if b["name"] != "TruckBox"]}
    blend = _build("bpy", tmp_path, spec)
    before = _digest(blend.parent)
    out = tmp_path / "out"
    res = _render("bpy", blend, out, "--lidar", "hdl64e", "--samples", "1", "--levels", "clear,0.06",
                  "--frame-range", "1:3:2", "--resolution", "192x128", "--quiet")
    assert res.returncode == 0, res.stderr[-3000:]
    assert _digest(blend.parent) == before
    for f in ("000000", "000001"):
        counts = check_points_on_depth(out, f, convex=True, min_points=100)
        assert counts["labelled"] > 50
        meta = json.loads((out / "meta" / f"{f}.json").read_text())
        assert meta["scene"]["lidar"]["mount"].startswith("the camera")
    assert check_boxes_project_onto_masks(out, "000000") + check_boxes_project_onto_masks(out, "000001") >= 1


@pytest.mark.blender
@pytest.mark.slow
def test_the_renders_kitti_tree_round_trips_through_fogsim_fog_kitti(lidar_render, tmp_path):
    """fogsim's own KITTI export is a KITTI dataset: `fogsim fog --kitti` reads it, with its labels and scans,
    and fogs both sensors again; the render's dataset.json has the cross-sensor table."""
    from fogsim.cli import main
    from fogsim.lidar.formats import read_points

    manifest = json.loads((lidar_render / "dataset.json").read_text())
    rows = manifest["lidar"]["cross_sensor"]
    assert rows and {r["level"] for r in rows} == {"clear", "beta0.06"}
    assert all(r["lidar_share"] is None or 0 <= r["lidar_share"] <= 1 for r in rows)
    assert all(r["lidar_seen"] <= r["objects"] for r in rows)
    assert (lidar_render / "cross_sensor.md").is_file() and (lidar_render / "lidar_bev.png").is_file()
    assert (lidar_render / "kitti" / "clear" / "ImageSets" / "train.txt").is_file()
    out = tmp_path / "refog"
    code = main(["fog", "--kitti", str(lidar_render / "kitti" / "clear"), "--lidar", "--levels", "0,0.06",
                 "--quiet", "--out", str(out)])
    assert code == 0
    meta = json.loads(sorted((out / "meta").glob("*.json"))[0].read_text())
    kept = [o for o in meta["objects"] if o["kept"]]
    assert kept and all("lidar_points" in o for o in kept)  # the export's 3D boxes hold the export's scan
    assert sum(o["lidar_points"]["clear"] for o in kept) > 0
    refogged = read_points(out / meta["lidar"]["levels"]["clear"]["file"], "kitti")
    assert len(refogged) > 1000


@pytest.mark.blender
@pytest.mark.slow
def test_the_renders_semantic_kitti_sequences_and_pcds_read_back(lidar_render):
    """Each level's ``semantic_kitti/<level>/sequences/00`` read with SemanticKITTI's own label logic
    (:func:`test_semantic_kitti.read_sequence`): the scans are the level's, every instance is a meta object
    whose SemanticKITTI id its class maps to and whose points lie in its 3D box, scenery has no instance,
    the clear level's labels are what the sweep hit, fog clutter is 110 exactly where the outcome file says
    clutter; the .pcd beside each scan carries the same scan, labels and outcomes (open3d, pypcd4)."""
    from fogsim.dataset.semantic_kitti import FOG_ID, FOGSIM_TO_SEMANTIC_KITTI
    from fogsim.lidar.fog import CLUTTER
    from fogsim.lidar.formats import read_points
    from fogsim.lidar.outcome_file import read_outcomes
    from fogsim.lidar.pcd import read_pcd
    from test_scan_pcd import by_row, check_pcd
    from test_semantic_kitti import read_sequence

    out = lidar_render
    metas = {f: json.loads((out / "meta" / f"{f}.json").read_text()) for f in ("000000", "000001")}
    things = {FOGSIM_TO_SEMANTIC_KITTI[c] for c in ("car", "van", "truck", "bus", "pedestrian", "cyclist")}
    for level in ("clear", "beta0.06"):
        frames, calib, cfg = read_sequence(out / "semantic_kitti" / level)
        assert [fr["frame"] for fr in frames] == list(metas)
        np.testing.assert_allclose(calib["Tr"], metas["000000"]["lidar"]["lidar_to_camera"], atol=1e-9)
        np.testing.assert_allclose(frames[0]["pose"], np.eye(4), atol=1e-9)
        for fr in frames:
            meta = metas[fr["frame"]]
            entry = meta["lidar"]["levels"][level]
            cloud = read_points(out / entry["file"], "kitti")
            np.testing.assert_array_equal(fr["points"][:, :3], cloud.xyz)
            outcome, index = read_outcomes(out / entry["outcome_file"])
            rows = by_row(outcome, index, len(cloud))
            np.testing.assert_array_equal(fr["semantic"] == FOG_ID, rows == CLUTTER)
            assert set(np.unique(fr["semantic"]).tolist()) <= set(cfg["labels"])
            objects = {o["id"]: o for o in meta["lidar"]["objects"]}
            assert not np.isin(fr["semantic"][fr["instance"] == 0], list(things)).any()  # things have instances
            for oid in np.unique(fr["instance"][fr["instance"] > 0]).tolist():
                mine = fr["instance"] == oid
                assert (fr["semantic"][mine] == FOGSIM_TO_SEMANTIC_KITTI[objects[oid]["class"]]).all()
                if level == "clear" and "lidar_box" in objects[oid]:
                    box = objects[oid]["lidar_box"]
                    local = (fr["points"][mine, :3] - box["centre_m"]) @ np.asarray(box["axes"])
                    assert (np.abs(local) <= np.asarray(box["half_m"]) + 0.05).all(), oid
            if level == "clear":  # β = 0: every sweep point kept, labelled by what it hit
                hit = np.load(out / meta["lidar"]["sweep"]["attributes"], allow_pickle=False)["object_id"]
                cars = np.isin(hit, [i for i, o in objects.items() if o["class"] == "car"])
                assert cars.any() and (fr["semantic"][cars] == 10).all()
                np.testing.assert_array_equal(fr["instance"][cars], hit[cars])
            raw = np.fromfile(out / entry["labels"], "<u4")
            np.testing.assert_array_equal(raw, (fr["instance"] << 16) | fr["semantic"])
            beam = np.load(out / meta["lidar"]["sweep"]["attributes"], allow_pickle=False)["beam"]
            # the KITTI .bin has no ring; the sweep knew each beam. The rows after the input's are the empty
            # rays' fog clutter: their beams are the sensor's (the sweep file keeps only the hits)
            ring = read_pcd(out / entry["pcd"])[1]["ring"].astype(np.int64)
            appended = np.ones(len(cloud), bool)
            appended[index[index >= 0]] = False
            assert (rows[appended] == CLUTTER).all() and ((ring[appended] >= 0) & (ring[appended] < 64)).all()
            ring[index[index >= 0]] = beam[index >= 0]
            check_pcd(out / entry["pcd"], cloud, rows, raw, ring)
    assert json.loads((out / "dataset.json").read_text())["lidar"]["semantic_kitti"]["fog_id"] == FOG_ID


@pytest.mark.blender
@pytest.mark.slow
def test_the_render_exports_as_nuscenes_samples_with_the_sweeps_beams(lidar_render, tmp_path):
    """``fogsim export nuscenes`` on the render: each level's samples are its scan (x y z, intensity × 255)
    and the ring estimated from the sensor's inclinations is the beam the sweep cast (the KITTI .bin of an
    hdl64e render stores none)."""
    from fogsim.cli import main
    from fogsim.lidar.outcome_file import read_outcomes
    from test_export_nuscenes import read_pcd_bin

    out = lidar_render
    assert main(["export", "nuscenes", str(out), "--out", str(tmp_path / "nusc"), "--quiet"]) == 0
    for f in ("000000", "000001"):
        meta = json.loads((out / "meta" / f"{f}.json").read_text())
        beam = np.load(out / meta["lidar"]["sweep"]["attributes"], allow_pickle=False)["beam"]
        for level, entry in meta["lidar"]["levels"].items():
            got = read_pcd_bin(tmp_path / "nusc" / level / "samples" / "LIDAR_TOP" / f"{f}.pcd.bin")
            scan = np.frombuffer((out / entry["file"]).read_bytes(), "<f4").reshape(-1, 4)
            np.testing.assert_array_equal(got[:, :3], scan[:, :3])
            np.testing.assert_allclose(got[:, 3], 255.0 * scan[:, 3], rtol=1e-6)
            _, index = read_outcomes(out / entry["outcome_file"])
            mine = index[index >= 0]  # the input's rows; after them the empty rays' clutter (no sweep record)
            np.testing.assert_array_equal(got[mine, 4], beam[index >= 0])
            others = np.setdiff1d(np.arange(len(scan)), mine)
            assert ((got[others, 4] >= 0) & (got[others, 4] < 64)).all()


@pytest.mark.detect
def test_the_renders_coco_masks_are_its_instance_masks(lidar_render):
    """Every COCO file a render writes, read with pycocotools: annToMask of every annotation is the object's
    pixels in masks/<frame>.png, and COCOeval ``segm`` gives AP 1.0 for the ground truth fed back."""
    from fogsim.io.depth_files import read_uint16_map
    from test_coco_masks import check_coco_masks

    masks = {f: read_uint16_map(lidar_render / "masks" / f"{f}.png") for f in ("000000", "000001")}
    assert check_coco_masks(lidar_render, masks) >= 2


@pytest.mark.blender
@pytest.mark.slow
def test_the_renders_kitti_tree_links_the_level_images_and_scans(lidar_render):
    import os

    for level in ("clear", "beta0.06"):
        tree = lidar_render / "kitti" / level / "training"
        for f in ("000000", "000001"):
            semantic = lidar_render / "semantic_kitti" / level / "sequences" / "00" / "velodyne" / f"{f}.bin"
            for twin, own in ((tree / "image_2" / f"{f}.png", lidar_render / "images" / level / f"{f}.png"),
                              (tree / "velodyne" / f"{f}.bin", lidar_render / "lidar" / level / f"{f}.bin"),
                              (semantic, lidar_render / "lidar" / level / f"{f}.bin")):
                assert not twin.is_symlink() and twin.read_bytes() == own.read_bytes()
                assert os.stat(twin).st_ino == os.stat(own).st_ino and os.stat(own).st_nlink >= 2
