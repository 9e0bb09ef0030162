"""The documents of the bird's-eye-view study (``fogsim study --sensor lidar|lidar+radar``), read back by
its report: each frame's ground truth and each model's predictions (:mod:`fogsim.detection.bev`).

=========================================  ======================  ===========================
document                                   model                   read by
=========================================  ======================  ===========================
``bev/<variant>/data/gt/<id>.json``        :class:`BevFrameTruth`  the report, the pictures
``bev/<variant>/predictions/…/<l>.json``   :class:`BevPredictions` the report, the pictures
``bev/study.json``                         :class:`BevStudyFile`   ``--report-only``
``report/cross_density.json`` (camera)     :class:`CameraTable`    the BEV report, beside it
=========================================  ======================  ===========================

Corners are the four ground corners of a rotated box in the LiDAR frame (x forward, y left; metres).
"""
from __future__ import annotations

from typing import Annotated, ClassVar, Literal

from pydantic import Field, RootModel

from fogsim.schema.base import Bool, NonNegInt, Number, Open, Text, int_in, items, number_in
from fogsim.schema.documents import TrainParameters

__all__ = ["BEV_CLASS_NAMES", "BevFrameTruth", "BevPredictions", "BevStudyFile", "CameraTable"]

#: the study's classes (YOLO id = index), as :data:`fogsim.detection.bev.source.BEV_CLASSES`
BEV_CLASS_NAMES = ("car", "pedestrian", "cyclist")
Corners = items(items(Number, 2, "[x, y] point"), 4, "list of 4 corners")
ImageBox = items(Number, 4, "[left, top, right, bottom] box")


class BevTruthObject(Open):
    """One labelled object: class, whether it is scored (False: a neighbouring class, ignored), KITTI's
    difficulty (0–3), its footprint, ground distance and the LiDAR points in its 3D box per level."""

    cls: Literal[BEV_CLASS_NAMES] = Field(alias="class")
    scored: Bool
    difficulty: int_in(0, 3)
    corners_m: Corners
    distance_m: number_in(0)
    points: dict[Text, NonNegInt]


class BevFrameTruth(Open):
    """``gt/<id>.json``: one frame's ground truth (written last: it marks the frame's rasters done)."""

    document: ClassVar[str] = "BEV ground truth"

    id: Annotated[str, Field(strict=True, min_length=1)]
    frame: Text
    split: Literal["train", "val"]
    objects: list[BevTruthObject]
    dontcare: list[ImageBox]
    ground_z: Number
    projection: items(items(Number, 4, "row of 4"), 3, "3×4 matrix")
    image_size: items(int_in(1, 1 << 20), 2, "[width, height]")


class BevDetection(Open):
    image_id: Annotated[str, Field(strict=True, min_length=1)]
    category_id: int_in(0, len(BEV_CLASS_NAMES) - 1)
    score: number_in(0, 1)
    corners_m: Corners


class BevPredictions(RootModel[list[BevDetection]]):
    """``predictions/<model>/<level>.json``: a model's rotated boxes on a level's validation rasters."""

    document: ClassVar[str] = "BEV prediction file"



class BevStudyParameters(Open):
    dataset: Text
    sensor: Literal["lidar", "lidar+radar"]
    levels: list[Text]
    variants: list[Text]
    grid: dict
    split_sha256: Text
    train: TrainParameters


class BevStudyFile(Open):
    """``bev/study.json``: the dataset, sensor, variants, grid and split a BEV study is tied to, and how its
    models were trained."""

    document: ClassVar[str] = "BEV study file"

    parameters: BevStudyParameters


class CameraCell(Open):
    ap50: Number | None = None
    recall_all: Number | None = None
    recall_by_distance: dict[Text, Number | None] = {}


class CameraTable(RootModel[dict[Text, dict[Text, CameraCell]]]):
    """The camera study's ``report/cross_density.json`` (rows → levels → cells), set beside the BEV tables."""

    document: ClassVar[str] = "camera cross-density table"
