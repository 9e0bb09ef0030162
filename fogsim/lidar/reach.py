"""How many LiDAR points an object carries at a distance, beside real KITTI's cars (numbers and a picture).

Real KITTI (HDL-64E S2, 10 Hz) labels cars with about 660 points at 14 m, 160 at 20 m (partly occluded) and
55 at 33 m (:data:`KITTI_CAR_POINTS`, measured on real KITTI frames: ``shared/notes/lidar-realism.md`` §5). A
target's points fall as 1/R²: a face of area A at range R meets A/(R²·Δφ·Δθ) rays (Δφ the azimuth step,
Δθ the beam spacing, radians). With the S2's 0.173° azimuth step at 10 Hz (1.33 M points/s over 64 lasers)
and its upper block's 1/3° beam spacing (the lasers above −8.33° that see cars at 10–40 m),
Δφ·Δθ = 1.76·10⁻⁵ sr, so the three cars give n·R² = 129 k (a car's rear, 1.8 × 1.26 m = 2.3 m², every ray
returned) down to 60 k (1.05 m²: about half of it — glass, dark paint, tyres, occlusion). The **KITTI car
band** (:func:`kitti_car_band`) is n(R) between those two: 60 k/R² to 129 k/R² (:data:`KITTI_CAR_BAND`).
A car seen from its side or obliquely shows up to 2.5× the rear's area and lies above it; one partly hidden
behind another, below.

* :func:`object_points_by_distance` — (class, distance m, clear-air points) of every labelled object a render's
  LiDAR counted (``meta/*.json`` → ``lidar.objects``: the box centre's range from the sensor).
* :func:`reach_table` — per class and distance bin: objects, median points, and for cars the shares below,
  inside and above the band.
* :func:`reach_picture` — points per object (log) against distance, cars foremost, the band shaded and the
  three KITTI cars marked (an RGB uint8 image, :mod:`fogsim.viz` style).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np

__all__ = ["KITTI_CAR_BAND", "KITTI_CAR_POINTS", "KITTI_HDL64E_STEPS_DEG", "REACH_BINS", "geometric_points",
           "kitti_car_band", "object_points_by_distance", "reach_picture", "reach_table"]

#: real KITTI cars: (distance m, points in the labelled box, what was seen)
KITTI_CAR_POINTS = ((14.0, 660, "fully visible"), (20.0, 160, "partly occluded"), (33.0, 55, "seen"))
#: the S2 on KITTI: (azimuth step, upper-block beam spacing), degrees
KITTI_HDL64E_STEPS_DEG = (0.173, 1.0 / 3.0)
#: n·R² (points · m²) of the KITTI car band: the least and the most of the measured cars
KITTI_CAR_BAND = (min(n * r * r for r, n, _ in KITTI_CAR_POINTS), max(n * r * r for r, n, _ in KITTI_CAR_POINTS))
#: distance bins of :func:`reach_table` (metres, [low, high))
REACH_BINS = (0.0, 10.0, 20.0, 30.0, 40.0, 60.0, 80.0, 120.0)
#: the picture's colours (RGB) by class; classes not listed are grey
CLASS_COLOURS = {"car": (214, 39, 40), "van": (255, 127, 14), "truck": (140, 86, 75), "bus": (140, 86, 75),
                 "pedestrian": (31, 119, 180), "cyclist": (44, 160, 44)}


def geometric_points(area_m2, r, azimuth_step_deg: float, beam_step_deg: float) -> np.ndarray:
    """Rays a face of ``area_m2`` (projected, facing the sensor) meets at range ``r`` (m): A/(R²·Δφ·Δθ)."""
    return np.asarray(area_m2, np.float64) / (np.asarray(r, np.float64) ** 2
                                              * math.radians(azimuth_step_deg) * math.radians(beam_step_deg))


def kitti_car_band(r) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) points of the KITTI car band at range ``r`` (m): :data:`KITTI_CAR_BAND` / R²."""
    r2 = np.asarray(r, np.float64) ** 2
    return KITTI_CAR_BAND[0] / r2, KITTI_CAR_BAND[1] / r2


def object_points_by_distance(root: str | Path, level: str = "clear") -> list[tuple[str, float, int]]:
    """(class, distance m, points at ``level``) of every object of every frame of the render ``root`` whose
    LiDAR record has a box (``meta/*.json`` → ``lidar.objects``; the distance: its box centre's range)."""
    rows = []
    for path in sorted(Path(root, "meta").glob("*.json")):
        lidar = json.loads(path.read_text()).get("lidar") or {}
        for obj in lidar.get("objects", []):
            box, points = (obj.get("box3d") or {}).get("lidar"), (obj.get("lidar_points") or {}).get(level)
            if box is not None and points is not None:
                rows.append((obj["class"], float(np.linalg.norm(box["centre_m"])), int(points)))
    return rows


def reach_table(rows: list[tuple[str, float, int]], bins=REACH_BINS) -> list[dict]:
    """Per class (cars first) and distance bin: ``objects``, ``median_points``, and for cars ``below`` /
    ``inside`` / ``above`` the KITTI car band (shares)."""
    classes = sorted({c for c, _, _ in rows}, key=lambda c: (c != "car", c))
    out = []
    for cls in classes:
        for lo, hi in zip(bins, bins[1:]):
            got = [(d, n) for c, d, n in rows if c == cls and lo <= d < hi]
            if not got:
                continue
            d, n = np.array(got, np.float64).T
            row = {"class": cls, "bin": [lo, hi], "objects": len(got), "median_points": float(np.median(n))}
            if cls == "car":
                low, high = kitti_car_band(d)
                row.update(below=float(np.mean(n < low)), inside=float(np.mean((n >= low) & (n <= high))),
                           above=float(np.mean(n > high)), band_at_median=[float(x) for x in kitti_car_band(
                               float(np.median(d)))])
            out.append(row)
    return out


def reach_picture(rows: list[tuple[str, float, int]], size: tuple[int, int] = (900, 540),
                  max_distance_m: float = 120.0, caption: str = "") -> np.ndarray:
    """Points per object (log scale, 0 drawn at the axis) against distance: the KITTI car band shaded, the
    three KITTI cars as black diamonds, the render's cars red (and their median per :data:`REACH_BINS`
    bin joined by a line) over its other classes."""
    w, h = size
    left, right, top, bottom = 64, 190, 36, 46
    img = np.full((h, w, 3), 255, np.uint8)
    ymax = 5.0  # log10 of 100 000 points

    def xy(d, n):
        x = left + np.clip(np.asarray(d, np.float64) / max_distance_m, 0, 1) * (w - left - right)
        y = h - bottom - np.clip(np.log10(np.maximum(np.asarray(n, np.float64), 1.0)) / ymax, 0, 1) \
            * (h - top - bottom)
        return np.round(x).astype(np.int32), np.round(y).astype(np.int32)
    r = np.linspace(2.0, max_distance_m, 300)
    low, high = kitti_car_band(r)
    xs, ylo = xy(r, low)
    _, yhi = xy(r, high)
    band = np.concatenate([np.stack([xs, yhi], 1), np.stack([xs, ylo], 1)[::-1]]).astype(np.int32)
    cv2.fillPoly(img, [band], (255, 222, 206))
    for k in range(0, int(max_distance_m) + 1, 10):
        x, _ = xy(k, 1)
        cv2.line(img, (int(x), top), (int(x), h - bottom), (236, 236, 236), 1)
        cv2.putText(img, f"{k}", (int(x) - 8, h - bottom + 16), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
    for e in range(0, 6):
        _, y = xy(0, 10 ** e)
        cv2.line(img, (left, int(y)), (w - right, int(y)), (236, 236, 236), 1)
        cv2.putText(img, f"{10 ** e:,}", (6, int(y) + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1)
    cv2.rectangle(img, (left, top), (w - right, h - bottom), (0, 0, 0), 1)
    order = sorted({c for c, _, _ in rows}, key=lambda c: (c == "car", c))  # cars drawn last, on top
    for cls in order:
        colour = CLASS_COLOURS.get(cls, (150, 150, 150))
        pts = [(d, n) for c, d, n in rows if c == cls and d <= max_distance_m]
        if pts:
            x, y = xy(*np.array(pts, np.float64).T)
            for px, py in zip(x, y):
                cv2.circle(img, (int(px), int(py)), 4 if cls == "car" else 3, colour, -1, cv2.LINE_AA)
    med = [row for row in reach_table(rows) if row["class"] == "car"]
    if len(med) > 1:
        cx, cy = xy([(a + b) / 2 for a, b in (m["bin"] for m in med)], [m["median_points"] for m in med])
        cv2.polylines(img, [np.stack([cx, cy], 1).astype(np.int32)], False, (150, 20, 20), 2, cv2.LINE_AA)
    for d, n, _ in KITTI_CAR_POINTS:
        x, y = xy(d, n)
        diamond = np.array([[x, y - 7], [x + 7, y], [x, y + 7], [x - 7, y]], np.int32)
        cv2.fillPoly(img, [diamond], (0, 0, 0))
    cv2.putText(img, "distance to the box centre (m)", (left + (w - left - right) // 2 - 110, h - 10),
                cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1)
    cv2.putText(img, "points in the box, clear air (0: on the axis)", (left, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                (0, 0, 0), 1)
    if caption:
        cv2.putText(img, caption, (left + 380, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (80, 80, 80), 1)
    lo_k, hi_k = (round(c / 1000) for c in KITTI_CAR_BAND)
    cv2.putText(img, f"band: {lo_k}k-{hi_k}k / R^2", (w - right + 10, h - bottom - 30),
                cv2.FONT_HERSHEY_SIMPLEX, 0.4, (80, 80, 80), 1)
    cv2.putText(img, f"(S2: {KITTI_HDL64E_STEPS_DEG[0]:g} x 1/3 deg)", (w - right + 10, h - bottom - 12),
                cv2.FONT_HERSHEY_SIMPLEX, 0.4, (80, 80, 80), 1)
    legend = [("real KITTI car", (0, 0, 0)), ("KITTI car band", (255, 200, 180)),
              ("render: car", CLASS_COLOURS["car"]), ("  car median", (150, 20, 20))]
    legend += [(f"render: {c}", CLASS_COLOURS.get(c, (150, 150, 150))) for c in order[::-1] if c != "car"]
    for i, (text, colour) in enumerate(legend):
        y = top + 14 + 18 * i
        cv2.circle(img, (w - right + 16, y - 4), 5, colour, -1, cv2.LINE_AA)
        cv2.putText(img, text, (w - right + 28, y), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1)
    return img
