"""The schemas of fogsim's own documents — the files it writes and reads back — declared once,
here, and checked where each is read (:func:`~fogsim.schema.base.check`, ``load_json``,
``load_npz``): a failure is one line ``FILE: FIELD.PATH: problem (got VALUE)``.

=============================  ==============================  =====================================
document                       model                           read by
=============================  ==============================  =====================================
``meta/<frame>.json``          :class:`FrameMeta`              finalize (render, fog), depth score
``meta/<frame>.json`` camera   :class:`FrameCamera`            ``fogsim depth score --pred-kind ray``
``fogsim_run.json``            :class:`FogRunFile`             ``fogsim fog --finalize-only`` / end
``<level>/<name>.json``        :class:`PointsSidecar`          ``fogsim fog --points``' outcome totals
``render_run.json``            :class:`RenderRunFile`          ``fogsim render --finalize-only``, benches
``dataset.json``               :class:`DatasetManifest`        the study, dataset readers
``coco/<level>.json``          :class:`CocoFile`               the study (ground truth)
``study.json``                 :class:`StudyFile`              ``fogsim study --report-only``
``predictions/…/<level>.json`` :class:`Predictions`            the study's report
``runs/<m>/fogsim_done.json``  :class:`DoneFile`               the study's report
``--class-map`` JSON           :class:`ClassMapFile`           ``fogsim study --class-map``
``lidar_holdout/<key>.npz``    :class:`Holdout`                ``fogsim depth score --holdout``
=============================  ==============================  =====================================

Every model here is :class:`~fogsim.schema.base.Open` (keys a newer fogsim adds are ignored)
except the class map, which people write (:class:`~fogsim.schema.base.Closed`). Per-frame
documents (a frame's meta) are skipped and named by their readers (exit 1); the others are
run-wide (exit 2).
"""
from __future__ import annotations

import re
from pathlib import PurePosixPath, PureWindowsPath
from typing import Annotated, Any, ClassVar

import numpy as np
from pydantic import AfterValidator, BeforeValidator, ConfigDict, Field, RootModel

from fogsim.schema.base import Bool, Closed, Int, NonNegInt, Number, Open, Text, int_in, items, number_in

__all__ = ["ClassMapFile", "CocoFile", "DatasetManifest", "DoneFile", "FogFrameMeta", "FogRunFile", "FrameCamera",
           "FrameMeta", "Holdout", "LEVEL_KEY", "PointsSidecar", "Predictions", "RenderRunFile", "StudyFile",
           "level_key", "relative_path"]

Name = Annotated[str, Field(strict=True, min_length=1)]
Box = items(Number, 4, "[x0, y0, x1, y1] box")
CocoBox = items(Number, 4, "[x, y, w, h] box")
Side = int_in(1, 1 << 20)


def relative_path(v: str) -> str:
    """A path inside its dataset: relative, forward slashes, no ``..`` (COCO ``file_name``)."""
    if PurePosixPath(v).is_absolute() or PureWindowsPath(v).is_absolute() or PureWindowsPath(v).drive \
            or "\\" in v or ".." in PurePosixPath(v).parts:
        raise ValueError("must be a path inside the dataset (relative, no '..')")
    return v


#: the characters a fog level's key may hold: it names a folder (``images/<key>/``, ``OUT/<key>/samples/…``)
LEVEL_KEY = re.compile(r"[A-Za-z0-9_.\-]+")


def level_key(v: str) -> str:
    """A fog level's key: letters, digits, ``_``, ``.``, ``-``, and not ``.`` or ``..`` — one folder's name,
    never a path (the rule of :class:`fogsim.fog.levels.FogLevel`, and of every key read back from a dataset)."""
    if not isinstance(v, str) or not LEVEL_KEY.fullmatch(v) or v in (".", ".."):
        raise ValueError(f"fog level key {v!r} may hold only letters, digits, '_', '.', '-' (and is not '.' or "
                         "'..'): it names a folder")
    return v


# ----------------------------------------------------------------------------- a dataset's frames
class ObjectRecord(Open):
    """One labelled object of a frame (renderer's or a real dataset's records)."""

    class_: Name = Field(alias="class")
    class_id: NonNegInt
    bbox: Box
    pixels: number_in(0)
    kept: Bool
    reason: Text | None = None
    distance_m: number_in(0) | None = None


class Stereo(Open):
    split: Name


class FrameMeta(Open):
    """``meta/<frame>.json``: the frame record (written last; its presence marks the frame done)."""

    document: ClassVar[str] = "frame record"

    frame: Name
    width: Side
    height: Side
    objects: list[ObjectRecord]
    key: Name | None = None          # fogged real samples: the sample key
    stereo: Stereo | None = None     # renders with --stereo


class FogFrameMeta(FrameMeta):
    """``meta/<frame>.json`` of a labelled ``fogsim fog`` run: also the sample's key."""

    key: Name


class CameraRecord(Open):
    intrinsics: dict  # Intrinsics.to_dict(): checked by Intrinsics.from_dict


class FrameCamera(Open):
    """The part of ``meta/<frame>.json`` that ``fogsim depth score --pred-kind ray`` reads: the
    frame's camera (its intrinsics turn planar depth into ray distance)."""

    document: ClassVar[str] = "frame record"

    camera: CameraRecord


# ----------------------------------------------------------------------------- run files
class RunLevel(Open):
    key: Name
    name: Text
    beta: number_in(0)


class RunLabels(Open):
    classes: Annotated[list[Name], Field(min_length=1)]
    min_pixels: NonNegInt = 0


class FogRunParameters(Open):
    levels: Annotated[list[RunLevel], Field(min_length=1)]
    labels: RunLabels | None = None
    inputs: dict = {}
    seed: Int = 0


class FogRunFile(Open):
    """``fogsim_run.json`` of ``fogsim fog``: the claimed parameters (and what was read)."""

    document: ClassVar[str] = "fogsim fog run file"

    parameters: FogRunParameters
    samples: NonNegInt | None = None  # how many samples the whole run (every shard) fogs


class RenderRunParameters(Open):
    exposure: Number = 1.0
    name: Text | None = None         # the preset's name
    seed: Int | None = None          # the dataset seed
    style: Text | dict | None = None  # the style's name, or the whole style (as render writes it)


class PointsSidecar(Open):
    """``OUT/<level>/<name>.json`` of ``fogsim fog --points`` (a scan's or a radar sweep's level): what the
    end-of-run outcome totals read (:mod:`fogsim.fog.outcome_totals`)."""

    document: ClassVar[str] = "points sidecar"

    outcomes: dict[str, NonNegInt]
    empty_ray_clutter: NonNegInt = 0  # LiDAR: fog clutter on rays that returned nothing in clear air


class RenderRunLevel(RunLevel):
    key: Annotated[Name, AfterValidator(lambda v: folder_name(v))]  # it names images/<key>/, labels/<key>/


class RenderRunConfig(Open):
    """The whole configuration a render ran with (``render_run.json``'s ``config``,
    :meth:`fogsim.render.preset.RenderConfig.to_dict`): what ``--finalize-only`` finalizes with."""

    name: Text
    source: Text
    style: dict
    camera: dict
    resolution: items(Side, 2, "[width, height]")
    quality: dict = {}
    levels: Annotated[list[RenderRunLevel], Field(min_length=1), AfterValidator(lambda v: _distinct_keys(v))]
    fog_model: dict = {}
    labels: dict = {}
    exposure: Number = 1.0
    frames: int_in(1)
    seed: int_in(0) = 0
    stereo_baseline_m: number_in(0) | None = None
    train_fraction: number_in(0, 1, lo_open=True, hi_open=True) = 0.8
    lighting: dict = {}
    sensor: dict = {}
    assets: dict = {}
    lidar: dict = {}
    radar: dict = {}


class RenderRunFile(Open):
    """``render_run.json``: the claimed parameters, the whole configuration (``config``) and the Blender
    that claimed it — read by ``fogsim render --finalize-only`` (the
    configuration) and by the fog-physics bench and fit-fog (exposure; preset, seed, style)."""

    document: ClassVar[str] = "render run file"

    parameters: RenderRunParameters = RenderRunParameters()
    config: RenderRunConfig | None = None
    blender: Text | None = None


def _distinct_keys(levels: list) -> list:
    keys = [lv.key for lv in levels]
    if len(set(keys)) != len(keys):
        raise ValueError(f"must be distinct level keys (got {keys})")
    return levels


# ----------------------------------------------------------------------------- dataset files
def folder_name(v: str) -> str:
    """A level key names a folder under images/ and labels/: no path of its own."""
    if "/" in v or "\\" in v or v in (".", ".."):
        raise ValueError("must be a folder name (no '/', '\\', '.' or '..')")
    return v


def _distinct(what: str):
    def check(v: list) -> list:
        names = [getattr(x, "key", x) for x in v]
        if len(set(names)) != len(names):
            raise ValueError(f"must be distinct {what} (got {names})")
        return v
    return AfterValidator(check)


class ManifestLevel(Open):
    key: Annotated[Name, AfterValidator(folder_name)]


class DatasetManifest(Open):
    """``dataset.json``: the levels (their keys name folders) and the dataset's class list."""

    document: ClassVar[str] = "fogsim dataset manifest"

    levels: Annotated[list[ManifestLevel], Field(min_length=1), _distinct("level keys")]
    classes: Annotated[list[Name], Field(min_length=1), _distinct("class names")]


class CocoImage(Open):
    id: Int
    file_name: Annotated[Name, AfterValidator(relative_path)]
    width: Side | None = None
    height: Side | None = None


class CocoAnnotation(Open):
    image_id: Int
    category_id: Int
    bbox: CocoBox
    iscrowd: int_in(0, 1) = 0


class CocoFile(Open):
    """``coco/<level>.json``: COCO detection ground truth (file names inside the dataset)."""

    document: ClassVar[str] = "COCO file"

    images: list[CocoImage]
    annotations: list[CocoAnnotation]


# ----------------------------------------------------------------------------- the study
class TrainParameters(Closed):
    """``study.json``'s ``train``: :class:`fogsim.detection.yolo.TrainConfig`'s fields."""

    model: Name = "yolov8n.yaml"
    epochs: int_in(1) = 20
    mixed_epochs: int_in(1) | None = None
    imgsz: int_in(1) = 320
    batch: int_in(1) = 8
    nbs: int_in(1) | None = None
    device: Text = "auto"
    workers: NonNegInt = 2
    seed: Int = 0
    patience: NonNegInt = 100
    cache: Bool = False
    plots: Bool = True


class StudyParameters(Open):
    dataset: Text
    levels: list[Name]
    validation_images_sha256: Text
    train: TrainParameters


class StudyFile(Open):
    """``study.json``: the dataset, levels and validation split the study is tied to, and how
    its models were trained."""

    document: ClassVar[str] = "study file"

    parameters: StudyParameters


class Detection(Open):
    image_id: Int
    category_id: Int
    bbox: CocoBox
    score: number_in(0, 1)


class Predictions(RootModel[list[Detection]]):
    """``predictions/<model>/<level>.json``: COCO results (a list of detections)."""

    document: ClassVar[str] = "prediction file"


class DoneFile(Open):
    """``runs/<model>/fogsim_done.json``: written last when a model's training finished."""

    document: ClassVar[str] = "training record"

    state: Text | None = None
    seconds_this_run: Number | None = None
    seconds_training: Number | None = None


class ClassMapFile(Closed):
    """A ``--class-map`` JSON: ``{"map": {source: target or null}, "classes": [target, …]}``
    (the flat ``{source: target}`` form is read as ``{"map": …}``)."""

    document: ClassVar[str] = "class map"

    map: dict[Name, Name | None]
    classes: Annotated[list[Name], Field(min_length=1)] | None = None


# ----------------------------------------------------------------------------- NPZ documents
def _vector(v: Any) -> np.ndarray:
    a = np.asarray(v)
    if a.dtype.kind not in "iuf":
        raise ValueError(f"must be an array of numbers, got dtype {a.dtype}")
    if not np.isfinite(a).all():
        raise ValueError("must hold finite numbers")
    return a.reshape(-1)


def _scalar_int(v: Any) -> int:
    a = np.asarray(v)
    if a.shape != () or a.dtype.kind not in "iu":
        raise ValueError(f"must be one integer, got an array of dtype {a.dtype} and shape {list(a.shape)}")
    return int(a)


def _scalar_number(v: Any) -> float:
    a = np.asarray(v)
    if a.shape != () or a.dtype.kind not in "iuf" or not np.isfinite(a):
        raise ValueError(f"must be one finite number, got dtype {a.dtype} and shape {list(a.shape)}")
    return float(a)


Vector = Annotated[Any, AfterValidator(_vector)]
ScalarSide = Annotated[Any, BeforeValidator(_scalar_int), AfterValidator(lambda v: _side(v))]
ScalarNumber = Annotated[Any, BeforeValidator(_scalar_number)]


def _side(v: int) -> int:
    if not 1 <= v <= 1 << 20:
        raise ValueError(f"must be an image side in [1, {1 << 20}]")
    return v


class Holdout(Open):
    """``lidar_holdout/<key>.npz``: held-out LiDAR points of one image — ``u``, ``v`` (px),
    ``ray`` (m) of equal length, ``width``, ``height`` (px) and optionally the camera
    ``fx``, ``fy``, ``cx``, ``cy`` (px)."""

    document: ClassVar[str] = "LiDAR hold-out file"

    model_config = ConfigDict(arbitrary_types_allowed=True, extra="ignore", frozen=True)

    u: Vector
    v: Vector
    ray: Vector
    width: ScalarSide
    height: ScalarSide
    fx: ScalarNumber | None = None
    fy: ScalarNumber | None = None
    cx: ScalarNumber | None = None
    cy: ScalarNumber | None = None
