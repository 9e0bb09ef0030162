"""Every reader of a fogsim document, walked with the shapes the third reliability trial used: a
list for the object (or an object for the list), each declared key missing, each declared key of
the wrong type (one level into lists of records too), and a stray file. Each must raise one
:class:`~fogsim.errors.InputError` line naming the file and the field — no other exception.

The mutations come from the document's own model (:mod:`fogsim.schema.documents`), so a field
added to a model is walked by construction.
"""
from __future__ import annotations

import json
import shutil
import typing
from pathlib import Path

import numpy as np
import pytest
from pydantic import BaseModel

from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.reader import dataset_levels, frame_records, read_checked_meta, val_ground_truth
from fogsim.depth.lidar_source import read_holdout
from fogsim.detection.class_map import load_class_map
from fogsim.errors import InputError
from fogsim.fog.batch import finalize_dataset
from fogsim.schema import documents as docs
from test_fog_physics_bench import bench_dir  # noqa: F401  (the fixture: three small committed runs)

META = {"frame": "000000", "width": 64, "height": 32, "key": "a/b",
        "objects": [{"class": "car", "class_id": 0, "bbox": [1, 2, 10, 12], "pixels": 90, "kept": True,
                     "reason": None, "distance_m": 12.5}]}
RUN = {"fogsim_version": "0", "samples": 1, "parameters": {
    "levels": [{"key": "clear", "name": "clear", "beta": 0.0}], "labels": {"classes": ["car"], "min_pixels": 0},
    "inputs": {}, "seed": 0}}
MANIFEST = {"levels": [{"key": "clear"}], "classes": ["car"]}
COCO = {"images": [{"id": 1, "file_name": "images/clear/000000.png", "width": 64, "height": 32}],
        "annotations": [{"image_id": 1, "category_id": 1, "bbox": [1, 2, 9, 10], "iscrowd": 0}]}
PREDICTIONS = [{"image_id": 1, "category_id": 1, "bbox": [1, 2, 9, 10], "score": 0.5}]
CLASS_MAP = {"map": {"car": "vehicle"}, "classes": ["vehicle"]}


def _write(path: Path, doc) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc))
    return path


def _read_meta(root: Path, doc):
    _write(root / "meta" / "000000.json", doc)
    return read_checked_meta(root, "000000", docs.FogFrameMeta), root / "meta" / "000000.json"


def _read_run(root: Path, doc):
    return finalize_dataset(_write(root / "fogsim_run.json", doc).parent), root / "fogsim_run.json"


def _read_manifest(root: Path, doc):
    return dataset_levels(_write(root / "dataset.json", doc).parent), root / "dataset.json"


def _read_coco(root: Path, doc):
    _write(root / "dataset.json", MANIFEST)
    (root / "splits").mkdir(parents=True, exist_ok=True)
    (root / "splits" / "clear_val.txt").write_text("/x/images/clear/000000.png\n")
    return val_ground_truth(_write(root / "coco" / "clear.json", doc).parents[1], "clear"), root / "coco" / "clear.json"


def _read_predictions(root: Path, doc):
    from fogsim.detection.study import read_predictions

    return read_predictions(_write(root / "pred.json", doc)), root / "pred.json"


def _read_class_map(root: Path, doc):
    return load_class_map(str(_write(root / "cmap.json", doc))), root / "cmap.json"


def _study(root: Path):
    """A study on a small synthetic dataset (its study.json written as a study writes it)."""
    from fogsim.detection.study import Study
    from fogsim.detection.yolo import TrainConfig
    from synthetic_dataset import make_dataset

    study = Study(make_dataset(root / "ds", frames=2), root / "s", TrainConfig())
    gts = study.ground_truth()
    study.check_parameters(gts)
    return study, gts


def _good_study_file() -> dict:
    from dataclasses import asdict

    from fogsim.detection.yolo import TrainConfig

    return {"fogsim_version": "0", "parameters": {"dataset": "/x", "levels": ["clear"],
                                                  "validation_images_sha256": "0" * 64, "train": asdict(TrainConfig())}}


def _read_study_file(root: Path, doc):
    study, gts = _study(root)
    path = study.files.study_file()
    if doc is not STUDY:  # the good walk reads the study's own file (its dataset is this one)
        _write(path, doc)
    return study.stored_config(gts), path


def _read_done_file(root: Path, doc):
    from fogsim.detection.yolo import MIXED_MODEL

    study, _ = _study(root)
    path = study.files.run_done(MIXED_MODEL)
    _write(path, doc)
    return study.training_records(), path


def _read_frame_camera(root: Path, doc):
    from fogsim.depth.score import score_dataset
    from fogsim.io.depth_files import write_depth

    depth = np.full((8, 12), 10.0, np.float32)
    write_depth(root / "ds" / "depth" / "000000.exr", depth)
    write_depth(root / "pred" / "000000.exr", depth)
    path = _write(root / "ds" / "meta" / "000000.json", doc)
    return score_dataset(root / "pred", root / "ds", "ray"), path


FRAME_CAMERA = {"frame": "000000", "camera": {"intrinsics": {"fx": 10.0, "fy": 10.0, "cx": 5.5, "cy": 3.5,
                                                              "width": 12, "height": 8}}}
STUDY = _good_study_file()
DONE = {"model": "mixed", "state": "trained", "seconds_this_run": 12.5}

#: (document, its model, a good copy, the reader: (folder, document) → (result, the file it read))
READERS = [
    ("frame record", docs.FogFrameMeta, META, _read_meta),
    ("fog run file", docs.FogRunFile, RUN, _read_run),
    ("dataset manifest", docs.DatasetManifest, MANIFEST, _read_manifest),
    ("COCO file", docs.CocoFile, COCO, _read_coco),
    ("prediction file", docs.Predictions, PREDICTIONS, _read_predictions),
    ("class map", docs.ClassMapFile, CLASS_MAP, _read_class_map),
    ("frame camera (depth score)", docs.FrameCamera, FRAME_CAMERA, _read_frame_camera),
    ("study file", docs.StudyFile, STUDY, _read_study_file),
    ("training record", docs.DoneFile, DONE, _read_done_file),
]


def _models_in(annotation) -> list[type[BaseModel]]:
    """The pydantic models a field's annotation holds (list[Model], Model | None, Annotated …)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models_in(arg)]


def _wrong(value):
    """A value of another JSON type than ``value``."""
    if isinstance(value, bool):
        return "yes"
    if isinstance(value, (int, float)):
        return "5"
    if isinstance(value, str):
        return 5
    if value is None:
        return [5]  # neither a number nor a string
    return "x"  # a list or an object → a string


def _fields(model: type[BaseModel]) -> dict:
    return {(f.alias or name): f for name, f in model.model_fields.items()}


def mutations(model: type[BaseModel], doc, path: str = ""):
    """(label, the changed document, the field path the message must name) of ``doc``."""
    if issubclass(model, typing.cast(type, docs.Predictions)):  # a list document: walk its first record
        yield "object for the list", {"records": doc}, ""
        for label, item, where in mutations(docs.Detection, doc[0], "[0]"):
            yield label, [item, *doc[1:]], where
        return
    if not path:
        yield "list for the object", [doc], ""
    for key, f in _fields(model).items():
        if key not in doc:
            continue
        where = f"{path}.{key}" if path else key
        if f.is_required():
            yield f"missing {where}", {k: v for k, v in doc.items() if k != key}, path or ""
        yield f"wrong type {where}", doc | {key: _wrong(doc[key])}, where
        inner = _models_in(f.annotation)
        value = doc[key]
        if inner and isinstance(value, list) and value and isinstance(value[0], dict):
            for label, item, w in mutations(inner[0], value[0], f"{where}[0]"):
                yield label, doc | {key: [item, *value[1:]]}, w
        elif inner and isinstance(value, dict) and not issubclass(inner[0], typing.cast(type, docs.Predictions)):
            for label, item, w in mutations(inner[0], value, where):
                yield label, doc | {key: item}, w


CASES = [pytest.param(read, label, bad, where, id=f"{name}: {label}")
         for name, model, good, read in READERS for label, bad, where in mutations(model, good)]


@pytest.mark.parametrize("name, model, good, read", READERS, ids=[r[0] for r in READERS])
def test_the_good_document_reads(name, model, good, read, tmp_path):
    """The walk starts from a document its reader takes (so each mutation fails for itself)."""
    if read is _read_run:  # finalize needs a frame: the run file alone must pass its own check
        _write(tmp_path / "fogsim_run.json", good)
        with pytest.raises(ValueError, match="no finished frames"):
            finalize_dataset(tmp_path)
        return
    read(tmp_path, good)


@pytest.mark.parametrize("read, label, bad, where", CASES)
def test_every_reader_refuses_each_shape_in_one_line(read, label, bad, where, tmp_path):
    with pytest.raises(InputError) as info:
        _, path = read(tmp_path, bad)
    text = str(info.value)
    assert "\n" not in text and "Traceback" not in text
    assert info.value.source.endswith((".json",)), text  # names the file
    assert where in text, text


def test_the_walk_covers_every_declared_field():
    """Each model's declared keys are each walked (missing when required, wrong type always)."""
    labels = {c.values[1] for c in CASES}
    assert len(CASES) >= 60
    for key in ("frame", "width", "objects[0].bbox", "objects[0].class", "parameters.levels[0].beta",
                "parameters.labels.classes", "levels[0].key", "images[0].file_name", "annotations[0].bbox",
                "[0].score", "map", "classes", "parameters.train.epochs", "parameters.train", "state"):
        assert any(label.endswith(key) for label in labels), key


def test_a_stray_meta_file_is_skipped_and_named(tmp_path):
    layout = DatasetLayout(tmp_path)
    _write(layout.meta("000000"), META)
    for name, text in (("notes", "{}"), ("list", "[]"), ("copy", json.dumps(META)), ("half", '{"frame": ')):
        (tmp_path / "meta" / f"{name}.json").write_text(text)
    records = frame_records(layout, docs.FogFrameMeta)
    assert records.frames == ["000000"] and len(records.metas) == 1
    assert len(records.skipped) == 4 and all("\n" not in s for s in records.skipped)
    for name in ("notes", "list", "copy", "half"):
        assert any(f"{name}.json: " in s for s in records.skipped), records.skipped


HOLDOUT = {"u": np.array([1.5, 2.5], np.float32), "v": np.array([1.5, 2.5], np.float32),
           "ray": np.array([5.0, 6.0], np.float32), "width": np.int64(16), "height": np.int64(8),
           "fx": np.float64(10), "fy": np.float64(10), "cx": np.float64(7.5), "cy": np.float64(3.5)}


def _npz_mutations():
    for key in HOLDOUT:
        if docs.Holdout.model_fields[key].is_required():
            yield f"missing {key}", {k: v for k, v in HOLDOUT.items() if k != key}, key
        yield f"{key} as text", HOLDOUT | {key: np.array(["x", "y"])}, key
        yield f"{key} as a 2-array", HOLDOUT | {key: np.array([1, 2])} if key in ("width", "height") else \
            HOLDOUT | {key: np.array([np.inf, 1.0])}, key


@pytest.mark.parametrize("label, fields, where", list(_npz_mutations()), ids=[m[0] for m in _npz_mutations()])
def test_the_holdout_reader_refuses_each_shape_in_one_line(label, fields, where, tmp_path):
    np.savez(tmp_path / "good.npz", **HOLDOUT)
    assert read_holdout(tmp_path / "good.npz").camera is not None
    np.savez(tmp_path / "h.npz", **fields)
    with pytest.raises(InputError) as info:
        read_holdout(tmp_path / "h.npz")
    text = str(info.value)
    assert "\n" not in text and text.startswith(str(tmp_path / "h.npz")) and where in text, text


def test_the_fog_physics_bench_reads_render_run_json_checked(bench_dir, tmp_path):  # noqa: F811
    """``render_run.json`` as ``fogsim bench fog-physics --analyse-only`` reads it (the exposure)."""
    from fogsim.bench.fog_physics import analyse

    out = tmp_path / "b"
    shutil.copytree(bench_dir, out)
    for bad, says in (("[]", "must be a JSON object"), ('{"parameters": {"exposure": "high"}}', "parameters.exposure")):
        (out / "clear" / "render_run.json").write_text(bad)
        with pytest.raises(InputError) as info:
            analyse(out)
        assert str(info.value).startswith(str(out / "clear" / "render_run.json")) and says in str(info.value)
