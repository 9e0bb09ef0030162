"""``fogsim fog`` on datasets with labels: the render's dataset layout with the dataset's own
class list (Cityscapes end to end through the CLI; a Waymo-like folder dataset with a
hand-written label reader), resume, shards + --finalize-only, --no-labels, bad input."""
import json
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from cityscapes_tree import BASES, make_tree, scene
from conftest import tree_digest
from fogsim.cli import main
from fogsim.dataset.layout import DatasetLayout, frame_from_key, frames_from_keys
from fogsim.errors import InputError
from fogsim.fog.batch import FogJob, finalize_dataset, run
from fogsim.fog.levels import parse_levels
from fogsim.io.images import read_image, write_image
from fogsim.readers.base import DepthSpec, Labels
from fogsim.readers.cityscapes_labels import CITYSCAPES_CLASSES
from fogsim.readers.folder import folder_samples

LEVELS = ["clear", "beta0.03", "beta0.06", "beta0.09", "beta0.12"]
FRAMES = [f"leftImg8bit__val__aachen__{b}_leftImg8bit" for b in BASES]


@pytest.fixture
def tree(tmp_path):
    return make_tree(tmp_path / "cs")


def fog(root, out, *extra):
    return main(["fog", "--cityscapes", str(root), "--split", "val", "--out", str(out), "--quiet", *extra])


def read(path):
    return json.loads(Path(path).read_text())


def test_frame_names_are_flat_and_collisions_refused():
    assert frame_from_key("ctx/123_FRONT") == "ctx__123_FRONT"
    assert frame_from_key("a") == "a"
    with pytest.raises(InputError, match="'a__b'.*also that of a/b"):
        frames_from_keys(["a/b", "a__b"])
    for bad in ("", "/abs", "a/../b", "a//b"):
        with pytest.raises(ValueError):
            frame_from_key(bad)


def test_cityscapes_dataset_end_to_end(tree, tmp_path, capsys):
    out = tmp_path / "out"
    before = tree_digest(tree)
    assert fog(tree, out) == 0
    assert tree_digest(tree) == before
    assert "dataset: 2 frames" in capsys.readouterr().out
    layout = DatasetLayout(out)
    assert layout.done_frames() == FRAMES
    manifest = read(layout.manifest())
    assert manifest["classes"] == list(CITYSCAPES_CLASSES) and manifest["frames"] == 2
    assert manifest["counts"] == {"person": 4, "rider": 0, "car": 4, "truck": 0, "bus": 0, "train": 0,
                                  "motorcycle": 0, "bicycle": 0}
    assert manifest["filtered"] == {"group (cargroup)": 2, "ignored class (caravan)": 2}
    assert [lv["key"] for lv in manifest["levels"]] == LEVELS and manifest["source"] == "fogsim fog"
    run_file = read(out / "fogsim_run.json")["parameters"]
    assert run_file["labels"] == {"classes": list(CITYSCAPES_CLASSES), "min_pixels": 0}
    for frame, base in zip(FRAMES, BASES):
        meta = read(layout.meta(frame))
        assert meta["classes"] == list(CITYSCAPES_CLASSES) and meta["source"].endswith(f"{base}_leftImg8bit.png")
        assert [lv["key"] for lv in meta["levels"]] == LEVELS
        assert meta["airlight_rgb"] == [255.0, 255.0, 255.0] and meta["encoding"] == "disparity"
        assert meta["depth_coverage"] == pytest.approx(1 - 36 / (64 * 32), abs=1e-6)  # 32 + 4 holes
        assert meta["camera"]["fx"] == 50.0 and meta["camera"]["cx"] == 31.5
        assert {o["distance_source"] for o in meta["objects"]} == {"valid disparity (median ray distance)",
                                                                    "unknown"}
        clear = read_image(layout.image("clear", frame))
        src = read_image(tree / "leftImg8bit" / "val" / "aachen" / f"{base}_leftImg8bit.png")
        assert clear.tobytes() == src.tobytes()  # β = 0: the input
        fogged = read_image(layout.image("beta0.12", frame)).astype(int)
        assert (fogged >= clear.astype(int) - 1).all() and fogged.mean() > clear.mean() + 20
        lines = {lv: layout.label(lv, frame).read_text() for lv in LEVELS}
        assert len(set(lines.values())) == 1  # one label file, copied to every level
        kept = [o for o in meta["objects"] if o["kept"]]
        assert [int(line.split()[0]) for line in lines["clear"].splitlines()] == [o["class_id"] for o in kept]
        assert sorted(int(line.split()[0]) for line in lines["clear"].splitlines()) == [0, 0, 2, 2]  # person, car
    for lv in LEVELS:
        coco = read(layout.coco(lv))
        assert [c["name"] for c in coco["categories"]] == list(CITYSCAPES_CLASSES)
        assert [c["id"] for c in coco["categories"]] == list(range(1, 9))
        assert len(coco["images"]) == 2 and len(coco["annotations"]) == 12
        for ann in coco["annotations"]:
            assert "distance_m" in ann and "distance_source" in ann
            assert "visible_fraction" not in ann  # a real record has none
        crowd = [a for a in coco["annotations"] if a["iscrowd"]]
        assert sorted(a["ignore_reason"] for a in crowd) == ["group (cargroup)"] * 2 + ["ignored class (caravan)"] * 2
        assert all(a["category_id"] == 3 for a in crowd)  # car
        unknown = [a for a in coco["annotations"] if a["distance_m"] is None]
        assert len(unknown) == 2 and all(a["category_id"] == 1 for a in unknown)  # the all-hole person
        yaml = layout.data_yaml(lv).read_text()
        assert '  0: "person"' in yaml and '  7: "bicycle"' in yaml and "car\"\n  3" in yaml
        train = layout.split_file(lv, "train").read_text().split()
        val = layout.split_file(lv, "val").read_text().split()
        assert sorted(Path(p).stem for p in train + val) == FRAMES
    assert len(layout.split_file("all", "train").read_text().split()) == 5 * len(train)
    sheet = read_image(layout.contact_sheet())
    assert sheet.ndim == 3 and sheet.shape[0] > 32


def test_resume_skips_done_frames_and_redoes_an_unfinished_one(tree, tmp_path, capsys):
    out = tmp_path / "out"
    assert fog(tree, out, "--levels", "0.03") == 0
    layout = DatasetLayout(out)
    mtime = os.path.getmtime(layout.image("beta0.03", FRAMES[0]))
    capsys.readouterr()
    assert fog(tree, out, "--levels", "0.03") == 0
    assert "fogged 0 of 2 images × 1 levels (2 already done" in capsys.readouterr().out
    assert os.path.getmtime(layout.image("beta0.03", FRAMES[0])) == mtime
    layout.meta(FRAMES[1]).unlink()  # images and labels written, meta not: unfinished
    assert fog(tree, out, "--levels", "0.03") == 0
    assert "fogged 1 of 2" in capsys.readouterr().out and layout.frame_done(FRAMES[1])
    assert fog(tree, out, "--levels", "0.03", "--min-pixels", "5") == 2  # other parameters: refused
    assert "fogsim_run.json" in capsys.readouterr().err


def test_shards_then_finalize_only_equal_one_run(tree, tmp_path, capsys):
    one, sharded = tmp_path / "one", tmp_path / "sharded"
    assert fog(tree, one, "--levels", "0.03,0.09") == 0
    for i in range(2):
        assert fog(tree, sharded, "--levels", "0.03,0.09", "--shard", f"{i}/2", "--workers", "2") == 0
        assert not (sharded / "coco").exists() and not (sharded / "dataset.json").exists()
    assert "--finalize-only --out" in capsys.readouterr().out
    assert main(["fog", "--finalize-only", "--out", str(sharded)]) == 0
    files = sorted(p.relative_to(one) for p in one.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(sharded) for p in sharded.rglob("*") if p.is_file())
    for rel in files:
        if rel.suffix == ".png":
            assert read_image(one / rel).tobytes() == read_image(sharded / rel).tobytes(), rel
        elif rel.name != "fogsim_run.json":
            a = (one / rel).read_text().replace(str(one.resolve()), "ROOT")
            assert a == (sharded / rel).read_text().replace(str(sharded.resolve()), "ROOT"), rel
    # re-split at finalize time
    assert main(["fog", "--finalize-only", "--out", str(sharded), "--train-fraction", "0.5"]) == 0
    assert read(sharded / "dataset.json")["split"]["train_fraction"] == 0.5


def test_no_labels_keeps_the_images_only_layout(tree, tmp_path):
    out = tmp_path / "out"
    assert fog(tree, out, "--levels", "0.03", "--no-labels") == 0
    rel = f"leftImg8bit/val/aachen/{BASES[0]}_leftImg8bit"
    assert (out / "beta0.03" / f"{rel}.png").is_file() and (out / "beta0.03" / f"{rel}.json").is_file()
    assert not any((out / d).exists() for d in ("images", "labels", "meta", "coco", "dataset.json"))
    assert "labels" not in read(out / "fogsim_run.json")["parameters"]
    assert main(["fog", "--finalize-only", "--out", str(out)]) == 2
    # a tree without gtFine: the same layout without asking
    bare = make_tree(tmp_path / "bare", gt=False)
    assert fog(bare, tmp_path / "o2", "--levels", "0.03") == 0
    assert (tmp_path / "o2" / "beta0.03" / f"{rel}.png").is_file()


def test_bad_label_input_fails_clearly_naming_the_file(tree, tmp_path, capsys):
    gt = tree / "gtFine" / "val" / "aachen"
    (gt / f"{BASES[1]}_gtFine_instanceIds.png").unlink()
    out = tmp_path / "out"
    assert fog(tree, out, "--levels", "0.03") == 1
    err = capsys.readouterr().err
    assert f"{BASES[1]}_gtFine_instanceIds.png: missing Cityscapes instance labels" in err
    assert "--no-labels" in err
    layout = DatasetLayout(out)
    assert layout.done_frames() == FRAMES[:1]
    assert not layout.image("beta0.03", FRAMES[1]).exists()  # nothing of the failed frame
    assert not list(out.rglob("*.part"))
    ids, _, _ = scene()
    write_image(gt / f"{BASES[1]}_gtFine_instanceIds.png", np.pad(ids, ((0, 2), (0, 0))))
    assert fog(tree, out, "--levels", "0.03") == 1
    assert "instanceIds is 64×34 but the image" in capsys.readouterr().err
    assert fog(tree, tmp_path / "jpg", "--levels", "0.03", "--format", "jpg") == 2
    assert "PNG images" in capsys.readouterr().err
    assert main(["fog", "--finalize-only", "--out", str(tmp_path / "nothing")]) == 2
    assert "not a fogsim fog output" in capsys.readouterr().err
    assert main(["fog", "--out", str(tmp_path / "x")]) == 2
    assert main(["fog", "--finalize-only", "--cityscapes", str(tree), "--out", str(out)]) == 2


# --- a Waymo-like dataset through a folder and a hand-written label reader -----------------------
WAYMO = ("vehicle", "pedestrian", "cyclist")


@dataclass(frozen=True)
class BoxReader:
    """Labels of one image from a list of (class, box, distance) — what a Waymo reader hands over."""

    boxes: tuple
    classes: tuple = WAYMO
    source: str = "labels.json"

    def __call__(self) -> Labels:
        objects = [{"class": c, "class_id": WAYMO.index(c), "bbox": list(b), "pixels": (b[2] - b[0]) * (b[3] - b[1]),
                    "kept": True, "reason": None, "distance_m": d,
                    "distance_source": "laser box centre" if d is not None else "unknown",
                    "difficulty": 1, "object_id": f"obj{i}"}
                   for i, (c, b, d) in enumerate(self.boxes)]
        return Labels(self.classes, objects)


def waymo_like(folder_dataset, boxes_by_key):
    samples = folder_samples(folder_dataset / "images", folder_dataset / "depth", DepthSpec("", kind="ray"))
    return [replace(s, key=f"ctx/{s.key.replace('/', '_')}_FRONT", labels=BoxReader(boxes_by_key[s.key]))
            for s in samples]


def test_waymo_like_labels_through_the_library(folder_dataset, tmp_path):
    boxes = {"a": (("vehicle", (1.5, 2.25, 10.0, 9.0), 31.2), ("pedestrian", (20, 5, 22, 12), None)),
             "sub/b": (("cyclist", (-0.4, 0, 4, 24.6), 12.0),)}  # within rounding of the edge: clamped
    samples = waymo_like(folder_dataset, boxes)
    out = tmp_path / "out"
    job = FogJob(tuple(parse_levels("0,0.05")), str(out), labels=True, classes=WAYMO, min_pixels=20,
                 inputs={"test": 1})
    summary = run(samples, job, workers=2, progress=False)
    assert summary.done == 2 and not summary.failed
    ds = finalize_dataset(out)
    assert ds["classes"] == list(WAYMO) and ds["counts"] == {"vehicle": 1, "pedestrian": 0, "cyclist": 1}
    assert ds["filtered"] == {"too few pixels (< 20)": 1}  # the 2×7 pedestrian, by --min-pixels
    layout = DatasetLayout(out)
    assert layout.done_frames() == ["ctx__a_FRONT", "ctx__sub_b_FRONT"]
    coco = json.loads(layout.coco("beta0.05").read_text())
    assert [c["name"] for c in coco["categories"]] == list(WAYMO)
    anns = {a["object_id"]: a for a in coco["annotations"] if a["image_id"] == 1}
    assert anns["obj0"]["bbox"] == [1.5, 2.25, 8.5, 6.75] and anns["obj0"]["distance_m"] == 31.2
    assert anns["obj0"]["difficulty"] == 1 and anns["obj0"]["distance_source"] == "laser box centre"
    assert anns["obj1"]["iscrowd"] == 1 and anns["obj1"]["distance_m"] is None
    b = [a for a in coco["annotations"] if a["image_id"] == 2][0]
    assert b["bbox"] == [0.0, 0.0, 4.0, 24.0] and b["category_id"] == 3
    assert layout.label("clear", "ctx__sub_b_FRONT").read_text() == "2 0.062500 0.500000 0.125000 1.000000\n"


def test_label_boxes_outside_the_image_and_wrong_classes_fail_their_sample(folder_dataset, tmp_path):
    boxes = {"a": (("vehicle", (0, 0, 40, 10), 5.0),),  # image is 32 wide
             "sub/b": (("vehicle", (0, 0, 4, 4), 5.0),)}
    samples = waymo_like(folder_dataset, boxes)
    samples[1] = replace(samples[1], labels=BoxReader(boxes["sub/b"], classes=("car",)))
    job = FogJob(tuple(parse_levels("0.05")), str(tmp_path / "out"), labels=True, classes=WAYMO)
    summary = run(samples, job, progress=False)
    errors = dict(summary.failed)
    assert len(errors) == 2
    assert "labels.json: annotation 0: box [0, 0, 40, 10] lies outside the 32×24 image" in errors[samples[0].source]
    assert "labels of classes ['car']" in errors[samples[1].source]
    assert DatasetLayout(tmp_path / "out").done_frames() == []
    assert not (tmp_path / "out" / "images").exists()


# --- fogsim study on the fogged Cityscapes dataset -------------------------------------------------
import importlib.util  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402

from fogsim.dataset.reader import dataset_classes, val_ground_truth  # noqa: E402
from fogsim.detection.class_map import BUILTIN, ClassMap, load_class_map, map_detections, map_ground_truth  # noqa: E402
from fogsim.detection.coco_eval import distance_coverage, ignore_policy  # noqa: E402
from fogsim.detection.study import Study, sim_class_map  # noqa: E402
from fogsim.detection.yolo import MIXED_MODEL, TrainConfig, training_view  # noqa: E402
from fogsim.scene.classes import LABELLED  # noqa: E402
from synthetic_dataset import make_dataset  # noqa: E402

STUDY_LEVELS = ["clear", "beta0.06"]


@pytest.fixture(scope="module")
def fogged(tmp_path_factory):
    """The two-frame Cityscapes tree fogged at clear and β = 0.06 into the dataset layout."""
    base = tmp_path_factory.mktemp("fogged")
    root = make_tree(base / "cs")
    out = base / "ds"
    assert main(["fog", "--cityscapes", str(root), "--split", "val", "--levels", "0,0.06", "--out", str(out),
                 "--quiet"]) == 0
    return out


def test_study_reads_the_class_list_from_the_dataset(fogged, tmp_path):
    assert dataset_classes(fogged) == list(CITYSCAPES_CLASSES)
    study = Study(fogged, tmp_path / "s", TrainConfig())
    assert study.levels == STUDY_LEVELS and study.classes == list(CITYSCAPES_CLASSES)
    data = training_view(fogged, tmp_path / "yolo", STUDY_LEVELS)
    text = data[MIXED_MODEL].read_text()
    assert '  0: "person"' in text and '  2: "car"' in text and "pedestrian" not in text
    manifest = fogged / "dataset.json"
    bad = json.loads(manifest.read_text())
    try:
        manifest.write_text(json.dumps(bad | {"classes": ["car", "car"]}))
        with pytest.raises(InputError, match=r"classes: must be distinct class names"):
            dataset_classes(fogged)
    finally:
        manifest.write_text(json.dumps(bad))


def test_unknown_distance_policies_and_their_counts(fogged):
    gt = val_ground_truth(fogged, "clear")
    cov = distance_coverage(gt, 100.0)
    # the validation frame: 2 cars, 1 person with a distance, 1 all-hole person; 2 ignore regions
    assert cov == {"objects": 4, "within": 3, "beyond": 0, "unknown": 1, "no_distance": 0, "ignore": 3, "count": 4,
                   "max_distance_m": 100.0}
    assert distance_coverage(gt, 12.0)["beyond"] == 2  # 15.3 m person and 23.4 m car
    crowd = {pol: sum(a["iscrowd"] for a in ignore_policy(gt, 100.0, pol)["annotations"])
             for pol in ("ignore", "count")}
    assert crowd == {"ignore": 3, "count": 2}
    with pytest.raises(ValueError, match="unknown_distance"):
        ignore_policy(gt, 100.0, "drop")


def test_class_maps():
    waymo = load_class_map("fogsim-to-waymo")
    assert set(waymo.mapping) == set(LABELLED) == set(BUILTIN["fogsim-to-cityscapes"].mapping)
    assert waymo.category_ids(LABELLED) == {1: 1, 2: 1, 3: 1, 4: 1, 5: 2, 6: 3, 7: None, 8: None}
    cs = BUILTIN["fogsim-to-cityscapes"]
    assert {c: cs.mapping[c] for c in ("car", "truck", "bus", "pedestrian", "cyclist")} == {
        "car": "car", "truck": "truck", "bus": "bus", "pedestrian": "person", "cyclist": "rider"}
    assert cs.reached() == ["person", "rider", "car", "truck", "bus"]
    dets = [{"image_id": 1, "category_id": c, "bbox": [0, 0, 1, 1], "score": 0.5} for c in (1, 5, 8)]
    assert [d["category_id"] for d in map_detections(dets, cs, LABELLED)] == [3, 1]  # car, person; sign dropped
    gt = {"images": [], "annotations": [dict(d, id=i) for i, d in enumerate(dets)], "categories": []}
    mapped = map_ground_truth(gt, waymo, LABELLED)
    assert [a["category_id"] for a in mapped["annotations"]] == [1, 2]
    assert [c["name"] for c in mapped["categories"]] == ["vehicle", "pedestrian", "cyclist"]
    inline = load_class_map('{"map": {"a": "x", "b": null}, "classes": ["x", "y"]}')
    assert inline == ClassMap("json", {"a": "x", "b": None}, ("x", "y"))
    assert load_class_map('{"a": "x", "c": "z"}').targets == ("x", "z")
    with pytest.raises(InputError, match="no entry in class map"):
        inline.check_source(["a", "c"], "ds")
    with pytest.raises(InputError, match="not a class map"):
        load_class_map("no-such-map")
    with pytest.raises(InputError, match="not readable as JSON"):
        load_class_map("{oops")
    with pytest.raises(InputError, match="not in its class list"):
        load_class_map('{"map": {"a": "x"}, "classes": ["y"]}')
    # sim → real: the identity, the built-in whose lists match, else ask for --class-map
    assert sim_class_map(None, ["a"], ["a"], "ds").name == "identity"
    assert sim_class_map(None, LABELLED, CITYSCAPES_CLASSES, "ds") is cs
    assert sim_class_map(None, LABELLED, WAYMO, "ds") is waymo
    with pytest.raises(InputError, match="give --class-map"):
        sim_class_map(None, LABELLED, ["thing"], "ds")
    with pytest.raises(InputError, match="maps to"):
        sim_class_map(waymo, LABELLED, CITYSCAPES_CLASSES, "ds")


def perfect(gt, score=0.9, ids=None):
    """A detection on every annotation (ignore regions too), category through ``ids`` if given."""
    return [{"image_id": a["image_id"], "category_id": (ids or {}).get(a["category_id"], a["category_id"]),
             "bbox": a["bbox"], "score": score} for a in gt["annotations"]]


def write_predictions(paths_and_dets):
    for path, dets in paths_and_dets:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(dets))


@pytest.mark.detect
def test_study_report_on_the_fogged_cityscapes_dataset(fogged, tmp_path):
    """Each level model finds every object of its own level; the report counts the all-hole
    person by --unknown-distance, in Cityscapes' classes."""
    pytest.importorskip("pycocotools")
    out = tmp_path / "study"
    study = Study(fogged, out, TrainConfig())
    gts = study.ground_truth()
    study.check_parameters(gts)
    write_predictions((study.prediction(m, lv), perfect(gts[lv]) if m in (lv, MIXED_MODEL) else [])
                      for m in study.models for lv in STUDY_LEVELS)
    table = study.report()
    for lv in STUDY_LEVELS:
        assert table["oracle"][lv]["objects"] == 3 and table["oracle"][lv]["ap50"] == pytest.approx(1.0)
        assert table[MIXED_MODEL][lv]["recall_max"] == pytest.approx(1.0)
    assert table["clear"]["beta0.06"]["recall_max"] == 0.0
    md = (out / "report" / "report.md").read_text()
    assert "`--unknown-distance ignore` evaluates 3 objects, `count` 4; this report: **ignore**" in md
    assert "Classes of the dataset: person, rider, car, truck, bus, train, motorcycle, bicycle." in md
    policy = json.loads((out / "report" / "distance_policy.json").read_text())
    assert policy["per_level"]["clear"]["unknown"] == 1 and policy["unknown_distance"] == "ignore"
    counted = Study(fogged, out, TrainConfig(), unknown_distance="count").report()
    assert counted["oracle"]["clear"]["objects"] == 4 and counted["oracle"]["clear"]["recall_max"] == 1.0
    # in another class list: persons and riders only (a JSON map)
    cmap = load_class_map(json.dumps({"map": {c: ("human" if c in ("person", "rider") else None)
                                              for c in CITYSCAPES_CLASSES}}))
    mapped = Study(fogged, out, TrainConfig(), class_map=cmap).report()
    assert mapped["oracle"]["clear"]["objects"] == 1  # the person with a distance
    assert "Evaluated through the class map `json` in the classes human." in (out / "report" / "report.md").read_text()


@pytest.mark.detect
def test_sim_to_real_rows(fogged, tmp_path):
    """Models of a rendered dataset (fogsim's classes) on the fogged Cityscapes levels: the
    built-in fogsim-to-cityscapes map, rows 'sim <model>', every row on the classes it reaches."""
    pytest.importorskip("pycocotools")
    sim_ds = make_dataset(tmp_path / "sim", frames=4)
    out = tmp_path / "study"
    study = Study(fogged, out, TrainConfig(), sim_dataset=sim_ds)
    assert study.sim_map.name == "fogsim-to-cityscapes"
    gts = study.ground_truth()
    study.check_parameters(gts)
    write_predictions((study.prediction(m, lv), perfect(gts[lv])) for m in study.models for lv in STUDY_LEVELS)
    to_fogsim = {1: 5, 3: 1}  # Cityscapes person → fogsim pedestrian, car → car (the models' ids)
    write_predictions((study.sim_prediction(m, lv), perfect(gts[lv], 0.8, to_fogsim) if m == MIXED_MODEL else [])
                      for m in study.sim.models for lv in STUDY_LEVELS)
    with pytest.raises(InputError, match="prediction files are missing"):
        Study(fogged, tmp_path / "other", TrainConfig(), sim_dataset=sim_ds).report()
    table = study.report()
    assert set(table) >= {f"sim {m}" for m in study.sim.models}
    for lv in STUDY_LEVELS:
        assert table[f"sim {MIXED_MODEL}"][lv]["ap50"] == pytest.approx(1.0)
        assert table["sim clear"][lv]["recall_max"] == 0.0
        assert table["oracle"][lv]["ap50"] == pytest.approx(1.0)
    md = (out / "report" / "report.md").read_text()
    assert "| sim mixed |" in md and "mapped by `fogsim-to-cityscapes`" in md
    assert "person, rider, car, truck, bus." in md
    assert (out / "report" / "recall_heatmap.png").stat().st_size > 0
    with pytest.raises(InputError, match="is the --dataset itself"):
        Study(fogged, tmp_path / "x", TrainConfig(), sim_dataset=fogged)


@pytest.mark.detect
@pytest.mark.slow
def test_tiny_training_on_the_fogged_cityscapes_dataset(fogged, tmp_path):
    if importlib.util.find_spec("ultralytics") is None or importlib.util.find_spec("pycocotools") is None:
        pytest.skip("the 'detect' extra (Ultralytics, pycocotools) is not installed")
    out = tmp_path / "study"
    r = subprocess.run([sys.executable, "-m", "fogsim", "study", "--dataset", str(fogged), "--out", str(out),
                        "--epochs", "1", "--imgsz", "64", "--batch", "2", "--workers", "0", "--device", "cpu",
                        "--no-plots", "--quiet"], capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    # --quiet: the summary line only; the table is in the report
    assert r.stdout.startswith("report: ") and "**recall**" in (out / "report" / "cross_density.md").read_text()
    for m in (*STUDY_LEVELS, MIXED_MODEL):
        assert (out / "runs" / m / "fogsim_done.json").is_file()
    assert '  7: "bicycle"' in (out / "yolo" / "clear" / "data.yaml").read_text()
    table = json.loads((out / "report" / "cross_density.json").read_text())
    assert table["oracle"]["clear"]["objects"] == 3 and table["oracle"]["clear"]["unknown_distance"] == "ignore"
    # the same study with a sim-to-real row: only the rendered dataset's models are trained now
    done = {m: (out / "runs" / m / "fogsim_done.json").stat().st_mtime for m in (*STUDY_LEVELS, MIXED_MODEL)}
    sim = make_dataset(tmp_path / "sim", frames=4)
    r = subprocess.run([sys.executable, "-m", "fogsim", "study", "--dataset", str(fogged), "--out", str(out),
                        "--sim-dataset", str(sim), "--epochs", "1", "--imgsz", "64", "--batch", "2", "--workers", "0",
                        "--device", "cpu", "--no-plots", "--quiet"], capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    assert {m: (out / "runs" / m / "fogsim_done.json").stat().st_mtime for m in done} == done
    table_md = (out / "report" / "cross_density.md").read_text()
    assert "| sim mixed |" in table_md and "| sim beta0.12 |" in table_md
    for m in ("clear", "beta0.12", MIXED_MODEL):
        assert (out / "sim_to_real" / "study" / "runs" / m / "fogsim_done.json").is_file()
        dets = json.loads((out / "sim_to_real" / "predictions" / m / "beta0.06.json").read_text())
        assert all(1 <= d["category_id"] <= len(LABELLED) for d in dets)  # the rendered classes, as predicted


def test_split_by_folder_keeps_each_sequence_on_one_side(folder_dataset, tmp_path):
    from fogsim.dataset.writer import split_frames

    frames = [f"seg{g:02d}__{t:04d}_FRONT" for g in range(20) for t in range(5)]
    groups = {f: f.split("__")[0] for f in frames}
    train, val = split_frames(frames, 0.7, 0, groups)
    assert train and val and sorted(train + val) == sorted(frames)
    assert not {groups[f] for f in train} & {groups[f] for f in val}
    assert (train, val) == split_frames(list(reversed(frames)), 0.7, 0, groups)
    assert split_frames(frames, 0.7) != (train, val)  # by frame, sequences straddle the cut
    one = {f: "same" for f in frames}
    assert split_frames(frames, 0.7, 0, one) == split_frames(frames, 0.7)  # one group: by frame
    # every group on the train side: the group nearest the cut moves to val, whole
    two = frames[:10]
    t, v = split_frames(two, 0.999, 0, groups)
    assert len(v) == 5 and len({groups[f] for f in v}) == 1 and len(t) == 5
    # through fogsim fog's finalize: the sample key's folder is the group
    boxes = {"a": (("vehicle", (1, 1, 9, 9), 10.0),), "sub/b": (("vehicle", (1, 1, 9, 9), 10.0),)}
    samples = [replace(s, key=f"seg_{s.key.replace('/', '_')}/{i:04d}_FRONT") for i, s in
               enumerate(waymo_like(folder_dataset, boxes))]
    out = tmp_path / "out"
    job = FogJob(tuple(parse_levels("0")), str(out), labels=True, classes=WAYMO)
    assert run(samples, job, progress=False).done == 2
    ds = finalize_dataset(out, 0.5, "folder")
    assert ds["split"]["groups"] == 2 and "group = the sample key's folder" in ds["split"]["rule"]
    with pytest.raises(ValueError, match="--split-by"):
        finalize_dataset(out, 0.5, "segment")


def test_split_by_is_recorded_and_used_by_finalize_only(tree, tmp_path):
    out = tmp_path / "out"
    make_tree(tree, "train")  # a second folder of samples: leftImg8bit/train/aachen
    assert main(["fog", "--cityscapes", str(tree), "--split", "val,train", "--out", str(out), "--quiet",
                 "--levels", "0", "--split-by", "folder"]) == 0
    assert read(out / "fogsim_run.json")["parameters"]["inputs"]["split_by"] == "folder"
    ds = read(out / "dataset.json")
    assert ds["split"]["groups"] == 2 and ds["split"]["train"] == ds["split"]["val"] == 2
    for part in ("train", "val"):
        names = [Path(p).stem for p in (out / "splits" / f"clear_{part}.txt").read_text().split()]
        assert len({n.split("__")[1] for n in names}) == 1  # one Cityscapes split on each side
    assert main(["fog", "--finalize-only", "--out", str(out), "--split-by", "frame"]) == 0
    assert "groups" not in read(out / "dataset.json")["split"]


def test_real_dataset_objects_get_box_based_visibility_per_level(tmp_path):
    """A black box on grey at 10 m stays visible in every fog level; the same box at 40 m is
    beyond the visibility ln(20)/0.12 ≈ 25 m and is flagged invisible there (contrast < 5 %),
    in the meta and in that level's COCO file; numbers checked against Koschmieder by hand."""
    from fogsim.colour import srgb_to_linear
    from fogsim.io.depth_files import write_depth

    img = np.full((48, 64, 3), 128, np.uint8)
    img[16:32, 24:40] = 0
    for name, d in (("near", 10.0), ("far", 40.0)):
        write_image(tmp_path / "images" / f"{name}.png", img)
        write_depth(tmp_path / "depth" / f"{name}.exr", np.full((48, 64), d, np.float32))
    samples = folder_samples(tmp_path / "images", tmp_path / "depth", DepthSpec("", kind="ray"))
    d_of = {"near": 10.0, "far": 40.0}
    samples = [replace(s, labels=BoxReader((("vehicle", (24, 16, 40, 32), d_of[s.key]),))) for s in samples]
    out = tmp_path / "out"
    job = FogJob(tuple(parse_levels("0,0.12")), str(out), labels=True, classes=WAYMO, inputs={"test": 2})
    assert not run(samples, job, progress=False).failed
    finalize_dataset(out)
    layout = DatasetLayout(out)

    def lum(v):  # grey value → linear luminance
        return float(srgb_to_linear(np.float32(v) / 255))

    for name, d in d_of.items():
        (obj,) = read(layout.meta(frame_from_key(name)))["objects"]
        t = np.exp(-0.12 * d)
        box, ring = round(0 * t + 255 * (1 - t)), round(128 * t + 255 * (1 - t))  # Koschmieder, sRGB blend
        fog = obj["visibility"]["beta0.12"]
        assert fog["transmission"] == pytest.approx(t, rel=1e-3)
        assert fog["contrast"] == pytest.approx(abs(lum(box) - lum(ring)) / lum(ring), abs=2e-3)
        assert obj["visibility"]["clear"]["contrast"] == pytest.approx(1.0, abs=1e-3)
        assert obj["visibility"]["clear"]["visible"] is True
        assert fog["visible"] is (name == "near")
    coco = read(layout.coco("beta0.12"))
    by_image = {im["frame"]: im["id"] for im in coco["images"]}
    vis = {a["image_id"]: a["visible"] for a in coco["annotations"]}
    assert vis[by_image["near"]] is True and vis[by_image["far"]] is False
