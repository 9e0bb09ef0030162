"""Ultralytics YOLO per fog level: offline set-up, training view, training, prediction.

Optional extra ``detect`` (Ultralytics is AGPL-3.0; imported only here, lazily). Ultralytics
runs offline: ``YOLO_OFFLINE=1``, ``YOLO_AUTOINSTALL=false``, its settings in a folder of
ours with a bundled TTF as ``Arial.ttf`` (else it downloads one to draw plots), models built
from a YAML (``yolov8n.yaml``, ``yolo12m.yaml`` …: random weights, nothing downloaded) and
``amp=False`` (its AMP check loads pretrained weights).

Ultralytics writes label caches beside the label folders, so training reads the dataset
through a *training view* (:func:`training_view`): symlinks to ``images/<level>`` and
``labels/<level>``, split lists and data YAMLs of its own — the dataset is never written.
Boxes: predictions are COCO results (xywh, pixels of the original image, category = YOLO
class + 1; :mod:`fogsim.boxes`), the convention of :mod:`fogsim.detection.coco_eval`. The
dataset is read through :mod:`fogsim.dataset.reader`.
"""
from __future__ import annotations

import csv
import os
import re
import shutil
import time
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path

from fogsim.boxes import coco_category, xyxy_to_xywh
from fogsim.dataset.layout import MIXED_MODEL, PARTS, DatasetLayout
from fogsim.dataset.reader import dataset_classes, read_split
from fogsim.dataset.writer import data_yaml
from fogsim.detection.layout import DONE_FILE
from fogsim.errors import FogsimError, InputError
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.documents import write_json

AUGMENTED_MODEL = "augmented"  # trained on clear images fogged on the fly (fogsim.detection.augmented)
SCATTER_MODEL = "scatter"  # trained on every level of a scatter-fogged render (fogsim.detection.fog_models)
MIN_ULTRALYTICS = (8, 4, 37)  # earlier releases inflate mAP (PR curve extended to recall 1)
# MIXED_MODEL ("mixed", the model trained on every level at once) is defined in
# fogsim.dataset.layout beside MIXED_SPLIT ("all", the dataset's every-level split).


@dataclass
class TrainConfig:
    """How each detector is trained (Ultralytics arguments of the same names)."""

    model: str = "yolov8n.yaml"   # a model YAML: trained from scratch
    epochs: int = 20
    mixed_epochs: int | None = None  # mixed, augmented, scatter; default: epochs (the compute of the
                                     # five specialists together)
    imgsz: int = 320
    batch: int = 8
    nbs: int | None = None        # nominal batch: gradients accumulate to it; None = batch (no
                                  # accumulation: small data needs the steps). Ultralytics' own: 64
    device: str = "auto"          # auto: first CUDA GPU when present, else cpu
    workers: int = 2
    seed: int = 0
    patience: int = 100
    cache: bool = False           # decoded images in RAM (Ultralytics: may break determinism)
    plots: bool = True

    def epochs_for(self, model_name: str) -> int:
        every_level = model_name in (MIXED_MODEL, AUGMENTED_MODEL, SCATTER_MODEL)  # every level's worth per epoch
        return self.mixed_epochs if every_level and self.mixed_epochs else self.epochs


def _version_tuple(text: str) -> tuple[int, ...]:
    """``"8.4.37rc1"`` → ``(8, 4, 37)``."""
    return tuple(int(re.match(r"\d*", p).group() or 0) for p in text.split(".")[:3])


def load_ultralytics(config_dir: str | Path):
    """The ``ultralytics`` module, set up to run offline with its settings in ``config_dir``."""
    config_dir = Path(config_dir).resolve()
    os.environ.setdefault("YOLO_CONFIG_DIR", str(config_dir))
    os.environ["YOLO_OFFLINE"] = "1"
    os.environ["YOLO_AUTOINSTALL"] = "false"
    try:
        import matplotlib
        import ultralytics
    except ImportError as exc:
        raise FogsimError(f"detector training needs the 'detect' extra ({exc.name} is missing): "
                          "pip install torch==2.14.1 torchvision==0.29.1, then pip install -e '.[blender,detect]' "
                          "(every extra of this venv in one command: docs/dependencies.md)") from None
    if _version_tuple(ultralytics.__version__) < MIN_ULTRALYTICS:
        raise FogsimError(f"ultralytics {ultralytics.__version__} inflates mAP; install >= 8.4.37")
    fonts = Path(os.environ["YOLO_CONFIG_DIR"]) / "Ultralytics"
    fonts.mkdir(parents=True, exist_ok=True)
    ttf = Path(matplotlib.get_data_path()) / "fonts" / "ttf" / "DejaVuSans.ttf"
    for name in ("Arial.ttf", "Arial.Unicode.ttf"):
        if not (fonts / name).exists():
            shutil.copyfile(ttf, fonts / name)
    return ultralytics


def resolve_device(device: str) -> str:
    """``auto`` → ``"0"`` when CUDA is available, else ``"cpu"``; anything else unchanged."""
    if device != "auto":
        return device
    import torch
    return "0" if torch.cuda.is_available() else "cpu"


def check_model(model: str, config_dir: str | Path, task: str | None = None) -> None:
    """Refuse, before any training, a model that is neither a YAML Ultralytics knows nor an
    existing weights file (a missing ``.pt`` name would be fetched from the hub), or whose task is not
    ``task`` (e.g. ``obb``: oriented boxes) when given."""
    ultralytics = load_ultralytics(config_dir)
    if not (model.endswith((".yaml", ".yml")) or Path(model).is_file()):
        raise InputError(model, "--model must be a model YAML (yolov8n.yaml, yolo11n.yaml, yolo12m.yaml …) "
                                "or an existing weights file: nothing can be downloaded")
    try:
        built = ultralytics.YOLO(model)
    except Exception as exc:  # Ultralytics raises FileNotFoundError, KeyError … for bad YAMLs
        raise InputError(model, f"Ultralytics cannot build this model: {exc}") from None
    if task is not None and built.task != task:
        kind = {"obb": "an oriented-box"}.get(task, f"a {task}")
        raise InputError(model, f"a {built.task} model; this study needs {kind} model "
                                f"(task {task}: e.g. yolov8n-{task}.yaml, yolo11n-{task}.yaml)")


# --- training view -------------------------------------------------------------------------------

def training_view(dataset: Path, view: Path, levels: list[str], classes=None,
                  augmented: str | None = None) -> dict[str, Path]:
    """The dataset's YOLO layout seen through symlinks under ``view``; returns a data YAML per
    model (each level, and ``mixed`` over every level), class names ``classes`` (default: the
    dataset's own list, from ``dataset.json``). With ``augmented`` (the clear level's key) also
    :data:`AUGMENTED_MODEL`: the clear training images listed once per level (the mixed model's
    number of images per epoch, to be fogged on the fly), validated on the mixed val split.

    ``view/<model>/<part>/<level>/{images,labels}`` link to the dataset's level folders, so
    Ultralytics' label cache (``…/<level>/labels.cache``) is one per model and split: never in
    the dataset, never shared by two trainings (shards may run concurrently).
    """
    dataset, view = dataset.resolve(), view.resolve()
    layout = DatasetLayout(dataset)
    classes = dataset_classes(layout) if classes is None else classes
    folders = {"images": layout.images_dir, "labels": layout.labels_dir}
    for lv in levels:
        for kind, folder in folders.items():
            if not folder(lv).is_dir():
                raise InputError(folder(lv), f"missing {kind} folder of fog level {lv!r}")
    data = {}
    models = [*((lv, [lv], [lv]) for lv in levels), (MIXED_MODEL, levels, levels)]
    if augmented is not None:
        models.append((AUGMENTED_MODEL, [augmented] * len(levels), levels))
    for model, train_members, val_members in models:
        members = list(dict.fromkeys(train_members + val_members))
        for part in PARTS:  # the mixed and augmented models validate on the mixed val split
            paths = []
            for lv in train_members if part == "train" else val_members:
                base = view / model / part / lv
                base.mkdir(parents=True, exist_ok=True)
                for kind, folder in folders.items():
                    replace_symlink(base / kind, folder(lv))
                paths += [base / "images" / layout.image(lv, f).name for f in read_split(layout, lv, part)]
            atomic_write_bytes(view / model / f"{part}.txt", ("\n".join(map(str, paths)) + "\n").encode())
        data[model] = view / model / "data.yaml"
        desc = f"fogsim training view of {dataset}: model {model} ({', '.join(members)})"
        atomic_write_bytes(data[model], data_yaml(view / model, "train.txt", "val.txt", desc, classes).encode())
    return data


def replace_symlink(link: Path, target: Path) -> None:
    """``link`` → ``target``, also when shards build the same view at the same time."""
    if link.is_symlink() and link.resolve() == target.resolve():
        return
    tmp = link.with_name(f".{link.name}.{os.getpid()}")
    tmp.unlink(missing_ok=True)
    tmp.symlink_to(target, target_is_directory=True)
    os.replace(tmp, link)


# --- training ------------------------------------------------------------------------------------

def train(name: str, data_file: Path, run: Path, cfg: TrainConfig, config_dir: Path, trainer=None,
          overrides: dict | None = None) -> Path:
    """Train (or resume, or skip when done) model ``name``; returns its ``best.pt``.

    ``run`` is the model's Ultralytics run folder (:meth:`fogsim.detection.layout.StudyLayout.run`:
    weights, results.csv, plots); its :data:`~fogsim.detection.layout.DONE_FILE`, written last,
    marks it trained. An interrupted run resumes from ``weights/last.pt`` (data, folder and device
    of this call, in case the study moved). ``trainer``: a custom Ultralytics trainer class
    (``YOLO.train(trainer=…)``), e.g. :func:`fogsim.detection.augmented.fog_trainer`'s. ``overrides``: more
    Ultralytics training arguments (the BEV study turns its colour augmentation off).
    """
    run = Path(run).resolve()
    best, last, done = run / "weights" / "best.pt", run / "weights" / "last.pt", run / DONE_FILE
    if done.is_file() and best.is_file():
        return best
    ultralytics = load_ultralytics(config_dir)
    started, state = time.perf_counter(), "trained"
    device = resolve_device(cfg.device)
    if last.is_file() and _resumable(last):
        state = "resumed"
        with _failure(f"training {name} failed"):
            ultralytics.YOLO(str(last)).train(resume=True, data=str(data_file), save_dir=str(run), device=device,
                                              workers=cfg.workers, trainer=trainer)
    elif last.is_file():
        state = "finished earlier"  # its last epoch was saved, the marker was not
    else:
        shutil.rmtree(run, ignore_errors=True)  # a start that saved no weights: begin again
        with _failure(f"training {name} failed"):
            ultralytics.YOLO(cfg.model).train(
                data=str(data_file), epochs=cfg.epochs_for(name), imgsz=cfg.imgsz, batch=cfg.batch,
                nbs=cfg.nbs or cfg.batch, device=device, workers=cfg.workers, seed=cfg.seed, deterministic=True,
                patience=cfg.patience, cache="ram" if cfg.cache else False, plots=cfg.plots,
                pretrained=False, amp=False, project=str(run.parent), name=run.name, exist_ok=True, trainer=trainer,
                **(overrides or {}))
    if not best.is_file():
        raise FogsimError(f"{run}: Ultralytics finished without writing weights/best.pt")
    write_json(done, {"model": name, "data": str(data_file), "config": asdict(cfg),
                      "ultralytics": ultralytics.__version__, "state": state,
                      "seconds_this_run": round(time.perf_counter() - started, 1),
                      "seconds_training": training_seconds(run)})
    return best


def training_seconds(run: Path) -> float | None:
    """Seconds Ultralytics spent training the model of ``run``, over every run that resumed it (the last
    ``time`` of its ``results.csv``); None where the file or the column is missing or unreadable."""
    try:
        with open(Path(run) / "results.csv", newline="") as f:
            rows = [{k.strip(): v for k, v in row.items() if k} for row in csv.DictReader(f)]
        return round(float(rows[-1]["time"]), 1)
    except (OSError, IndexError, KeyError, TypeError, ValueError):
        return None


ANSI = re.compile(r"\x1b\[[0-9;]*m")  # Ultralytics colours its messages


@contextmanager
def _failure(what: str):
    """An error inside Ultralytics (ValueError, RuntimeError … from its data loader, trainer or
    predictor) → one line ``what: Type: message`` (a FogsimError: exit 1), no traceback. Our own
    errors and Ctrl-C pass unchanged."""
    try:
        yield
    except FogsimError:
        raise
    except Exception as exc:
        message = " ".join(ANSI.sub("", str(exc)).split())  # Ultralytics' messages span lines, in colour
        raise FogsimError(f"{what}: {type(exc).__name__}: {message}") from None


def _resumable(checkpoint: Path) -> bool:
    """Whether an Ultralytics checkpoint is mid-training: it has its optimizer and epochs left.
    (The final epoch's checkpoint keeps the optimizer until the final evaluation strips it.)

    The one unpickling load in fogsim, and deliberately so: ``last.pt`` is Ultralytics' own
    pickle, written into this study's ``OUT/runs`` by the training that is being resumed, and
    Ultralytics unpickles it again to resume. It is never a file a user hands in (``--model``
    weights go to Ultralytics, which documents that they must be trusted)."""
    import torch
    try:
        ckpt = torch.load(checkpoint, map_location="cpu", weights_only=False)
        epochs = int(ckpt["train_args"]["epochs"])
    except Exception as exc:  # a kill while Ultralytics wrote it (it writes in place)
        raise FogsimError(f"{checkpoint}: unreadable checkpoint ({exc}); delete its run folder "
                          f"({checkpoint.parent.parent}) to train this model again") from None
    return ckpt.get("optimizer") is not None and 0 <= ckpt.get("epoch", -1) and ckpt["epoch"] + 1 < epochs


# --- prediction ----------------------------------------------------------------------------------

def predict(weights: Path, gt: dict, image_root: Path, cfg: TrainConfig, config_dir: Path,
            conf: float = 0.001, iou: float = 0.7, max_det: int = 100, chunk: int = 32) -> list[dict]:
    """COCO results of ``weights`` on every image of ``gt`` (paths relative to ``image_root``).

    ``conf``/``iou`` are Ultralytics' validation defaults (a low threshold for AP); ``max_det``
    is COCO's maxDets.
    """
    ultralytics = load_ultralytics(config_dir)
    with _failure(f"loading {weights} failed"):
        model = ultralytics.YOLO(str(weights))
    device = resolve_device(cfg.device)
    images = gt["images"]
    out = []
    for start in range(0, len(images), chunk):
        batch = images[start:start + chunk]
        paths = [image_root / im["file_name"] for im in batch]
        for path in paths:
            if not path.is_file():
                raise InputError(path, "validation image listed in the COCO file is missing")
        with _failure(f"prediction with {weights} failed"):
            results = model.predict([str(p) for p in paths], imgsz=cfg.imgsz, conf=conf, iou=iou,
                                    max_det=max_det, device=device, verbose=False, stream=True)
            for im, res in zip(batch, results):
                boxes = res.boxes
                for xyxy, score, cls in zip(boxes.xyxy.tolist(), boxes.conf.tolist(), boxes.cls.tolist()):
                    out.append({"image_id": im["id"], "category_id": coco_category(int(cls)), "score":
                                round(float(score), 5), "bbox": [round(v, 2) for v in xyxy_to_xywh(xyxy)]})
    return out


def predict_obb(weights: Path, images: list[tuple[str, Path]], cfg: TrainConfig, config_dir: Path,
                conf: float = 0.001, iou: float = 0.7, max_det: int = 100, chunk: int = 32) -> list[dict]:
    """Oriented boxes of an OBB model on ``images`` ((image id, path) pairs): ``{"image_id", "category_id"
    (YOLO class), "score", "corners_px" (4 × [u, v], pixels of the image)}``. Each image is read as
    Ultralytics' own loader reads it for training (a multi-page TIFF's pages as channels), so a model of
    any channel count sees what it was trained on."""
    import cv2

    ultralytics = load_ultralytics(config_dir)
    from ultralytics.utils.patches import imread

    with _failure(f"loading {weights} failed"):
        model = ultralytics.YOLO(str(weights))
    device = resolve_device(cfg.device)
    out = []
    for start in range(0, len(images), chunk):
        batch = images[start:start + chunk]
        arrays = []
        for _, path in batch:
            flags = cv2.IMREAD_UNCHANGED if Path(path).suffix.lower() in (".tif", ".tiff") else cv2.IMREAD_COLOR
            im = imread(str(path), flags) if Path(path).is_file() else None
            if im is None:
                raise InputError(path, "BEV raster missing or unreadable")
            arrays.append(im)
        with _failure(f"prediction with {weights} failed"):
            results = model.predict(arrays, imgsz=cfg.imgsz, conf=conf, iou=iou, max_det=max_det, device=device,
                                    verbose=False, stream=True)
            for (image_id, _), res in zip(batch, results):
                if res.obb is None:
                    raise FogsimError(f"{weights} is not an oriented-box (OBB) model")
                out += obb_records(image_id, res.obb)
    return out


def obb_records(image_id: str, obb) -> list[dict]:
    """One image's oriented boxes (an Ultralytics ``Results.obb``) as :func:`predict_obb`'s records: the four
    corners in pixels of the image (edges: Ultralytics' coordinates), ``category_id`` the YOLO class."""
    return [{"image_id": image_id, "category_id": int(cls), "score": round(float(score), 5),
             "corners_px": [[round(u, 3), round(v, 3)] for u, v in corners]}
            for corners, score, cls in zip(obb.xyxyxyxy.tolist(), obb.conf.tolist(), obb.cls.tolist())]
