"""``fogsim.detection.yolo``: the training view of a dataset, predictions as COCO results,
Ultralytics' errors as one line, and (with the 'detect' extra) a training killed between epochs
resuming from its last checkpoint.

Markers: the real training needs Ultralytics (``detect``, ``slow``); the others need neither and
stay in the fast tier."""
import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import tree_digest
from fogsim.dataset.reader import val_ground_truth
from fogsim.detection.yolo import MIXED_MODEL, TrainConfig, training_seconds, training_view
from fogsim.errors import InputError
from study_driver import LEVELS, ROOT, TINY, driver, need_detect_extra, study_dataset


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    return study_dataset(tmp_path_factory)


def test_training_seconds_is_the_last_epochs_cumulative_time(tmp_path):
    # Ultralytics' results.csv: its header padded with spaces in older releases, `time` cumulative over resumes
    (tmp_path / "results.csv").write_text("  epoch,    time,train/box_loss\n1,17.96,5.1\n2,36.19,4.3\n3,61.04,4.0\n")
    assert training_seconds(tmp_path) == 61.0
    (tmp_path / "results.csv").write_text("epoch,train/box_loss\n1,5.1\n")  # no time column
    assert training_seconds(tmp_path) is None
    (tmp_path / "results.csv").write_text("epoch,time\n")  # no epoch yet
    assert training_seconds(tmp_path) is None
    assert training_seconds(tmp_path / "absent") is None


def test_training_view_reads_the_dataset_without_writing_it(dataset, tmp_path):
    before = tree_digest(dataset)
    data = training_view(dataset, tmp_path / "yolo", LEVELS)
    assert set(data) == {*LEVELS, MIXED_MODEL}
    n_train = len((dataset / "splits" / "clear_train.txt").read_text().split())
    for model, yaml in data.items():
        lines = (yaml.parent / "train.txt").read_text().split()
        assert len(lines) == n_train * (len(LEVELS) if model == MIXED_MODEL else 1)
        for line in lines:
            image = Path(line)
            label = Path("/labels/".join(line.rsplit("/images/", 1))).with_suffix(".txt")  # Ultralytics' rule
            assert image.is_file() and label.is_file()
            assert image.resolve().parent.parent == (dataset / "images").resolve()
        assert "names:\n  0: \"car\"" in yaml.read_text()
    # caches of different models / splits land in different folders of the view
    view = tmp_path / "yolo" / "clear" / "train" / "clear" / "labels"
    assert view.resolve() == (dataset / "labels" / "clear").resolve()
    assert tree_digest(dataset) == before


class FakeBoxes:
    def __init__(self, rows):
        self.xyxy = FakeTensor([r[:4] for r in rows])
        self.conf = FakeTensor([r[4] for r in rows])
        self.cls = FakeTensor([r[5] for r in rows])


class FakeTensor(list):
    def tolist(self):
        return list(self)


def test_predict_writes_coco_results_in_image_pixels(dataset, tmp_path, monkeypatch):
    """Ultralytics' xyxy boxes (original-image pixels) → COCO xywh, class + 1, per image id."""
    import fogsim.detection.yolo as detect

    gt = val_ground_truth(dataset, "beta0.03")
    seen = []

    class FakeYOLO:
        def __init__(self, weights):
            assert weights == "w.pt"

        def predict(self, paths, **kw):
            seen.extend(paths)
            assert kw["conf"] == 0.001 and kw["max_det"] == 100 and kw["imgsz"] == 320
            for n, _ in enumerate(paths):
                yield type("Result", (), {"boxes": FakeBoxes([(10 + n, 20, 40, 60, 0.75, 2)])})()

    monkeypatch.setattr(detect, "load_ultralytics", lambda config_dir: type("U", (), {"YOLO": FakeYOLO}))
    monkeypatch.setattr(detect, "resolve_device", lambda device: "cpu")
    dets = detect.predict(Path("w.pt"), gt, dataset, TrainConfig(), tmp_path, chunk=2)
    assert seen == [str(dataset / im["file_name"]) for im in gt["images"]]
    assert [d["image_id"] for d in dets] == [im["id"] for im in gt["images"]]
    assert dets[0] == {"image_id": gt["images"][0]["id"], "category_id": 3, "score": 0.75, "bbox": [10, 20, 30, 40]}
    assert [d["bbox"][0] for d in dets] == [10 + (n % 2) for n in range(len(dets))]  # n restarts per chunk
    missing = dict(gt, images=[dict(gt["images"][0], file_name="images/beta0.03/gone.png")])
    with pytest.raises(InputError, match="gone.png.*missing"):
        detect.predict(Path("w.pt"), missing, dataset, TrainConfig(), tmp_path)


def test_ultralytics_errors_become_one_line_naming_the_model(tmp_path, monkeypatch):
    """#19: whatever Ultralytics raises while training or predicting → FogsimError (exit 1)
    'training <model> failed: …' on one line; Ctrl-C passes unchanged."""
    import fogsim.detection.yolo as detect
    from fogsim.errors import FogsimError, exit_code

    raised = [ValueError("\x1b[31mbatch size 2 is\ntoo large\x1b[0m for 1 image")]

    class FakeYOLO:
        def __init__(self, model):
            pass

        def train(self, **kw):
            raise raised[0]

        def predict(self, paths, **kw):
            raise RuntimeError("CUDA out of memory.\nTried to allocate")

    monkeypatch.setattr(detect, "load_ultralytics", lambda config_dir: type("U", (), {"YOLO": FakeYOLO}))
    monkeypatch.setattr(detect, "resolve_device", lambda device: "cpu")
    with pytest.raises(FogsimError) as err:
        detect.train("beta0.06", tmp_path / "data.yaml", tmp_path / "runs" / "beta0.06", TrainConfig(), tmp_path)
    assert str(err.value) == "training beta0.06 failed: ValueError: batch size 2 is too large for 1 image"
    assert exit_code(err.value) == 1
    raised[0] = KeyboardInterrupt()
    with pytest.raises(KeyboardInterrupt):
        detect.train("beta0.06", tmp_path / "data.yaml", tmp_path / "runs" / "beta0.06", TrainConfig(), tmp_path)
    image = tmp_path / "images" / "a.png"
    image.parent.mkdir()
    image.write_bytes(b"")
    gt = {"images": [{"id": 1, "file_name": "images/a.png"}], "annotations": []}
    with pytest.raises(FogsimError, match="^prediction with w.pt failed: RuntimeError: CUDA out of memory. Tried"):
        detect.predict(Path("w.pt"), gt, tmp_path, TrainConfig(), tmp_path)


@pytest.mark.detect
@pytest.mark.slow
def test_interrupted_training_resumes_from_last_checkpoint(dataset, tmp_path, monkeypatch):
    """SIGKILL between epochs (last.pt still holds its optimizer), then rerun: training resumes
    at the next epoch instead of starting again."""
    need_detect_extra()
    from fogsim.detection.yolo import _resumable, load_ultralytics

    monkeypatch.setenv("YOLO_CONFIG_DIR", str(tmp_path / "config"))
    load_ultralytics(tmp_path / "config")  # imported now, not while racing the training below

    out = tmp_path / "study"
    args = [sys.executable, str(ROOT / "scripts" / "train_per_density.py"), "--out", str(out), "--dataset",
            str(dataset), "--epochs", "3", *TINY[2:]]
    last = out / "runs" / "clear" / "weights" / "last.pt"
    proc = subprocess.Popen(args, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        caught = False
        while not caught and proc.poll() is None:
            time.sleep(0.02)
            try:
                caught = last.is_file() and _resumable(last)  # epoch 1 saved in full
            except Exception:  # still being written
                pass
        proc.kill()
    finally:
        proc.wait()
    assert last.is_file() and _resumable(last), "the run was not caught between its two epochs"
    assert not (out / "runs" / "clear" / "fogsim_done.json").exists()
    r = driver("--out", out, "--dataset", dataset, "--epochs", "3", *TINY[2:])
    assert r.returncode == 0, r.stderr[-3000:]
    results = (out / "runs" / "clear" / "results.csv").read_text().splitlines()[1:]
    epochs = [line.split(",")[0].strip() for line in results]
    # the resumed run went on from the killed one's checkpoint, not from scratch (an epoch whose
    # row was written just before the kill, but not its checkpoint, is run again: Ultralytics' way)
    assert epochs[0] == "1" and epochs.count("1") == 1 and epochs[-1] == "3" and set(epochs) == {"1", "2", "3"}
    assert not _resumable(last) and (out / "report" / "report.md").is_file()
    assert json.loads((out / "runs" / "clear" / "fogsim_done.json").read_text())["state"] == "resumed"
    # a checkpoint cut short by a kill: a clear error naming it, not a traceback
    (out / "runs" / "clear" / "fogsim_done.json").unlink()
    last.write_bytes(last.read_bytes()[:1000])
    r = driver("--out", out, "--dataset", dataset, "--epochs", "3", *TINY[2:])
    assert r.returncode == 1 and "last.pt: unreadable checkpoint" in r.stderr and "Traceback" not in r.stderr
