"""Stereo: realistic disparity holes from a rendered rectified pair, in Cityscapes' format.

The renderer's right camera is the left one moved ``baseline`` metres along its x axis (a
rectified pair with the same K), so a point at planar depth Z has disparity d = baseline·fx/Z
pixels. OpenCV's semi-global matcher (SGBM, with its left–right consistency check, uniqueness
test and speckle filter) then leaves the holes real stereo has: the left band, occlusions,
sky, textureless surfaces and far range. Output is Cityscapes-style: uint16 p = 256·d + 1,
p = 0 invalid, with a ``camera.json`` (``extrinsic.baseline``, ``intrinsic.fx/fy/u0/v0``),
so synthetic and real Cityscapes go through the same loader.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from fogsim.camera import StereoCamera


@dataclass(frozen=True)
class SGBMParams:
    """Semi-global matching settings; ``num_disparities`` 0 = derive from the closest depth."""

    block_size: int = 5
    num_disparities: int = 0
    min_depth_m: float = 2.5
    uniqueness: int = 10
    speckle_window: int = 100
    speckle_range: int = 2
    lr_max_diff: int = 1


def disparity_range(baseline_m: float, fx: float, min_depth_m: float) -> int:
    """SGBM's numDisparities: the disparity at ``min_depth_m``, rounded up to a multiple of 16."""
    return max(16, int(math.ceil(baseline_m * fx / min_depth_m / 16.0)) * 16)


def _matcher(camera: StereoCamera, params: SGBMParams):
    n = params.num_disparities or disparity_range(camera.baseline, camera.intrinsics.fx, params.min_depth_m)
    bs = params.block_size
    return cv2.StereoSGBM_create(
        minDisparity=0, numDisparities=n, blockSize=bs, P1=8 * bs * bs, P2=32 * bs * bs,
        disp12MaxDiff=params.lr_max_diff, uniquenessRatio=params.uniqueness,
        speckleWindowSize=params.speckle_window, speckleRange=params.speckle_range,
        mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)


def _gray(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2GRAY)


def _pixels(raw: np.ndarray) -> np.ndarray:
    """OpenCV's fixed-point disparity (1/16 px, invalid ≤ 0) → float pixels, 0 = hole."""
    d = raw.astype(np.float32) / 16.0
    d[d <= 0] = 0.0
    return d


def sgbm_disparity(left_rgb: np.ndarray, right_rgb: np.ndarray, camera: StereoCamera,
                   params: SGBMParams = SGBMParams()) -> np.ndarray:
    """Disparity in pixels (float32, H×W) of the left image; 0 where SGBM gives no match."""
    return _pixels(_matcher(camera, params).compute(_gray(left_rgb), _gray(right_rgb)))


def wls_disparity(left_rgb: np.ndarray, right_rgb: np.ndarray, camera: StereoCamera,
                  params: SGBMParams = SGBMParams(), lam: float = 8000.0, sigma_color: float = 1.5) -> np.ndarray:
    """SGBM followed by opencv-contrib's edge-aware weighted-least-squares disparity filter,
    guided by the left image, with its left–right confidence (a classical baseline). OpenCV
    leaves the left band and L/R-inconsistent occlusions undefined: 0 there."""
    from fogsim.deps import require_contrib
    require_contrib("createRightMatcher", "createDisparityWLSFilter")  # opencv-contrib only
    left_m = _matcher(camera, params)
    right_m = cv2.ximgproc.createRightMatcher(left_m)
    gl, gr = _gray(left_rgb), _gray(right_rgb)
    wls = cv2.ximgproc.createDisparityWLSFilter(left_m)
    wls.setLambda(lam)
    wls.setSigmaColor(sigma_color)
    out = wls.filter(left_m.compute(gl, gr), np.ascontiguousarray(left_rgb[:, :, ::-1]),
                     disparity_map_right=right_m.compute(gr, gl))
    return _pixels(out)


def hole_fraction(disparity: np.ndarray) -> float:
    """Share of pixels without a valid disparity."""
    return float(np.mean(~(disparity > 0)))


def right_world_to_camera(left_world_to_camera, baseline_m: float) -> np.ndarray:
    """World→camera of the right camera of a rectified pair: the left moved +baseline along x."""
    M = np.array(left_world_to_camera, dtype=np.float64)
    M[0, 3] -= baseline_m
    return M
