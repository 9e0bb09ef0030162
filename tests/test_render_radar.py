"""Synthetic radar in a render (fogsim.render.radar_*): detections lie on their objects' boxes, move as their
objects do, follow the radar equation, are seeded, and their files read back by the nuScenes spec and by
pypcd4; the cross-sensor table gains the radar column.

The pure parts run everywhere with geometry built here; the render tests run real Blender (the bpy module) on
tiny frames (96×64, one sample).
"""
from __future__ import annotations

import json
import math
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from fogsim.lidar.boxes import Box3D
from fogsim.radar.detections import GHOST, OBJECT
from fogsim.radar.sensors import RadarSensor
from fogsim.render.radar_rcs import CLASS_RCS_DBSM, aspect_rad, object_rcs_dbsm

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
pytest.importorskip("embreex", reason="the radar's ray caster needs embreex (the 'blender' extra)")


def box_mesh(centre, size, yaw=0.0):
    """(vertices, faces) of a box (the LiDAR tests' :func:`test_render_lidar.box_mesh` without its pose)."""
    from test_render_lidar import box_mesh as posed_box

    return posed_box(centre, size, yaw)[:2]


def ars408(**kw) -> RadarSensor:
    spec = json.loads((ROOT / "fogsim" / "presets" / "radar" / "ars408-lr.json").read_text())
    for k, v in kw.items():
        spec[k] = v
        spec["sources"][k] = "test"
    return RadarSensor.from_dict(spec)


def box_distance(points: np.ndarray, centre, size_lwh, yaw) -> np.ndarray:
    """Euclidean distance of world points from an upright box (0 inside)."""
    c, s = math.cos(yaw), math.sin(yaw)
    d = np.asarray(points, np.float64) - np.asarray(centre, np.float64)
    local = np.stack([d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c, d[:, 2]], 1)
    out = np.maximum(np.abs(local) - np.asarray(size_lwh, np.float64) / 2, 0.0)
    return np.linalg.norm(out, axis=1)


# ----------------------------------------------------------------------------- pure
def test_rcs_by_class_and_aspect():
    """Head-on and broadside are the table's values; between them the power interpolates by cos²/sin²."""
    front, side = CLASS_RCS_DBSM["car"]
    assert object_rcs_dbsm("car", 0.0) == pytest.approx(front) and object_rcs_dbsm("car", math.pi / 2) == \
        pytest.approx(side)
    mid = 10 * math.log10((10 ** (front / 10) + 10 ** (side / 10)) / 2)
    assert object_rcs_dbsm("car", math.pi / 4) == pytest.approx(mid)
    assert object_rcs_dbsm("pedestrian", 1.0) == pytest.approx(-8.0)
    assert aspect_rad([0, 1], [0, -5]) == pytest.approx(0.0)
    assert aspect_rad([1, 0], [0, 3]) == pytest.approx(math.pi / 2)


def _scene(sensor, seed=0, **motion):
    """A car 30 m ahead (rear face at 27.75 m, driving away at 5 m/s), a pedestrian, the road; the radar
    0.5 m above the road driving at 10 m/s."""
    from fogsim.render.lidar_scan import Geometry, RayCaster
    from fogsim.render.radar_scan import Motion, radar_sweep

    car, ped, road = box_mesh([30, 0, 0.75], [4.5, 1.8, 1.5]), box_mesh([15, 3, 0.9], [0.5, 0.5, 1.8]), \
        box_mesh([60, 0, -0.05], [200, 60, 0.1])
    geo = Geometry.from_parts([(*car, 5, 0.5), (*ped, 6, 0.5), (*road, 1, 0.3)])
    pose = np.eye(4)
    pose[2, 3] = 0.5
    m = Motion(np.array(motion.get("ego", [10.0, 0, 0])), {5: np.array(motion.get("car", [5.0, 0, 0]))})
    return radar_sweep(RayCaster(geo), pose, sensor, {5: "car", 6: "pedestrian", 1: "road"},
                       {5: np.array([1.0, 0, 0])}, m, np.random.default_rng(seed)), pose


def test_detections_follow_the_radar_equation_and_the_motion():
    """A noise-free sensor (accuracies 0, no false alarms): each object detection lies on its box, its SNR is
    the sensor's radar equation at its RCS and range and above the threshold, its radial velocity the
    relative velocity projected on its ray within half a resolution step, the compensated one the object's;
    the car's powers sum to its RCS head-on (10 dBsm); its ghost is the strongest detection mirrored through
    the road, GHOST_LOSS_DB weaker."""
    from fogsim.render.radar_scan import GHOST_LOSS_DB

    s = ars408(range_accuracy_m=0.0, azimuth_accuracy_deg=0.0, false_alarms_per_scan=0.0,
               near_range={**ars408().near_range, "range_accuracy_m": 0.0, "azimuth_accuracy_deg": 0.0})
    sw, pose = _scene(s)
    np.testing.assert_allclose(sw.xyz, sw.xyz_true, atol=1e-4)
    np.testing.assert_allclose(sw.snr_db, s.snr_db(sw.rcs_dbsm, sw.range_m), atol=1e-3)
    assert (sw.snr_db >= s.detection_threshold_db - 1e-4).all()
    car = (sw.kind == OBJECT) & (sw.object_id == 5)
    ped = (sw.kind == OBJECT) & (sw.object_id == 6)
    assert car.sum() >= 1 and ped.sum() >= 1
    world = sw.xyz.astype(np.float64) + pose[:3, 3]
    assert (box_distance(world[car], [30, 0, 0.75], [4.5, 1.8, 1.5], 0) < 1e-3).all()
    assert (box_distance(world[ped], [15, 3, 0.9], [0.5, 0.5, 1.8], 0) < 1e-3).all()
    assert 10 * math.log10((10 ** (sw.rcs_dbsm[car] / 10)).sum()) == pytest.approx(10.0, abs=0.01)
    u = sw.xyz_true / np.linalg.norm(sw.xyz_true, axis=1, keepdims=True)
    v_obj = np.where(car[:, None], [5.0, 0, 0], 0.0)
    expect = (v_obj - [10.0, 0, 0]) @ np.eye(3) * 1.0
    expect = np.einsum("ij,ij->i", u, expect)
    res = s.velocity_resolution_mps
    real = car | ped
    assert np.abs(sw.radial_velocity[real] - expect[real]).max() <= res / 2 + 1e-5
    assert np.abs(sw.radial_velocity_comp[real] - np.einsum("ij,ij->i", u, v_obj)[real]).max() <= res + 1e-5
    ghost = sw.kind == GHOST
    assert ghost.sum() == 1 and sw.source_id[ghost][0] == 5 and sw.object_id[ghost][0] == -1
    strongest = np.flatnonzero(car)[np.argmax(sw.snr_db[car])]
    mirrored = (sw.xyz_true[strongest] + pose[:3, 3]) * [1, 1, -1] - pose[:3, 3]
    np.testing.assert_allclose(sw.xyz_true[ghost][0], mirrored, atol=1e-4)
    assert sw.rcs_dbsm[ghost][0] == pytest.approx(sw.rcs_dbsm[strongest] - GHOST_LOSS_DB, abs=1e-4)


def test_noise_stays_within_the_accuracy_and_the_sweep_is_seeded():
    """The bundled ARS 408: measured ranges and azimuths within ± the accuracy of the true ones; the same
    generator gives the same sweep bit for bit, another one other noise."""
    s = ars408()
    a, _ = _scene(s, seed=1)
    b, _ = _scene(s, seed=1)
    c, _ = _scene(s, seed=2)
    for k in ("xyz", "radial_velocity", "rcs_dbsm", "kind", "object_id"):
        assert getattr(a, k).tobytes() == getattr(b, k).tobytes()
    assert a.xyz.tobytes() != c.xyz.tobytes()
    true_r = np.linalg.norm(a.xyz_true, axis=1)
    near = a.scan == 1
    acc = np.where(near, s.near_range["range_accuracy_m"], s.range_accuracy_m)
    real = a.kind != 3
    assert (np.abs(a.range_m - true_r)[real] <= acc[real] + 1e-4).all()


def test_the_cross_sensor_table_gains_the_radar_column():
    from fogsim.lidar.objects import cross_sensor_table, table_markdown

    records = [{"kept": True, "distance_m": 5.0, "lidar_points": {"clear": 50, "fog": 1},
                "radar_detections": {"clear": 2, "fog": 1}, "visibility": {"clear": {"visible": True},
                                                                          "fog": {"visible": False}}},
               {"kept": True, "distance_m": 30.0, "radar_detections": {"clear": 1, "fog": 0}}]
    rows = cross_sensor_table(records, ["clear", "fog"], (0, 10, 40))
    fog_near = next(r for r in rows if r["level"] == "fog" and r["bin"] == [0, 10])
    assert (fog_near["lidar_share"], fog_near["radar_share"], fog_near["camera_share"]) == (0.0, 1.0, 0.0)
    far = [r for r in rows if r["bin"] == [10, 40]]
    assert [r["radar_share"] for r in far] == [1.0, 0.0] and all(r["lidar_share"] is None for r in far)
    md = table_markdown(rows)
    assert "(LiDAR / radar / camera)" in md and "0 % / 100 % / 0 % (n=1)" in md
    lidar_only = [{k: v for k, v in records[0].items() if k != "radar_detections"}]
    assert "radar" not in table_markdown(cross_sensor_table(lidar_only, ["clear"], (0, 10)))


def test_the_preset_key_and_the_flag(tmp_path):
    """A preset's "radar" (a bundled name or a block) and --radar give the sensor; a bad name or block is
    refused naming the flag or the file, before anything is written."""
    from fogsim.errors import InputError
    from fogsim.render.frame import describe_frame
    from fogsim.render.preset import load_render_preset

    preset = tmp_path / "p.json"
    preset.write_text(json.dumps({"style": "urban-canyon", "camera": "waymo-front", "quality": "draft",
                                  "radar": "srr-corner"}))
    cfg = load_render_preset(str(preset))
    assert cfg.radar_sensor.name == "srr-corner" and cfg.to_dict()["radar"]["name"] == "srr-corner"
    cfg = load_render_preset(str(preset), radar="ars408-lr")
    desc = describe_frame(cfg, 0)
    pose = np.asarray(desc["radar"]["radar_to_world"])
    assert pose[2, 3] == pytest.approx(0.5)  # the ARS 408's mount height above the street
    with pytest.raises(ValueError, match="--radar"):
        load_render_preset("default", radar="nope")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"frequency_ghz": 77}))
    with pytest.raises(InputError, match="bad.json"):
        load_render_preset("default", radar=str(bad))


# ----------------------------------------------------------------------------- renders (real Blender)
RENDER = ["--lidar", "hdl64e", "--radar", "ars408-lr", "--frames", "2", "--resolution", "96x64", "--samples", "1",
          "--levels", "clear,0.06", "--seed", "3", "--quiet"]


@pytest.fixture(scope="module")
def radar_render(tmp_path_factory):
    from test_blender import _need_bpy, run

    _need_bpy()
    out = tmp_path_factory.mktemp("radar") / "out"
    res = run([sys.executable, "-m", "fogsim", "render", *RENDER, "--out", str(out)])
    assert res.returncode == 0, res.stderr[-3000:]
    return out


def spec_read_nuscenes_radar(path: Path) -> np.ndarray:
    """nuScenes' radar PCD read as its devkit documents it (RadarPointCloud.from_file): ASCII header lines up to
    DATA, the 18 FIELDS with their SIZE and TYPE, DATA binary, WIDTH × POINTS records, little-endian, packed."""
    raw = path.read_bytes()
    header, body = raw.split(b"DATA binary\n", 1)
    keys = {}
    for line in header.decode("ascii").splitlines():
        if line and not line.startswith("#"):
            k, *v = line.split()
            keys[k] = v
    assert keys["VERSION"] == ["0.7"] and keys["FIELDS"] == [
        "x", "y", "z", "dyn_prop", "id", "rcs", "vx", "vy", "vx_comp", "vy_comp", "is_quality_valid", "ambig_state",
        "x_rms", "y_rms", "invalid_state", "pdh0", "vx_rms", "vy_rms"]
    assert keys["SIZE"] == ["4", "4", "4", "1", "2", "4", "4", "4", "4", "4", "1", "1", "1", "1", "1", "1", "1", "1"]
    assert keys["TYPE"] == ["F", "F", "F", "I", "I", "F", "F", "F", "F", "F", "I", "I", "I", "I", "I", "I", "I", "I"]
    n = int(keys["POINTS"][0])
    assert int(keys["WIDTH"][0]) * int(keys["HEIGHT"][0]) == n
    fmt = "<" + "".join({("F", "4"): "f", ("I", "1"): "b", ("I", "2"): "h"}[t, s]
                        for t, s in zip(keys["TYPE"], keys["SIZE"]))
    size = struct.calcsize(fmt)
    assert size == 43 and len(body) >= n * size
    return np.array([struct.unpack_from(fmt, body, k * size) for k in range(n)], np.float64).reshape(n, 18)


@pytest.mark.blender
@pytest.mark.slow
def test_detections_lie_on_their_boxes_and_move_with_their_objects(radar_render):
    """Every detection labelled with an object is within 0.5 m of that object's 3D box; its radial velocity is
    the object's relative velocity (the render's motion record) on the true ray within half the sensor's
    velocity resolution; the level files read back by the nuScenes spec and by pypcd4 equal the labels."""
    from fogsim.dataset.radar import read_labels

    pypcd4 = pytest.importorskip("pypcd4")
    out = radar_render
    checked = moving = 0
    for f in ("000000", "000001"):
        meta = json.loads((out / "meta" / f"{f}.json").read_text())
        radar = meta["radar"]
        r2w = np.asarray(radar["radar_to_world"], np.float64)
        boxes = {o["id"]: o["box3d"]["world"] for o in radar["objects"] if "box3d" in o}
        motion = radar["motion"]
        res = radar["sensor_spec"]["velocity_resolution_mps"]
        for key, entry in radar["levels"].items():
            lab = read_labels(out / entry["labels"])
            spec = spec_read_nuscenes_radar(out / entry["file"])
            pc = pypcd4.PointCloud.from_path(out / entry["file"]).numpy()
            assert len(spec) == len(lab["kind"]) == len(pc) and len(spec) > 0
            np.testing.assert_allclose(pc[:, :3], spec[:, :3])
            xyz = spec[:, :3]
            np.testing.assert_allclose(np.linalg.norm(xyz, axis=1), lab["range_m"], atol=1e-3)
            on = (lab["kind"] == OBJECT) & np.isin(lab["object_id"], list(boxes))
            world = xyz @ r2w[:3, :3].T + r2w[:3, 3]
            for j in np.flatnonzero(on):
                b = boxes[int(lab["object_id"][j])]
                assert box_distance(world[j:j + 1], b["centre_m"], b["size_lwh_m"], b["yaw"])[0] <= 0.5
                checked += 1
            # velocities: nuScenes vx, vy along the ray; the true ray and the motion record give the truth
            true = np.stack([lab["x_true"], lab["y_true"], lab["z_true"]], 1).astype(np.float64)
            u = true / np.linalg.norm(true, axis=1, keepdims=True)
            u_world = u @ r2w[:3, :3].T
            v_obj = np.array([motion["object_velocity_mps"].get(str(int(i)), [0, 0, 0]) for i in lab["object_id"]])
            expect = np.einsum("ij,ij->i", u_world, v_obj - np.asarray(motion["camera_velocity_mps"]))
            real = lab["kind"] == OBJECT
            assert np.abs(lab["radial_velocity_mps"][real] - expect[real]).max() <= res / 2 + 1e-4
            az = np.arctan2(xyz[:, 1], xyz[:, 0])
            np.testing.assert_allclose(spec[:, 6] * np.cos(az) + spec[:, 7] * np.sin(az), lab["radial_velocity_mps"],
                                       atol=1e-4)
            moving += int((np.abs(v_obj[real]).sum(axis=1) > 0).sum())
    assert checked >= 5 and moving >= 1


@pytest.mark.blender
@pytest.mark.slow
def test_the_cross_sensor_table_has_three_columns(radar_render):
    out = radar_render
    manifest = json.loads((out / "dataset.json").read_text())
    rows = manifest["lidar"]["cross_sensor"]
    assert rows and all({"lidar_share", "radar_share", "camera_share"} <= set(r) for r in rows)
    assert any(r["radar_share"] is not None for r in rows)
    assert all(r["radar_seen"] <= r["radar_objects"] for r in rows)
    assert "(LiDAR / radar / camera)" in (out / "cross_sensor.md").read_text()
    assert (out / "radar_bev.png").is_file() and manifest["radar"]["bev_frame"] is not None
    clear = manifest["radar"]["levels"]["clear"]["outcomes"]
    assert clear["kept"] > 0 and clear.get("lost", 0) == 0


@pytest.mark.blender
@pytest.mark.slow
def test_scene_mode_sees_an_unoccluded_car_at_30_m(tmp_path):
    """A user's scene: the camera 1.6 m above a road looking along +y, a car whose rear is 30 m ahead of the
    radar (the camera + nuScenes' offset); the clear level has detections on it, inside its box."""
    from fogsim.dataset.radar import read_labels
    from fogsim.render.radar_frame import RADAR_CAMERA_OFFSET
    from test_scene_mode import _build, _render

    forward, _, up = RADAR_CAMERA_OFFSET
    spec = {"resolution": [96, 64], "frames": [1, 1],
            "camera": {"location": [0, 0, 1.6], "rotation_deg": [90, 0, 0], "lens": 35, "sensor_width": 36,
                       "sensor_height": 24, "sensor_fit": "AUTO", "shift_x": 0, "shift_y": 0},
            "boxes": [{"name": "Road", "size": [40, 120, 0.2], "location": [0, 50, -0.1], "color": [0.2, 0.2, 0.2]},
                      {"name": "Car", "size": [1.8, 4.5, 1.5], "location": [0, forward + 30 + 2.25, 0.75],
                       "class": "car", "color": [0.7, 0.1, 0.1]}]}
    blend = _build("bpy", tmp_path, spec)
    out = tmp_path / "out"
    res = _render("bpy", blend, out, "--radar", "ars408-lr", "--samples", "1", "--levels", "clear,0.06", "--quiet")
    assert res.returncode == 0, res.stderr[-3000:]
    meta = json.loads((out / "meta" / "000000.json").read_text())
    assert meta["radar"]["radar_to_world"][2][3] == pytest.approx(1.6 + up)
    car = next(o for o in meta["radar"]["objects"] if o["class"] == "car")
    assert car["radar_detections"]["clear"] >= 1
    lab = read_labels(out / meta["radar"]["levels"]["clear"]["labels"])
    on = (lab["kind"] == OBJECT) & (lab["object_id"] == car["id"])
    assert on.sum() >= 1 and np.min(lab["range_m"][on]) == pytest.approx(30.0, abs=0.5)
    box = Box3D(np.array(car["box3d"]["world"]["centre_m"]), np.eye(3), np.array([0.9, 2.25, 0.75]))
    assert np.allclose(box.centre, [0, forward + 32.25, 0.75], atol=1e-3)


@pytest.mark.blender
@pytest.mark.slow
def test_the_nuscenes_export_carries_the_radar_sweeps(radar_render, tmp_path, capsys):
    """``fogsim export nuscenes`` on a render with ``--radar ars408-lr``: each level's sweep lands in
    ``samples/RADAR_FRONT/<frame>.pcd`` (the ARS 408 faces forward) as the render wrote it, readable by the
    spec's reader; beside it the LiDAR's samples."""
    from fogsim.cli import main
    from fogsim.dataset.nuscenes import radar_channel

    assert [radar_channel(y) for y in (0, 60, -60, 135, -135, 180)] == [
        "RADAR_FRONT", "RADAR_FRONT_LEFT", "RADAR_FRONT_RIGHT", "RADAR_BACK_LEFT", "RADAR_BACK_RIGHT",
        "RADAR_BACK_RIGHT"]
    out, nusc = radar_render, tmp_path / "nusc"
    assert main(["export", "nuscenes", str(out), "--out", str(nusc), "--quiet"]) == 0
    summary = json.loads((nusc / "fogsim_nuscenes.json").read_text())
    assert summary["radar"]["samples_per_channel_and_level"] == {"RADAR_FRONT": {"clear": 2, "beta0.06": 2}}
    for f in ("000000", "000001"):
        meta = json.loads((out / "meta" / f"{f}.json").read_text())
        for level, entry in meta["radar"]["levels"].items():
            got = nusc / level / "samples" / "RADAR_FRONT" / f"{f}.pcd"
            assert got.read_bytes() == (out / entry["file"]).read_bytes()
            assert len(spec_read_nuscenes_radar(got)) == max(entry["detections_out"], 1)  # empty: one NaN row
            assert (nusc / level / "samples" / "LIDAR_TOP" / f"{f}.pcd.bin").is_file()
    capsys.readouterr()
    assert main(["export", "nuscenes", str(out), "--out", str(tmp_path / "said")]) == 0
    said = capsys.readouterr().out  # every channel written is named, with its samples per level
    assert said.startswith("exported LIDAR_TOP (clear 2, beta0.06 2) and RADAR_FRONT (clear 2, beta0.06 2) samples")
