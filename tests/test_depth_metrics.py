"""Depth metrics against values computed by hand on tiny arrays."""
import math

import numpy as np
import pytest

from fogsim.depth.metrics import depth_metrics


def test_metrics_by_hand():
    gt = np.array([[10.0, 20.0], [40.0, np.inf]])
    pred = np.array([[12.0, 20.0], [30.0, 5.0]])
    m = depth_metrics(pred, gt)
    # pixels: (12 vs 10), (20 vs 20), (30 vs 40); the inf pixel does not count
    assert m["pixels"] == 3
    assert m["abs_rel"] == pytest.approx((0.2 + 0 + 0.25) / 3)
    assert m["sq_rel"] == pytest.approx((4 / 10 + 0 + 100 / 40) / 3)
    assert m["rmse"] == pytest.approx(math.sqrt((4 + 0 + 100) / 3))
    assert m["mae"] == pytest.approx(12 / 3)
    assert m["rmse_log"] == pytest.approx(math.sqrt((math.log(1.2) ** 2 + 0 + math.log(0.75) ** 2) / 3))
    # ratios 1.2, 1.0, 1.333: two below 1.25, all below 1.5625
    assert m["delta1"] == pytest.approx(2 / 3) and m["delta2"] == 1.0 and m["delta3"] == 1.0


def test_cap_mask_and_invalid_predictions():
    gt = np.array([10.0, 90.0, 30.0, 30.0])
    pred = np.array([10.0, 90.0, 0.0, 31.0])
    m = depth_metrics(pred, gt)  # 90 m is beyond the 80 m cap, the 0 prediction is invalid
    assert m["pixels"] == 2 and m["abs_rel"] == pytest.approx((0 + 1 / 30) / 2)
    only = depth_metrics(pred, gt, mask=np.array([True, True, True, False]))
    assert only["pixels"] == 1 and only["abs_rel"] == 0.0
    none = depth_metrics(pred, gt, mask=np.zeros(4, bool))
    assert none["pixels"] == 0 and math.isnan(none["rmse"])
    with pytest.raises(ValueError, match="shape"):
        depth_metrics(pred[:3], gt)


def test_reference_accuracy_and_smoothness():
    from fogsim.depth.metrics import laplacian_variance, reference_accuracy

    target = np.array([[10.0, 0.0], [20.0, 10.0]])   # a hole at (0, 1)
    pred = np.array([[12.0, 5.0], [20.0, 10.0]])
    assert reference_accuracy(pred, target) == pytest.approx(100 - 100 * 7 / 40)
    flat, noisy = np.full((16, 16), 5.0), np.random.default_rng(0).uniform(0, 10, (16, 16))
    assert laplacian_variance(flat) == 0.0 and laplacian_variance(noisy) > 1.0
