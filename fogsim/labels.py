"""Per-object ground truth from the instance mask: boxes, visibility, distance; YOLO and COCO.

Conventions:

* Instance masks are H×W uint16; 0 is background/sky, object ids are ≥ 1.
* Boxes come from the *visible* mask pixels and are ``[x0, y0, x1, y1)`` in pixel-edge
  coordinates: x1 = last column + 1, so a single pixel at column 5 has x0 = 5, x1 = 6.
* YOLO: ``class cx cy w h`` with the box centre and size normalised by the image width and
  height, 6 decimals: rounding back recovers the integer box exactly (for images under
  600 000 pixels a side).
* COCO: ``bbox = [x, y, w, h]`` floats in pixel-edge coordinates, ``area`` = the visible
  (mask) pixel count, and ``category_id`` = YOLO class id + 1 (COCO ids start at 1; 0 is
  the background for most COCO consumers).
* Distance: the median ray distance (metres, camera centre to surface) over the object's
  visible pixels; non-finite values (no hit) are ignored.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scene.classes import CLASS_ID, LABELLED, is_labelled

DISTANCE_STAT = "median ray distance over visible pixels"


@dataclass(frozen=True)
class _Runs:
    """Horizontal runs of equal non-zero ids, grouped by id (raster order within an id)."""

    id: np.ndarray      # id of each run
    start: np.ndarray   # flat index of its first pixel
    length: np.ndarray  # its length in pixels
    ids: np.ndarray     # the distinct ids, ascending
    first: np.ndarray   # index of each id's first run

    @classmethod
    def of(cls, mask: np.ndarray) -> "_Runs":
        if mask.ndim != 2:
            raise ValueError(f"an instance mask is 2-D, got shape {mask.shape}")
        w = mask.shape[1]
        flat = np.ascontiguousarray(mask).ravel()
        change = np.empty(flat.size, bool)
        change[:1] = True
        np.not_equal(flat[1:], flat[:-1], out=change[1:])
        change[::w] = True  # every row starts a run, so no run crosses a row end
        start = np.flatnonzero(change)
        length = np.diff(np.append(start, flat.size))
        run_id = flat[start]
        fg = run_id > 0
        run_id, start, length = run_id[fg], start[fg], length[fg]
        order = np.argsort(run_id, kind="stable")
        run_id, start, length = run_id[order], start[order], length[order]
        ids, first = np.unique(run_id, return_index=True)
        return cls(run_id, start, length, ids, first)

    def pixel_index(self, wanted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Flat indices of the pixels of the ``wanted`` ids (all present), grouped by id, and the
        group bounds: id k's pixels are ``idx[bounds[k]:bounds[k + 1]]``."""
        sel = np.isin(self.id, wanted)
        start, length = self.start[sel], self.length[sel]
        offsets = np.cumsum(length) - length
        idx = np.repeat(start - offsets, length) + np.arange(length.sum())
        run_id = self.id[sel]
        _, group_start = np.unique(run_id, return_index=True)
        bounds = np.append(offsets[group_start], idx.size)
        return idx, bounds


def boxes_from_mask(mask: np.ndarray) -> dict[int, dict]:
    """``{id: {"bbox": [x0, y0, x1, y1], "pixels": n}}`` for every id > 0 in the mask.

    Works on the horizontal runs of the mask (one pass over the pixels), so its cost
    does not grow with the number of ids.
    """
    return _boxes(_Runs.of(mask), mask.shape[1])


def _boxes(runs: _Runs, width: int) -> dict[int, dict]:
    if not runs.ids.size:
        return {}
    row, x0 = np.divmod(runs.start, width)
    x1 = x0 + runs.length
    last = np.append(runs.first[1:], runs.id.size) - 1
    bx0 = np.minimum.reduceat(x0, runs.first)
    bx1 = np.maximum.reduceat(x1, runs.first)
    pixels = np.add.reduceat(runs.length, runs.first)
    y0, y1 = row[runs.first], row[last] + 1  # runs are in raster order within an id
    return {int(i): {"bbox": [int(a), int(b), int(c), int(d)], "pixels": int(n)}
            for i, a, b, c, d, n in zip(runs.ids, bx0, y0, bx1, y1, pixels)}


def median_distance(mask: np.ndarray, ray_distance: np.ndarray, ids) -> dict[int, float]:
    """Median ray distance (metres) over each id's pixels, ignoring non-finite values.

    Ids absent from the mask, or with no finite distance, map to NaN.
    """
    return _median_distance(_Runs.of(mask), ray_distance, ids)


def _median_distance(runs: _Runs, ray_distance: np.ndarray, ids) -> dict[int, float]:
    wanted = np.asarray(sorted(set(int(i) for i in ids)), dtype=np.int64)
    out = {int(i): float("nan") for i in wanted}
    present = wanted[np.isin(wanted, runs.ids)]
    if not present.size:
        return out
    idx, bounds = runs.pixel_index(present)
    values = np.ascontiguousarray(ray_distance).ravel()[idx]
    for i, a, b in zip(present, bounds[:-1], bounds[1:]):
        v = values[a:b]
        v = v[np.isfinite(v)]
        if v.size:
            out[int(i)] = float(np.median(v))
    return out


def object_records(mask: np.ndarray, ray_distance: np.ndarray, objects: list[dict],
                   silhouettes: dict[int, dict], min_pixels: int = 25,
                   min_visible_fraction: float = 0.1) -> list[dict]:
    """One record per labelled object with at least one visible pixel, in ``objects`` order.

    ``silhouettes[id]`` holds ``pixels_in_image`` and ``pixels_total`` (unoccluded silhouette
    area inside the image and in all), from :func:`fogsim.silhouette.silhouette_areas`.
    ``visible_fraction`` = visible pixels / pixels_in_image (≤ 1; 1 when the silhouette is
    empty, e.g. a sub-pixel object); ``truncation`` = 1 − pixels_in_image / pixels_total.
    Objects below ``min_pixels`` visible pixels or ``min_visible_fraction`` stay in the list
    with ``kept = False`` and a ``reason``; only kept records go to YOLO labels, and to COCO
    as objects (the others as ignore regions).
    Objects with no visible pixel (hidden or outside the view) get no record.
    """
    h, w = mask.shape
    runs = _Runs.of(mask)
    boxes = _boxes(runs, w)
    labelled = [o for o in objects if is_labelled(o["class"]) and int(o["id"]) in boxes]
    dist = _median_distance(runs, ray_distance, [o["id"] for o in labelled])
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
            "kept": reason is None, "reason": reason})
    return records


# ----------------------------------------------------------------------------- YOLO
def yolo_line(record: dict, width: int, height: int) -> str:
    """``"cls cx cy w h"``: class id and the box centre/size normalised to [0, 1], 6 decimals."""
    x0, y0, x1, y1 = record["bbox"]
    return (f"{record['class_id']} {(x0 + x1) / 2 / width:.6f} {(y0 + y1) / 2 / height:.6f} "
            f"{(x1 - x0) / width:.6f} {(y1 - y0) / height:.6f}")


def parse_yolo_line(line: str, width: int, height: int) -> tuple[int, list[int]]:
    """Inverse of :func:`yolo_line`: ``(class_id, [x0, y0, x1, y1])`` in whole pixels."""
    fields = line.split()
    if len(fields) != 5:
        raise ValueError(f"a YOLO box line has 5 fields (cls cx cy w h), got {line!r}")
    cx, cy, bw, bh = (float(f) for f in fields[1:])
    box = [round((cx - bw / 2) * width), round((cy - bh / 2) * height),
           round((cx + bw / 2) * width), round((cy + bh / 2) * height)]
    return int(fields[0]), box


# ----------------------------------------------------------------------------- COCO
def coco_category(class_id: int) -> int:
    """COCO category id of a YOLO class id: one more (COCO ids start at 1)."""
    return class_id + 1


def coco_categories() -> list[dict]:
    """COCO categories in YOLO order."""
    return [{"id": coco_category(CLASS_ID[name]), "name": name, "supercategory": "street"} for name in LABELLED]


def coco_annotation(record: dict, ann_id: int, image_id: int) -> dict:
    """A COCO annotation; ``area`` is the visible pixel count, not the box area. A record the
    filters dropped (too few pixels, too occluded) becomes an ignore region, ``iscrowd = 1``
    with its ``ignore_reason``: a detection on it is neither a hit nor a false alarm, in
    pycocotools as in :mod:`fogsim.evaluate` (COCO trainers skip crowd boxes)."""
    x0, y0, x1, y1 = record["bbox"]
    return {"id": ann_id, "image_id": image_id, "category_id": coco_category(record["class_id"]),
            "bbox": [float(x0), float(y0), float(x1 - x0), float(y1 - y0)],
            "area": float(record["pixels"]), "iscrowd": int(not record["kept"]),
            "distance_m": record["distance_m"], "visible_fraction": record["visible_fraction"],
            "truncation": record["truncation"]} | ({} if record["kept"] else {"ignore_reason": record["reason"]})
