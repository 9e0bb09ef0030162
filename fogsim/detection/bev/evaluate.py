"""BEV detection scores per (model, fog level): KITTI's BEV AP, recalls, recall by distance.

Matching, per frame and class, detections by descending score (at most :data:`MAX_DETS` a frame): each
takes the unmatched ground-truth footprint of its class with the highest rotated IoU
(:func:`fogsim.detection.bev.boxes.rotated_iou`: the exact polygon overlap — stricter than the ProbIoU
Ultralytics' own OBB validation prints, so its mAP50 runs higher) at or above the class's threshold — KITTI's 0.7 for
cars, 0.5 for pedestrians and cyclists (:data:`IOU_THRESHOLDS`); a scored object is preferred to an
ignored one. A detection is then

* a hit (true positive) on a *counted* object: scored class, within the difficulty asked for;
* **ignored** (neither hit nor false alarm) on an ignored object — a neighbouring class (Van for cars,
  Person_sitting for pedestrians) or an object above the difficulty asked for (KITTI's rule: ``moderate``
  counts difficulties 1–2, ``hard`` 1–3, ``all`` every object) — or when it lies in a **DontCare** region:
  DontCare rows are image regions with no 3D box, so a detection is in one when the vertical segment at
  its centre, from the frame's ground (the median bottom of its labelled boxes, else 1.73 m below the
  LiDAR) to 1.5 m above it, projects into the region in image 2;
* else a false alarm.

Scores: ``ap`` — BEV AP with KITTI's 40 recall points (the precision envelope at recall 1/40 … 1), the
mean over the classes with counted objects in the level (``ap_<class>`` each); ``ap_loose`` — the same at
KITTI's looser thresholds (:data:`LOOSE_IOU_THRESHOLDS`: 0.5 for cars, 0.25 for the others); ``recall`` — Ultralytics'
recall at the confidence maximising the class-mean F1 (the camera study's recall,
:func:`fogsim.detection.coco_eval.ultralytics_pr`); ``recall_max`` — with every detection;
``recall_seen`` — the same as ``recall`` over the objects the LiDAR still sees at that level (≥
:data:`~fogsim.lidar.objects.MIN_POINTS` points in the box: the LiDAR's seen rule), so a detector is not
charged for what the fog took; ``recall_by_distance`` — ``recall_max`` per ground-distance bin.
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.detection.bev.boxes import iou_matrix
from fogsim.detection.coco_eval import pr_curves, ultralytics_pr
from fogsim.lidar.objects import MIN_POINTS
from fogsim.schema.bev import BEV_CLASS_NAMES

IOU_THRESHOLDS = {"car": 0.7, "pedestrian": 0.5, "cyclist": 0.5}
#: KITTI's second, looser set (OpenPCDet prints both): car 0.5 — the camera study's mAP@50 threshold
LOOSE_IOU_THRESHOLDS = {"car": 0.5, "pedestrian": 0.25, "cyclist": 0.25}
#: KITTI's difficulty settings: the highest difficulty counted (None: every object)
DIFFICULTIES = {"all": None, "easy": 1, "moderate": 2, "hard": 3}
MAX_DETS = 100
DONTCARE_SEGMENT_M = 1.5
R40 = np.linspace(1 / 40, 1.0, 40)


def distance_bins(max_m: float, step_m: float = 10.0) -> tuple[tuple[float, float], ...]:
    """Bins of ``step_m`` from 0 to ``max_m`` (the grid's reach) rounded up to a whole bin."""
    edges = np.arange(0.0, math.ceil(max_m / step_m - 1e-9) * step_m + 1e-9, step_m).tolist()
    return tuple(zip(edges[:-1], edges[1:]))


def counted(obj: dict, difficulty: str) -> bool:
    """Whether an object is a counted ground truth (scored and within the difficulty asked for)."""
    top = DIFFICULTIES[difficulty]
    return obj["scored"] and (top is None or 1 <= obj["difficulty"] <= top)


def in_dontcare(corners: np.ndarray, truth: dict) -> bool:
    """Whether a detection's footprint lies in one of the frame's DontCare regions (the module docstring)."""
    if not truth["dontcare"]:
        return False
    x, y = np.asarray(corners, np.float64).mean(0)
    z0 = truth["ground_z"]
    P = np.asarray(truth["projection"], np.float64)
    p = np.array([[x, y, z0, 1.0], [x, y, z0 + DONTCARE_SEGMENT_M, 1.0]]) @ P.T
    if (p[:, 2] <= 0).any():
        return False
    uv = p[:, :2] / p[:, 2:] + 0.5  # KITTI's pixel centres → fogsim's pixel edges
    u, v_lo, v_hi = uv[:, 0].mean(), uv[:, 1].min(), uv[:, 1].max()
    return any(left <= u <= right and v_lo <= bottom and v_hi >= top for left, top, right, bottom in truth["dontcare"])


def match(truths: list[dict], dets: list[dict], difficulty: str = "all", thresholds: dict = IOU_THRESHOLDS):
    """(records (class id, score, hit, ignored) per kept detection, {(frame, object index): score} of the
    counted objects hit) at the IoU ``thresholds`` per class."""
    by_frame: dict = {}
    for d in dets:
        by_frame.setdefault(d["image_id"], []).append(d)
    records, hit = [], {}
    for t in truths:
        frame_dets = sorted(by_frame.get(t["id"], []), key=lambda d: -d["score"])[:MAX_DETS]
        for cid, name in enumerate(BEV_CLASS_NAMES):
            gts = [(k, o) for k, o in enumerate(t["objects"]) if o["class"] == name]
            gts.sort(key=lambda ko: not counted(ko[1], difficulty))  # counted first
            ds = [d for d in frame_dets if d["category_id"] == cid]
            if not ds:
                continue
            ious = iou_matrix([np.asarray(d["corners_m"]) for d in ds], [np.asarray(o["corners_m"]) for _, o in gts])
            taken = np.zeros(len(gts), bool)
            for i, d in enumerate(ds):
                best, best_iou = -1, thresholds[name]
                for j, (_, o) in enumerate(gts):
                    if taken[j]:
                        continue
                    if best > -1 and counted(gts[best][1], difficulty) and not counted(o, difficulty):
                        break  # a counted match beats an ignored one
                    if ious[i, j] >= best_iou:
                        best, best_iou = j, ious[i, j]
                if best == -1:
                    ignored = in_dontcare(d["corners_m"], t)
                    records.append((cid, d["score"], False, ignored))
                    continue
                taken[best] = True
                k, o = gts[best]
                if counted(o, difficulty):
                    records.append((cid, d["score"], True, False))
                    hit[(t["id"], k)] = max(hit.get((t["id"], k), 0.0), d["score"])
                else:
                    records.append((cid, d["score"], False, True))
    return records, hit


def ap_r40(scores: np.ndarray, tp: np.ndarray, fp: np.ndarray, n: int) -> float:
    """KITTI's AP|R40 of one class from its cumulative TP / FP by descending score."""
    if n == 0:
        return float("nan")
    if len(tp) == 0:
        return 0.0
    recall, precision = tp / n, tp / np.maximum(tp + fp, np.spacing(1))
    envelope = np.maximum.accumulate(precision[::-1])[::-1]
    idx = np.searchsorted(recall, R40, side="left")
    return float(np.mean([envelope[i] if i < len(envelope) else 0.0 for i in idx]))


def evaluate_level(truths: list[dict], dets: list[dict], level: str, difficulty: str = "all",
                   bins=distance_bins(50.0), seen_points: int = MIN_POINTS) -> dict:
    """Every score of one (model, level) cell (the module docstring); ``truths`` are the validation frames'
    ground truth, ``dets`` the model's detections on the level's rasters."""
    records, hit = match(truths, dets, difficulty)
    objects = [((t["id"], k), o) for t in truths for k, o in enumerate(t["objects"]) if counted(o, difficulty)]
    n_gt = {cid: sum(o["class"] == name for _, o in objects) for cid, name in enumerate(BEV_CLASS_NAMES)}
    curves = pr_curves(records, n_gt)
    _, recall, conf = ultralytics_pr(curves)
    aps = {BEV_CLASS_NAMES[cid]: ap_r40(*curves[cid]) for cid in curves}
    scored_aps = [v for v in aps.values() if np.isfinite(v)]
    loose_records, _ = match(truths, dets, difficulty, LOOSE_IOU_THRESHOLDS)
    loose = pr_curves(loose_records, n_gt)
    loose_aps = [v for v in (ap_r40(*loose[cid]) for cid in loose) if np.isfinite(v)]
    seen = [(key, o) for key, o in objects if o["points"].get(level, 0) >= seen_points]
    at = conf if np.isfinite(conf) else 1.0
    by_bin = {}
    for lo, hi in bins:
        inside = [key for key, o in objects if lo <= o["distance_m"] < hi]
        by_bin[f"{lo:g}-{hi:g} m"] = (sum(key in hit for key in inside) / len(inside)) if inside else None
    n = max(len(objects), 1)
    return {"ap": float(np.mean(scored_aps)) if scored_aps else float("nan"),
            **{f"ap_{name}": aps.get(name, float("nan")) for name in BEV_CLASS_NAMES},
            "ap_loose": float(np.mean(loose_aps)) if loose_aps else float("nan"),
            "recall": recall if np.isfinite(recall) else 0.0, "conf": conf,
            "recall_max": len(hit) / n,
            "recall_seen": (sum(hit.get(key, -1.0) >= at for key, _ in seen) / len(seen)) if seen else None,
            "recall_by_distance": by_bin, "objects": len(objects), "objects_seen": len(seen),
            "objects_per_class": {BEV_CLASS_NAMES[c]: m for c, m in n_gt.items()},
            "ignored_detections": sum(r[3] for r in records), "detections": len(records),
            "difficulty": difficulty}
