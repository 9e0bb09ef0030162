"""Scoring depth completion against exact rendered depth, and what it does to the fog.

For one stereo frame of a fogsim dataset (``--stereo``): the SGBM disparity has holes; each
completion method fills them; every result is scored against the exact depth on the hole
pixels, on the SGBM-valid pixels and on all pixels (:mod:`fogsim.depth_metrics`), and the
frame is fogged at each level with the exact and with the completed depth to measure the
error a user would see in the foggy image (PSNR, mean absolute error in 8-bit levels).
Learned completions (ILA) plug in through :func:`fogsim.fill.register_fill`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import (Intrinsics, StereoCamera, decode_disparity_png, depth_to_disparity, disparity_to_depth,
                     planar_to_ray)
from .dataset_writer import DatasetLayout
from .depth_metrics import depth_metrics, laplacian_variance, reference_accuracy
from .fill import fill_holes
from .fog import Fogger
from .io import read_depth_file, read_image, read_json, read_uint16_map
from .stereo import wls_disparity

CLASSICAL = ("sgbm", "inpaint", "ipbasic", "wls")


@dataclass
class StereoFrame:
    name: str
    left: np.ndarray        # RGB uint8
    right: np.ndarray
    exact: np.ndarray       # planar depth, metres, inf = sky
    sgbm: np.ndarray        # planar depth from SGBM, 0 = hole
    camera: StereoCamera


def load_stereo_frame(layout: DatasetLayout, name: str) -> StereoFrame:
    """Read a committed stereo frame (its meta names the split of its Cityscapes files)."""
    meta = read_json(layout.meta(name))
    if not meta.get("stereo"):
        raise ValueError(f"{layout.meta(name)}: frame has no stereo pair (render with --stereo)")
    split = meta["stereo"]["split"]
    cam_json = read_json(layout.cityscapes("camera", name, split))
    K = Intrinsics.from_dict(meta["camera"]["intrinsics"])
    cam = StereoCamera(cam_json["extrinsic"]["baseline"], K)
    disp = decode_disparity_png(read_uint16_map(layout.cityscapes("disparity", name, split)))
    return StereoFrame(name, read_image(layout.cityscapes("leftImg8bit", name, split)),
                       read_image(layout.cityscapes("rightImg8bit", name, split)),
                       read_depth_file(layout.depth(name)),
                       disparity_to_depth(disp, cam.baseline, K.fx), cam)


def complete(frame: StereoFrame, method: str) -> np.ndarray:
    """Planar depth with SGBM's holes handled by ``method`` (``sgbm`` leaves them: 0)."""
    if method == "sgbm":
        return frame.sgbm
    if method == "wls":
        d = wls_disparity(frame.left, frame.right, frame.camera)
        depth = disparity_to_depth(d, frame.camera.baseline, frame.camera.intrinsics.fx)
        return fill_holes(depth, "ipbasic")  # WLS leaves its left band and occlusions undefined
    return fill_holes(frame.sgbm, method, frame.left)  # classical or registered (ILA) fills


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(255.0 ** 2 / mse)


def evaluate_frame(frame: StereoFrame, completions: dict[str, np.ndarray], levels,
                   cap_m: float = 80.0) -> dict:
    """Metrics per method on holes / SGBM-valid / all pixels, and foggy-image error per level."""
    holes = frame.sgbm == 0
    regions = {"holes": holes, "valid": ~holes, "all": None}
    K = frame.camera.intrinsics
    fog_exact = Fogger(frame.left, planar_to_ray(frame.exact, K))
    reference = {lv.key: fog_exact(lv.beta) for lv in levels if lv.beta > 0}
    out = {"frame": frame.name, "hole_fraction": float(holes.mean()), "methods": {}}
    b, fx = frame.camera.baseline, K.fx
    exact_disp, sgbm_disp = depth_to_disparity(frame.exact, b, fx), depth_to_disparity(frame.sgbm, b, fx)
    for method, depth in completions.items():
        rec = {r: depth_metrics(depth, frame.exact, m, cap_m) for r, m in regions.items()}
        disp = depth_to_disparity(depth, b, fx)
        rec["reference"] = {"accuracy_vs_sgbm": reference_accuracy(disp, sgbm_disp),
                            "accuracy_vs_exact": reference_accuracy(disp, exact_disp),
                            "laplacian_variance": laplacian_variance(disp)}
        if not (depth == 0).any():  # only dense depth can be fogged
            fogger = Fogger(frame.left, planar_to_ray(depth, K))
            rec["fog"] = {key: {"psnr": psnr(fogger(lv.beta), reference[key]),
                                "mae": float(np.mean(np.abs(fogger(lv.beta).astype(np.int16)
                                                            - reference[key])))}
                          for lv in levels if lv.beta > 0 for key in [lv.key]}
        out["methods"][method] = rec
    return out


def summarise(frames: list[dict]) -> dict:
    """Mean over frames of every number, per method, keeping the nesting (region → metric,
    fog → level → psnr/mae); non-finite values (no pixels, identical images) are skipped."""
    return _mean_tree([f["methods"] for f in frames])


def _mean_tree(trees: list):
    if isinstance(trees[0], dict):
        return {k: _mean_tree([t[k] for t in trees if k in t]) for k in trees[0]}
    vals = [float(v) for v in trees if v is not None and np.isfinite(v)]
    return float(np.mean(vals)) if vals else float("nan")
