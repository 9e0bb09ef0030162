"""The per-density study on LiDAR and LiDAR + radar: BEV rasters, one oriented-box detector per fog level
plus a mixed one, every model on every level (``fogsim study --sensor lidar|lidar+radar``, ``docs/study.md``).

Models, per variant (:class:`~fogsim.detection.bev.build.Variant`): one per fog level of the dataset
(trained on that level's training rasters) and ``mixed`` (every level's at once, for ``--mixed-epochs``,
default ``--epochs``: the compute of the level models together) — the camera study's rules
(:mod:`fogsim.detection.study`). ``lidar+radar`` trains the ``lidar`` variant's models too, so one report
compares them. With ``fog_models`` each LiDAR fog model's variant (the clear scans fogged again by it) gets
its own ``mixed`` model, run on every such variant's levels: does the fog a detector is trained on change
what it finds in another model's fog?

Detector: Ultralytics' oriented-box (OBB) YOLO from a model YAML (``yolov8n-obb.yaml`` by default; random
weights, nothing downloaded), trained by :func:`fogsim.detection.yolo.train` — seeded, deterministic,
resumable, ``--device`` — on rasters of ``imgsz`` pixels (the grid's cell is chosen so the raster *is* the
network's input: no resampling blurs single points), its colour augmentation off (the channels are
measurements) and its scale augmentation off (a cell is a fixed number of metres: a car is 4 m long in every
raster, and Ultralytics' default ±50 % zoom would teach the detector otherwise — on a 60-frame render it cost
the clear model's car AP at IoU 0.7 from 0.78 to 0.45 and doubled its length errors, see docs/study.md);
mosaic, translation and left–right flips stay: they move and mirror the scene without changing its scale.

The folder OUT/bev (:class:`BevStudyLayout`): ``study.json``; per variant ``<variant>/data`` (the BEV
dataset, :mod:`~fogsim.detection.bev.build`), ``<variant>/yolo`` (the training view: symlinks, lists, data
YAMLs), ``<variant>/runs/<model>`` (Ultralytics' run; ``fogsim_done.json`` last), ``<variant>/predictions/
<model>/<level>.json`` (and ``…/<model>/on_<other variant>/<level>.json`` for the fog-model rows);
``report/``. Every unit — a model's training, a prediction file — is skipped when done; ``shard=(i, N)``
takes units i, i+N, …
"""
from __future__ import annotations

import hashlib
import json
import shutil
from dataclasses import asdict, dataclass
from pathlib import Path

from tqdm import tqdm

from fogsim.dataset.layout import MIXED_MODEL, PARTS
from fogsim.dataset.writer import data_yaml
from fogsim.detection.bev.build import BevLayout, Variant, build_variant
from fogsim.detection.bev.grid import BevGrid
from fogsim.detection.bev.source import BEV_CLASSES, LidarLevels
from fogsim.detection.yolo import TrainConfig, check_model, predict_obb, replace_symlink, train
from fogsim.errors import InputError
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.documents import write_json
from fogsim.runs import claim_output
from fogsim.schema.base import check, load_json
from fogsim.schema.bev import BevFrameTruth, BevPredictions, BevStudyFile

DEFAULT_BEV_MODEL = "yolov8n-obb.yaml"
#: Ultralytics' training overrides: the rasters' channels are measurements, not colours (HSV jitter off), and
#: their cells are metres (no zoom: the module docstring)
AUGMENT = {"hsv_h": 0.0, "hsv_s": 0.0, "hsv_v": 0.0, "scale": 0.0}
ORACLE = "oracle"


class BevStudyLayout:
    """Every path under OUT/bev (the module docstring)."""

    def __init__(self, out: str | Path):
        self.out = Path(out)
        self.root = self.out / "bev"

    def study_file(self) -> Path:
        return self.root / "study.json"

    def config_dir(self) -> Path:
        return self.out / "ultralytics_config"  # the camera study's too: one settings folder per OUT

    def data(self, v: Variant) -> BevLayout:
        return BevLayout(self.root / v.folder / "data", v)

    def view(self, v: Variant) -> Path:
        return self.root / v.folder / "yolo"

    def run(self, v: Variant, model: str) -> Path:
        return self.root / v.folder / "runs" / model

    def run_done(self, v: Variant, model: str) -> Path:
        return self.run(v, model) / "fogsim_done.json"

    def weights(self, v: Variant, model: str) -> Path:
        return self.run(v, model) / "weights" / "best.pt"

    def predictions(self, v: Variant, model: str) -> Path:
        return self.root / v.folder / "predictions" / model

    def prediction(self, v: Variant, model: str, level: str, on: Variant | None = None) -> Path:
        """Model ``model`` of variant ``v`` on the validation rasters of ``level`` (of variant ``on``, default
        ``v``)."""
        base = self.predictions(v, model)
        return (base if on is None or on == v else base / f"on_{on.folder}") / f"{level}.json"

    def report(self, name: str = "") -> Path:
        return self.root / "report" / name if name else self.root / "report"


@dataclass(frozen=True)
class Unit:
    """One model to train and run: ``model`` of ``variant``, run on its own levels and those of ``also``."""

    variant: Variant
    model: str
    also: tuple[Variant, ...] = ()

    @property
    def name(self) -> str:
        return f"{self.variant.name}/{self.model}"


class BevStudy:
    """One BEV study of ``dataset`` under ``out`` (the module docstring). ``sensor``: ``lidar`` or
    ``lidar+radar``; ``grid`` defaults to :meth:`BevGrid.for_image` of ``cfg.imgsz``."""

    def __init__(self, dataset: str | Path, out: str | Path, sensor: str, cfg: TrainConfig,
                 grid: BevGrid | None = None, fog_models: tuple[str, ...] = ()):
        if sensor not in ("lidar", "lidar+radar"):
            raise ValueError(f"--sensor must be camera, lidar or lidar+radar, got {sensor!r}")
        self.source = LidarLevels(dataset)
        self.sensor, self.cfg = sensor, cfg
        self.files = BevStudyLayout(out)
        self.grid = grid or BevGrid.for_image(cfg.imgsz)
        self.levels = self.source.levels
        clash = [lv for lv in self.levels if lv in (MIXED_MODEL, ORACLE)]
        if clash:
            raise InputError(self.source.layout.manifest(), f"fog level keys {clash} clash with the rows mixed, oracle")
        self.variants = [Variant()] + ([Variant(radar=True)] if sensor == "lidar+radar" else [])
        if len(set(fog_models)) != len(fog_models):
            raise ValueError(f"--fog-models lists a model twice: {','.join(fog_models)}")
        self.fog_variants = [Variant(fog_model=m) for m in fog_models]
        self.units = [Unit(v, m) for v in self.variants for m in (*self.levels, MIXED_MODEL)]
        self.units += [Unit(fv, MIXED_MODEL, tuple(o for o in self.fog_variants if o != fv))
                       for fv in self.fog_variants]

    # ------------------------------------------------------------------ parameters
    def all_variants(self) -> list[Variant]:
        return self.variants + self.fog_variants

    def parameters(self) -> dict:
        ids = json.dumps(self.source.split, sort_keys=True).encode()
        return {"dataset": str(self.source.root), "sensor": self.sensor, "levels": self.levels,
                "variants": [v.name for v in self.all_variants()], "grid": self.grid.to_dict(),
                "split_sha256": hashlib.sha256(ids).hexdigest(), "train": asdict(self.cfg), "augment": AUGMENT}

    @classmethod
    def stored(cls, dataset: str | Path, out: str | Path, sensor: str, fog_models: tuple[str, ...] = ()) -> "BevStudy":
        """The study of ``out`` with the training configuration and grid its ``study.json`` records (what
        ``--report-only`` needs: no training flags to repeat)."""
        path = BevStudyLayout(out).study_file()
        if not path.is_file():
            raise InputError(path, "no BEV study here: train the models first")
        stored = load_json(path, BevStudyFile).parameters
        try:
            grid = BevGrid.from_dict(stored.grid)
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(path, f"parameters.grid: not a BEV grid ({exc})") from None
        return cls(dataset, out, sensor, TrainConfig(**stored.train.model_dump()), grid, fog_models)

    def stored_config(self) -> TrainConfig:
        """The training parameters of ``study.json`` (after checking it is this dataset's study)."""
        path = self.files.study_file()
        if not path.is_file():
            raise InputError(path, "no BEV study here: train the models first")
        stored = load_json(path, BevStudyFile).parameters
        mine = self.parameters()
        raw = json.loads(path.read_text())["parameters"]
        for key in ("dataset", "sensor", "levels", "variants", "grid", "split_sha256"):
            if raw.get(key) != json.loads(json.dumps(mine[key])):
                raise InputError(path, f"this BEV study was run with another {key} ({raw.get(key)!r})")
        return TrainConfig(**stored.train.model_dump())

    # ------------------------------------------------------------------ data
    def prepare(self, progress: bool = True) -> None:
        """Build (or complete) every variant's BEV dataset."""
        for v in self.all_variants():
            build_variant(self.source, self.files.data(v), self.grid, self.cfg.seed, progress)

    def training_view(self, v: Variant) -> dict[str, Path]:
        """The variant's data seen by Ultralytics: per model (each level, ``mixed``) lists of its training and
        validation rasters through symlinks ``yolo/<model>/<part>/<level>/{images,labels}`` (so its label
        caches are one per model and never in the data), and a data YAML with the channel count."""
        data, view = self.files.data(v), self.files.view(v).resolve()
        out = {}
        for model, members in [*((lv, [lv]) for lv in self.levels), (MIXED_MODEL, self.levels)]:
            for part in PARTS:
                paths = []
                for lv in members:
                    base = view / model / part / lv
                    base.mkdir(parents=True, exist_ok=True)
                    replace_symlink(base / "images", data.images_dir(lv).resolve())
                    replace_symlink(base / "labels", data.labels_dir(lv).resolve())
                    paths += [base / "images" / data.image(lv, i).name for i in self.source.split[part]]
                atomic_write_bytes(view / model / f"{part}.txt", ("\n".join(map(str, paths)) + "\n").encode())
            text = data_yaml(view / model, "train.txt", "val.txt", f"fogsim BEV view: {v.name} {model}", BEV_CLASSES)
            out[model] = view / model / "data.yaml"
            atomic_write_bytes(out[model], (text + f"channels: {len(v.channels)}\n").encode())
        return out

    # ------------------------------------------------------------------ training and prediction
    def mine(self, shard: tuple[int, int]) -> list[Unit]:
        return self.units[shard[0]::shard[1]]

    def run_models(self, shard: tuple[int, int] = (0, 1), progress: bool = True) -> None:
        """Build the data, then train every unit of this shard and predict with it (resumable)."""
        self.prepare(progress)
        units = self.mine(shard)
        if any(not self.files.run_done(u.variant, u.model).is_file() for u in units):
            check_model(self.cfg.model, self.files.config_dir(), task="obb")  # before study.json: a typo can't lock OUT
        claim_output(self.files.study_file(), self.parameters(), what="BEV study")
        views = {v: self.training_view(v) for v in {u.variant for u in units}}
        for u in tqdm(units, desc="BEV models", unit="model", disable=not progress):
            if not self.files.run_done(u.variant, u.model).is_file():
                shutil.rmtree(self.files.predictions(u.variant, u.model), ignore_errors=True)  # older weights'
            best = train(u.name, views[u.variant][u.model], self.files.run(u.variant, u.model), self.cfg,
                         self.files.config_dir(), overrides=AUGMENT)
            for on in (u.variant, *u.also):
                for lv in self.levels:
                    path = self.files.prediction(u.variant, u.model, lv, on)
                    if not path.is_file():
                        write_json(path, self.predict(best, on, lv))

    def predict(self, weights: Path, on: Variant, level: str) -> list[dict]:
        """The model's rotated boxes on the validation rasters of ``level`` of variant ``on``, in metres."""
        data = self.files.data(on)
        images = [(i, data.image(level, i)) for i in self.source.split["val"]]
        dets = predict_obb(weights, images, self.cfg, self.files.config_dir())
        for d in dets:
            xy = self.grid.to_metres(d.pop("corners_px"))
            d["corners_m"] = [[round(float(x), 4), round(float(y), 4)] for x, y in xy]
        return dets

    def prediction_files(self) -> list[Path]:
        return [self.files.prediction(u.variant, u.model, lv, on) for u in self.units
                for on in (u.variant, *u.also) for lv in self.levels]

    def missing_predictions(self) -> list[Path]:
        return [p for p in self.prediction_files() if not p.is_file()]

    # ------------------------------------------------------------------ reading back
    def truths(self, v: Variant) -> list[dict]:
        """The validation frames' ground truth of variant ``v`` (checked)."""
        out = []
        for i in self.source.split["val"]:
            path = self.files.data(v).truth(i)
            if not path.is_file():
                raise InputError(path, "missing BEV ground truth: run the study (or --prepare-only) first")
            out.append(load_json(path, BevFrameTruth).model_dump(by_alias=True))
        return out

    def read_predictions(self, path: Path) -> list[dict]:
        from fogsim.io.documents import read_json

        dets = read_json(path)
        check(dets, BevPredictions, path)
        return dets

    # ------------------------------------------------------------------ the plan
    def plan(self, shard: tuple[int, int] = (0, 1)) -> str:
        """What a run would do, after checking what can be checked without training: the dataset's trees,
        the first validation frame's labels, scans (and radar), and that the model YAML builds an OBB model."""
        first = self.source.split["val"][0]
        labels = self.source.labels(first)
        for lv in self.levels:
            self.source.scan(lv, first)
            if self.sensor == "lidar+radar":
                if not self.source.has_radar:
                    raise InputError(self.source.root / "radar", "--sensor lidar+radar needs each level's radar "
                                                                 "detections (a render with --radar)")
                self.source.radar(lv, first)
        check_model(self.cfg.model, self.files.config_dir(), task="obb")
        n_train = len(self.source.split["train"])
        lines = [f"dataset {self.source.root}: levels {', '.join(self.levels)}; {n_train} training / "
                 f"{len(self.source.split['val'])} validation frames per level "
                 f"({len(labels.objects)} labelled objects in frame {first})",
                 f"BEV grid: {self.grid.describe()}",
                 f"variants: {', '.join(f'{v.name} ({len(v.channels)} channels)' for v in self.all_variants())}",
                 f"detector: {self.cfg.model} (OBB, builds), imgsz {self.cfg.imgsz}, batch {self.cfg.batch}, "
                 f"device {self.cfg.device}, seed {self.cfg.seed}",
                 f"models: {len(self.units)} in all; shard {shard[0]}/{shard[1]} trains {len(self.mine(shard))}:"]
        total = 0
        for u in self.mine(shard):
            images = n_train * (len(self.levels) if u.model == MIXED_MODEL else 1)
            epochs = self.cfg.epochs_for(u.model)
            total += images * epochs
            done = " (done)" if self.files.run_done(u.variant, u.model).is_file() else ""
            on = f", also run on {', '.join(o.name for o in u.also)}" if u.also else ""
            lines.append(f"  {u.name}: {epochs} epochs × {images} rasters{on}{done}")
        lines.append(f"training images this shard: {total:,} (epochs × rasters); predictions: "
                     f"{len(self.prediction_files())} files in all")
        return "\n".join(lines)
