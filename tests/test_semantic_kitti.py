"""A render's LiDAR levels as SemanticKITTI sequences (fogsim.dataset.semantic_kitti, issue 40 item 2), read
with SemanticKITTI's own label logic reimplemented here from its documented format (semantic-kitti-api's
README and config/semantic-kitti.yaml): ``sequences/NN/velodyne/*.bin`` 4 × float32 per point,
``labels/*.label`` one uint32 per point — lower 16 bits the semantic id, upper 16 the instance —, files
paired by their sorted order, ``learning_map`` applied through a lookup table built from the yaml.

The pure tests ray-cast a street of boxes (no Blender); :func:`read_sequence` is also what the render test
(tests/test_render_lidar.py) reads a real render's tree with.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.semantic_kitti import (
    FOG_ID,
    FOGSIM_TO_SEMANTIC_KITTI,
    LABELS,
    SemanticKittiTree,
    label_yaml,
    write_sequences,
)
from fogsim.lidar.fog import CLUTTER, LidarFogger

sys.path.insert(0, str(Path(__file__).resolve().parent))

#: SemanticKITTI's ids for the classes fogsim renders, as its yaml names them (the test's own table)
EXPECTED_NAME = {"car": "car", "van": "car", "truck": "truck", "bus": "bus", "pedestrian": "person",
                 "cyclist": "bicyclist", "traffic_sign": "traffic-sign", "road": "road", "sidewalk": "sidewalk",
                 "building": "building", "pole": "pole", "tree": "vegetation", "lane_marking": "lane-marking"}
#: SemanticKITTI's 19 training classes, in its learning_map_inv order (0 = unlabeled, ignored)
TRAINING = ("unlabeled", "car", "bicycle", "motorcycle", "truck", "other-vehicle", "person", "bicyclist",
            "motorcyclist", "road", "parking", "sidewalk", "other-ground", "building", "fence", "vegetation",
            "trunk", "terrain", "pole", "traffic-sign")


def read_config(path: Path) -> dict:
    yaml = pytest.importorskip("yaml")
    return yaml.safe_load(path.read_text())


def read_sequence(root: Path, sequence: str = "00", config: Path | None = None) -> list[dict]:
    """SemanticKITTI's reading of ``root/sequences/<sequence>``: per frame (sorted) the points (N×4), the
    semantic ids, the instance ids and the training ids through the yaml's learning_map; plus the calib
    (``key: 12 numbers`` → 4×4) and the poses (one 3×4 line per frame)."""
    seq = root / "sequences" / sequence
    scans = sorted((seq / "velodyne").glob("*.bin"))
    labels = sorted((seq / "labels").glob("*.label"))
    assert [p.stem for p in scans] == [p.stem for p in labels] and scans
    cfg = read_config(config or root / "semantic-kitti.yaml")
    lut = np.zeros(max(cfg["learning_map"]) + 100, np.int32)
    lut[list(cfg["learning_map"])] = list(cfg["learning_map"].values())
    calib = {}
    for line in (seq / "calib.txt").read_text().splitlines():
        key, values = line.split(":", 1)
        m = np.eye(4)
        m[:3, :4] = np.array(values.split(), np.float64).reshape(3, 4)
        calib[key] = m
    poses = [np.vstack([np.array(line.split(), np.float64).reshape(3, 4), [0, 0, 0, 1]])
             for line in (seq / "poses.txt").read_text().splitlines()]
    assert len(poses) == len(scans)
    frames = []
    for scan, label, pose in zip(scans, labels, poses):
        points = np.fromfile(scan, np.float32).reshape(-1, 4)
        raw = np.fromfile(label, np.uint32)
        assert raw.shape == (len(points),)
        sem, inst = raw & 0xFFFF, raw >> 16
        assert ((inst << 16) + sem == raw).all()
        frames.append({"frame": scan.stem, "points": points, "semantic": sem, "instance": inst,
                       "training": lut[sem], "pose": pose})
    return frames, calib, cfg


def test_the_yaml_is_semantic_kittis_plus_fog():
    """The yaml's ids and names are SemanticKITTI's (fog 110 added), every id has a colour and a training
    class, learning_map_inv inverts learning_map on the training classes, fogsim's classes land on the ids
    SemanticKITTI gives them."""
    yaml = pytest.importorskip("yaml")
    cfg = yaml.safe_load(label_yaml())
    assert {k: cfg["labels"][k] for k in (0, 1, 10, 11, 13, 15, 18, 20, 30, 31, 40, 44, 48, 50, 51, 70, 71, 72, 80,
                                          81)} == {
        0: "unlabeled", 1: "outlier", 10: "car", 11: "bicycle", 13: "bus", 15: "motorcycle", 18: "truck",
        20: "other-vehicle", 30: "person", 31: "bicyclist", 40: "road", 44: "parking", 48: "sidewalk",
        50: "building", 51: "fence", 70: "vegetation", 71: "trunk", 72: "terrain", 80: "pole", 81: "traffic-sign"}
    assert cfg["labels"][FOG_ID] == "fog"
    assert set(cfg["labels"]) == set(cfg["color_map"]) == set(cfg["learning_map"])
    assert all(len(c) == 3 and all(0 <= v <= 255 for v in c) for c in cfg["color_map"].values())
    inv = cfg["learning_map_inv"]
    assert [cfg["labels"][inv[k]] for k in range(len(TRAINING))] == ["unlabeled", *TRAINING[1:]]
    assert cfg["labels"][inv[20]] == "fog" and cfg["learning_map"][FOG_ID] == 20
    assert all(cfg["learning_map"][inv[k]] == k for k in inv)
    assert cfg["learning_map"][13] == 5 and cfg["learning_map"][60] == 9 and cfg["learning_map"][252] == 1
    assert cfg["learning_ignore"][0] is True and not any(v for k, v in cfg["learning_ignore"].items() if k)
    for cls, name in EXPECTED_NAME.items():
        assert cfg["labels"][FOGSIM_TO_SEMANTIC_KITTI[cls]] == name, cls
    assert set(LABELS) == set(cfg["labels"])


def test_a_swept_street_reads_back_through_semantic_kittis_logic(tmp_path):
    """A car (mask id 5) in front of a building (id 2) on a road (id 3): the render's label rule
    (:func:`fogsim.render.lidar_frame.semantic_labels`) written as a sequence reads back with the car's
    points as SemanticKITTI car / instance 5 inside its box, the building and road without instance, and
    the fog's clutter as 110 (training class 20) exactly where the fog model says clutter."""
    pytest.importorskip("embreex", reason="the LiDAR ray caster needs embreex (the 'blender' extra)")
    from fogsim.render.lidar_frame import semantic_labels
    from fogsim.render.lidar_scan import Geometry, RayCaster, sweep
    from test_render_lidar import box_mesh, sensor

    car = box_mesh([12.0, 0.0, -0.7], [4.0, 1.8, 1.5])
    wall = box_mesh([22.5, 0.0, 5.0], [1.0, 60.0, 20.0])
    road = box_mesh([20.0, 0.0, -1.55], [80.0, 40.0, 0.1])
    geo = Geometry.from_parts([(*car[:2], 5, 0.5), (*wall[:2], 2, 0.8), (*road[:2], 3, 0.1)])
    s = sensor(vertical_fov_deg=[-20, 10], beams=24)
    scan = sweep(RayCaster(geo), np.eye(4), s, "street")
    classes = {5: "car", 2: "building", 3: "road"}
    levels = {"clear": 0.0, "beta0.06": 0.06}
    fogged = {k: LidarFogger(scan.cloud, s)(b, np.random.default_rng(0)) for k, b in levels.items()}
    metas = []
    for k, f in fogged.items():
        SemanticKittiTree(tmp_path, k).write_frame("000000", f.cloud, semantic_labels(scan, f, classes))
    w2c = np.array([[0, -1, 0, 0], [0, 0, -1, 0], [1, 0, 0, 0], [0, 0, 0, 1]], np.float64)  # camera at the LiDAR
    metas.append({"camera": {"world_to_camera": w2c.tolist()},
                  "lidar": {"lidar_to_camera": w2c.tolist(),
                            "semantic_kitti": {"levels": list(levels), "P": [[100, 0, 50, 0], [0, 100, 40, 0],
                                                                              [0, 0, 1, 0]]}}})
    summary = write_sequences(DatasetLayout(tmp_path), ["000000"], metas)
    assert summary["levels"] == ["beta0.06", "clear"] and summary["fog_id"] == FOG_ID
    clutter = 0
    for k, f in fogged.items():
        frames, calib, cfg = read_sequence(tmp_path / "semantic_kitti" / k)
        (fr,) = frames
        np.testing.assert_array_equal(fr["points"][:, :3], f.cloud.xyz)
        np.testing.assert_allclose(calib["Tr"], w2c) and np.testing.assert_allclose(fr["pose"], np.eye(4))
        assert calib["P2"][0, 0] == 100
        # the truth: what each reported point hit, and what fog did to it
        rows = np.flatnonzero(f.output_index >= 0)
        hit = np.zeros(len(f.cloud), np.int64)
        hit[f.output_index[rows]] = scan.object_id[rows]
        is_clutter = np.zeros(len(f.cloud), bool)
        is_clutter[f.output_index[rows]] = f.outcome[rows] == CLUTTER
        clutter += int(is_clutter.sum())
        names = np.array([cfg["labels"][int(v)] for v in fr["semantic"]])
        assert (names[is_clutter] == "fog").all() and (fr["training"][is_clutter] == 20).all()
        assert (fr["instance"][is_clutter] == 0).all()
        solid = ~is_clutter
        for oid, want, instance in ((5, "car", 5), (2, "building", 0), (3, "road", 0)):
            mine = solid & (hit == oid)
            assert mine.sum() > 20 or (levels[k] > 0 and oid != 5), (k, oid)  # fog may hide all of a wall
            assert (names[mine] == want).all() and (fr["instance"][mine] == instance).all()
        assert (fr["training"][solid & (hit == 5)] == TRAINING.index("car")).all()
        assert (fr["training"][solid & (hit == 3)] == TRAINING.index("road")).all()
        # geometry: every car-labelled point lies in the car's box (clear: no range noise)
        if levels[k] == 0:
            p = fr["points"][fr["instance"] == 5, :3]
            assert len(p) and (np.abs(p - [12.0, 0.0, -0.7]) <= np.array([2.0, 0.9, 0.75]) + 1e-3).all()
    assert clutter > 0  # β = 0.06 puts fog echoes in the scan
    # a frame that failed after its scans (no record): named, since it shifts the API's pose pairing
    SemanticKittiTree(tmp_path, "clear").write_frame("000001", fogged["clear"].cloud,
                                                     np.zeros(len(fogged["clear"].cloud), np.uint32))
    again = write_sequences(DatasetLayout(tmp_path), ["000000"], metas)
    assert again["uncommitted_scans"] == {"clear": ["000001"]} and "uncommitted_scans" not in summary
