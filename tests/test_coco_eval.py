"""Detection evaluator: hand-built cases, and agreement with pycocotools."""
import numpy as np
import pytest

pytestmark = pytest.mark.detect
pytest.importorskip("pycocotools")

from fogsim.detection.coco_eval import evaluate, mark_far_ignored, match, yolo_predictions  # noqa: E402


def gt_dict(boxes, distances, cats=None, size=(200, 100)):
    """One image per list entry of boxes (xywh)."""
    images, anns, k = [], [], 1
    for i, (bs, ds) in enumerate(zip(boxes, distances), start=1):
        images.append({"id": i, "file_name": f"images/clear/{i:06d}.png", "width": size[0], "height": size[1]})
        for j, (b, d) in enumerate(zip(bs, ds)):
            anns.append({"id": k, "image_id": i, "category_id": (cats[i - 1][j] if cats else 1),
                         "bbox": list(map(float, b)), "area": float(b[2] * b[3]), "iscrowd": 0, "distance_m": d})
            k += 1
    return {"images": images, "annotations": anns, "categories": [{"id": c, "name": f"c{c}"} for c in (1, 2, 3)]}


def det(image_id, box, score, cat=1):
    return {"image_id": image_id, "category_id": cat, "bbox": list(map(float, box)), "score": score}


GT = gt_dict([[(10, 10, 30, 20), (100, 40, 20, 40)], [(50, 30, 40, 30)]], [[12.0, 40.0], [80.0]])


def test_perfect_predictions_score_one():
    dets = [det(a["image_id"], a["bbox"], 0.9) for a in GT["annotations"]]
    r = evaluate(GT, dets)
    assert r["ap50"] == pytest.approx(1.0) and r["ap50_matcher"] == pytest.approx(1.0)
    assert r["recall_max"] == 1.0 and r["recall_at_conf"] == 1.0 and r["ultralytics_R"] == pytest.approx(1.0)
    assert r["recall_by_distance"] == {"0-25 m": 1.0, "25-50 m": 1.0, "50-100 m": 1.0}


def test_detection_on_an_ignored_far_object_changes_nothing():
    far = gt_dict([[(10, 10, 30, 20), (150, 10, 30, 30)]], [[20.0, 150.0]])
    base = [det(1, (10, 10, 30, 20), 0.9)]
    with_far = base + [det(1, (150, 10, 30, 30), 0.95)]
    a, b = evaluate(far, base), evaluate(far, with_far)
    for key in ("ap50", "ap50_matcher", "recall_max", "ultralytics_P", "ultralytics_R"):
        assert a[key] == pytest.approx(b[key]), key
    assert a["ignored"] == 1 and a["objects"] == 1 and a["ultralytics_P"] == pytest.approx(1.0)
    # dropping the far object instead would have made that detection a false positive
    dropped = dict(far, annotations=[x for x in far["annotations"] if x["distance_m"] < 100])
    assert evaluate(dropped, with_far)["ultralytics_P"] < 1.0


def test_a_filtered_object_from_the_dataset_stays_ignored_at_any_distance():
    """The renderer writes objects its filters dropped (too small, too occluded) as iscrowd = 1."""
    gt = gt_dict([[(10, 10, 30, 20), (150, 10, 4, 4)]], [[20.0, 15.0]])
    gt["annotations"][1]["iscrowd"] = 1
    base = [det(1, (10, 10, 30, 20), 0.9)]
    a, b = evaluate(gt, base), evaluate(gt, base + [det(1, (150, 10, 4, 4), 0.95)])
    for key in ("ap50", "ap50_matcher", "recall_max", "ultralytics_P", "ultralytics_R"):
        assert a[key] == pytest.approx(b[key]) == pytest.approx(1.0), key
    assert b["ignored"] == 1 and b["objects"] == 1


def test_duplicates_are_false_positives():
    dets = [det(1, (10, 10, 30, 20), 0.9), det(1, (11, 10, 30, 20), 0.8)]
    records, matched = match(mark_far_ignored(GT, 100.0), dets)
    assert sorted(r[2] for r in records) == [False, True]
    r = evaluate(GT, dets)
    assert r["recall_max"] == pytest.approx(1 / 3)


def test_agrees_with_pycocotools_on_random_data():
    rng = np.random.default_rng(3)
    boxes, dists, cats, dets = [], [], [], []
    for img in range(1, 9):
        n = int(rng.integers(1, 7))
        bs = [(float(rng.uniform(0, 150)), float(rng.uniform(0, 60)), float(rng.uniform(5, 50)),
               float(rng.uniform(5, 40))) for _ in range(n)]
        boxes.append(bs)
        dists.append([float(rng.uniform(5, 140)) for _ in range(n)])
        cats.append([int(rng.integers(1, 4)) for _ in range(n)])
        for b, c in zip(bs, cats[-1]):
            for _ in range(int(rng.integers(0, 3))):  # 0-2 detections per object, jittered
                j = rng.normal(0, 3, 4)
                dets.append(det(img, (b[0] + j[0], b[1] + j[1], max(1, b[2] + j[2]), max(1, b[3] + j[3])),
                                float(rng.uniform(0.05, 1)), c if rng.random() > 0.1 else int(rng.integers(1, 4))))
        for _ in range(int(rng.integers(0, 3))):  # false alarms
            dets.append(det(img, (rng.uniform(0, 150), rng.uniform(0, 60), 20, 20), float(rng.uniform(0, 1)),
                            int(rng.integers(1, 4))))
    gt = gt_dict(boxes, dists, cats)
    r = evaluate(gt, dets)
    assert r["ignored"] > 0 and 0.2 < r["ap50"] < 0.99
    assert r["ap50_matcher"] == pytest.approx(r["ap50"], abs=1e-4)


def test_yolo_predictions(tmp_path):
    (tmp_path / "000001.txt").write_text("0 0.125 0.2 0.15 0.2 0.9\n")
    dets = yolo_predictions(tmp_path, GT)
    assert dets == [{"image_id": 1, "category_id": 1, "score": 0.9, "bbox": pytest.approx([10, 10, 30, 20])}]
    (tmp_path / "000002.txt").write_text("0 0.1 0.2\n")
    with pytest.raises(Exception, match="000002.txt: line 1"):
        yolo_predictions(tmp_path, GT)


def test_cross_density_table_and_report(tmp_path):
    from fogsim.detection.table import cross_density, markdown, write_report
    from fogsim.io.images import read_image

    perfect = [det(a["image_id"], a["bbox"], 0.9) for a in GT["annotations"]]
    half = perfect[:1] + [det(1, (150, 60, 10, 10), 0.95)]
    gt = {"clear": GT, "beta0.12": GT}
    table = cross_density(gt, {"clear": {"clear": perfect, "beta0.12": half},
                               "beta0.12": {"clear": half, "beta0.12": perfect}})
    assert table["clear"]["clear"]["ap50"] == pytest.approx(1.0)
    assert table["clear"]["beta0.12"]["recall_max"] == pytest.approx(1 / 3)
    md = markdown(table)
    assert "| clear | **1.000** | 0.333 |" in md  # the best of each column in bold
    write_report(table, tmp_path)
    for f in ("cross_density.json", "cross_density.csv", "cross_density.md", "recall_heatmap.png", "map50_heatmap.png"):
        assert (tmp_path / f).is_file()
    assert read_image(tmp_path / "map50_heatmap.png").shape[0] > 100


def test_annotations_without_distance_are_kept():
    gt = gt_dict([[(10, 10, 30, 20)]], [[None]])
    r = evaluate(gt, [det(1, (10, 10, 30, 20), 0.9)])
    assert r["objects"] == 1 and r["ignored"] == 0 and r["recall_max"] == 1.0
    assert r["recall_by_distance"]["0-25 m"] is None
