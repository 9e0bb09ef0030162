"""Per-object ground truth from the instance mask: boxes, visibility, distance (their COCO
record: :mod:`fogsim.dataset.coco`).

Conventions (the box formats and their conversions live in :mod:`fogsim.boxes`):

* Instance masks are H×W uint16; 0 is background/sky, object ids are ≥ 1.
* Boxes come from the *visible* mask pixels and are ``[x0, y0, x1, y1)`` in pixel-edge
  coordinates: x1 = last column + 1, so a single pixel at column 5 has x0 = 5, x1 = 6.
* YOLO lines: :func:`fogsim.boxes.yolo_line` (``class cx cy w h``, normalised, 6 decimals).
* Distance: the median ray distance (metres, camera centre to surface) over the object's
  visible pixels; non-finite values (no hit) are ignored.
* ``asset_file``: the model file of an object from the user's asset library
  (:mod:`fogsim.scene.library`); None for fogsim's procedural models.
"""
from __future__ import annotations

import numpy as np

from fogsim.boxes import MaskRuns
from fogsim.scene.classes import CLASS_ID, is_labelled

DISTANCE_STAT = "median ray distance over visible pixels"
#: the label filters' defaults (a preset's ``labels`` block overrides them): an object with fewer
#: visible pixels, or a smaller visible fraction of its silhouette, is kept out of the YOLO labels
from fogsim.schema.presets import MIN_PIXELS, MIN_VISIBLE_FRACTION  # noqa: E402  (the preset's defaults)


def asset_file(obj: dict) -> str | None:
    """The library model file of a scene object, None for a procedural one."""
    asset = obj.get("asset", {})
    return asset["params"]["file"] if asset.get("type") == "library" else None


def object_records(mask: np.ndarray, ray_distance: np.ndarray, objects: list[dict],
                   silhouettes: dict[int, dict], min_pixels: int = MIN_PIXELS,
                   min_visible_fraction: float = MIN_VISIBLE_FRACTION) -> list[dict]:
    """One record per labelled object with at least one visible pixel, in ``objects`` order.

    ``silhouettes[id]`` holds ``pixels_in_image`` and ``pixels_total`` (unoccluded silhouette
    area inside the image and in all), from :func:`fogsim.render.silhouette.silhouette_areas`.
    ``visible_fraction`` = visible pixels / pixels_in_image (≤ 1; 1 when the silhouette is
    empty, e.g. a sub-pixel object); ``truncation`` = 1 − pixels_in_image / pixels_total.
    Objects below ``min_pixels`` visible pixels or ``min_visible_fraction`` stay in the list
    with ``kept = False`` and a ``reason``; only kept records go to YOLO labels, and to COCO
    as objects (the others as ignore regions).
    Objects with no visible pixel (hidden or outside the view) get no record.
    """
    h, w = mask.shape
    runs = MaskRuns.of(mask)
    boxes = runs.boxes()
    labelled = [o for o in objects if is_labelled(o["class"]) and int(o["id"]) in boxes]
    dist = runs.median_distance(ray_distance, [o["id"] for o in labelled])
    records = []
    for obj in labelled:
        oid = int(obj["id"])
        if oid not in silhouettes:
            raise ValueError(f"object {oid} ({obj['class']}) is visible but has no silhouette")
        box, sil = boxes[oid], silhouettes[oid]
        in_image, total = int(sil["pixels_in_image"]), int(sil["pixels_total"])
        visible = min(1.0, box["pixels"] / in_image) if in_image > 0 else 1.0
        truncation = 1.0 - in_image / total if total > 0 else 0.0
        x0, y0, x1, y1 = box["bbox"]
        reason = ("too few pixels" if box["pixels"] < min_pixels
                  else "too occluded" if visible < min_visible_fraction else None)
        d = dist[oid]
        records.append({
            "id": oid, "class": obj["class"], "class_id": CLASS_ID[obj["class"]],
            "bbox": box["bbox"], "pixels": box["pixels"],
            "visible_fraction": round(visible, 4), "truncation": round(max(truncation, 0.0), 4),
            "truncated": x0 == 0 or y0 == 0 or x1 == w or y1 == h,
            "distance_m": None if np.isnan(d) else round(d, 3), "distance_stat": DISTANCE_STAT,
            "kept": reason is None, "reason": reason, "asset_file": asset_file(obj)})
    return records


def relabel_distorted(records: list[dict], mask: np.ndarray, ray_distance: np.ndarray,
                      min_pixels: int = MIN_PIXELS, min_visible_fraction: float = MIN_VISIBLE_FRACTION) -> list[dict]:
    """The records of the pinhole render re-measured on the lens-distorted ``mask`` (and ray
    distance resampled with it, :func:`fogsim.sensor.distort_nearest`): box, pixels, truncated
    flag, distance and ``kept`` come from the distorted mask (what the image shows); the scene's
    ``visible_fraction`` and ``truncation`` stay those of the pinhole render. Objects the lens
    pushes out of the image are dropped."""
    h, w = mask.shape
    runs = MaskRuns.of(mask)
    boxes = runs.boxes()
    out = [dict(r) for r in records if r["id"] in boxes]
    dist = runs.median_distance(ray_distance, [r["id"] for r in out])
    for r in out:
        box = boxes[r["id"]]
        x0, y0, x1, y1 = box["bbox"]
        d = dist[r["id"]]
        reason = ("too few pixels" if box["pixels"] < min_pixels
                  else "too occluded" if r["visible_fraction"] < min_visible_fraction else None)
        r.update(bbox=box["bbox"], pixels=box["pixels"], truncated=x0 == 0 or y0 == 0 or x1 == w or y1 == h,
                 distance_m=None if np.isnan(d) else round(d, 3), kept=reason is None, reason=reason)
    return out
