"""Which fog level is this image? Two estimators and their confusion matrix; routing.

* ``dark-channel`` (physics): fog adds airlight, lifting the dark channel
  (:func:`fogsim.fog.model.dark_channel`: min over RGB and a 15×15 window) everywhere; the
  level is the one whose training median of the mean dark channel is nearest.
* ``features`` (a small classifier trained on our renders): nearest class centroid of
  standardised image statistics — mean dark channel, grey-level contrast, mean saturation,
  share of near-white pixels, mean gradient magnitude.
Routing sends each validation image to the detector of its estimated level; compare with the
oracle (the true level's detector), the clear model and a model trained on all levels.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from fogsim.fog.model import dark_channel

FEATURES = ("dark_channel", "contrast", "saturation", "white_share", "gradient")


def image_features(rgb: np.ndarray) -> np.ndarray:
    """The statistics above for an RGB uint8 image, as a float vector (0–1 scales)."""
    img = rgb.astype(np.float32) / 255.0
    dark = dark_channel(img, 15)
    grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).astype(np.float32) / 255.0
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
    gx, gy = cv2.Sobel(grey, cv2.CV_32F, 1, 0), cv2.Sobel(grey, cv2.CV_32F, 0, 1)
    return np.array([dark.mean(), grey.std(), hsv[:, :, 1].mean() / 255.0,
                     (img.min(axis=2) > 0.9).mean(), np.sqrt(gx * gx + gy * gy).mean()], np.float64)


@dataclass
class LevelEstimator:
    """Nearest-centroid classifier over features (``method="features"``) or the dark channel alone."""

    levels: list[str]
    centroids: np.ndarray   # levels × features (standardised)
    mean: np.ndarray
    std: np.ndarray
    method: str

    @classmethod
    def fit(cls, features: np.ndarray, labels: list[str], method: str = "features") -> "LevelEstimator":
        if method not in ("features", "dark-channel"):
            raise ValueError(f"method must be 'features' or 'dark-channel', got {method!r}")
        X = features[:, :1] if method == "dark-channel" else features
        levels = list(dict.fromkeys(labels))
        mean, std = X.mean(axis=0), X.std(axis=0) + 1e-9
        Z = (X - mean) / std
        lab = np.array(labels)
        stat = np.median if method == "dark-channel" else np.mean
        centroids = np.stack([stat(Z[lab == lv], axis=0) for lv in levels])
        return cls(levels, centroids, mean, std, method)

    def predict(self, features: np.ndarray) -> list[str]:
        X = features[:, :1] if self.method == "dark-channel" else features
        Z = (X - self.mean) / self.std
        d = ((Z[:, None, :] - self.centroids[None]) ** 2).sum(axis=2)
        return [self.levels[i] for i in d.argmin(axis=1)]


def confusion(true: list[str], predicted: list[str], levels: list[str]) -> dict:
    """Counts (rows true, columns predicted) and accuracy."""
    idx = {lv: i for i, lv in enumerate(levels)}
    m = np.zeros((len(levels), len(levels)), int)
    for t, p in zip(true, predicted):
        m[idx[t], idx[p]] += 1
    return {"levels": levels, "matrix": m.tolist(), "accuracy": float(np.trace(m) / max(m.sum(), 1))}


def route(predictions: dict[str, dict[str, list]], estimates: dict[str, dict[int, str]]) -> dict[str, list]:
    """Routed detections per validation level: image i of level L gets the detections of the
    model of its estimated level ``estimates[L][i]`` on that image.

    ``predictions[model][level]`` are COCO results; ``estimates[level][image_id]`` a model name.
    """
    by_image: dict = {}  # (model, level, image id) → its detections, grouped once
    for model, levels in predictions.items():
        for level, dets in levels.items():
            for d in dets:
                by_image.setdefault((model, level, d["image_id"]), []).append(d)
    return {level: [d for image_id, model in per_image.items() for d in by_image.get((model, level, image_id), [])]
            for level, per_image in estimates.items()}
