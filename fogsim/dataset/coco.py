"""The COCO record of the dataset format: categories, annotations and the per-level COCO file.

Conventions (boxes: :mod:`fogsim.boxes`):

* ``bbox = [x, y, w, h]`` floats in pixel-edge coordinates (from a record's ``[x0, y0, x1, y1)``);
  ``area`` = the record's ``pixels``: the visible (instance mask) pixel count for renders, the box
  area for real datasets' labels; ``category_id`` = YOLO class id + 1 (COCO ids start at 1; 0 is
  the background for most COCO consumers).
* A record the label filters dropped (too few pixels, too occluded), or a real dataset's ignore
  region (a Cityscapes group), is an ignore region: ``iscrowd = 1`` with its ``ignore_reason``.
* ``distance_m`` is always present (None = unknown); :data:`COCO_EXTRA_FIELDS` are copied when the
  record has them (``box3d``: the object's oriented 3D box, :mod:`fogsim.render.boxes3d`); with a LiDAR,
  ``lidar_points`` is the points in that box at the file's level; the per-level
  :data:`COCO_VISIBILITY_FIELDS` come from the record's ``visibility[<level key>]``
  (:func:`fogsim.fog.visibility.attach_visibility` computes them).

Records are the renderer's (:func:`fogsim.render.labels.object_records`) or a real dataset's
(:class:`fogsim.readers.base.Labels`), both as stored in ``meta/<frame>.json``.
"""
from __future__ import annotations

from fogsim.boxes import coco_category, xyxy_to_xywh
from fogsim.dataset.layout import DatasetLayout
from fogsim.scene.classes import LABELLED

#: optional per-record fields a COCO annotation carries when the record has them (rendered records:
#: ``visible_fraction``, ``truncation``; real datasets': the distance's provenance, Waymo's
#: difficulty and object id, …)
COCO_EXTRA_FIELDS = ("visible_fraction", "truncation", "distance_source", "difficulty", "object_id", "box3d")
#: the per-level fields of a record's ``visibility[<level key>]`` that go into that level's annotations
COCO_VISIBILITY_FIELDS = ("transmission", "contrast", "visible")


def coco_categories(classes=LABELLED) -> list[dict]:
    """COCO categories in YOLO order: ``id`` = index in ``classes`` + 1 (renders: fogsim's
    :data:`~fogsim.scene.classes.LABELLED`; real datasets: their own class list)."""
    return [{"id": coco_category(i), "name": name, "supercategory": "street"} for i, name in enumerate(classes)]


def coco_annotation(record: dict, ann_id: int, image_id: int) -> dict:
    """A COCO annotation of one record (the module docstring's conventions). An ignore region
    (``iscrowd = 1``) makes a detection on it neither a hit nor a false alarm, in pycocotools as in
    :mod:`fogsim.detection.coco_eval` (COCO trainers skip crowd boxes)."""
    ann = {"id": ann_id, "image_id": image_id, "category_id": coco_category(record["class_id"]),
           "bbox": [float(v) for v in xyxy_to_xywh(record["bbox"])],
           "area": float(record["pixels"]), "iscrowd": int(not record["kept"]),
           "distance_m": record.get("distance_m")}
    ann |= {k: record[k] for k in COCO_EXTRA_FIELDS if k in record}
    return ann | ({} if record["kept"] else {"ignore_reason": record.get("reason")})


def visibility_fields(record: dict, level_key: str) -> dict:
    """The COCO annotation fields ``transmission``, ``contrast``, ``visible`` of one level
    (``{}`` when the record has no visibility for it, e.g. a dataset from before this existed:
    the evaluator then counts the object as visible)."""
    vis = (record.get("visibility") or {}).get(level_key)
    return {} if vis is None else {k: vis.get(k) for k in COCO_VISIBILITY_FIELDS}


def lidar_fields(record: dict, level_key: str) -> dict:
    """``lidar_points``: the LiDAR points in the object's 3D box at this level (``{}`` without a LiDAR)."""
    points = (record.get("lidar_points") or {}).get(level_key)
    return {} if points is None else {"lidar_points": points}


def coco_dataset(metas: list[dict], level, layout: DatasetLayout, classes=LABELLED) -> dict:
    """COCO detection JSON of one fog ``level`` (its ``key`` and ``to_dict()``: a
    :class:`fogsim.fog.levels.FogLevel`); image ids follow the order of ``metas`` (the frame
    records, sorted by frame) from 1; categories named by ``classes`` (the dataset's own list;
    renders: fogsim's LABELLED)."""
    images, annotations = [], []
    for image_id, meta in enumerate(metas, start=1):
        path = layout.relative(layout.image(level.key, meta["frame"]))
        images.append({"id": image_id, "file_name": path, "width": meta["width"],
                       "height": meta["height"], "frame": meta["frame"]})
        for rec in meta["objects"]:
            annotations.append(coco_annotation(rec, len(annotations) + 1, image_id)
                               | visibility_fields(rec, level.key)  # transmission, contrast, visible
                               | lidar_fields(rec, level.key))
    return {"info": {"description": f"fogsim, fog level {level.key}", "fog_level": level.to_dict(),
                     "area": "visible (instance mask) pixel count",
                     "category_id": "YOLO class id + 1"},
            "licenses": [], "images": images, "annotations": annotations,
            "categories": coco_categories(classes)}
