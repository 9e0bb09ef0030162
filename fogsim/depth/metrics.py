"""Depth accuracy against exact (rendered) depth: the standard monocular-depth metrics.

Pixels count where the exact depth is finite and in (0, ``cap_m``] (default 80 m, as in the
KITTI convention) and the prediction is valid (> 0); predictions are clipped to
[``min_m``, ``cap_m``]. Optionally restricted further by ``mask`` (e.g. SGBM holes only).
"""
from __future__ import annotations

import numpy as np

METRICS = ("abs_rel", "sq_rel", "rmse", "rmse_log", "mae", "delta1", "delta2", "delta3", "pixels")


def depth_metrics(pred: np.ndarray, gt: np.ndarray, mask: np.ndarray | None = None,
                  cap_m: float = 80.0, min_m: float = 1e-3) -> dict[str, float]:
    """AbsRel, SqRel, RMSE (m), RMSE log, MAE (m), δ < 1.25 / 1.25² / 1.25³ and pixel count."""
    if pred.shape != gt.shape:
        raise ValueError(f"prediction {pred.shape} and ground truth {gt.shape} differ in shape")
    valid = np.isfinite(gt) & (gt > 0) & (gt <= cap_m) & np.isfinite(pred) & (pred > 0)
    if mask is not None:
        valid &= mask
    n = int(valid.sum())
    if n == 0:
        return {k: float("nan") for k in METRICS[:-1]} | {"pixels": 0}
    g = gt[valid].astype(np.float64)
    p = np.clip(pred[valid].astype(np.float64), min_m, cap_m)
    ratio = np.maximum(p / g, g / p)
    return {"abs_rel": float(np.mean(np.abs(p - g) / g)),
            "sq_rel": float(np.mean((p - g) ** 2 / g)),
            "rmse": float(np.sqrt(np.mean((p - g) ** 2))),
            "rmse_log": float(np.sqrt(np.mean((np.log(p) - np.log(g)) ** 2))),
            "mae": float(np.mean(np.abs(p - g))),
            "delta1": float(np.mean(ratio < 1.25)),
            "delta2": float(np.mean(ratio < 1.25 ** 2)),
            "delta3": float(np.mean(ratio < 1.25 ** 3)),
            "pixels": n}


def reference_accuracy(pred_disparity: np.ndarray, target_disparity: np.ndarray) -> float:
    """The ILA reference's "accuracy": 100 − 100·Σ|pred − target| / Σ target over *all* pixels,
    holes (target 0) included — self-referential when the target is the stereo input."""
    total = float(np.sum(target_disparity))
    if total == 0:
        return float("nan")
    return 100.0 - 100.0 * float(np.sum(np.abs(pred_disparity - target_disparity))) / total


def laplacian_variance(disparity: np.ndarray) -> float:
    """Variance of the Laplacian of a disparity map (the reference's smoothness score; lower = smoother)."""
    import cv2

    return float(cv2.Laplacian(np.asarray(disparity, np.float64), cv2.CV_64F).var())
