"""The COCO record of the dataset format: categories, annotations and the per-level COCO file.

Conventions (boxes: :mod:`fogsim.boxes`):

* ``bbox = [x, y, w, h]`` floats in pixel-edge coordinates (from a record's ``[x0, y0, x1, y1)``);
  ``area`` = the record's ``pixels``: the visible (instance mask) pixel count for renders, the box
  area for real datasets' labels; ``category_id`` = YOLO class id + 1 (COCO ids start at 1; 0 is
  the background for most COCO consumers).
* A record the label filters dropped (too few pixels, too occluded), or a real dataset's ignore
  region (a Cityscapes group), is an ignore region: ``iscrowd = 1`` with its ``ignore_reason``.
* An ignore region of **every** class — KITTI's ``DontCare``, STF's unlabelled types: the reader's
  per-class copies of one label line (records sharing a ``line`` number) — is **one** annotation of the
  category :data:`EVERY_CLASS` (``DontCare``, id = number of classes + 1, listed after the dataset's
  classes only when the dataset has such a region) with ``every_class: true``. COCO matches a crowd
  region to detections of its own category only: a per-category evaluator expands it first
  (:func:`expand_every_class`; fogsim's study does, :func:`fogsim.dataset.reader.val_ground_truth`).
* ``segmentation`` (COCO's compressed RLE, :mod:`fogsim.rle`; :func:`frame_segmentations`): the
  object's visible instance mask where the dataset has one — a render's ``masks/<frame>.png``, a
  record's own ``segmentation`` (Cityscapes' gtFine instances); an ignore region without a mask: the
  RLE of its box (so every ``iscrowd`` annotation carries one); a box-only object (Waymo, KITTI): its box
  as a polygon ``[[x0, y0, x1, y0, x1, y1, x0, y1]]``, as KITTI→COCO converters write it, marked
  ``segmentation_is_box: true`` — so every annotation has one and ``pycocotools.COCO.annToMask`` works on
  any fogsim COCO file, but a box is no outline: such files serve box evaluation, not
  ``COCOeval(iouType="segm")``.
* ``distance_m`` is always present (None = unknown); :data:`COCO_EXTRA_FIELDS` are copied when the
  record has them (``box3d``: the object's oriented 3D box, :mod:`fogsim.render.boxes3d`); with a LiDAR,
  ``lidar_points`` is the points in that box at the file's level; the per-level
  :data:`COCO_VISIBILITY_FIELDS` come from the record's ``visibility[<level key>]``
  (:func:`fogsim.fog.visibility.attach_visibility` computes them).

Records are the renderer's (:func:`fogsim.render.labels.object_records`) or a real dataset's
(:class:`fogsim.readers.base.Labels`), both as stored in ``meta/<frame>.json``.
"""
from __future__ import annotations

import copy

from fogsim.boxes import coco_category, xyxy_to_xywh
from fogsim.dataset.layout import DatasetLayout
from fogsim.io.depth_files import read_uint16_map
from fogsim.rle import box_rle, rle_encode, rle_encode_box
from fogsim.scene.classes import LABELLED

#: optional per-record fields a COCO annotation carries when the record has them (rendered records:
#: ``visible_fraction``, ``truncation``; real datasets': the distance's provenance, Waymo's
#: difficulty and object id, …)
COCO_EXTRA_FIELDS = ("visible_fraction", "truncation", "distance_source", "difficulty", "object_id", "box3d")
#: the per-level fields of a record's ``visibility[<level key>]`` that go into that level's annotations
COCO_VISIBILITY_FIELDS = ("transmission", "contrast", "visible")
#: the category name of an ignore region of every class (KITTI's word for it)
EVERY_CLASS = "DontCare"


def coco_categories(classes=LABELLED) -> list[dict]:
    """COCO categories in YOLO order: ``id`` = index in ``classes`` + 1 (renders: fogsim's
    :data:`~fogsim.scene.classes.LABELLED`; real datasets: their own class list)."""
    return [{"id": coco_category(i), "name": name, "supercategory": "street"} for i, name in enumerate(classes)]


def every_class_category(classes) -> dict:
    """The category of an ignore region of every class: after the dataset's own (module docstring)."""
    return {"id": coco_category(len(classes)), "name": EVERY_CLASS, "supercategory": "ignore"}


def coco_annotation(record: dict, ann_id: int, image_id: int, segmentation: dict | None = None,
                    every_class_id: int | None = None) -> dict:
    """A COCO annotation of one record (the module docstring's conventions). An ignore region
    (``iscrowd = 1``) makes a detection on it neither a hit nor a false alarm, in pycocotools as in
    :mod:`fogsim.detection.coco_eval` (COCO trainers skip crowd boxes). ``segmentation``: its RLE
    (None: no ``segmentation`` key); ``every_class_id``: the record is an ignore region of every class,
    of this category."""
    category = coco_category(record["class_id"]) if every_class_id is None else every_class_id
    ann = {"id": ann_id, "image_id": image_id, "category_id": category,
           "bbox": [float(v) for v in xyxy_to_xywh(record["bbox"])],
           "area": float(record["pixels"]), "iscrowd": int(not record["kept"]),
           "distance_m": record.get("distance_m")}
    if segmentation is not None:
        ann["segmentation"] = segmentation
        if isinstance(segmentation, list):  # a box-only label's box as a polygon (the module docstring)
            ann["segmentation_is_box"] = True
    ann |= {k: record[k] for k in COCO_EXTRA_FIELDS if k in record}
    if every_class_id is not None:
        ann["every_class"] = True
    return ann | ({} if record["kept"] else {"ignore_reason": record.get("reason")})


def coco_records(records: list[dict]) -> list[tuple[int, bool]]:
    """The records of one frame that become annotations, as ``(index, every_class)``: the per-class
    copies of one label line's ignore region (not kept, one ``line`` number) are one region of every
    class (the first copy stands for them); every other record is itself."""
    lines: dict = {}
    for i, rec in enumerate(records):
        if not rec["kept"] and rec.get("line") is not None:
            lines.setdefault(rec["line"], []).append(i)
    out = []
    for i, rec in enumerate(records):
        group = lines.get(rec.get("line")) if not rec["kept"] else None
        if group is None or len(group) == 1:
            out.append((i, False))
        elif group[0] == i:
            out.append((i, True))
    return out


def frame_segmentations(layout: DatasetLayout, meta: dict) -> list[dict | None]:
    """The COCO ``segmentation`` (RLE) of each record of a frame, or None (the module docstring): the
    record's own ``segmentation``; else, when the frame has an instance mask (``masks/<frame>.png``, a
    render's, of the frame's size), the mask pixels of the record's integer ``id``; else, for an ignore
    region, its box's RLE, and for a kept box-only record its box as a polygon (:func:`box_polygon`)."""
    records, h, w = meta["objects"], meta["height"], meta["width"]
    mask = None
    path = layout.mask(meta["frame"])
    if any("segmentation" not in r for r in records) and path.is_file():
        mask = read_uint16_map(path)
        if mask.shape != (h, w):
            mask = None
    out = []
    for rec in records:
        seg = rec.get("segmentation")
        rid = rec.get("id")
        if seg is None and mask is not None and isinstance(rid, int) and not isinstance(rid, bool):
            seg = _mask_rle(mask, rid, rec)
        if seg is None and not rec["kept"]:
            seg = box_rle(rec["bbox"], h, w)
        if seg is None:  # a box-only label (no mask): its box as a polygon
            seg = box_polygon(rec["bbox"])
        out.append(seg)
    return out


def box_polygon(bbox) -> list[list[float]]:
    """A box ``[x0, y0, x1, y1)`` (pixel edges) as a COCO polygon: its four corners, clockwise from the top left."""
    x0, y0, x1, y1 = (float(v) for v in bbox)
    return [[x0, y0, x1, y0, x1, y1, x0, y1]]


def _mask_rle(mask, rid: int, record: dict) -> dict | None:
    """The RLE of ``mask == rid``, from the record's box when its ``pixels`` are all there (a render's box
    is its mask's), else from the whole mask; None when the id has no pixel."""
    h, w = mask.shape
    x0, y0, x1, y1 = (int(round(float(v))) for v in record["bbox"])
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(max(x1, x0), w), min(max(y1, y0), h)
    crop = mask[y0:y1, x0:x1] == rid
    if crop.any() and crop.sum() == record.get("pixels"):
        return rle_encode_box(crop, y0, x0, h, w)
    inside = mask == rid
    return rle_encode(inside) if inside.any() else None


def expand_every_class(gt: dict) -> dict:
    """A copy of a COCO dict in which each ignore region of every class (``every_class``) is one crowd
    annotation per category of the dataset's own classes (new ids after the largest), and the
    :data:`EVERY_CLASS` category is gone: what a per-category evaluator needs to ignore every class's
    detections there. A dict without such regions comes back as a copy."""
    gt = copy.deepcopy(gt)
    every = {c["id"] for c in gt.get("categories", []) if c.get("name") == EVERY_CLASS}
    regions = [a for a in gt["annotations"] if a.get("every_class") or a["category_id"] in every]
    if not regions:
        return gt
    cats = [c for c in gt["categories"] if c["id"] not in every]
    anns = [a for a in gt["annotations"] if not (a.get("every_class") or a["category_id"] in every)]
    next_id = max((a["id"] for a in gt["annotations"]), default=0) + 1
    for region in regions:
        for cat in cats:
            anns.append(dict(region, id=next_id, category_id=cat["id"], iscrowd=1, every_class=True))
            next_id += 1
    return {**gt, "annotations": anns, "categories": cats}


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


def coco_dataset(metas: list[dict], level, layout: DatasetLayout, classes=LABELLED,
                 segmentations: list[list[dict | None]] | None = None) -> dict:
    """COCO detection JSON of one fog ``level`` (its ``key`` and ``to_dict()``: a
    :class:`fogsim.fog.levels.FogLevel`); image ids follow the order of ``metas`` (the frame
    records, sorted by frame) from 1; categories named by ``classes`` (the dataset's own list;
    renders: fogsim's LABELLED), and :data:`EVERY_CLASS` after them when a frame has such a region.
    ``segmentations``: per frame, :func:`frame_segmentations` (None: computed here)."""
    images, annotations = [], []
    every = every_class_category(classes)
    any_every = False
    for image_id, meta in enumerate(metas, start=1):
        path = layout.relative(layout.image(level.key, meta["frame"]))
        images.append({"id": image_id, "file_name": path, "width": meta["width"],
                       "height": meta["height"], "frame": meta["frame"]})
        segs = frame_segmentations(layout, meta) if segmentations is None else segmentations[image_id - 1]
        for i, every_class in coco_records(meta["objects"]):
            rec = meta["objects"][i]
            any_every |= every_class
            annotations.append(coco_annotation(rec, len(annotations) + 1, image_id, segs[i],
                                               every["id"] if every_class else None)
                               | visibility_fields(rec, level.key)  # transmission, contrast, visible
                               | lidar_fields(rec, level.key))
    return {"info": {"description": f"fogsim, fog level {level.key}", "fog_level": level.to_dict(),
                     "area": "visible (instance mask) pixel count",
                     "category_id": "YOLO class id + 1",
                     "segmentation": "COCO compressed RLE of the visible instance mask (ignore regions without "
                                     "one: their box); box-only labels: the box as a polygon "
                                     "(segmentation_is_box)"},
            "licenses": [], "images": images, "annotations": annotations,
            "categories": coco_categories(classes) + ([every] if any_every else [])}
