"""The per-density detection study: train, predict, evaluate, report (``fogsim study``;
``docs/study.md``).

Models: one detector per fog level of the dataset (named by level key) and ``mixed``, trained
on every level at once. Each is run on the validation images of every level. Report rows: the
models, ``oracle`` (each level's own model on it: routing by the true level) and
``routed (<estimator>)`` (each validation image sent to the model of its *estimated* level,
:mod:`fogsim.detection.level_estimation`). Columns: validation levels.

The folder OUT (``study.json``, ``yolo/``, ``runs/<model>/``, ``predictions/<model>/<level>.json``,
``report/``, ``sim_to_real/``) is :class:`fogsim.detection.layout.StudyLayout`'s.

Every unit (a model's training, one prediction file) is skipped when done, so an interrupted
study resumes; ``shard=(i, N)`` takes models i, i+N, … for a scheduler's array job.

Classes are the dataset's own (``dataset.json``): fogsim's 8 for renders, Waymo's or
Cityscapes' for fogged real data. ``class_map`` (:mod:`fogsim.detection.class_map`) evaluates
every row in another class list (e.g. a render in Waymo's classes, to set it beside a Waymo
study). ``unknown_distance`` (``ignore``/``count``) decides objects whose distance is unknown
(:func:`fogsim.detection.coco_eval.ignore_policy`); the report states how many objects each
policy evaluates.

**Sim-to-real** (``sim_dataset``, a rendered dataset): its models (one per level + mixed) are
trained by a study of its own (:meth:`~fogsim.detection.layout.StudyLayout.sim_study`) and run on
this (real) dataset's validation images (:meth:`~fogsim.detection.layout.StudyLayout.sim_prediction`);
their detections go through the class map sim → real (given, or the identity for equal class lists, or the built-in
whose lists match: ``fogsim-to-waymo``, ``fogsim-to-cityscapes``) and appear as rows
``sim <model>``. Then every row is evaluated on the real classes the map reaches, so the rows
are comparable (Cityscapes' train, motorcycle, bicycle have no fogsim source).

**Post-process vs path-traced fog** (``eval_dataset`` + ``scatter_dataset``, renders of this
render's scenes with volumetric and scatter fog, :mod:`fogsim.detection.fog_models`): a model
``scatter`` is trained on every level of the scatter render, every model predicts on the
path-traced render's validation images (``path_traced/predictions/<model>/<level>.json``), and the
table gains rows ``trained on Koschmieder fog`` (``mixed``) and ``trained on scatter fog``
evaluated on the path-traced levels.
"""
from __future__ import annotations

import hashlib
import json
import shutil
from dataclasses import asdict
from pathlib import Path

import numpy as np
from tqdm import tqdm

from fogsim.augment.spec import FogSpec
from fogsim.dataset.layout import MIXED_MODEL, DatasetLayout
from fogsim.dataset.reader import (
    clear_level,
    dataset_classes,
    dataset_levels,
    missing_files,
    read_distance,
    read_split,
    val_ground_truth,
)
from fogsim.detection.class_map import BUILTIN, ClassMap, identity, map_detections, map_ground_truth, restriction
from fogsim.detection.coco_eval import BINS, UNKNOWN_DISTANCE, distance_coverage
from fogsim.detection.fog_models import ROWS, check_same_scenes, path_traced_lines
from fogsim.detection.layout import StudyLayout
from fogsim.detection.level_estimation import LevelEstimator, confusion, image_features, route
from fogsim.detection.table import (
    TRAINING_SECONDS,
    cross_density,
    heatmap,
    markdown,
    training_header,
    training_row,
    write_report,
)
from fogsim.detection.yolo import (
    AUGMENTED_MODEL,
    SCATTER_MODEL,
    TrainConfig,
    check_model,
    predict,
    train,
    training_view,
)
from fogsim.errors import InputError
from fogsim.fog.visibility import INVISIBLE_RULE
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.documents import read_json, write_json
from fogsim.io.images import read_image, write_image
from fogsim.runs import claim_output
from fogsim.schema.base import check, load_json
from fogsim.schema.documents import DoneFile, Predictions, StudyFile

ESTIMATORS = ("features", "dark-channel")
ESTIMATOR_TRAIN_IMAGES = 200  # per level: enough for centroids, bounded time on large datasets


class Study:
    """Paths and parameters of one study under ``out`` on ``dataset``. ``cfg`` is needed to
    train; the report reads the training parameters the study was run with from ``study.json``."""

    def __init__(self, dataset: str | Path, out: str | Path, cfg: TrainConfig | None = None, *,
                 unknown_distance: str = "ignore", class_map: ClassMap | None = None,
                 sim_dataset: str | Path | None = None, augment: FogSpec | None = None,
                 eval_dataset: str | Path | None = None, scatter_dataset: str | Path | None = None):
        self.dataset, self.out, self.cfg = Path(dataset).resolve(), Path(out).resolve(), cfg
        self.layout, self.files = DatasetLayout(self.dataset), StudyLayout(self.out)
        self.levels = dataset_levels(self.layout)
        self.classes = dataset_classes(self.layout)
        if unknown_distance not in UNKNOWN_DISTANCE:
            raise ValueError(f"--unknown-distance must be one of {', '.join(UNKNOWN_DISTANCE)}, "
                             f"got {unknown_distance!r}")
        self.unknown_distance = unknown_distance
        self.sim = None if sim_dataset is None else Study(sim_dataset, self.files.sim_study(), cfg)
        if self.sim is not None:
            if self.sim.dataset == self.dataset:
                raise InputError(sim_dataset, "--sim-dataset is the --dataset itself")
            self.sim_map = sim_class_map(class_map, self.sim.classes, self.classes, self.sim.layout.manifest())
            self.eval_map = restriction(self.classes, self.sim_map.reached(), "classes reached by " + self.sim_map.name)
        else:
            self.sim_map = None
            if class_map is not None:
                class_map.check_source(self.classes, str(self.layout.manifest()))
            self.eval_map = class_map
        clash = [lv for lv in self.levels if lv in (MIXED_MODEL, AUGMENTED_MODEL, SCATTER_MODEL, "oracle", *ROWS)
                 or lv.startswith("routed")]
        if clash:
            raise InputError(self.layout.manifest(), f"fog level keys {clash} clash with the study's "
                                                     "row names (mixed, augmented, scatter, oracle, routed …)")
        self.models = [*self.levels, MIXED_MODEL]
        self.augment, self.clear = augment, None
        if augment is not None:
            self.clear = clear_level(self.layout)
            if self.clear is None:
                raise InputError(self.layout.manifest(), "--augment trains on the clear images: the dataset "
                                                         "has no level with β = 0")
            self.models.append(AUGMENTED_MODEL)
        self.eval_layout = self.scatter_layout = None
        if (eval_dataset is None) != (scatter_dataset is None):
            raise ValueError("--eval-dataset and --scatter-dataset come together (path-traced fog to evaluate on, "
                             "scatter fog to train on)")
        if eval_dataset is not None:
            if self.sim is not None:
                raise ValueError("--eval-dataset compares fog models on renders; --sim-dataset is for a real "
                                 "--dataset: give one of them")
            self.scatter_layout = DatasetLayout(Path(scatter_dataset).resolve())
            self.eval_layout = DatasetLayout(Path(eval_dataset).resolve())
            check_same_scenes(self.layout, self.scatter_layout, "--scatter-dataset", "scatter")
            check_same_scenes(self.layout, self.eval_layout, "--eval-dataset", "volumetric")
            self.models.append(SCATTER_MODEL)
        self.config_dir = self.files.config_dir()

    def prediction(self, model: str, level: str) -> Path:
        return self.files.prediction(model, level)

    def sim_prediction(self, model: str, level: str) -> Path:
        """Detections of the sim study's model ``model`` on this dataset's level ``level``
        (in the sim dataset's classes, as the model predicts)."""
        return self.files.sim_prediction(model, level)

    def _dataset_parameters(self, gts: dict) -> dict:
        """What ties predictions to the dataset: its path, levels and validation images (ids and
        files — they change when frames are added or the split is redrawn)."""
        return {"dataset": str(self.dataset), "levels": self.levels, "validation_images_sha256": _images_digest(gts)}

    def check_parameters(self, gts: dict) -> None:
        """Write ``study.json``, or refuse when OUT holds a study with other parameters."""
        params = self._dataset_parameters(gts) | {"train": asdict(self.cfg)}
        if self.augment is not None:  # only then: a study without it keeps its study.json
            params["augment"] = {"beta": list(self.augment.beta), "sample": self.augment.sample}
        if self.eval_layout is not None:  # likewise
            params["path_traced"] = self._path_traced_parameters()
        claim_output(self.files.study_file(), params, what="study")

    def _path_traced_parameters(self) -> dict:
        return {"scatter_dataset": str(self.scatter_layout.root), "eval_dataset": str(self.eval_layout.root),
                "eval_validation_images_sha256": _images_digest(self.eval_ground_truth())}

    def stored_config(self, gts: dict) -> TrainConfig:
        """The training parameters in ``study.json``, after checking it is this dataset's study."""
        path = self.files.study_file()
        if not path.is_file():
            raise InputError(path, "no study here: train the models first")
        stored = load_json(path, StudyFile).parameters
        keys = ("dataset", "levels", "validation_images_sha256")
        if {k: getattr(stored, k) for k in keys} != self._dataset_parameters(gts):
            raise InputError(path, f"this study was run on another dataset or validation split than {self.dataset}")
        if self.eval_layout is not None and read_json(path)["parameters"].get("path_traced") != \
                self._path_traced_parameters():
            raise InputError(path, "this study's path-traced predictions were made without, or on other renders "
                                   "than, this --eval-dataset and --scatter-dataset")
        return TrainConfig(**stored.train.model_dump())

    def ground_truth(self) -> dict:
        return {lv: val_ground_truth(self.layout, lv) for lv in self.levels}

    def eval_ground_truth(self) -> dict:
        """The path-traced render's validation ground truth per level (``--eval-dataset``)."""
        return {lv: val_ground_truth(self.eval_layout, lv) for lv in self.levels}

    def run_models(self, shard: tuple[int, int] = (0, 1), progress: bool = True) -> None:
        """Train every model of this shard and predict with it on every level (resumable)."""
        gts = self.ground_truth()
        self.check_files(gts)  # a missing image named in the dataset, not as Ultralytics' link to it
        eval_gts = None
        if self.eval_layout is not None:
            eval_gts = self.eval_ground_truth()
            self.check_files(eval_gts, self.eval_layout)
            self.check_files({lv: val_ground_truth(self.scatter_layout, lv) for lv in self.levels}, self.scatter_layout)
        mine = self.models[shard[0]::shard[1]]
        if AUGMENTED_MODEL in mine:  # the data's checks first: check_model writes OUT/ultralytics_config
            self.check_depth()
        if any(not self.files.run_done(m).is_file() for m in mine):
            check_model(self.cfg.model, self.config_dir)  # before study.json: a typo must not lock OUT
        self.check_parameters(gts)
        data = training_view(self.dataset, self.files.training_view(), self.levels, self.classes, self.clear)
        if self.scatter_layout is not None:  # the scatter render's own mixed view
            data[SCATTER_MODEL] = training_view(self.scatter_layout.root, self.files.scatter_view(), self.levels,
                                                self.classes)[MIXED_MODEL]
        for name in tqdm(mine, desc="models", unit="model", disable=not progress):
            if not self.files.run_done(name).is_file():
                shutil.rmtree(self.files.predictions(name), ignore_errors=True)  # from older weights
                shutil.rmtree(self.files.eval_predictions(name), ignore_errors=True)
            best = train(name, data[name], self.files.run(name), self.cfg, self.config_dir, self.trainer(name))
            for lv in self.levels:
                path = self.prediction(name, lv)
                if not path.is_file():
                    write_json(path, predict(best, gts[lv], self.dataset, self.cfg, self.config_dir))
                path = self.files.eval_prediction(name, lv)
                if eval_gts is not None and not path.is_file():
                    write_json(path, predict(best, eval_gts[lv], self.eval_layout.root, self.cfg, self.config_dir))
        if self.sim is not None:
            self.run_sim_models(gts, shard, progress)

    def trainer(self, name: str):
        """The Ultralytics trainer class of model ``name``: the fogging one for ``augmented``, else
        None (Ultralytics' default)."""
        if name != AUGMENTED_MODEL:
            return None
        from fogsim.detection.augmented import fog_trainer
        from fogsim.detection.yolo import load_ultralytics
        return fog_trainer(load_ultralytics(self.config_dir), self.dataset, self.augment, self.cfg.seed)

    def run_sim_models(self, gts: dict, shard: tuple[int, int] = (0, 1), progress: bool = True) -> None:
        """Train the sim study's models of this shard (on the rendered dataset) and run each on
        this dataset's validation images of every level (resumable)."""
        self.sim.run_models(shard, progress)
        for name in self.sim.models[shard[0]::shard[1]]:
            stamp = self.sim.files.run_done(name).stat().st_mtime
            best = self.sim.files.weights(name)
            for lv in self.levels:
                path = self.sim_prediction(name, lv)
                if path.is_file() and path.stat().st_mtime < stamp:
                    path.unlink()  # made with weights that were retrained since
                if not path.is_file():
                    write_json(path, predict(best, gts[lv], self.dataset, self.cfg, self.config_dir))

    def check_files(self, gts: dict, layout: DatasetLayout | None = None) -> None:
        """Every image and label the split lists and the COCO files name must be in the dataset
        (``layout``, default the study's), before training starts (Ultralytics would fail
        mid-study naming its links under OUT/yolo)."""
        layout = self.layout if layout is None else layout
        missing = missing_files(layout, self.levels)
        missing += [p for lv in self.levels for im in gts[lv]["images"]
                    if not (p := layout.root / im["file_name"]).is_file()]
        missing = list(dict.fromkeys(missing))  # a validation image is in both
        if missing:
            more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
            raise InputError(missing[0], f"missing from the dataset{more}: its split lists or COCO files name "
                                         "it; restore it, or rebuild the lists with fogsim render --finalize-only")

    def check_depth(self) -> None:
        """The augmented model fogs the clear training frames from their depth: every one must
        have it (the first is read, to check its record and camera too) before training starts."""
        frames = read_split(self.layout, self.clear, "train")
        if frames:
            read_distance(self.layout, frames[0])
        missing = [p for f in frames if not (p := self.layout.depth(f)).is_file()]
        if missing:
            raise InputError(missing[0], f"no depth for this frame ({len(missing)} of {len(frames)} clear training "
                                         "frames lack one): --augment needs a rendered dataset's depth/<frame>.exr")

    def missing_predictions(self) -> list[Path]:
        paths = [self.prediction(m, lv) for m in self.models for lv in self.levels]
        if self.sim is not None:
            paths += [self.sim_prediction(m, lv) for m in self.sim.models for lv in self.levels]
        if self.eval_layout is not None:
            paths += [self.files.eval_prediction(m, lv) for m in self.models for lv in self.levels]
        return [p for p in paths if not p.is_file()]

    def evaluation_rows(self, gts: dict, preds: dict) -> tuple[dict, dict]:
        """(ground truth per level, detections per row and level) in the evaluation's classes:
        the class map's targets (or the dataset's classes, restricted to those the sim map
        reaches when a sim dataset is given); sim rows are named ``sim <model>``."""
        rows = dict(preds)
        if self.eval_map is not None:
            gts = {lv: map_ground_truth(gt, self.eval_map, self.classes) for lv, gt in gts.items()}
            rows = {m: {lv: map_detections(d, self.eval_map, self.classes) for lv, d in by.items()}
                    for m, by in rows.items()}
        if self.sim is not None:
            for m in self.sim.models:
                rows[f"sim {m}"] = {lv: map_detections(read_predictions(self.sim_prediction(m, lv)), self.sim_map,
                                                       self.sim.classes) for lv in self.levels}
        return gts, rows

    def coverage(self, gts: dict, max_distance_m: float) -> dict:
        """:func:`~fogsim.detection.coco_eval.distance_coverage` of each level's validation ground
        truth (the same objects at every level), in the evaluation's classes."""
        if self.eval_map is not None:
            gts = {lv: map_ground_truth(gt, self.eval_map, self.classes) for lv, gt in gts.items()}
        return {lv: distance_coverage(gt, max_distance_m) for lv, gt in gts.items()}

    def report(self, max_distance_m: float = 100.0, visible_only: bool = False) -> dict:
        """Evaluate every row on every level and write ``OUT/report``; returns the table. Recall is
        reported both ways (``recall_all``, ``recall_visible``); ``visible_only`` also scores
        mAP@50 and the distance bins with the invisible objects ignored."""
        missing = self.missing_predictions()
        if missing:
            raise InputError(missing[0], f"{len(missing)} prediction files are missing: "
                                         "run the remaining models (shards) first")
        gts = self.ground_truth()
        cfg = self.stored_config(gts)
        training = self.training_records()  # every document read (and checked) before a report file is written
        preds = {m: {lv: read_predictions(self.prediction(m, lv)) for lv in self.levels} for m in self.models}
        rows = dict(preds)
        rows["oracle"] = {lv: preds[lv][lv] for lv in self.levels}
        levels_out = {}
        for method, (est_true, est_pred, estimates) in self.estimate_levels(gts).items():
            rows[f"routed ({method})"] = route(preds, estimates)
            levels_out[method] = confusion(est_true, est_pred, self.levels)
        eval_gts, rows = self.evaluation_rows(gts, rows)
        policy = {"max_distance_m": max_distance_m, "unknown_distance": self.unknown_distance,
                  "visible_only": visible_only}
        table = cross_density(eval_gts, rows, **policy)
        path_traced = self.path_traced_table(policy)
        if path_traced is not None:
            table |= {row: path_traced[model] for row, model in ROWS.items()}
        out = self.files.report()
        write_report(table, out)
        if path_traced is not None:
            write_json(out / "path_traced.json", path_traced)
        write_json(out / "fog_level.json", levels_out)
        coverage = self.coverage(gts, max_distance_m)
        write_json(out / "distance_policy.json", {
            "unknown_distance": self.unknown_distance, "max_distance_m": max_distance_m, "per_level": coverage,
            "class_map": None if self.eval_map is None else self.eval_map.to_dict(),
            "sim_class_map": None if self.sim_map is None else self.sim_map.to_dict()})
        for method, conf in levels_out.items():
            m = np.array(conf["matrix"], float)
            share = m / np.maximum(m.sum(axis=1, keepdims=True), 1)
            grid = {t: {p: {"share": share[i, j]} for j, p in enumerate(self.levels)}
                    for i, t in enumerate(self.levels)}
            write_image(out / f"fog_level_{method}.png",
                        heatmap(grid, "share", title=f"fog level, {method}: share (row: true, column: estimated)"))
        md = self.report_markdown(table, levels_out, max_distance_m, cfg, coverage, visible_only, training,
                                  path_traced)
        atomic_write_bytes(out / "report.md", md.encode())
        return table

    def path_traced_table(self, policy: dict) -> dict | None:
        """Every model on the path-traced render's levels (``{model: {level: cell}}``, in the
        evaluation's classes), None without ``--eval-dataset``."""
        if self.eval_layout is None:
            return None
        gts = self.eval_ground_truth()
        preds = {m: {lv: read_predictions(self.files.eval_prediction(m, lv)) for lv in self.levels}
                 for m in self.models}
        if self.eval_map is not None:
            gts = {lv: map_ground_truth(gt, self.eval_map, self.classes) for lv, gt in gts.items()}
            preds = {m: {lv: map_detections(d, self.eval_map, self.classes) for lv, d in by.items()}
                     for m, by in preds.items()}
        return cross_density(gts, preds, **policy)

    def _classes_lines(self) -> list[str]:
        lines = [f"Classes of the dataset: {', '.join(self.classes)}."]
        if self.sim is not None:
            lines.append(f"Sim-to-real rows (`sim <model>`): models trained on the rendered dataset "
                         f"`{self.sim.dataset}` ({', '.join(self.sim.classes)}), their detections mapped by "
                         f"`{self.sim_map.name}`; every row is evaluated on the classes it reaches: "
                         f"{', '.join(self.sim_map.reached())}.")
        elif self.eval_map is not None:
            lines.append(f"Evaluated through the class map `{self.eval_map.name}` in the classes "
                         f"{', '.join(self.eval_map.reached())}.")
        return lines + [""]

    def estimate_levels(self, gts: dict) -> dict:
        """Per estimator: (true levels, estimated levels, ``{level: {image_id: estimated level}}``)
        of every validation image; fitted on training images of every level."""
        X, y = [], []
        for lv in self.levels:
            frames = read_split(self.layout, lv, "train")
            step = max(1, len(frames) // ESTIMATOR_TRAIN_IMAGES)
            for f in frames[::step]:
                X.append(image_features(read_image(self.layout.image(lv, f))))
                y.append(lv)
        val = [(lv, im["id"], image_features(read_image(self.dataset / im["file_name"])))
               for lv in self.levels for im in gts[lv]["images"]]
        V = np.stack([v[2] for v in val])
        out = {}
        for method in ESTIMATORS:
            predicted = LevelEstimator.fit(np.stack(X), y, method).predict(V)
            estimates: dict = {lv: {} for lv in self.levels}
            for (lv, image_id, _), p in zip(val, predicted):
                estimates[lv][image_id] = p
            out[method] = ([v[0] for v in val], predicted, estimates)
        return out

    def training_records(self) -> dict[str, DoneFile]:
        """Each model's ``fogsim_done.json`` (checked), an empty record for a model without one."""
        records = {}
        for m in self.models:
            done = self.files.run_done(m)
            records[m] = load_json(done, DoneFile) if done.is_file() else DoneFile()
        return records

    def report_markdown(self, table: dict, levels_out: dict, max_distance_m: float, cfg: TrainConfig,
                        coverage: dict | None = None, visible_only: bool = False,
                        training: dict[str, DoneFile] | None = None, path_traced: dict | None = None) -> str:
        n_train = len(read_split(self.layout, self.levels[0], "train"))
        n_val = len(read_split(self.layout, self.levels[0], "val"))
        ignored = (f"farther ones, and invisible ones ({INVISIBLE_RULE}), are ignored in map50 and by distance"
                   if visible_only else "farther ones are ignored")  # the headline policy, with the numbers
        lines = ["# Cross-density detection study", "",
                 f"Dataset `{self.dataset}`: {n_train} training / {n_val} validation frames per level; "
                 f"model `{cfg.model}`{' from scratch' if cfg.model.endswith(('.yaml', '.yml')) else ''}, "
                 f"{cfg.epochs} epochs "
                 f"(mixed and augmented: {cfg.epochs_for(MIXED_MODEL)} over every level's worth), "
                 f"{cfg.imgsz} px, batch {cfg.batch}. "
                 f"Objects within {max_distance_m:g} m count; {ignored}.",
                 "", "Recall = Ultralytics' R (recall at the max-F1 confidence), over every object and over "
                 f"the visible ones only (recall_visible: invisible objects, {INVISIBLE_RULE} against their "
                 "surround in that level's image, are ignored); map50 = COCO AP@0.5 "
                 "(pycocotools). Rows: trained on (oracle = each level's own model; routed = the model "
                 "of the estimated level); columns: validated on.", "", *self._classes_lines(),
                 *_coverage_lines(coverage, self.unknown_distance, max_distance_m), markdown(table),
                 "**recall by distance** (every detection; model on its own level, mixed, augmented, routed)", "",
                 "| row | level | " + " | ".join(f"{lo:g}–{hi:g} m" for lo, hi in BINS) + " |",
                 "|---" * (len(BINS) + 2) + "|"]
        for row in ("oracle", MIXED_MODEL, *(r for r in table if r == AUGMENTED_MODEL or r.startswith("routed"))):
            for lv, cell in table[row].items():
                vals = ["—" if v is None else f"{v:.3f}" for v in cell["recall_by_distance"].values()]
                lines.append(f"| {row} | {lv} | " + " | ".join(vals) + " |")
        if AUGMENTED_MODEL in table:
            lines += ["", *_winner_lines(table, self.levels, self.augment)]
        if path_traced is not None:
            lines += ["", *path_traced_lines(path_traced, self.levels, self.eval_layout.root, self.scatter_layout.root)]
        lines += ["", f"**training** (seconds: {TRAINING_SECONDS})", "", *training_header(["model"])]
        training = self.training_records() if training is None else training
        lines += [training_row([m], cfg.epochs_for(m), training[m]) for m in self.models]
        lines += ["", "**fog-level estimators** on the validation images (rows: true, columns: estimated)", ""]
        for method, conf in levels_out.items():
            lines += [f"{method}: accuracy {conf['accuracy']:.3f}", "",
                      "| true \\ estimated | " + " | ".join(self.levels) + " |", "|---" * (len(self.levels) + 1) + "|"]
            lines += [f"| {lv} | " + " | ".join(str(v) for v in row) + " |"
                      for lv, row in zip(self.levels, conf["matrix"])]
            lines.append("")
        return "\n".join(lines)


def _images_digest(gts: dict) -> str:
    """SHA-256 of every level's validation images (ids and files: they change when frames are
    added or the split is redrawn)."""
    images = {lv: [[im["id"], im["file_name"]] for im in gt["images"]] for lv, gt in gts.items()}
    return hashlib.sha256(json.dumps(images, sort_keys=True).encode()).hexdigest()


def read_predictions(path: Path) -> list[dict]:
    """A prediction file (COCO results), checked against :class:`~fogsim.schema.documents.Predictions`."""
    dets = read_json(path)
    check(dets, Predictions, path)
    return dets


def _winner_lines(table: dict, levels: list[str], augment: FogSpec | None) -> list[str]:
    """Which training wins on each level: the level's own specialist (oracle), ``mixed`` (every
    level on disk) or ``augmented`` (clear images, fog drawn per sample), by mAP@50 and recall."""
    rows = ("oracle", MIXED_MODEL, AUGMENTED_MODEL)
    span = "" if augment is None else f" (β {augment.sample}-uniform in {augment.beta[0]:g}–{augment.beta[-1]:g} 1/m)"
    lines = [f"**augmented{span} vs mixed vs specialists** (map50 / recall_all; best in bold)", "",
             "| level | " + " | ".join(rows) + " | wins (map50) |", "|---" * (len(rows) + 2) + "|"]
    wins = {r: 0 for r in rows}
    for lv in levels:
        cells = {r: table[r][lv] for r in rows}
        best = max(rows, key=lambda r: cells[r]["ap50"])
        wins[best] += 1
        lines.append(f"| {lv} | " + " | ".join(
            (f"**{c['ap50']:.3f}**" if r == best else f"{c['ap50']:.3f}") + f" / {c['recall_all']:.3f}"
            for r, c in cells.items()) + f" | {best} |")
    lines += ["", "Levels won by mAP@50: " + ", ".join(f"{r} {n}" for r, n in wins.items()) + "."]
    return lines


def _coverage_lines(coverage: dict | None, policy: str, max_distance_m: float) -> list[str]:
    """The objects each unknown-distance policy evaluates (validation ground truth, one level:
    the boxes are the same at every level)."""
    if not coverage:
        return []
    c = next(iter(coverage.values()))
    return [f"Distances (validation objects): {c['within']} within {max_distance_m:g} m, {c['beyond']} beyond "
            f"(ignored), {c['unknown']} of unknown distance"
            + (f", {c['no_distance']} without a distance field (counted)" if c["no_distance"] else "")
            + f". `--unknown-distance ignore` evaluates {c['ignore']} objects, `count` {c['count']}; "
            f"this report: **{policy}**.", ""]


def sim_class_map(given: ClassMap | None, sim_classes, real_classes, where) -> ClassMap:
    """The class map sim → real: ``given`` (checked against both lists), the identity for equal
    lists, or the built-in map whose source and target lists are these; else an error asking
    for ``--class-map``."""
    sim_classes, real_classes = list(sim_classes), list(real_classes)
    if given is not None:
        given.check_source(sim_classes, str(where))
        if list(given.targets) != real_classes:
            raise InputError(where, f"class map {given.name} maps to {list(given.targets)}, but the real dataset's "
                                    f"classes are {real_classes}")
        return given
    if sim_classes == real_classes:
        return identity(sim_classes)
    for cmap in BUILTIN.values():
        if set(cmap.mapping) == set(sim_classes) and list(cmap.targets) == real_classes:
            return cmap
    raise InputError(where, f"the rendered dataset's classes {sim_classes} are not the real dataset's "
                            f"{real_classes}: give --class-map ({', '.join(BUILTIN)} or a JSON map)")
