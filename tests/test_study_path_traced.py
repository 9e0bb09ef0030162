"""``fogsim study --eval-dataset --scatter-dataset`` (fogsim.detection.fog_models): the checks that
the three renders show the same scenes, the report's rows ``trained on Koschmieder fog`` /
``trained on scatter fog`` on the path-traced levels, and a tiny real training with them.

The three "renders" are one synthetic dataset copied, each copy's ``dataset.json`` given the preset
record a render writes (fog kind, scene settings, frame seeds); the path-traced copy's images are
darkened so its numbers differ. Markers: the report test needs pycocotools (``detect``), the real
training Ultralytics too (``detect``, ``slow``); the checks need neither."""
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from fogsim.detection.fog_models import ROWS, SCATTER_MODEL
from fogsim.detection.study import Study
from fogsim.detection.yolo import MIXED_MODEL, TrainConfig
from fogsim.errors import InputError
from fogsim.io.images import read_image, write_image
from study_driver import LEVELS, TINY, driver, need_detect_extra, study_dataset

PRESET = {"name": "default", "style": "urban", "camera": "waymo-front", "resolution": [96, 64], "exposure": 0.0,
          "seed": 0, "labels": {}, "quality": "draft"}


def as_render(src: Path, dst: Path, kind: str | None) -> Path:
    """A copy of ``src`` whose dataset.json says it is a render with fog kind ``kind``
    (None: the preset records no kind, i.e. Koschmieder)."""
    shutil.copytree(src, dst)
    manifest = json.loads((dst / "dataset.json").read_text())
    fog = {} if kind is None else {"kind": kind}
    frames = sorted(p.stem for p in (dst / "meta").glob("*.json"))
    manifest |= {"preset": PRESET | {"fog_model": fog}, "seed": 0, "frame_seeds": {f: 1000 + int(f) for f in frames}}
    (dst / "dataset.json").write_text(json.dumps(manifest))
    return dst


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    base = study_dataset(tmp_path_factory)
    root = tmp_path_factory.mktemp("renders")
    ds = as_render(base, root / "koschmieder", None)
    scatter = as_render(base, root / "scatter", "scatter")
    volumetric = as_render(base, root / "volumetric", "volumetric")
    for lv in LEVELS[1:]:  # path-traced fog: other images than the training render's
        for png in (volumetric / "images" / lv).glob("*.png"):
            write_image(png, (read_image(png) * 0.7).astype(np.uint8))
    return ds, scatter, volumetric


def edit_manifest(path: Path, change) -> Path:
    manifest = json.loads((path / "dataset.json").read_text())
    change(manifest)
    (path / "dataset.json").write_text(json.dumps(manifest))
    return path / "dataset.json"


def test_arguments_come_together(renders, tmp_path):
    ds, scatter, volumetric = renders
    for args in (("--eval-dataset", volumetric), ("--scatter-dataset", scatter)):
        r = driver("--out", tmp_path / "s", "--dataset", ds, *args)
        assert r.returncode == 2 and "--eval-dataset and --scatter-dataset come together" in r.stderr, r.stderr
    r = driver("--out", tmp_path / "s", "--dataset", ds, "--eval-dataset", volumetric, "--scatter-dataset", scatter,
               "--sim-dataset", scatter)
    assert r.returncode == 2 and "give one of them" in r.stderr
    r = driver("--out", volumetric / "study", "--dataset", ds, "--eval-dataset", volumetric,
               "--scatter-dataset", scatter)
    assert r.returncode == 2 and "--out lies inside --eval-dataset" in r.stderr
    assert not (tmp_path / "s").exists()
    with pytest.raises(ValueError, match="come together"):
        Study(ds, tmp_path / "s", TrainConfig(), eval_dataset=volumetric)


def mismatches(ds: Path, scatter: Path, volumetric: Path, tmp: Path):
    """(flag, broken copy, file the error must name, message part) for every check."""
    def copy(src, name, change=None):
        out = tmp / name
        shutil.copytree(src, out)
        return out, (edit_manifest(out, change) if change else out / "dataset.json")

    out, manifest = copy(volumetric, "kind", lambda m: m["preset"]["fog_model"].update(kind="koschmieder"))
    yield "--eval-dataset", out, manifest, "must be a render with fog kind 'volumetric'"
    out, manifest = copy(scatter, "kind_s", lambda m: m["preset"]["fog_model"].update(kind="volumetric"))
    yield "--scatter-dataset", out, manifest, "must be a render with fog kind 'scatter'"
    out, manifest = copy(volumetric, "beta", lambda m: m["levels"][2].update(beta=0.07))
    yield "--eval-dataset", out, manifest, "levels (key, β)"
    out, manifest = copy(volumetric, "classes", lambda m: m["classes"].reverse())
    yield "--eval-dataset", out, manifest, "classes"
    out, manifest = copy(volumetric, "style", lambda m: m["preset"].update(style="suburban"))
    yield "--eval-dataset", out, manifest, "preset style"
    out, manifest = copy(scatter, "seeds", lambda m: m["frame_seeds"].update({"000003": 7}))
    yield "--scatter-dataset", out, manifest, "frame seeds"
    out, _ = copy(volumetric, "split")
    split = out / "splits" / "beta0.06_val.txt"
    split.write_text("\n".join(split.read_text().split()[1:]) + "\n")
    yield "--eval-dataset", out, split, "lists other val frames than --dataset"
    out, _ = copy(volumetric, "not_a_render", lambda m: m.pop("preset"))
    yield "--eval-dataset", out, out / "dataset.json", "its fog is None"


def test_mismatched_renders_are_one_line_naming_the_file(renders, tmp_path):
    ds, scatter, volumetric = renders
    for n, (flag, broken, named, message) in enumerate(mismatches(ds, scatter, volumetric, tmp_path)):
        given = {"--eval-dataset": volumetric, "--scatter-dataset": scatter} | {flag: broken}
        out = tmp_path / f"study{n}"
        r = driver("--out", out, "--dataset", ds, *[str(v) for kv in given.items() for v in kv], *TINY)
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-2000:]
        assert r.stderr.startswith(f"fogsim: error: {named}: ") and message in r.stderr, (message, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1 and not out.exists()  # nothing written
    # the study's own dataset must be the Koschmieder render
    with pytest.raises(InputError, match="--dataset must be a render with Koschmieder fog"):
        Study(scatter, tmp_path / "x", TrainConfig(), eval_dataset=volumetric, scatter_dataset=scatter)
    assert not (tmp_path / "x").exists()


def perfect(gt, score=0.9):
    return [{"image_id": a["image_id"], "category_id": a["category_id"], "bbox": a["bbox"], "score": score}
            for a in gt["annotations"]]


@pytest.mark.detect
def test_report_has_the_two_rows_with_numbers(renders, tmp_path):
    """mixed finds every object of the path-traced levels, scatter only those of clear air: the
    rows are 1 and (1 at clear, 0 in fog), computed on the path-traced ground truth."""
    pytest.importorskip("pycocotools")
    ds, scatter, volumetric = renders
    study = Study(ds, tmp_path / "study", TrainConfig(), eval_dataset=volumetric, scatter_dataset=scatter)
    assert study.models == [*LEVELS, MIXED_MODEL, SCATTER_MODEL]
    gts, eval_gts = study.ground_truth(), study.eval_ground_truth()
    study.check_parameters(gts)
    for m in study.models:
        for lv in LEVELS:
            for path, gt in ((study.prediction(m, lv), gts[lv]), (study.files.eval_prediction(m, lv), eval_gts[lv])):
                path.parent.mkdir(parents=True, exist_ok=True)
                keep = m == MIXED_MODEL or (m == SCATTER_MODEL and lv == "clear")
                path.write_text(json.dumps(perfect(gt) if keep else []))
    study.files.eval_prediction(SCATTER_MODEL, "beta0.12").unlink()
    with pytest.raises(InputError, match="1 prediction files are missing"):
        study.report()
    study.files.eval_prediction(SCATTER_MODEL, "beta0.12").write_text("[]")

    table = study.report()
    koschmieder, scattered = table["trained on Koschmieder fog"], table["trained on scatter fog"]
    for lv in LEVELS:
        assert koschmieder[lv]["ap50"] == pytest.approx(1.0) and koschmieder[lv]["recall_all"] == pytest.approx(1.0)
        assert scattered[lv]["ap50"] == pytest.approx(1.0 if lv == "clear" else 0.0)
        assert koschmieder[lv]["objects"] == sum(a["distance_m"] <= 100 for a in eval_gts[lv]["annotations"])
    out = study.files.report()
    assert set(json.loads((out / "path_traced.json").read_text())) == set(study.models)
    assert set(ROWS) <= set(json.loads((out / "cross_density.json").read_text()))
    md = (out / "report.md").read_text()
    assert "| trained on Koschmieder fog | **1.000** | **1.000** | **1.000** | **1.000** | **1.000** |" in md
    assert "| trained on scatter fog | **1.000** | 0.000 | 0.000 | 0.000 | 0.000 |" in md
    assert "| trained on scatter fog (`scatter`) | **1.000** / 1.000 | 0.000 / 0.000 |" in md
    assert "scatter − Koschmieder training on path-traced fog: clear +0.000, beta0.03 -1.000" in md
    assert "| scatter | 20 |" in md  # the training table: scatter trains the mixed model's epochs
    assert (out / "map50_heatmap.png").stat().st_size > 0
    moved = tmp_path / "volumetric_copy"  # predictions of another eval render: the report refuses
    shutil.copytree(volumetric, moved)
    with pytest.raises(InputError, match="path-traced predictions were made without, or on other renders"):
        Study(ds, tmp_path / "study", TrainConfig(), eval_dataset=moved, scatter_dataset=scatter).report()


@pytest.mark.detect
@pytest.mark.slow
def test_tiny_real_training_with_path_traced_rows_resume_and_shards(renders, tmp_path):
    need_detect_extra()
    ds, scatter, volumetric = renders
    given = ("--dataset", ds, "--eval-dataset", volumetric, "--scatter-dataset", scatter)
    out = tmp_path / "study"
    r = driver("--out", out, "--shard", "1/2", *given, *TINY)  # models 1, 3, 5: beta0.03, beta0.09, mixed
    assert r.returncode == 0 and "--report-only" in r.stdout, r.stderr[-3000:]
    trained = ["beta0.03", "beta0.09", MIXED_MODEL]
    assert sorted(p.name for p in (out / "runs").iterdir()) == trained
    assert sorted(p.name for p in (out / "path_traced" / "predictions").iterdir()) == trained
    stamp = (out / "path_traced" / "predictions" / MIXED_MODEL / "clear.json").stat().st_mtime_ns
    r = driver("--out", out, "--shard", "0/2", *given, *TINY)  # the rest, scatter included; then the report
    assert r.returncode == 0, r.stderr[-3000:]
    assert (out / "path_traced" / "predictions" / MIXED_MODEL / "clear.json").stat().st_mtime_ns == stamp
    view = (out / "yolo_scatter" / MIXED_MODEL / "train.txt").read_text().split()
    assert view and all(Path(p).resolve().is_relative_to(scatter.resolve()) for p in view)  # trained on scatter
    assert (out / "runs" / SCATTER_MODEL / "weights" / "best.pt").is_file()
    md = (out / "report" / "report.md").read_text()
    for row in ROWS:
        line = next(ln for ln in md.splitlines() if ln.startswith(f"| {row} |"))
        assert all(float(c.strip("* ")) >= 0 for c in line.split("|")[2:-1]), line
    r = driver("--out", out, *given, *TINY[:1], "2", *TINY[2:])  # another configuration: refused
    assert r.returncode == 2 and "other parameters" in r.stderr
