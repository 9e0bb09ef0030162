"""A built-in image + depth pair, made procedurally, so fogsim runs with no dataset.

A pinhole camera 1.5 m above a flat road looks along it: road with lane marks, two rows
of building facades, boxes standing in for cars at known distances, and sky (no hit). The
depth is exact planar Z, computed analytically from the geometry, in metres.
"""
from __future__ import annotations

import numpy as np

from fogsim.camera import Intrinsics

CAMERA_HEIGHT = 1.5  # metres


def demo_scene(rng: np.random.Generator, width: int = 640, height: int = 400,
               hfov_deg: float = 60.0) -> tuple[np.ndarray, np.ndarray, Intrinsics]:
    """(RGB uint8, planar depth float32 metres with inf for sky, intrinsics)."""
    K = Intrinsics.from_hfov(hfov_deg, width, height)
    u = (np.arange(width) - K.cx) / K.fx          # ray direction x/z per column
    v = (np.arange(height) - K.cy) / K.fy         # ray direction y/z per row (y down)
    U, V = np.meshgrid(u, v)
    with np.errstate(divide="ignore", invalid="ignore"):  # inf·0 and inf % n off the planes
        return _paint(rng, K, U, V, width, height)


def _paint(rng, K, U, V, width, height):
    depth = np.full((height, width), np.inf, np.float32)
    rgb = np.zeros((height, width, 3), np.float32)

    # sky: a vertical gradient
    sky = np.clip(-V * 2, 0, 1)[..., None]
    rgb[:] = (1 - sky) * np.array([200, 215, 230]) + sky * np.array([110, 150, 205])

    # road (y = +h below the camera): Z = h / v for v > 0
    z_road = np.where(V > 1e-6, CAMERA_HEIGHT / V, np.inf)
    x_road = U * z_road
    road = np.isfinite(z_road) & (z_road < 400)
    depth[road] = z_road[road]
    tex = rng.normal(0, 6, (height, width))
    rgb[road] = (np.array([92, 92, 96]) + tex[road, None])
    lane = road & (np.abs(np.abs(x_road) - 1.75) < 0.08) & ((z_road % 9) < 4.5)
    rgb[lane] = [235, 235, 225]
    walk = road & (np.abs(x_road) > 5.5)
    rgb[walk] = np.array([150, 145, 135]) + tex[walk, None]

    # facades: vertical planes at x = ±(7 + jitter), up to a height per block
    for side in (-1, 1):
        x_wall = side * (7.0 + rng.uniform(0, 1.5))
        z_wall = np.where(U * side > 1e-6, x_wall / U, np.inf)
        y_wall = V * z_wall                              # height below camera (down positive)
        block = np.floor(z_wall / 12.0)
        tops = CAMERA_HEIGHT - rng.uniform(6, 22, 64)   # roof line (y, down positive)
        top = tops[np.clip(block, 0, 63).astype(int)]
        hit = np.isfinite(z_wall) & (z_wall < depth) & (y_wall > top) & (y_wall < CAMERA_HEIGHT)
        depth[hit] = z_wall[hit]
        hue = rng.uniform(0, 1, 64)[np.clip(block, 0, 63).astype(int)]
        base = np.stack([150 + 60 * hue, 120 + 40 * (1 - hue), 100 + 30 * hue], -1)
        window = ((z_wall % 3) < 1.6) & ((y_wall % 3) < 1.5) & (y_wall < 0)
        colour = np.where(window[..., None], base * 0.45, base)
        rgb[hit] = colour[hit] + tex[hit, None]

    # "cars": boxes facing the camera at known distances, on the lanes
    for z_car in sorted(rng.uniform(8, 120, 6), reverse=True):
        x_car = rng.choice([-3.5, 0.0, 3.5]) + rng.uniform(-0.4, 0.4)
        w_car, h_car = 1.8, 1.5
        u0, u1 = K.cx + K.fx * (x_car - w_car / 2) / z_car, K.cx + K.fx * (x_car + w_car / 2) / z_car
        v0, v1 = K.cy + K.fy * (CAMERA_HEIGHT - h_car) / z_car, K.cy + K.fy * CAMERA_HEIGHT / z_car
        rows = slice(max(0, int(np.ceil(v0))), min(height, int(np.ceil(v1))))
        cols = slice(max(0, int(np.ceil(u0))), min(width, int(np.ceil(u1))))
        patch = depth[rows, cols]
        front = patch > z_car
        patch[front] = z_car
        colour = rng.uniform(30, 220, 3)
        rgb[rows, cols][front] = colour
    return np.clip(rgb + 0.5, 0, 255).astype(np.uint8), depth, K
