"""Hostile copies of fogsim's own documents through the command line (issue 18, the schema cases):
damaged or stray ``meta/*.json`` and ``fogsim_run.json`` of a labelled run (finalize and resume),
a damaged study folder (``study.json``, predictions, ``fogsim_done.json``), the dataset's
``dataset.json`` and COCO files as a study reads them, ``--class-map`` and LiDAR hold-out files.

Each case checks what a user relies on: the exit code (2: a run-wide document is wrong; 1: a
per-frame one, skipped and named), one line naming the file or flag, no traceback, every
input (and the damaged document itself) byte-identical, no partial file, and nothing written
on an exit-2 error (no report, no dataset files rewritten).
"""
from __future__ import annotations

import hashlib
import json
import shutil
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from cityscapes_tree import make_tree
from conftest import tree_digest
from fogsim.cli import main
from fogsim.io.depth_files import write_depth
from fogsim.io.parts import PART_SUFFIX


# ----------------------------------------------------------------------------- inputs
def labelled_run(tmp: Path) -> Path:
    """A finished labelled run: the two-frame Cityscapes tree (tmp/in/cs) fogged into tmp/out."""
    cs = make_tree(tmp / "in" / "cs")
    out = tmp / "out"
    assert main(fog_cs(cs, out)) == 0
    return out


def fog_cs(cs: Path, out: Path) -> list[str]:
    return ["fog", "--cityscapes", str(cs), "--split", "val", "--levels", "0,0.06", "--out", str(out), "--quiet"]


def a_meta(out: Path) -> Path:
    return sorted((out / "meta").glob("*.json"))[0]


def study_folder(tmp: Path) -> tuple[Path, Path]:
    """A fogged dataset (tmp/in/ds) and a study on it (tmp/out) whose predictions are all written
    (so --report-only runs)."""
    from fogsim.detection.study import Study
    from fogsim.detection.yolo import TrainConfig

    ds = labelled_run(tmp)
    shutil.move(str(ds), tmp / "in" / "ds")
    ds = tmp / "in" / "ds"
    study = Study(ds, tmp / "out", TrainConfig())
    gts = study.ground_truth()
    study.check_parameters(gts)
    for m in study.models:
        for lv in study.levels:
            dets = [{"image_id": a["image_id"], "category_id": a["category_id"], "bbox": a["bbox"], "score": 0.9}
                    for a in gts[lv]["annotations"]]
            path = study.prediction(m, lv)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(dets))
    return ds, tmp / "out"


def report_only(ds: Path, s: Path, *extra: str) -> list[str]:
    return ["study", "--dataset", str(ds), "--out", str(s), "--report-only", "--quiet", *extra]


def edit_json(path: Path, change: Callable):
    data = json.loads(path.read_text())
    new = change(data)
    path.write_text(json.dumps(data if new is None else new))


@dataclass
class Case:
    """``build(tmp) -> (argv, documents)``: the run must exit ``code`` and print every string of
    ``says`` (``{tmp}`` → the case's folder); ``documents``: files (the damaged one among them)
    that must be byte-identical afterwards. ``marks``: pytest marks (e.g. detect)."""

    id: str
    build: Callable[[Path], tuple[list[str], list[Path]]]
    code: int
    says: tuple[str, ...]
    marks: tuple = field(default=())


# --- a labelled run's meta files and run file (T1) ----------------------------------------------
def _finalize_meta(damage: Callable[[Path], Path], resume: bool = False):
    def build(tmp):
        out = labelled_run(tmp)
        damaged = damage(out)
        argv = fog_cs(tmp / "in" / "cs", out) if resume else ["fog", "--finalize-only", "--out", str(out), "--quiet"]
        return argv, [damaged]
    return build


def _meta_is(text: str):
    def damage(out):
        p = a_meta(out)
        p.write_text(text)
        return p
    return damage


def _meta_edit(change):
    def damage(out):
        p = a_meta(out)
        edit_json(p, change)
        return p
    return damage


def _stray(name: str, text: str):
    def damage(out):
        p = out / "meta" / name
        p.write_text(text)
        return p
    return damage


def _copied_meta(out):
    p = out / "meta" / "copy.json"
    shutil.copyfile(a_meta(out), p)
    return p


def _run_file(change):
    def build(tmp):
        out = labelled_run(tmp)
        path = out / "fogsim_run.json"
        if isinstance(change, str):
            path.write_text(change)
        else:
            edit_json(path, change)
        return ["fog", "--finalize-only", "--out", str(out), "--quiet"], [path, out / "dataset.json"]
    return build


def _resume_run_file(text: str):
    def build(tmp):
        out = labelled_run(tmp)
        (out / "fogsim_run.json").write_text(text)
        return fog_cs(tmp / "in" / "cs", out), [out / "fogsim_run.json"]
    return build


def _set(path: list, value):
    def change(d):
        for k in path[:-1]:
            d = d[k]
        d[path[-1]] = value
    return change


def _drop(path: list):
    def change(d):
        for k in path[:-1]:
            d = d[k]
        del d[path[-1]]
    return change


RUN_CASES = [
    Case("finalize-meta-list", _finalize_meta(_meta_is("[]")), 1, ("meta/", "must be a JSON object", "skipped")),
    Case("finalize-meta-no-objects", _finalize_meta(_meta_edit(_drop(["objects"]))), 1, ("meta/", "lacks 'objects'")),
    Case("finalize-meta-stray-empty", _finalize_meta(_stray("notes.json", "{}")), 1, ("notes.json", "lacks")),
    Case("finalize-meta-stray-copy", _finalize_meta(_copied_meta), 1, ("copy.json", "not this file's 'copy'")),
    Case("finalize-meta-bbox-string", _finalize_meta(_meta_edit(_set(["objects", 0, "bbox"], "1 2 3 4"))), 1,
         ("meta/", "objects[0].bbox: must be a list")),
    Case("finalize-meta-width-string", _finalize_meta(_meta_edit(_set(["width"], "64"))), 1,
         ("meta/", "width: must be an integer")),
    Case("finalize-meta-not-json", _finalize_meta(_meta_is("{oops")), 1, ("meta/", "not readable as JSON")),
    Case("finalize-meta-kept-string", _finalize_meta(_meta_edit(_set(["objects", 0, "kept"], "yes"))), 1,
         ("meta/", "objects[0].kept: must be true or false")),
    Case("resume-after-meta-damage", _finalize_meta(_meta_is("[]"), resume=True), 1, ("meta/", "skipped")),
    Case("resume-stray-meta", _finalize_meta(_stray("notes.json", "{}"), resume=True), 1, ("notes.json",)),
    Case("finalize-runfile-list", _run_file("[]"), 2, ("fogsim_run.json", "must be a JSON object")),
    Case("finalize-runfile-no-levels", _run_file(_drop(["parameters", "levels"])), 2,
         ("fogsim_run.json", "parameters: lacks 'levels'")),
    Case("finalize-runfile-classes-int", _run_file(_set(["parameters", "labels", "classes"], 5)), 2,
         ("fogsim_run.json", "parameters.labels.classes: must be a list")),
    Case("finalize-runfile-beta-string", _run_file(_set(["parameters", "levels", 0, "beta"], "0.06")), 2,
         ("fogsim_run.json", "parameters.levels[0].beta: must be a finite number")),
    Case("finalize-runfile-not-json", _run_file("{oops"), 2, ("fogsim_run.json", "not readable as JSON")),
    Case("resume-runfile-list", _resume_run_file("[]"), 2,
         ("fogsim_run.json", "malformed run file: must be a JSON object")),
    Case("finalize-runfile-inputs-list", _run_file(_set(["parameters", "inputs"], [])), 2,
         ("fogsim_run.json", "parameters.inputs")),
]


# --- a study folder and the dataset files it reads (T2, T12, T5) --------------------------------
def _study(change: Callable[[Path, Path], Path | None], *extra: str):
    def build(tmp):
        ds, s = study_folder(tmp)
        damaged = change(ds, s)
        return report_only(ds, s, *extra), [damaged] if damaged else []
    return build


def _study_json(change):
    def c(ds, s):
        p = s / "study.json"
        edit_json(p, change) if callable(change) else p.write_text(change)
        return p
    return c


def _prediction(change):
    def c(ds, s):
        p = s / "predictions" / "mixed" / "beta0.06.json"
        edit_json(p, change) if callable(change) else p.write_text(change)
        return p
    return c


def _dataset_file(rel: str, change):
    def c(ds, s):
        p = ds / rel
        edit_json(p, change)
        return p
    return c


def _first_bbox_str(d):
    d[0]["bbox"] = "1 2 3 4"


def _coco_images(key, value):
    def change(d):
        for im in d["images"]:
            im[key] = value(im) if callable(value) else value
    return change


def _done_file(text):
    def c(ds, s):
        p = s / "runs" / "mixed" / "fogsim_done.json"
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
        return p
    return c


def _class_map_file(data):
    def c(ds, s):
        p = ds.parent / "cmap.json"
        p.write_text(json.dumps(data))
        return p
    return c


def _class_map_arg(tmp_rel: str):
    def build(tmp):
        argv, docs = _study(_class_map_file({"map": {"person": "human"}, "classes": 5}))(tmp)
        return argv + ["--class-map", str(tmp / tmp_rel)], docs
    return build


D = ("detect",)
STUDY_CASES = [
    Case("report-studyjson-list", _study(_study_json("[]")), 2, ("study.json", "must be a JSON object"), D),
    Case("report-studyjson-no-train", _study(_study_json(_drop(["parameters", "train"]))), 2,
         ("study.json", "parameters: lacks 'train'"), D),
    Case("report-studyjson-train-extra-key", _study(_study_json(_set(["parameters", "train", "lr"], 0.1))), 2,
         ("study.json", "parameters.train: unknown key ['lr']"), D),
    Case("report-studyjson-epochs-string", _study(_study_json(_set(["parameters", "train", "epochs"], "20"))), 2,
         ("study.json", "parameters.train.epochs: must be an integer"), D),
    Case("report-pred-dict", _study(_prediction('{"detections": []}')), 2,
         ("predictions/mixed/beta0.06.json", "must be a list"), D),
    Case("report-pred-bbox-string", _study(_prediction(_first_bbox_str)), 2,
         ("predictions/mixed/beta0.06.json", "[0].bbox: must be a list"), D),
    Case("report-pred-score-nan", _study(_prediction("[{\"image_id\": 1, \"category_id\": 3, "
                                                     "\"bbox\": [1, 2, 3, 4], \"score\": NaN}]")), 2,
         ("predictions/mixed/beta0.06.json", "[0].score"), D),
    Case("report-done-file-list", _study(_done_file("[]")), 2, ("fogsim_done.json", "must be a JSON object"), D),
    Case("report-coco-bbox-string", _study(_dataset_file("coco/beta0.06.json",
                                                         lambda d: d["annotations"][0].update(bbox="1 2 3 4"))), 2,
         ("coco/beta0.06.json", "annotations[0].bbox: must be a list"), D),
    Case("report-coco-abspath", _study(_dataset_file("coco/beta0.06.json",
                                                     _coco_images("file_name", "/etc/passwd"))), 2,
         ("coco/beta0.06.json", "file_name: must be a path inside the dataset"), D),
    Case("report-coco-dotdot", _study(_dataset_file("coco/clear.json",
                                                    _coco_images("file_name", lambda im: "../" + im["file_name"]))),
         2, ("coco/clear.json", "must be a path inside the dataset"), D),
    Case("report-coco-images-dict", _study(_dataset_file("coco/clear.json", lambda d: d.update(images={}))), 2,
         ("coco/clear.json", "images: must be a list"), D),
    Case("report-manifest-classes-int", _study(_dataset_file("dataset.json", lambda d: d.update(classes=5))), 2,
         ("dataset.json", "classes: must be a list"), D),
    Case("report-manifest-level-path", _study(_dataset_file("dataset.json",
                                                           lambda d: d["levels"][0].update(key="../x"))), 2,
         ("dataset.json", "levels[0].key: must be a folder name"), D),
    Case("report-manifest-levels-twice", _study(_dataset_file(
        "dataset.json", lambda d: d.update(levels=[d["levels"][0], d["levels"][0]]))), 2,
         ("dataset.json", "levels: must be distinct level keys"), D),
    Case("report-classmap-text-classes-int", _study(lambda ds, s: None, "--class-map",
                                                    '{"map": {"person": "human"}, "classes": 5}'), 2,
         ("--class-map", "classes: must be a list"), D),
    Case("report-classmap-file-classes-int", _class_map_arg("in/cmap.json"), 2,
         ("cmap.json", "classes: must be a list"), D),
    Case("report-classmap-map-list", _study(lambda ds, s: None, "--class-map", '{"map": ["person"]}'), 2,
         ("--class-map", "map: must be a JSON object"), D),
    Case("report-classmap-target-int", _study(lambda ds, s: None, "--class-map", '{"person": 3}'), 2,
         ("--class-map", "map.person"), D),
]


# --- LiDAR hold-out files (T3) -------------------------------------------------------------------
def _holdout(change: Callable[[Path], None]):
    def build(tmp):
        h, pred = tmp / "in" / "h" / "lidar_holdout" / "ctx", tmp / "in" / "pred" / "ctx"
        h.mkdir(parents=True)
        fields = {"u": np.array([3.5, 10.5], np.float32), "v": np.array([2.5, 5.5], np.float32),
                  "ray": np.array([10.0, 20.0], np.float32), "width": np.int64(16), "height": np.int64(8)}
        np.savez(h / "1000_FRONT.npz", **fields)
        write_depth(pred / "1000_FRONT.exr", np.full((8, 16), 12.0, np.float32))
        change(h / "1000_FRONT.npz")
        argv = ["depth", "score", "--pred", str(tmp / "in" / "pred"), "--pred-kind", "ray", "--holdout",
                str(tmp / "in" / "h"), "--out", str(tmp / "out")]
        return argv, [h / "1000_FRONT.npz"]
    return build


def _resave(**changes):
    def change(path):
        with np.load(path) as z:
            fields = {k: z[k] for k in z.files}
        fields.update(changes)
        fields = {k: v for k, v in fields.items() if v is not None}
        np.savez(path, **fields)
    return change


def _truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2])


def _pickled(path):
    buf = path.with_suffix(".npy")
    np.save(buf, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with zipfile.ZipFile(path, "w") as z:
        z.write(buf, "u.npy")
    buf.unlink()


HOLDOUT_CASES = [
    Case("holdout-truncated", _holdout(_truncate), 2, ("1000_FRONT.npz", "not a readable .npz")),
    Case("holdout-not-zip", _holdout(lambda p: p.write_bytes(b"P6 not an npz at all")), 2,
         ("1000_FRONT.npz", "not a zip file")),
    Case("holdout-width-array", _holdout(_resave(width=np.array([16, 16]))), 2,
         ("1000_FRONT.npz", "width: must be one integer")),
    Case("holdout-width-string", _holdout(_resave(width=np.array("wide"))), 2,
         ("1000_FRONT.npz", "width: must be one integer")),
    Case("holdout-u-string", _holdout(_resave(u=np.array(["a", "b"]))), 2,
         ("1000_FRONT.npz", "u: must be an array of numbers")),
    Case("holdout-no-ray", _holdout(_resave(ray=None)), 2, ("1000_FRONT.npz", "lacks 'ray'")),
    Case("holdout-ray-nan", _holdout(_resave(ray=np.array([np.nan, 1.0], np.float32))), 2,
         ("1000_FRONT.npz", "ray: must hold finite numbers")),
    Case("holdout-pickled", _holdout(_pickled), 2, ("1000_FRONT.npz", "pickled")),
]

CASES = RUN_CASES + STUDY_CASES + HOLDOUT_CASES


def _digests(paths: list[Path]) -> dict:
    return {p: hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else None for p in paths}


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id, marks=[getattr(pytest.mark, m) for m in c.marks])
                                  for c in CASES])
def test_hostile_document(case: Case, tmp_path, capsys, monkeypatch):
    if "detect" in case.marks:
        pytest.importorskip("pycocotools")
    monkeypatch.chdir(tmp_path)
    argv, documents = case.build(tmp_path)
    documents = [tmp_path / "in"] + documents
    files = [d for d in documents if d.is_file()]
    before_in, before_docs = tree_digest(tmp_path / "in"), _digests(files)
    listing = {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*") if p.is_file()}
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == case.code, err
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err  # one line: the error, or the one skipped frame
    for text in case.says:
        assert text.replace("{tmp}", str(tmp_path)) in err, err
    assert tree_digest(tmp_path / "in") == before_in, "an input changed"
    assert _digests(files) == before_docs, "the damaged document was rewritten"
    left = list(tmp_path.rglob(f"*{PART_SUFFIX}")) + [p for p in tmp_path.rglob("*")
                                                       if p.is_file() and p.stat().st_size == 0]
    assert not left, f"partial files left: {left}"
    if case.code == 2:  # a run-wide problem: nothing written, nothing rewritten
        now = {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*") if p.is_file()}
        assert now == listing, sorted(set(now.items()) ^ set(listing.items()))


def test_at_least_thirty_document_cases():
    ids = [c.id for c in CASES]
    assert len(ids) >= 30 and len(set(ids)) == len(ids)


def test_a_good_study_folder_and_holdout_pass_the_same_checks(tmp_path, capsys):
    """The harness itself: the unharmed documents give exit 0 (so each case fails for its damage)."""
    out = labelled_run(tmp_path / "a")
    assert main(["fog", "--finalize-only", "--out", str(out), "--quiet"]) == 0
    argv, _ = _holdout(lambda p: None)(tmp_path / "b")
    assert main(argv) == 0
    if pytest.importorskip("pycocotools"):
        ds, s = study_folder(tmp_path / "c")
        assert main(report_only(ds, s)) == 0, capsys.readouterr().err


def test_fog_finalize_only_says_how_many_samples_have_no_frame(tmp_path, capsys):
    """Also seen in the trial: --finalize-only after only some shards wrote a partial dataset
    without a word. The run file records how many samples the run has; finalize says how many
    of them have no frame yet."""
    cs = make_tree(tmp_path / "in" / "cs")
    out = tmp_path / "out"
    assert main(fog_cs(cs, out) + ["--shard", "0/2"]) == 0
    assert json.loads((out / "fogsim_run.json").read_text())["samples"] == 2
    capsys.readouterr()
    assert main(["fog", "--finalize-only", "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "dataset: 1 frame, in both train and val" in said, said
    assert "1 of the run's samples have no frame yet" in said, said
    assert main(fog_cs(cs, out) + ["--shard", "1/2"]) == 0
    capsys.readouterr()
    assert main(["fog", "--finalize-only", "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "dataset: 2 frames" in said and "no frame yet" not in said, said
