"""The LiDAR and radar stages build their Embree scenes from only the triangles their rays can meet
(:meth:`fogsim.render.lidar_scan.Geometry.seen_from`) and count the points per object of every fog level in
one pass (:func:`fogsim.lidar.objects.fogged_object_points`): the same hits and the same counts as the whole
frame and the plain per-level count, checked here on scenes built to catch a wrong cut."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fogsim.lidar.boxes import Box3D, box_members, points_in_boxes
from fogsim.lidar.fog import KEPT, FoggedScan
from fogsim.lidar.objects import fogged_object_points, object_points
from fogsim.lidar.points import PointCloud
from fogsim.lidar.sensors import LidarSensor

pytest.importorskip("embreex", reason="the LiDAR ray caster needs embreex (the 'blender' extra)")

from fogsim.render.lidar_scan import Geometry, RayCaster, sensor_caster, sweep  # noqa: E402


def street(rng: np.random.Generator) -> Geometry:
    """Boxes (1–20 m tall, 2–150 m away, all around) on a 600 m ground of two triangles, and two big
    triangles whose corners all lie outside the beams' band but which cross it (above and below)."""
    import trimesh

    parts = []
    for k in range(60):
        a, r = rng.uniform(-math.pi, math.pi), rng.uniform(2, 150)
        h = rng.uniform(1, 20)
        m = trimesh.creation.box(extents=[rng.uniform(0.5, 5), rng.uniform(0.5, 5), h])
        m.apply_translation([r * math.cos(a), r * math.sin(a), h / 2 + rng.uniform(0, 8)])
        parts.append((m.vertices, m.faces, k + 1, rng.uniform(0.05, 0.8)))
    ground = np.array([[-300, -300, 0], [300, -300, 0], [300, 300, 0], [-300, 300, 0]], float)
    parts.append((ground, [[0, 1, 2], [0, 2, 3]], 100, 0.15))
    # corners far above and far below the band, the face crossing it at 30 m ahead (x = 30)
    parts.append(([[30, -5, 60], [30, 5, 60], [30, 0, -60]], [[0, 1, 2]], 101, 0.5))
    parts.append(([[-30, -5, 60], [-30, 5, 60], [-40, 0, 60]], [[0, 1, 2]], 102, 0.5))  # wholly above: culled
    return Geometry.from_parts(parts)


def lidar(**kw) -> LidarSensor:
    grid = {} if "inclinations_deg" in kw else {"vertical_fov_deg": [-20, 3]}
    return LidarSensor.from_dict({"name": "t", "beams": 24, **grid,
                                  "horizontal_resolution_deg": 0.5, "max_range_m": 90.0, "intensity_scale": "0-1",
                                  "reflectivity_per_intensity": 1.0, "reference_reflectivity": 0.001, **kw})


def same_scan(a, b) -> None:
    np.testing.assert_array_equal(a.cloud.index, b.cloud.index)
    np.testing.assert_array_equal(a.object_id, b.object_id)
    np.testing.assert_array_equal(a.cloud.range_m, b.cloud.range_m)
    np.testing.assert_array_equal(a.reflectivity, b.reflectivity)
    np.testing.assert_array_equal(a.cloud.raw_intensity, b.cloud.raw_intensity)


#: lasers off the sensor's axis (a KITTI HDL-64E's 0.1–0.2 m vertical offsets, larger here): rays from their lasers
OFFSETS = {"inclinations_deg": np.linspace(3, -20, 24).tolist(),
           "vertical_offsets_m": np.linspace(0.6, 0.05, 24).tolist()}


@pytest.mark.parametrize("fov, extra", [(360.0, {}), (120.0, {}), (360.0, OFFSETS), (120.0, OFFSETS)])
def test_the_culled_scene_gives_the_sweep_of_the_whole_one(fov, extra):
    """A sensor 1.8 m up, turned and tilted: the sweep over its culled scene (top and bottom beams' cones,
    raised by the lasers' offsets where they have them, its field of view, its range) is the sweep over the
    whole scene, point for point; and the cut is real."""
    geo = street(np.random.default_rng(4))
    pose = np.eye(4)
    yaw, pitch = math.radians(25), math.radians(4)
    rz = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]])
    ry = np.array([[math.cos(pitch), 0, math.sin(pitch)], [0, 1, 0], [-math.sin(pitch), 0, math.cos(pitch)]])
    pose[:3, :3], pose[:3, 3] = rz @ ry, [3.0, -2.0, 1.8]
    s = lidar(horizontal_fov_deg=fov, **extra)
    culled = sensor_caster(geo, pose, s)
    assert len(culled.geometry.faces) < 0.8 * len(geo.faces)
    assert 101 in culled.geometry.face_id and 102 not in culled.geometry.face_id
    whole = sweep(RayCaster(geo), pose, s, "whole")
    assert (whole.object_id == 101).any() and (whole.object_id == 100).any()
    same_scan(whole, sweep(culled, pose, s, "culled"))


def test_faces_at_the_edges_of_the_band_are_kept_when_a_beam_meets_them():
    """Thin faces 20 m out on every side, spanning a beam's inclination by a few hundredths of a degree at
    the top and the bottom of the band (kept: the beam meets them), and faces just outside it (dropped)."""
    s = lidar()
    top, bottom = max(s.inclinations_deg), min(s.inclinations_deg)
    parts, k = [], 0
    for a in np.radians(np.arange(0, 360, 7.3)):
        for lo, hi in ((top - 0.03, top + 0.02), (bottom - 0.02, bottom + 0.03), (top + 0.06, top + 0.3),
                       (bottom - 0.3, bottom - 0.06)):
            k += 1
            u, w = np.array([math.cos(a), math.sin(a), 0.0]), np.array([-math.sin(a), math.cos(a), 0.0])
            corners = [20 * u + 20 * math.tan(math.radians(lo)) * np.array([0, 0, 1]) - 0.5 * w,
                       20 * u + 20 * math.tan(math.radians(lo)) * np.array([0, 0, 1]) + 0.5 * w,
                       20 * u + 20 * math.tan(math.radians(hi)) * np.array([0, 0, 1])]
            parts.append((corners, [[0, 1, 2]], k, 0.5))
    geo = Geometry.from_parts(parts)
    culled = sensor_caster(geo, np.eye(4), s)
    inside = {i for i in range(1, k + 1) if i % 4 in (1, 2)}
    assert set(culled.geometry.face_id.tolist()) == inside
    whole = sweep(RayCaster(geo), np.eye(4), s, "whole")
    assert set(whole.object_id.tolist()) == inside  # every kept face is met by its beam
    same_scan(whole, sweep(culled, np.eye(4), s, "culled"))


def test_the_range_cut_keeps_a_triangle_whose_corners_are_all_beyond_the_range():
    """A 400 m wide wall 50 m ahead has every corner 200 m away: the range cut keeps it (a corner's distance
    less the longest edge), and drops a small one 200 m away."""
    wall = ([[50, -200, -20], [50, 200, -20], [50, 0, 40]], [[0, 1, 2]], 1, 0.5)
    far = ([[200, 0, 0], [200, 1, 0], [200, 0, 1]], [[0, 1, 2]], 2, 0.5)
    geo = Geometry.from_parts([wall, far])
    cut = geo.seen_from(np.eye(4), max_range_m=90.0)
    assert cut.face_id.tolist() == [1]


def test_a_wedge_cut_gives_the_radars_hits():
    """A forward field of ±60° in azimuth and ±7° in elevation (the radar's rays), from 0.5 m up."""
    geo = street(np.random.default_rng(9))
    pose = np.eye(4)
    pose[:3, 3] = [0, 0, 0.5]
    az, el = np.meshgrid(np.radians(np.linspace(-60, 60, 400)), np.radians(np.linspace(-7, 7, 30)), indexing="ij")
    d = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], -1).reshape(-1, 3)
    cut = geo.seen_from(pose, (-7, 7), (-60, 60), 250.0)
    assert len(cut.faces) < 0.7 * len(geo.faces)
    origin = np.broadcast_to(pose[:3, 3], d.shape)
    t0, p0, _ = RayCaster(geo).cast(origin, d)
    t1, p1, _ = RayCaster(cut).cast(origin, d)
    np.testing.assert_array_equal(t0, t1)
    np.testing.assert_array_equal(geo.face_id[p0[p0 >= 0]], cut.face_id[p1[p1 >= 0]])


def random_boxes(rng, n):
    return [Box3D.from_yaw(rng.uniform([-40, -40, 0], [40, 40, 2]), *rng.uniform([1, 0.5, 1], [6, 3, 3]),
                           rng.uniform(-math.pi, math.pi)) for _ in range(n)]


def test_box_members_are_the_points_each_box_contains():
    rng = np.random.default_rng(1)
    boxes = random_boxes(rng, 30)
    xyz = np.concatenate([rng.uniform(-60, 60, (20000, 3)),
                          np.concatenate([b.centre + rng.uniform(-1, 1, (200, 3)) for b in boxes])])
    members = box_members(xyz, boxes)
    for b, m in zip(boxes, members):
        np.testing.assert_array_equal(np.sort(m), np.flatnonzero(b.contains(xyz)))
    assert sum(len(m) for m in members) > 2000
    np.testing.assert_array_equal(points_in_boxes(xyz, boxes), [b.contains(xyz).sum() for b in boxes])


def test_the_fog_levels_counts_are_each_levels_own_count():
    """Real fog levels of a clear scan (kept, attenuated, lost, clutter, the empty rays' clutter), and a level
    whose kept points moved (counted afresh): the same counts as counting each level's cloud alone."""
    from fogsim.lidar.fog import LidarFogger
    from fogsim.lidar.rays import EmptyRays

    rng = np.random.default_rng(2)
    boxes = random_boxes(rng, 20) + [None]
    xyz = np.concatenate([rng.uniform(-60, 60, (5000, 3)),
                          np.concatenate([b.centre + rng.uniform(-3, 3, (300, 3)) for b in boxes if b])])
    clear = PointCloud.from_raw(xyz.astype(np.float32), rng.uniform(0, 1, len(xyz)).astype(np.float32), "0-1", "t")
    s = LidarSensor.preset("hdl64e")
    d = rng.normal(size=(2000, 3))
    empty = EmptyRays(d / np.linalg.norm(d, axis=1)[:, None], np.zeros(2000, np.int16), np.full(2000, np.inf))
    fogger = LidarFogger(clear, s, None, empty)
    levels = {f"b{b}": fogger(b, np.random.default_rng(7)) for b in (0.0, 0.01, 0.06, 0.12)}
    assert any(len(f.cloud) > (f.outcome >= 0).sum() for f in levels.values())  # clutter of empty rays
    f = levels["b0.06"]
    shifted = PointCloud(f.cloud.xyz + np.float32(0.5), f.cloud.intensity, f.cloud.raw_intensity, f.cloud.scale,
                         f.cloud.index, f.cloud.source)
    levels["moved"] = FoggedScan(shifted, f.outcome, f.output_index)
    assert (levels["moved"].outcome == KEPT).any()
    got = fogged_object_points(clear, levels, boxes)
    want = object_points({k: v.cloud for k, v in levels.items()}, boxes)
    assert got == want and got[-1] is None
    assert got[0]["b0.0"] > 0 and any(c["moved"] != c["b0.06"] for c in got if c)  # the shift changed counts
