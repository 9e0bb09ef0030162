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


@pytest.mark.slow
def test_the_fogged_kitti_route_end_to_end(street_fog, tmp_path, capsys):
    out = tmp_path / "study"
    common = ["study", "--sensor", "lidar", "--dataset", str(street_fog), "--out", str(out),
              "--fog-models", "soft-target,attenuation", *TINY]
    assert main([*common, "--prepare-only"]) == 0
    for shard in ("0/2", "1/2"):
        assert main([*common, "--shard", shard, "--no-report"]) == 0
    assert main(["study", "--sensor", "lidar", "--dataset", str(street_fog), "--out", str(out), "--quiet",
                 "--fog-models", "soft-target,attenuation", "--report-only"]) == 0  # the rest from study.json
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
    assert set(fog) == {"soft-target", "attenuation"} and all(set(v) == set(fog) for v in fog.values())
    md = (report / "report.md").read_text()
    for text in ("## lidar", "**BEV AP**", "## The sensors side by side", "## LiDAR fog models against each other",
                 "KITTI difficulty **moderate**", "| lidar@attenuation | mixed |"):
        assert text in md, text
    for png in ("bev_contact_sheet.png", "recall_by_distance.png", "lidar_ap_heatmap.png", "lidar_recall_heatmap.png"):
        assert (report / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the DontCare-free street: every labelled car of the grid is ground truth, in the field of view
    truth = json.loads(next((out / "bev" / "lidar" / "data" / "gt").glob("*.json")).read_text())
    assert truth["objects"] and all(o["class"] == "car" for o in truth["objects"])
    # a rerun trains nothing and gives the same tables
    done = {p: p.read_bytes() for p in (out / "bev").rglob("fogsim_done.json")}
    assert len(done) == 6 + 2
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
