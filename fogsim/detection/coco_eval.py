"""Detection metrics per (model, fog level): AP50, recalls, recall by distance.

Ground truth is a fogsim COCO file (one per level; the boxes are the same at every level).
Objects beyond ``max_distance_m`` (by their ``distance_m``, the median ray distance of their
visible pixels) are *ignored*, not dropped: they are marked ``iscrowd = 1``, so a detection
on one is neither a true nor a false positive (pycocotools overwrites an ``ignore`` key with
``iscrowd``; dropping them would turn correct detections into false positives).

* ``ap50`` — COCO AP at IoU 0.5 (101-point interpolation) from pycocotools, all areas.
* ``recall_max`` — recall with every detection; ``recall_at_conf`` — with score ≥ ``conf``.
* ``ultralytics_R`` / ``ultralytics_P`` — at the confidence that maximises the class-mean
  F1, as Ultralytics reports "R" and "P" (most likely the paper's Recall).
* ``recall_by_distance`` — recall with every detection, per distance bin (metres).

``visible_only``: objects whose annotation says ``visible: false`` (fogsim's per-level flag:
contrast against the surround below 5 % in that level's image, :mod:`fogsim.fog.visibility`)
become ignore regions as well, so a detector is not charged for what no eye can see; an
annotation without the field (or ``null``) counts as visible. The result records
``visible_only`` and ``ignored_invisible`` (objects within the distance limit that this
policy ignored).
Matching is COCO's: detections by descending score take the best-IoU unmatched non-ignored
ground truth of their class at IoU ≥ 0.5, else an ignored one (then they are ignored), else
they are false positives — so duplicates are false positives. The matcher's own AP equals
pycocotools' (tested), which vouches for the recall numbers built on it.
"""
from __future__ import annotations

import contextlib
import copy
import io
from pathlib import Path

import numpy as np

from fogsim.boxes import box_convert, coco_category, yolo_to_xywh
from fogsim.errors import FogsimError, InputError

BINS = ((0.0, 25.0), (25.0, 50.0), (50.0, 100.0))


#: what the distance cut does with an object whose ``distance_m`` is None (unknown, e.g. a far
#: Waymo box without a laser label or a Cityscapes instance without valid disparity):
#: ``ignore`` it (an ignore region, as a far object) or ``count`` it as ground truth
UNKNOWN_DISTANCE = ("ignore", "count")


def ignore_policy(gt: dict, max_distance_m: float, unknown_distance: str = "count") -> dict:
    """A copy of a COCO dict with the evaluation's ignore regions marked ``iscrowd = 1``: the
    dataset's own (filtered objects, groups), objects beyond ``max_distance_m``, and — with
    ``unknown_distance="ignore"`` — objects whose ``distance_m`` is None. Annotations without a
    ``distance_m`` key at all (e.g. from another tool) are always counted. New ignore rules (a
    visibility cut …) belong here, beside these."""
    if unknown_distance not in UNKNOWN_DISTANCE:
        raise ValueError(f"unknown_distance must be one of {', '.join(UNKNOWN_DISTANCE)}, got {unknown_distance!r}")
    gt = copy.deepcopy(gt)
    for a in gt["annotations"]:
        d = a.get("distance_m")
        unknown = "distance_m" in a and d is None and unknown_distance == "ignore"
        a["iscrowd"] = int(bool(a.get("iscrowd")) or (d is not None and d > max_distance_m) or unknown)
    return gt


def mark_invisible_ignored(gt: dict) -> dict:
    """A copy of a COCO dict whose annotations with ``visible`` False are ``iscrowd = 1``
    (a missing or null ``visible`` counts as visible)."""
    gt = copy.deepcopy(gt)
    for a in gt["annotations"]:
        a["iscrowd"] = int(bool(a.get("iscrowd")) or a.get("visible") is False)
    return gt


def mark_far_ignored(gt: dict, max_distance_m: float) -> dict:
    """A copy of a COCO dict whose annotations beyond ``max_distance_m`` are ``iscrowd = 1``
    (annotations with an unknown or no ``distance_m`` are kept): :func:`ignore_policy` with
    ``unknown_distance="count"``."""
    return ignore_policy(gt, max_distance_m, "count")


def distance_coverage(gt: dict, max_distance_m: float) -> dict:
    """How many ground-truth objects (not the dataset's own ignore regions) each unknown-distance
    policy evaluates: ``within`` (known distance ≤ max), ``beyond`` (ignored by both),
    ``unknown`` (distance None), ``no_distance`` (no ``distance_m`` key: always counted);
    ``ignore`` = within + no_distance, ``count`` = that + unknown."""
    real = [a for a in gt["annotations"] if not a.get("iscrowd")]
    within = sum(a.get("distance_m") is not None and a["distance_m"] <= max_distance_m for a in real)
    beyond = sum(a.get("distance_m") is not None and a["distance_m"] > max_distance_m for a in real)
    unknown = sum("distance_m" in a and a["distance_m"] is None for a in real)
    absent = sum("distance_m" not in a for a in real)
    return {"objects": len(real), "within": within, "beyond": beyond, "unknown": unknown, "no_distance": absent,
            "ignore": within + absent, "count": within + absent + unknown, "max_distance_m": max_distance_m}


def yolo_predictions(folder: str | Path, gt: dict) -> list[dict]:
    """COCO results from YOLO txt predictions ``cls cx cy w h conf`` named after each image."""
    out = []
    for img in gt["images"]:
        path = Path(folder) / (Path(img["file_name"]).stem + ".txt")
        if not path.is_file():
            continue
        for n, line in enumerate(path.read_text().splitlines(), 1):
            parts = line.split()
            if not parts:
                continue
            if len(parts) != 6:
                raise InputError(path, f"line {n}: expected 'class cx cy w h confidence', got {line!r}")
            c, cx, cy, w, h, conf = int(parts[0]), *map(float, parts[1:])
            W, H = img["width"], img["height"]
            out.append({"image_id": img["id"], "category_id": coco_category(c), "score": conf,
                        "bbox": yolo_to_xywh(cx, cy, w, h, W, H)})
    return out


def _iou(a: np.ndarray, b: np.ndarray, crowd: np.ndarray) -> np.ndarray:
    """IoU of xywh boxes a (n×4) with b (m×4); for ignored (crowd) b, intersection over a's
    area, as pycocotools does."""
    ax, bx = box_convert(a, "xywh", "xyxy"), box_convert(b, "xywh", "xyxy")
    iw = np.clip(np.minimum(ax[:, None, 2], bx[None, :, 2]) - np.maximum(ax[:, None, 0], bx[None, :, 0]), 0, None)
    ih = np.clip(np.minimum(ax[:, None, 3], bx[None, :, 3]) - np.maximum(ax[:, None, 1], bx[None, :, 1]), 0, None)
    inter = iw * ih
    area_a = (a[:, 2] * a[:, 3])[:, None]
    union = np.where(crowd[None], area_a, area_a + (b[:, 2] * b[:, 3])[None] - inter)
    return np.where(union > 0, inter / np.maximum(union, 1e-12), 0.0)


def match(gt: dict, dets: list[dict], iou_thr: float = 0.5, max_dets: int = 100):
    """COCO matching. Returns per-detection (category, score, tp, ignored) and per-GT matched flags."""
    by_key: dict = {}
    for a in gt["annotations"]:
        by_key.setdefault((a["image_id"], a["category_id"]), ([], []))[0].append(a)
    for d in dets:
        by_key.setdefault((d["image_id"], d["category_id"]), ([], []))[1].append(d)
    records, gt_matched = [], {}
    for (_, cat), (gts, ds) in by_key.items():
        ds = sorted(ds, key=lambda d: -d["score"])[:max_dets]
        gts = sorted(gts, key=lambda a: a["iscrowd"])  # non-ignored first, as COCO
        if not ds:
            continue
        crowd = np.array([bool(a["iscrowd"]) for a in gts], bool)
        ious = _iou(np.array([d["bbox"] for d in ds], float).reshape(-1, 4),
                    np.array([a["bbox"] for a in gts], float).reshape(-1, 4), crowd)
        taken = np.zeros(len(gts), bool)
        for i, d in enumerate(ds):
            best, best_iou = -1, iou_thr
            for j, a in enumerate(gts):
                if taken[j] and not a["iscrowd"]:
                    continue
                if best > -1 and not gts[best]["iscrowd"] and a["iscrowd"]:
                    break  # a real match beats an ignored one
                if ious[i, j] >= best_iou:
                    best, best_iou = j, ious[i, j]
            if best == -1:
                records.append((cat, d["score"], False, False))
                continue
            taken[best] = True
            ignored = bool(gts[best]["iscrowd"])
            records.append((cat, d["score"], not ignored, ignored))
            if not ignored:
                gt_matched[gts[best]["id"]] = max(gt_matched.get(gts[best]["id"], 0.0), d["score"])
    return records, gt_matched


def pr_curves(records, n_gt: dict):
    """Per category: scores (descending), cumulative TP and FP, number of non-ignored GT."""
    out = {}
    for cat, n in n_gt.items():
        rec = [(sc, tp) for c, sc, tp, ign in records if c == cat and not ign]
        rec.sort(key=lambda r: -r[0])
        scores = np.array([r[0] for r in rec], float)
        tp = np.cumsum([r[1] for r in rec]).astype(float)
        fp = np.cumsum([not r[1] for r in rec]).astype(float)
        out[cat] = (scores, tp, fp, n)
    return out


def coco_ap(curves: dict) -> float:
    """COCO's 101-point interpolated AP, averaged over categories that have ground truth."""
    aps = []
    for scores, tp, fp, n in curves.values():
        if n == 0:
            continue
        if len(tp) == 0:
            aps.append(0.0)
            continue
        rc, pr = tp / n, tp / np.maximum(tp + fp, np.spacing(1))
        pr = np.maximum.accumulate(pr[::-1])[::-1]
        idx = np.searchsorted(rc, np.linspace(0, 1, 101), side="left")
        aps.append(float(np.mean([pr[i] if i < len(pr) else 0.0 for i in idx])))
    return float(np.mean(aps)) if aps else float("nan")


def pycocotools_ap50(gt: dict, dets: list[dict]) -> float:
    """AP at IoU 0.5 over all areas from pycocotools (maxDets 100)."""
    try:
        from pycocotools.coco import COCO
        from pycocotools.cocoeval import COCOeval
    except ImportError:
        raise FogsimError("detection evaluation needs pycocotools: pip install pycocotools") from None
    if not dets:
        return 0.0
    with contextlib.redirect_stdout(io.StringIO()):
        coco = COCO()
        coco.dataset = copy.deepcopy(gt)
        coco.createIndex()
        ev = COCOeval(coco, coco.loadRes(copy.deepcopy(dets)), "bbox")
        ev.params.iouThrs = np.array([0.5])
        ev.params.areaRng, ev.params.areaRngLbl, ev.params.maxDets = [[0, 1e10]], ["all"], [100]
        ev.evaluate()
        ev.accumulate()
    p = ev.eval["precision"][0, :, :, 0, 0]
    valid = p[:, (p > -1).any(axis=0)]
    return float(valid.mean()) if valid.size else float("nan")


def ultralytics_pr(curves: dict) -> tuple[float, float, float]:
    """(P, R, confidence) at the confidence maximising the class-mean F1 (Ultralytics' way)."""
    px = np.linspace(0, 1, 1000)
    ps, rs = [], []
    for scores, tp, fp, n in curves.values():
        if n == 0:
            continue
        if len(scores) == 0:
            ps.append(np.zeros_like(px))
            rs.append(np.zeros_like(px))
            continue
        r, p = tp / n, tp / np.maximum(tp + fp, 1e-16)
        rs.append(np.interp(-px, -scores, r, left=0))
        ps.append(np.interp(-px, -scores, p, left=1))
    if not rs:
        return float("nan"), float("nan"), float("nan")
    P, R = np.mean(ps, axis=0), np.mean(rs, axis=0)
    f1 = 2 * P * R / np.maximum(P + R, 1e-16)
    i = int(np.argmax(f1))
    return float(P[i]), float(R[i]), float(px[i])


def evaluate(gt: dict, dets: list[dict], max_distance_m: float = 100.0, conf: float = 0.25,
             bins=BINS, unknown_distance: str = "count", visible_only: bool = False) -> dict:
    """All metrics of one (model, level) cell; ``gt`` is a fogsim COCO dict, ``dets`` COCO results;
    ignore regions by :func:`ignore_policy` (``unknown_distance``: ``count`` or ``ignore``);
    ``visible_only``: invisible objects are ignored too (see the module docstring)."""
    gt = ignore_policy(gt, max_distance_m, unknown_distance)
    counted = sum(not a["iscrowd"] for a in gt["annotations"])
    if visible_only:
        gt = mark_invisible_ignored(gt)
    records, matched = match(gt, dets)
    real = [a for a in gt["annotations"] if not a["iscrowd"]]
    n_gt = {c["id"]: sum(a["category_id"] == c["id"] for a in real) for c in gt["categories"]}
    curves = pr_curves(records, n_gt)
    P, R, at = ultralytics_pr(curves)
    n = max(len(real), 1)
    by_bin = {}
    for lo, hi in bins:
        inside = [a for a in real if a.get("distance_m") is not None and lo <= a["distance_m"] < hi]
        by_bin[f"{lo:g}-{hi:g} m"] = (sum(a["id"] in matched for a in inside) / len(inside)) if inside else None
    return {"ap50": pycocotools_ap50(gt, dets), "ap50_matcher": coco_ap(curves),
            "recall_max": len(matched) / n,
            "recall_at_conf": sum(s >= conf for s in matched.values()) / n, "conf": conf,
            "ultralytics_P": P, "ultralytics_R": R, "ultralytics_conf": at,
            "recall_by_distance": by_bin, "objects": len(real),
            "ignored": len(gt["annotations"]) - len(real), "max_distance_m": max_distance_m,
            "unknown_distance": unknown_distance, "visible_only": visible_only,
            "ignored_invisible": counted - len(real)}
