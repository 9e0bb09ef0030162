"""Fog-level estimation on images fogged by the library itself, and routing."""
import numpy as np
import pytest

from fogsim.camera import planar_to_ray
from fogsim.detection.level_estimation import LevelEstimator, confusion, image_features, route
from fogsim.fog.model import Fogger
from fogsim.fog.synthetic import demo_scene

LEVELS = {"clear": 0.0, "beta0.03": 0.03, "beta0.06": 0.06, "beta0.09": 0.09, "beta0.12": 0.12}


def fogged_set(seed, n):
    rng = np.random.default_rng(seed)
    feats, labels = [], []
    for _ in range(n):
        rgb, depth, K = demo_scene(rng, 160, 100)
        f = Fogger(rgb, planar_to_ray(depth, K))
        for key, beta in LEVELS.items():
            feats.append(image_features(f(beta)))
            labels.append(key)
    return np.array(feats), labels


@pytest.mark.parametrize("method", ["features", "dark-channel"])
def test_estimators_separate_fog_levels(method):
    Xtr, ytr = fogged_set(0, 6)
    Xva, yva = fogged_set(1, 3)
    est = LevelEstimator.fit(Xtr, ytr, method)
    predicted = est.predict(Xva)
    c = confusion(yva, predicted, list(LEVELS))
    m = np.array(c["matrix"])
    # rows are the true levels, columns the estimated ones: every cell counted by hand
    assert m.tolist() == [[sum(t == a and p == b for t, p in zip(yva, predicted)) for b in LEVELS] for a in LEVELS]
    assert m.sum(axis=1).tolist() == [yva.count(lv) for lv in LEVELS] == [3] * len(LEVELS)
    right = sum(t == p for t, p in zip(yva, predicted))
    assert c["accuracy"] == pytest.approx(np.trace(m) / len(yva)) == pytest.approx(right / len(yva))
    assert c["accuracy"] >= (0.8 if method == "features" else 0.6)
    assert np.diag(m).min() >= (2 if method == "features" else 1)  # every level is recognised
    assert est.predict(Xva[:1]) == ["clear"]  # clear air is never mistaken
    assert m[0].tolist() == [3, 0, 0, 0, 0]  # ... for any of the clear images


def test_confusion_rows_are_true_levels_columns_estimates():
    c = confusion(["clear", "clear", "beta0.06", "beta0.12"], ["clear", "beta0.03", "beta0.12", "beta0.12"],
                  list(LEVELS))
    assert c["matrix"] == [[1, 1, 0, 0, 0], [0, 0, 0, 0, 0], [0, 0, 0, 0, 1], [0, 0, 0, 0, 0], [0, 0, 0, 0, 1]]
    assert c["accuracy"] == 0.5 and c["levels"] == list(LEVELS)


def test_dark_channel_rises_with_fog():
    rgb, depth, K = demo_scene(np.random.default_rng(2), 160, 100)
    f = Fogger(rgb, planar_to_ray(depth, K))
    dark = [image_features(f(b))[0] for b in LEVELS.values()]
    assert all(np.diff(dark) > 0)


def test_route_picks_the_estimated_models_detections():
    preds = {"clear": {"beta0.06": [{"image_id": 1, "score": 0.5}, {"image_id": 2, "score": 0.6}]},
             "beta0.06": {"beta0.06": [{"image_id": 1, "score": 0.9}, {"image_id": 2, "score": 0.8}]}}
    routed = route(preds, {"beta0.06": {1: "beta0.06", 2: "clear"}})
    assert sorted(d["score"] for d in routed["beta0.06"]) == [0.6, 0.9]
