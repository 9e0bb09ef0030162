"""LiDAR completion speed and accuracy on a 1920×1280 FRONT-like frame, against the fog step.

The scan is synthetic but has the real density pattern (``docs/real-data.md``): 64 TOP beam
rows ≈ 11 px apart whose highest lands near row 576 (so the rows cover the lower ≈ 55 %
of the image), one return every ≈ 4.9 px along a row, ≈ 10 % of returns missing, nothing
beyond 75 m or on the sky; ≈ 20 k points. The truth is the procedural street of
:func:`fogsim.fog.synthetic.demo_scene` (50° hfov). Per repeat, interleaved, one core
(``cv2.setNumThreads(1)``): the decode + projection of one Waymo v1 frame (the first of
``--waymo FILE``, else a synthetic frame of real sizes), point → sparse map + completion for
each classical method (the target: decode + projection + completion ≤ 1 s), and the fog step
of the same image (``Fogger``, the five paper levels) as the baseline; medians and the
ratios are printed.

    fogsim bench lidar [--repeat 5] [--waymo FILE.tfrecord]
"""
from __future__ import annotations

import cv2
import numpy as np

from fogsim.bench.timing import median_ms
from fogsim.camera import pixel_index, planar_to_ray, sparse_image
from fogsim.depth.complete import DEFAULT_METHOD, complete, holdout_split
from fogsim.depth.metrics import depth_metrics

TOP_ROWS, TOP_ROW_PX, ROW_STEP_PX, COL_STEP_PX = 64, 576.0, 11.0, 4.9
LIDAR_RANGE_M = 75.0
CLASSICAL = ("ipbasic", "linear")


def synthetic_scan(ray: np.ndarray, rng: np.random.Generator, rows: int = TOP_ROWS, top_row: float = TOP_ROW_PX,
                   row_step: float = ROW_STEP_PX, col_step: float = COL_STEP_PX, keep: float = 0.9,
                   max_range: float = LIDAR_RANGE_M) -> tuple[np.ndarray, np.ndarray]:
    """(uv N×2 float px, ray N float32 m) sampled from a dense ray map like a spinning LiDAR:
    ``rows`` beam rows from ``top_row`` down every ``row_step`` px (each row wavy by ±1 px),
    a return every ``col_step`` px with sub-pixel jitter, a fraction ``1 − keep`` dropped, and
    no return on +inf (sky) or beyond ``max_range``. Each point's distance is the map's value
    at its pixel (integer = pixel centre)."""
    h, w = ray.shape
    cols = np.arange(0.0, w, col_step)
    uv = []
    for k in range(rows):
        v = top_row + k * row_step + np.sin(cols / w * np.pi * 2 + k) * 1.0
        u = cols + rng.uniform(-0.3, 0.3, cols.shape)
        uv.append(np.stack([u, v], 1))
    uv = np.concatenate(uv)
    row, col, inside = pixel_index(uv, w, h)
    r = np.where(inside, ray[row, col], np.inf)
    ok = inside & np.isfinite(r) & (r <= max_range) & (rng.uniform(0, 1, len(r)) < keep)
    return uv[ok], r[ok].astype(np.float32)


def bench_frame(seed: int = 0):
    """(RGB, true ray distance, intrinsics, uv, ray) of the 1920×1280 synthetic FRONT frame."""
    from fogsim.fog.synthetic import demo_scene

    rng = np.random.default_rng(seed)
    rgb, depth, K = demo_scene(rng, 1920, 1280, hfov_deg=50.0)
    truth = planar_to_ray(depth, K)
    uv, ray = synthetic_scan(truth, rng)
    return rgb, truth, K, uv, ray


def _median_s(fns: dict, repeat: int) -> dict:
    """Median seconds of interleaved repeats (:func:`fogsim.bench.timing.median_ms`)."""
    return {k: v / 1e3 for k, v in median_ms(fns, repeat).items()}


def _waymo_decode(path: str | None):
    """A callable decoding + projecting the FRONT LiDAR points of one frame (the first frame of
    ``path``, or :func:`fogsim.bench.waymo_lidar.build_frame`'s synthetic frame of real
    sizes: TOP 64×2650 + four 200×600), and what it decodes."""
    from fogsim.readers.waymo.lidar_geometry import camera_points
    from fogsim.readers.waymo.lidar_v1 import parse_v1_lidar

    if path:
        from fogsim.depth.lidar_source import waymo_points_source
        from fogsim.readers.waymo import waymo_samples

        return waymo_points_source(waymo_samples(path, ("FRONT",))[0]), f"first frame of {path}"
    from fogsim.bench.waymo_lidar import build_frame

    frame = build_frame()

    def decode():
        pts = camera_points(parse_v1_lidar(frame, "bench"), "FRONT")
        return sparse_image(pts.uv, pts.ray, 1920, 1280)

    return decode, f"synthetic v1 frame of real sizes ({len(frame) / 1e6:.1f} MB)"


def run(repeat: int = 5, waymo: str | None = None) -> int:
    """Measure and print the table; returns 0 (the targets are reported, not enforced)."""
    from fogsim.fog.levels import load_preset
    from fogsim.fog.model import Fogger

    cv2.setNumThreads(1)
    rgb, truth, K, uv, ray = bench_frame()
    h, w = truth.shape
    levels = [lv.beta for lv in load_preset("paper")]
    used, _ = holdout_split(len(ray), 0.1, 0)
    held = np.setdiff1d(np.arange(len(ray)), used)
    result = {}

    def completion(method):
        def run():
            result[method] = complete(sparse_image(uv, ray, w, h), method)
        return run

    def fog():
        f = Fogger(rgb, result[DEFAULT_METHOD].ray)
        return [f(b) for b in levels]

    completion(DEFAULT_METHOD)()
    fns = {m: completion(m) for m in CLASSICAL} | {"fog": fog}
    decode, what = _waymo_decode(waymo)
    fns["decode"] = decode
    med = _median_s(fns, repeat)
    c = result[DEFAULT_METHOD]
    print(f"LiDAR completion benchmark: {w}×{h} FRONT-like frame, {len(ray)} synthetic points "
          f"({TOP_ROWS} beam rows from row {TOP_ROW_PX:.0f}, coverage {c.record['coverage']:.4f}), one core, "
          f"medians of {repeat} interleaved repeats")
    print(f"  {'fog step, 5 paper levels (baseline)':<46}{med['fog'] * 1e3:9.1f} ms")
    print(f"  {'Waymo decode + projection (FRONT, 1 frame)':<46}{med['decode'] * 1e3:9.1f} ms  ({what})")
    lower = np.zeros((h, w), bool)
    lower[int(TOP_ROW_PX):] = True
    row, col, _ = pixel_index(uv[held], w, h)
    for m in CLASSICAL:
        total = med["decode"] + med[m]
        print(f"  {f'points → sparse map + {m} completion':<46}{med[m] * 1e3:9.1f} ms  "
              f"= {med[m] / med['fog']:.2f}× the fog step; with decode {total * 1e3:.0f} ms = "
              f"{total / med['fog']:.2f}× the fog step  [{'ok' if total <= 1.0 else 'MISSED'}: ≤ 1 s]")
        # accuracy on the synthetic truth: held-out points, and all pixels the scan covers
        dense = complete(sparse_image(uv[used], ray[used], w, h), m).ray
        a = depth_metrics(dense[row, col], ray[held], cap_m=np.inf)
        b = depth_metrics(dense, np.where(truth <= LIDAR_RANGE_M, truth, np.inf), lower, cap_m=np.inf)
        print(f"      10 % of points held out: AbsRel {a['abs_rel']:.4f}, RMSE {a['rmse']:.3f} m, δ<1.25 "
              f"{a['delta1']:.4f}; every pixel ≤ {LIDAR_RANGE_M:.0f} m below row {TOP_ROW_PX:.0f}: AbsRel "
              f"{b['abs_rel']:.4f}, RMSE {b['rmse']:.3f} m, δ<1.25 {b['delta1']:.4f}")
    total = med["decode"] + med[DEFAULT_METHOD]
    print(f"bench lidar: decode + {DEFAULT_METHOD} completion {total * 1e3:.0f} ms per frame = "
          f"{total / med['fog']:.2f}× the fog step of five levels")  # the summary line (--quiet)
    return 0
