"""The BEV study end to end with a real Ultralytics OBB training (``fogsim study --sensor lidar``): the
fogged-KITTI route on the KITTI-format street fixture (``fogsim fog --kitti ROOT --lidar``, then the study
as two shards, a report, a rerun that trains nothing), the LiDAR fog models against each other, the
paper-scale plan (``--dry-run``), and — with Blender — the lidar+radar study of a render.

Markers: ``detect`` (Ultralytics), the trainings ``slow``; the render also ``blender``."""
import json
import math

import numpy as np
import pytest

import kitti_tree as kt
from fogsim.cli import main

pytestmark = pytest.mark.detect
TINY = ["--epochs", "1", "--mixed-epochs", "1", "--imgsz", "64", "--batch", "4", "--workers", "0", "--no-plots",
        "--quiet"]


@pytest.fixture(scope="module")
def street_fog(tmp_path_factory):
    """The docs' street fixture (six ray-cast HDL-64E frames, four cars each) fogged at the paper's levels."""
    pytest.importorskip("ultralytics")
    base = tmp_path_factory.mktemp("bev_street")
    root = kt.write_kitti_street(base / "kitti", kt.STREET)
    out = base / "fog"
    assert main(["fog", "--quiet", "--kitti", str(root), "--lidar", "--levels", "paper", "--out", str(out)]) == 0
    return out


def cells(report_json):
    return [c for row in report_json.values() for c in row.values()]


def ultralytics_round_trip(grid, boxes, tmp_path, hyp: dict | None = None):
    """The labels of ``boxes`` ((class, footprint) pairs) through Ultralytics: its OBB dataset reads a raster's
    label file (``hyp``: its augmentation, else none) into normalised (x, y, w, h, θ) boxes, which become an
    ``Results.obb`` as its predictor makes them, read by fogsim's own :func:`obb_records` and put back into
    metres by the grid. Returns the boxes that came back (class ids, corners in metres)."""
    import cv2
    import torch

    from fogsim.detection.bev.boxes import obb_line
    from fogsim.detection.yolo import load_ultralytics, obb_records

    load_ultralytics(tmp_path / "cfg")
    from ultralytics.cfg import get_cfg
    from ultralytics.data.dataset import YOLODataset
    from ultralytics.engine.results import Results

    (tmp_path / "images").mkdir(parents=True)
    (tmp_path / "labels").mkdir()
    cv2.imwrite(str(tmp_path / "images" / "f0.png"), np.zeros((grid.height, grid.width, 3), np.uint8))
    (tmp_path / "labels" / "f0.txt").write_text("".join(obb_line(c, corners, grid) + "\n" for c, corners in boxes))
    size = max(grid.width, grid.height)
    ds = YOLODataset(img_path=str(tmp_path / "images"), imgsz=size, augment=hyp is not None, task="obb",
                     hyp=get_cfg(overrides={"mosaic": 0.0, **(hyp or {})}), data={"names": {0: "car", 1: "pedestrian",
                                                                                  2: "cyclist"}, "channels": 3})
    item = ds[0]
    assert tuple(item["img"].shape[1:]) == (grid.height, grid.width)  # no letterbox: the raster is the input
    xywhr = item["bboxes"].clone()
    xywhr[:, [0, 2]] *= grid.width
    xywhr[:, [1, 3]] *= grid.height
    table = torch.cat([xywhr, torch.ones(len(xywhr), 1), item["cls"].reshape(-1, 1).float()], 1)
    res = Results(np.zeros((grid.height, grid.width, 3), np.uint8), "f0.png", ds.data["names"], obb=table)
    recs = obb_records("f0", res.obb)
    return [r["category_id"] for r in recs], [grid.to_metres(np.array(r["corners_px"])) for r in recs]


def test_labels_through_ultralytics_come_back_as_the_boxes(tmp_path):
    """GT footprints → fogsim's OBB label lines → Ultralytics' loader (minimum-area rectangles, its angle range
    [−π/4, 3π/4), the longer side as w) → a ``Results.obb`` → fogsim's prediction records → metres: each box
    comes back with exact IoU > 0.999 and, scored as predictions, AP 1 at KITTI's 0.7 / 0.5. With Ultralytics'
    left–right flip on, every box comes back mirrored (y → −y: the grid is symmetric about the car's axis)."""
    from fogsim.detection.bev.boxes import rotated_iou, yaw_box
    from fogsim.detection.bev.evaluate import evaluate_level
    from fogsim.detection.bev.grid import BevGrid
    from test_bev import ROUND_TRIP

    pytest.importorskip("ultralytics")
    grid = BevGrid.for_image(320)
    boxes = [(c, yaw_box(x, y, ln, w, yaw)) for c, x, y, ln, w, yaw in ROUND_TRIP]
    cls, back = ultralytics_round_trip(grid, boxes, tmp_path / "plain")
    assert sorted(cls) == sorted(c for c, _ in boxes)
    for c, gt in boxes:  # Ultralytics keeps the label file's order
        best = max(rotated_iou(b, gt) for k, b in zip(cls, back) if k == c)
        assert best > 0.999
    names = ("car", "pedestrian", "cyclist")
    truth = [{"id": "f0", "frame": "f0", "split": "val", "dontcare": [], "ground_z": -1.7, "image_size": [1, 1],
              "projection": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]],
              "objects": [{"class": names[c], "scored": True, "difficulty": 1, "kitti_type": names[c],
                           "corners_m": gt.tolist(), "distance_m": 10.0, "points": {"L": 50}} for c, gt in boxes]}]
    dets = [{"image_id": "f0", "category_id": k, "score": 0.9, "corners_m": b.tolist()} for k, b in zip(cls, back)]
    cell = evaluate_level(truth, dets, "L")
    assert cell["ap"] == pytest.approx(1.0) and cell["recall_max"] == 1.0
    _, flipped = ultralytics_round_trip(grid, boxes, tmp_path / "flip",
                                        {"fliplr": 1.0, "scale": 0.0, "translate": 0.0, "degrees": 0.0})
    for _, gt in boxes:
        assert max(rotated_iou(b, gt * [1, -1]) for b in flipped) > 0.999


def test_the_study_s_augmentation_keeps_a_cell_a_cell(tmp_path):
    """Through Ultralytics' training augmentation with the BEV study's overrides (translation and flips on),
    every box that stays clear of the image's edges keeps its size in pixels — so in metres: the cell is a
    fixed length and a car is as long in every raster. Ultralytics' default zoom (scale 0.5) would not."""
    import random

    from fogsim.detection.bev.boxes import yaw_box
    from fogsim.detection.bev.grid import BevGrid
    from fogsim.detection.bev.study import AUGMENT
    from test_bev import ROUND_TRIP

    pytest.importorskip("ultralytics")
    grid = BevGrid.for_image(320)
    boxes = [(c, yaw_box(x, y, ln, w, yaw)) for c, x, y, ln, w, yaw in ROUND_TRIP]

    def sides(corners):
        return sorted(np.linalg.norm(np.roll(corners, -1, 0)[:2] - corners[:2], axis=1))

    want = sorted(sides(b) for _, b in boxes)
    for seed, hyp in enumerate(({**AUGMENT, "translate": 0.1, "fliplr": 0.5}, {"scale": 0.5})):
        kept = []
        for k in range(4):
            random.seed(10 * seed + k)
            np.random.seed(10 * seed + k)
            _, back = ultralytics_round_trip(grid, boxes, tmp_path / f"aug{seed}_{k}", hyp)
            uv = [grid.to_pixels(b) for b in back]
            kept += [sides(b) for b, p in zip(back, uv) if p.min() > 1 and p[:, 0].max() < grid.width - 1
                     and p[:, 1].max() < grid.height - 1]
        assert len(kept) >= 20
        same = all(min(np.abs(np.subtract(s, w)).max() for w in want) < 0.02 for s in kept)  # 2 cm
        assert same == (seed == 0)


@pytest.mark.slow
def test_the_fogged_kitti_route_end_to_end(street_fog, tmp_path, capsys):
    out = tmp_path / "study"
    common = ["study", "--sensor", "lidar", "--dataset", str(street_fog), "--out", str(out),
              "--fog-models", "hahner2021,stf2020", *TINY]
    assert main([*common, "--prepare-only"]) == 0
    for shard in ("0/2", "1/2"):
        assert main([*common, "--shard", shard, "--no-report"]) == 0
    assert main(["study", "--sensor", "lidar", "--dataset", str(street_fog), "--out", str(out), "--quiet",
                 "--fog-models", "hahner2021,stf2020", "--report-only"]) == 0  # the rest from study.json
    report = out / "bev" / "report"
    table = json.loads((report / "cross_density_lidar.json").read_text())
    levels = ["clear", "beta0.03", "beta0.06", "beta0.09", "beta0.12"]
    assert list(table) == [*levels, "mixed", "oracle"] and all(list(row) == levels for row in table.values())
    for c in cells(table):
        assert 0 <= c["ap"] <= 1 and 0 <= c["recall"] <= 1 and 0 <= c["recall_max"] <= 1
        assert c["difficulty"] == "moderate"  # auto on real data: KITTI's headline
        assert all(v is None or 0 <= v <= 1 for v in c["recall_by_distance"].values())
    assert table["oracle"]["beta0.06"] == table["beta0.06"]["beta0.06"]
    fog = json.loads((report / "fog_models.json").read_text())
    assert set(fog) == {"hahner2021", "stf2020"} and all(set(v) == set(fog) for v in fog.values())
    md = (report / "report.md").read_text()
    for text in ("## lidar", "**BEV AP**", "## The sensors side by side", "## LiDAR fog models against each other",
                 "KITTI difficulty **moderate**", "| lidar@stf2020 | mixed |",
                 "| variant | model | epochs | training s | this run s | state |"):
        assert text in md, text
    for png in ("bev_contact_sheet.png", "recall_by_distance.png", "lidar_ap_heatmap.png", "lidar_recall_heatmap.png"):
        assert (report / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the DontCare-free street: every labelled car of the grid is ground truth, in the field of view
    truth = json.loads(next((out / "bev" / "lidar" / "data" / "gt").glob("*.json")).read_text())
    assert truth["objects"] and all(o["class"] == "car" for o in truth["objects"])
    # a rerun trains nothing and gives the same tables
    done = {p: p.read_bytes() for p in (out / "bev").rglob("fogsim_done.json")}
    assert len(done) == 6 + 2
    assert all(json.loads(b)["seconds_training"] > 0 for b in done.values())  # from each run's results.csv
    capsys.readouterr()
    assert main(common) == 0
    assert {p: p.read_bytes() for p in (out / "bev").rglob("fogsim_done.json")} == done
    assert json.loads((report / "cross_density_lidar.json").read_text()) == table


def test_the_paper_scale_plan_is_checked_without_training(street_fog, tmp_path, capsys):
    """docs/study.md's GPU commands, dry-run: the OBB model builds, the shard's models are listed."""
    out = tmp_path / "study"
    argv = ["study", "--sensor", "lidar", "--dataset", str(street_fog), "--out", str(out),
            "--model", "yolo11m-obb.yaml", "--imgsz", "640", "--epochs", "100", "--batch", "16", "--nbs", "64",
            "--device", "0", "--shard", "1/3", "--dry-run"]
    capsys.readouterr()
    assert main(argv) == 0
    plan = capsys.readouterr().out
    assert "yolo11m-obb.yaml (OBB, builds), imgsz 640" in plan
    assert "models: 6 in all; shard 1/3 trains 2:" in plan
    assert "lidar/beta0.03: 100 epochs × 5 rasters" in plan and "lidar/beta0.12: 100 epochs" in plan
    assert "lidar/mixed" not in plan  # models 1 and 4 of clear, …, beta0.12, mixed
    assert not (out / "bev" / "lidar" / "runs").exists() and not (out / "bev" / "study.json").exists()
    capsys.readouterr()
    argv[argv.index("yolo11m-obb.yaml")] = "yolov8n.yaml"
    assert main(argv) == 2  # a model of boxes without an angle: refused before anything
    assert "needs an oriented-box model" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.blender
def test_lidar_radar_study_of_a_render(tmp_path):
    """The issue's command at a smaller size: a render with LiDAR and radar, both variants trained."""
    pytest.importorskip("bpy")
    out = tmp_path / "S"
    assert main(["study", "--sensor", "lidar+radar", "--render", "3", "--resolution", "96x64", "--samples", "1",
                 "--out", str(out), *TINY]) == 0
    report = out / "bev" / "report"
    for name in ("lidar", "lidar_radar"):
        table = json.loads((report / f"cross_density_{name}.json").read_text())
        assert {"mixed", "oracle"} <= set(table)
        assert all(0 <= c["ap"] <= 1 or math.isnan(c["ap"]) for c in cells(table))
    raster = out / "bev" / "lidar_radar" / "data" / "images" / "clear"
    assert all(p.suffix == ".tiff" for p in raster.iterdir())
    rows = json.loads((report / "sensors.json").read_text())
    assert "lidar+radar, mixed: BEV AP" in rows and "lidar, own level's model: BEV AP" in rows
    assert np.isfinite([v for v in rows["lidar, mixed: recall"].values()]).all()
