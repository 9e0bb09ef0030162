"""``visible_only``: invisible objects become ignore regions; the study report shows recall both ways."""
import json

import numpy as np
import pytest

pytestmark = pytest.mark.detect
pytest.importorskip("pycocotools")

from fogsim.detection.coco_eval import evaluate, mark_invisible_ignored  # noqa: E402
from fogsim.detection.table import cross_density, markdown, write_report  # noqa: E402

# one image, three cars: A visible (10 m), B invisible (30 m), C without the field (20 m: visible)
GT = {"images": [{"id": 1, "file_name": "images/beta0.12/000001.png", "width": 200, "height": 100}],
      "annotations": [
          {"id": 1, "image_id": 1, "category_id": 1, "bbox": [10.0, 10.0, 30.0, 20.0], "area": 600.0, "iscrowd": 0,
           "distance_m": 10.0, "visible": True, "contrast": 0.4, "transmission": 0.3},
          {"id": 2, "image_id": 1, "category_id": 1, "bbox": [80.0, 10.0, 30.0, 20.0], "area": 600.0, "iscrowd": 0,
           "distance_m": 30.0, "visible": False, "contrast": 0.01, "transmission": 0.03},
          {"id": 3, "image_id": 1, "category_id": 1, "bbox": [150.0, 50.0, 30.0, 20.0], "area": 600.0,
           "iscrowd": 0, "distance_m": 20.0}],
      "categories": [{"id": 1, "name": "car"}]}


def det(box, score):
    return {"image_id": 1, "category_id": 1, "bbox": list(map(float, box)), "score": score}


def test_mark_invisible_ignored_turns_only_visible_false_into_crowd():
    gt = dict(GT, annotations=GT["annotations"] + [dict(GT["annotations"][0], id=4, visible=None)])
    out = mark_invisible_ignored(gt)
    assert [a["iscrowd"] for a in out["annotations"]] == [0, 1, 0, 0]
    assert [a["iscrowd"] for a in gt["annotations"]] == [0, 0, 0, 0]  # a copy


def test_recall_by_hand_both_ways():
    only_a = [det((10, 10, 30, 20), 0.9)]
    every, visible = evaluate(GT, only_a), evaluate(GT, only_a, visible_only=True)
    assert every["objects"] == 3 and every["recall_max"] == pytest.approx(1 / 3)
    assert every["ultralytics_R"] == pytest.approx(1 / 3) and every["ignored_invisible"] == 0
    assert visible["objects"] == 2 and visible["recall_max"] == pytest.approx(1 / 2)  # A of {A, C}
    assert visible["ultralytics_R"] == pytest.approx(1 / 2)
    assert visible["ignored"] == 1 and visible["ignored_invisible"] == 1 and visible["visible_only"] is True
    # a detection on the invisible car is a hit when it counts, and neither hit nor false alarm when ignored
    a_and_b = only_a + [det((80, 10, 30, 20), 0.8)]
    assert evaluate(GT, a_and_b)["recall_max"] == pytest.approx(2 / 3)
    v = evaluate(GT, a_and_b, visible_only=True)
    assert v["recall_max"] == pytest.approx(1 / 2) and v["ultralytics_P"] == pytest.approx(1.0)
    assert v["ap50"] == pytest.approx(evaluate(GT, only_a, visible_only=True)["ap50"])


def test_report_has_both_recall_columns(tmp_path):
    only_a = [det((10, 10, 30, 20), 0.9)]
    table = cross_density({"beta0.12": GT}, {"m": {"beta0.12": only_a}})
    cell = table["m"]["beta0.12"]
    assert cell["recall_all"] == pytest.approx(1 / 3) and cell["recall_visible"] == pytest.approx(1 / 2)
    assert cell["objects"] == 3 and cell["objects_visible"] == 2 and cell["visible_only"] is False
    headline = cross_density({"beta0.12": GT}, {"m": {"beta0.12": only_a}}, visible_only=True)["m"]["beta0.12"]
    assert (headline["recall_all"], headline["recall_visible"]) == (cell["recall_all"], cell["recall_visible"])
    assert headline["objects"] == 2 and headline["ultralytics_R"] == pytest.approx(1 / 2)
    md = markdown(table)
    assert "**recall** (every object" in md and "**recall_visible** (visible objects only" in md
    assert "| m | **0.333** |" in md and "| m | **0.500** |" in md
    write_report(table, tmp_path)
    stored = json.loads((tmp_path / "cross_density.json").read_text())["m"]["beta0.12"]
    assert stored["recall_visible"] == pytest.approx(0.5)
    assert (tmp_path / "cross_density.csv").read_text().splitlines()[0] == "model,level,recall,recall_visible,map50"
    assert (tmp_path / "recall_visible_heatmap.png").stat().st_size > 0


def test_study_report_recall_both_ways_on_a_dataset_with_visibility(tmp_path):
    """A synthetic dataset whose metas get per-object visibility from its own images (box-based),
    finalized again: COCO carries ``visible``; a detector that finds only the visible objects has
    recall_visible = 1 and recall < 1 at the thick levels; report.md and the PNG show both."""
    from fogsim.dataset.layout import DatasetLayout
    from fogsim.dataset.reader import read_meta
    from fogsim.dataset.writer import finalize
    from fogsim.detection.study import Study
    from fogsim.detection.yolo import MIXED_MODEL, TrainConfig
    from fogsim.fog.levels import parse_levels
    from fogsim.fog.visibility import attach_visibility
    from fogsim.io.documents import write_json
    from fogsim.io.images import read_image
    from synthetic_dataset import make_dataset

    root = make_dataset(tmp_path / "ds", frames=6, train_fraction=0.5)
    layout, levels = DatasetLayout(root), parse_levels("paper")
    for frame in layout.done_frames():
        meta = read_meta(layout, frame)
        images = {lv.key: read_image(layout.image(lv.key, frame)) for lv in levels}
        attach_visibility(meta["objects"], images["clear"], images, {lv.key: lv.beta for lv in levels})
        write_json(layout.meta(frame), meta)
    finalize(layout, levels, {"preset": "synthetic (tests)"}, 0.5)
    study = Study(root, tmp_path / "study", TrainConfig())
    gts = study.ground_truth()
    study.check_parameters(gts)
    thick = gts["beta0.12"]["annotations"]
    assert all("visible" in a and "contrast" in a and "transmission" in a for a in thick)
    near = [a for a in thick if a["distance_m"] <= 100]
    assert any(a["visible"] is False for a in near) and any(a["visible"] for a in near)
    for m in [*study.levels, MIXED_MODEL]:
        for lv in study.levels:
            seen = [{"image_id": a["image_id"], "category_id": a["category_id"], "bbox": a["bbox"], "score": 0.9}
                    for a in gts[lv]["annotations"] if a.get("visible") is not False]
            path = study.prediction(m, lv)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(seen))
    table = study.report(max_distance_m=100.0)
    cell = table["oracle"]["beta0.12"]
    n_vis = sum(a["visible"] is not False for a in near)
    assert cell["recall_visible"] == pytest.approx(1.0) and cell["objects_visible"] == n_vis
    assert cell["recall_all"] == pytest.approx(n_vis / len(near)) and n_vis < len(near)
    assert table["oracle"]["clear"]["recall_all"] == table["oracle"]["clear"]["recall_visible"] == pytest.approx(1.0)
    report = (tmp_path / "study" / "report" / "report.md").read_text()
    assert "**recall_visible**" in report and "**recall** (every object" in report
    assert (tmp_path / "study" / "report" / "recall_visible_heatmap.png").stat().st_size > 0
    assert np.isfinite(cell["ap50"])
