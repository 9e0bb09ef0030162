"""The per-density detection study (``fogsim.detection.study``): report rows (oracle, routed,
mixed), the study folder's layout, the driver's errors — and, when the 'detect' extra is
installed, a tiny real Ultralytics training through scripts/train_per_density.py.

Markers: the report tests need pycocotools and the real trainings Ultralytics (``detect``; the
trainings are also ``slow``); the others need neither and stay in the fast tier."""
import csv
import json
from pathlib import Path

import numpy as np
import pytest

from conftest import tree_digest
from fogsim.dataset.reader import val_ground_truth
from fogsim.detection.layout import StudyLayout
from fogsim.detection.study import Study
from fogsim.detection.yolo import MIXED_MODEL, TrainConfig
from fogsim.errors import InputError
from study_driver import LEVELS, TINY, driver, need_detect_extra, study_dataset
from synthetic_dataset import make_dataset


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return study_dataset(tmp_path_factory)


def test_study_layout_is_the_documented_folder(tmp_path):
    """The study folder's format (what a resumed or sharded study finds on disk)."""
    f = StudyLayout(tmp_path)
    assert f.study_file() == tmp_path / "study.json" and f.training_view() == tmp_path / "yolo"
    assert f.run_done(MIXED_MODEL) == tmp_path / "runs" / "mixed" / "fogsim_done.json"
    assert f.weights("clear") == tmp_path / "runs" / "clear" / "weights" / "best.pt"
    assert f.prediction("clear", "beta0.06") == tmp_path / "predictions" / "clear" / "beta0.06.json"
    assert f.report("report.md") == tmp_path / "report" / "report.md" and f.report() == tmp_path / "report"
    assert f.sim_study() == tmp_path / "sim_to_real" / "study"
    assert f.sim_prediction("mixed", "clear") == tmp_path / "sim_to_real" / "predictions" / "mixed" / "clear.json"


def perfect(gt, score=0.9):
    return [{"image_id": a["image_id"], "category_id": a["category_id"], "bbox": a["bbox"], "score": score}
            for a in gt["annotations"]]


def test_val_ground_truth_keeps_validation_frames_only(dataset):
    gt = val_ground_truth(dataset, "beta0.06")
    val = {Path(p).stem for p in (dataset / "splits" / "beta0.06_val.txt").read_text().split()}
    assert {Path(im["file_name"]).stem for im in gt["images"]} == val
    ids = {im["id"] for im in gt["images"]}
    assert gt["annotations"] and all(a["image_id"] in ids for a in gt["annotations"])


def write_predictions(study, gts, models):
    for model, by_level in models.items():
        for lv, dets in by_level.items():
            path = study.prediction(model, lv)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(dets))


@pytest.mark.detect
def test_report_rows_oracle_routed_mixed(dataset, tmp_path):
    """Each level model finds every object on its own level only; mixed finds them everywhere.
    Then oracle = 1 everywhere, the clear model fails in fog, and a routed row finds exactly the
    objects of the images its estimator sent to the right model. On this dataset the dark channel
    routes every image right (routed = oracle); the features estimator never misroutes clear air
    and misroutes a few fogged images, each to the next thicker level."""
    pytest.importorskip("pycocotools")
    study = Study(dataset, tmp_path / "study", TrainConfig())
    gts = study.ground_truth()
    study.check_parameters(gts)
    preds = {m: {lv: (perfect(gts[lv]) if m == lv else []) for lv in LEVELS} for m in LEVELS}
    preds[MIXED_MODEL] = {lv: perfect(gts[lv], 0.5) for lv in LEVELS}
    write_predictions(study, gts, preds)
    with pytest.raises(InputError, match="prediction files are missing"):
        Study(dataset, tmp_path / "empty", TrainConfig()).report()

    table = study.report(max_distance_m=100.0)
    for lv in LEVELS:
        near = sum(a["distance_m"] <= 100 for a in gts[lv]["annotations"])
        assert table["oracle"][lv]["objects"] == near < len(gts[lv]["annotations"])  # 140 m ignored
        for row in ("oracle", MIXED_MODEL):
            assert table[row][lv]["ap50"] == pytest.approx(1.0)
            assert table[row][lv]["recall_max"] == table[row][lv]["ultralytics_R"] == pytest.approx(1.0)
        assert table["clear"][lv]["recall_max"] == (1.0 if lv == "clear" else 0.0)

    # routing by hand: every image sent to its own level's model, what a perfect estimator does
    truth = {lv: {im["id"]: lv for im in gts[lv]["images"]} for lv in LEVELS}
    estimates = study.estimate_levels(gts)
    assert set(estimates) == {"features", "dark-channel"}
    assert estimates["dark-channel"][2] == truth
    for lv in LEVELS:
        assert table["routed (dark-channel)"][lv]["recall_max"] == pytest.approx(1.0)
    features = estimates["features"][2]
    assert features["clear"] == truth["clear"]
    assert table["routed (features)"]["clear"]["recall_max"] == pytest.approx(1.0)
    misrouted = [(lv, est) for lv in LEVELS for est in features[lv].values() if est != lv]
    assert len(misrouted) <= 0.2 * sum(len(truth[lv]) for lv in LEVELS)
    assert all(LEVELS.index(est) == LEVELS.index(lv) + 1 for lv, est in misrouted), misrouted
    # the routing plumbing: a routed row finds exactly the objects of the images sent to the right model
    for method, (true, predicted, per_image) in estimates.items():
        for lv in LEVELS:
            right = {i for i, est in per_image[lv].items() if est == lv}
            real = [a for a in gts[lv]["annotations"] if a["distance_m"] <= 100]
            expected = sum(a["image_id"] in right for a in real) / len(real)
            assert table[f"routed ({method})"][lv]["recall_max"] == pytest.approx(expected)
        assert len(true) == len(predicted) == sum(len(gts[lv]["images"]) for lv in LEVELS)
        assert true == [lv for lv in LEVELS for _ in gts[lv]["images"]]

    out = tmp_path / "study" / "report"
    for name in ("cross_density.json", "cross_density.csv", "cross_density.md", "recall_heatmap.png",
                 "map50_heatmap.png", "fog_level.json", "fog_level_features.png", "fog_level_dark-channel.png",
                 "report.md"):
        assert (out / name).stat().st_size > 0, name
    conf = json.loads((out / "fog_level.json").read_text())
    assert np.array(conf["features"]["matrix"]).sum() == sum(len(gts[lv]["images"]) for lv in LEVELS)
    assert conf["dark-channel"]["matrix"] == np.diag([len(gts[lv]["images"]) for lv in LEVELS]).tolist()
    assert np.array(conf["features"]["matrix"]).sum(axis=1).tolist() == [len(gts[lv]["images"]) for lv in LEVELS]
    assert "| routed (features) |" in (out / "report.md").read_text()


def test_study_refuses_a_folder_holding_other_parameters(dataset, tmp_path):
    study = Study(dataset, tmp_path / "s", TrainConfig(epochs=3))
    gts = study.ground_truth()
    study.check_parameters(gts)
    Study(dataset, tmp_path / "s", TrainConfig(epochs=3)).check_parameters(gts)  # same: fine
    with pytest.raises(InputError, match="study.json.*other parameters"):
        Study(dataset, tmp_path / "s", TrainConfig(epochs=4)).check_parameters(gts)
    assert study.stored_config(gts) == TrainConfig(epochs=3)  # what the report describes
    # the same dataset re-split (or grown): its predictions no longer fit, so the report refuses
    other = gts | {"clear": dict(gts["clear"], images=gts["clear"]["images"][1:])}
    with pytest.raises(InputError, match="another dataset or validation split"):
        study.stored_config(other)
    with pytest.raises(InputError, match="no study here"):
        Study(dataset, tmp_path / "none").stored_config(gts)


@pytest.mark.detect
def test_misrouted_images_lose_their_objects(dataset, tmp_path, monkeypatch):
    """Routing by hand: the first validation image of every level goes to a wrong model."""
    pytest.importorskip("pycocotools")
    study = Study(dataset, tmp_path / "study", TrainConfig())
    gts = study.ground_truth()
    study.check_parameters(gts)
    preds = {m: {lv: (perfect(gts[lv]) if m == lv else []) for lv in LEVELS} for m in LEVELS}
    preds[MIXED_MODEL] = {lv: [] for lv in LEVELS}
    write_predictions(study, gts, preds)
    wrong = {lv: gts[lv]["images"][0]["id"] for lv in LEVELS}
    estimates = {lv: {im["id"]: ("beta0.12" if lv == "clear" else "clear") if im["id"] == wrong[lv] else lv
                      for im in gts[lv]["images"]} for lv in LEVELS}
    monkeypatch.setattr(Study, "estimate_levels", lambda self, gts: {"features": ([], [], estimates)})
    monkeypatch.setattr("fogsim.detection.study.confusion", lambda *a: {"levels": LEVELS, "matrix": [[0] * 5] * 5,
                                                              "accuracy": 0.0})
    table = study.report()
    for lv in LEVELS:
        real = [a for a in gts[lv]["annotations"] if a["distance_m"] <= 100]
        kept = sum(a["image_id"] != wrong[lv] for a in real) / len(real)
        assert len(gts[lv]["images"]) > 1 and kept < 1.0
        assert table["routed (features)"][lv]["recall_max"] == pytest.approx(kept)
        assert table["oracle"][lv]["recall_max"] == 1.0


def test_driver_bad_input_names_the_problem(dataset, tmp_path):
    r = driver("--out", tmp_path / "s", "--dataset", tmp_path / "nowhere")
    assert r.returncode == 2 and "nowhere" in r.stderr and "dataset.json" in r.stderr
    r = driver("--out", tmp_path / "s", "--dataset", dataset, "--shard", "2/2")
    assert r.returncode == 2 and "--shard" in r.stderr
    r = driver("--out", tmp_path / "s", "--dataset", dataset, "--epochs", "0")
    assert r.returncode == 2 and "--epochs" in r.stderr
    r = driver("--out", tmp_path / "s", "--dataset", dataset, "--report-only")
    assert r.returncode == 2 and "prediction files are missing" in r.stderr


@pytest.mark.parametrize("manifest", [{"levels": "oops"}, [1, 2], {"levels": [{"name": "clear"}]},
                                      {"levels": [{"key": "../x"}]}])
def test_driver_malformed_dataset_json_is_one_line(tmp_path, manifest):
    """#19: a dataset.json of the wrong shape → one line naming it, exit 2 (not a TypeError traceback)."""
    fake = tmp_path / "fake"
    fake.mkdir()
    (fake / "dataset.json").write_text(json.dumps(manifest))
    r = driver("--out", tmp_path / "s", "--dataset", fake)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert f"{fake / 'dataset.json'}: malformed" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_driver_malformed_coco_file_is_one_line(dataset, tmp_path):
    import shutil

    ds = tmp_path / "ds"
    shutil.copytree(dataset, ds)
    (ds / "coco" / "beta0.06.json").write_text(json.dumps({"images": "oops", "annotations": []}))
    r = driver("--out", tmp_path / "s", "--dataset", ds)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert f"{ds / 'coco' / 'beta0.06.json'}: malformed COCO file" in r.stderr


def test_driver_names_a_missing_dataset_image_before_training(dataset, tmp_path):
    """#19: a validation image deleted from the dataset is named as the dataset's file (not
    Ultralytics' link under OUT/yolo), before any training and before study.json."""
    import shutil

    ds = tmp_path / "ds"
    shutil.copytree(dataset, ds)
    frame = (ds / "splits" / "beta0.06_val.txt").read_text().split()[1]
    gone = ds / "images" / "beta0.06" / Path(frame).name
    gone.unlink()
    out = tmp_path / "s"
    r = driver("--out", out, "--dataset", ds, *TINY, timeout=600)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert r.stderr.strip() == (f"fogsim: error: {gone}: missing from the dataset: its split lists or COCO files "
                                "name it; restore it, or rebuild the lists with fogsim render --finalize-only")
    assert not (out / "study.json").exists() and not (out / "runs").exists()


# --- a real training (needs the 'detect' extra) ---------------------------------------------------

@pytest.mark.detect
def test_real_ultralytics_failure_is_one_line_exit_1(tmp_path):
    """#19: Ultralytics refusing the data (every training image of one level undecodable:
    'No valid images found') ends the study with one line naming the model, exit 1."""
    need_detect_extra()
    ds = make_dataset(tmp_path / "ds3", frames=3)
    for frame in (ds / "splits" / "clear_train.txt").read_text().split():
        (ds / "images" / "clear" / Path(frame).name).write_bytes(b"not a png")
    r = driver("--out", tmp_path / "s", "--dataset", ds, "--imgsz", "32", "--batch", "2", *TINY[:2], *TINY[6:])
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr[-3000:]
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("fogsim: error: training clear failed: RuntimeError: No valid images found"), last


@pytest.mark.detect
@pytest.mark.slow
def test_tiny_real_training_resume_and_shards(dataset, tmp_path):
    need_detect_extra()
    before = tree_digest(dataset)
    out = tmp_path / "study"
    r = driver("--out", out, "--dataset", dataset, *TINY)
    assert r.returncode == 0, r.stderr[-3000:]
    table_md = (out / "report" / "cross_density.md").read_text()  # --quiet prints the summary line only
    assert r.stdout.startswith("report: ") and "**recall**" in table_md and "| routed (dark-channel) |" in table_md
    models = [*LEVELS, MIXED_MODEL]
    for m in models:
        assert (out / "runs" / m / "weights" / "best.pt").is_file()
        assert json.loads((out / "runs" / m / "fogsim_done.json").read_text())["config"]["epochs"] == 1
    preds = {(m, lv): json.loads((out / "predictions" / m / f"{lv}.json").read_text()) for m in models for lv in LEVELS}
    gt = val_ground_truth(dataset, "clear")
    ids = {im["id"] for im in gt["images"]}
    for dets in preds.values():
        for d in dets:
            assert d["image_id"] in ids and 1 <= d["category_id"] <= 8 and 0 < d["score"] <= 1
            x, y, w, h = d["bbox"]
            assert w > 0 and h > 0 and -1 <= x and x + w <= 97 and -1 <= y and y + h <= 65
    table = json.loads((out / "report" / "cross_density.json").read_text())
    assert set(table) == {*models, "oracle", "routed (features)", "routed (dark-channel)"}
    assert tree_digest(dataset) == before

    # a model trained but not marked (killed after its last epoch) is taken as done, predicts the same
    (out / "runs" / "clear" / "fogsim_done.json").unlink()
    for lv in LEVELS:
        (out / "predictions" / "clear" / f"{lv}.json").unlink()
    stamp = (out / "predictions" / "beta0.12" / "clear.json").stat().st_mtime_ns
    r = driver("--out", out, "--dataset", dataset, *TINY)
    assert r.returncode == 0, r.stderr[-3000:]
    assert (out / "predictions" / "beta0.12" / "clear.json").stat().st_mtime_ns == stamp  # done: skipped
    marker = json.loads((out / "runs" / "clear" / "fogsim_done.json").read_text())
    assert marker["state"] == "finished earlier"
    last = list(csv.DictReader((out / "runs" / "clear" / "results.csv").open()))[-1]
    assert marker["seconds_training"] == round(float(last["time"]), 1) > 0  # the training time survives the restart
    assert f"| clear | 1 | {marker['seconds_training']:.1f} |" in (out / "report" / "report.md").read_text()
    for lv in LEVELS:
        assert json.loads((out / "predictions" / "clear" / f"{lv}.json").read_text()) == preds["clear", lv]

    r = driver("--out", out, "--dataset", dataset, *TINY[:1], "2", *TINY[2:])
    assert r.returncode == 2 and "other parameters" in r.stderr
    for model, message in (("yolov8n.pt", "nothing can be downloaded"), ("no-such-model.yaml", "cannot build")):
        r = driver("--out", tmp_path / model, "--dataset", dataset, "--model", model, *TINY)
        assert r.returncode == 2 and model in r.stderr and message in r.stderr, r.stderr[-2000:]

    # shards: each trains its own models; the last to finish writes the report
    sharded = tmp_path / "sharded"
    r = driver("--out", sharded, "--dataset", dataset, "--shard", "1/2", *TINY)
    assert r.returncode == 0 and "--report-only" in r.stdout
    assert sorted(p.name for p in (sharded / "runs").iterdir()) == sorted(models[1::2])
    r = driver("--out", sharded, "--dataset", dataset, "--shard", "0/2", *TINY)
    assert r.returncode == 0, r.stderr[-3000:]
    assert (sharded / "report" / "report.md").is_file()
    # same seed, same data: the same weights, so the same predictions (CPU training is deterministic)
    assert json.loads((sharded / "predictions" / "mixed" / "beta0.06.json").read_text()) == preds["mixed", "beta0.06"]
