"""Pictures of the BEV study: a contact sheet of rasters with ground truth and predictions per level, and
recall against distance per sensor (RGB uint8 arrays)."""
from __future__ import annotations

import re

import cv2
import numpy as np

from fogsim.detection.bev.build import decode_raster
from fogsim.detection.bev.evaluate import counted
from fogsim.viz import label

GT_COLOUR, IGNORED_COLOUR, PRED_COLOUR = (40, 220, 40), (150, 150, 150), (240, 50, 50)
LEVEL_COLOURS = [(30, 30, 30), (31, 119, 180), (44, 160, 44), (255, 127, 14), (214, 39, 40), (148, 103, 189)]


def _draw(img: np.ndarray, grid, corners_m, colour, thickness: int = 1) -> None:
    uv = grid.to_pixels(np.asarray(corners_m)) * (img.shape[1] / grid.width)
    cv2.polylines(img, [np.round(uv).astype(np.int32)], True, colour, thickness, cv2.LINE_AA)


def tile(study, variant, level: str, truth: dict, dets: list[dict], conf: float, difficulty: str,
         size: int = 240) -> np.ndarray:
    """One raster in false colour at ``size`` px with its ground truth (green; ignored grey) and the
    detections scoring ≥ ``conf`` (red)."""
    from fogsim.detection.bev.grid import false_colour

    raster = decode_raster(study.files.data(variant).image(level, truth["id"]))
    img = cv2.resize(false_colour(raster), (size, round(size * raster.shape[0] / raster.shape[1])),
                     interpolation=cv2.INTER_NEAREST)
    for o in truth["objects"]:
        _draw(img, study.grid, o["corners_m"], GT_COLOUR if counted(o, difficulty) else IGNORED_COLOUR)
    for d in dets:
        if d["image_id"] == truth["id"] and d["score"] >= conf:
            _draw(img, study.grid, d["corners_m"], PRED_COLOUR)
    return img


def contact_sheet(study, tables: dict, frames: int = 2, size: int = 240) -> np.ndarray:
    """Rows: (variant, validation frame); columns: levels; each tile the level's raster with its ground truth
    and its own level's model's detections at that cell's max-F1 confidence."""
    rows = []
    for v in study.variants:
        table = tables[v.name]
        truths = study.truths(v)[:frames]
        for truth in truths:
            tiles = []
            for lv in study.levels:
                cell = table["oracle"][lv]
                conf = cell["conf"] if cell["conf"] is not None and np.isfinite(cell["conf"]) else 1.0
                dets = study.read_predictions(study.files.prediction(v, lv, lv))
                img = tile(study, v, lv, truth, dets, max(conf, 0.05), cell["difficulty"], size)
                tiles.append(label(img, lv, 22))
            head = np.full((tiles[0].shape[0], 120, 3), 255, np.uint8)
            for k, text in enumerate((v.name, f"frame {truth['id']}")):
                cv2.putText(head, text, (6, 40 + 18 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
            rows.append(np.hstack([head, *(np.pad(t, ((0, 0), (0, 4), (0, 0)), constant_values=255) for t in tiles)]))
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 6), (0, width - r.shape[1]), (0, 0)), constant_values=255) for r in rows]
    key = np.full((24, width, 3), 255, np.uint8)
    cv2.putText(key, "green: ground truth (grey: ignored); red: the level's own model (max-F1 confidence); "
                "car drives up the page", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([key, *rows])


def _bin_centres(labels) -> list[float]:
    out = []
    for text in labels:
        m = re.match(r"([\d.]+)-([\d.]+)", text)
        out.append((float(m.group(1)) + float(m.group(2))) / 2 if m else float("nan"))
    return out


def _panel(title: str, by_level: dict, levels: list[str], xmax: float, size=(320, 220)) -> np.ndarray:
    w, h = size
    left, right, top, bottom = 40, 10, 24, 30
    img = np.full((h, w, 3), 255, np.uint8)
    cv2.putText(img, title, (left, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.rectangle(img, (left, top), (w - right, h - bottom), (0, 0, 0), 1)

    def xy(d, r):
        return (int(left + d / xmax * (w - left - right)), int(h - bottom - r * (h - top - bottom)))
    for r in (0.0, 0.5, 1.0):
        x, y = xy(0, r)
        cv2.putText(img, f"{r:g}", (6, y + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
    for d in np.arange(0, xmax + 1e-9, 25 if xmax > 60 else 10):
        x, y = xy(d, 0)
        cv2.putText(img, f"{d:g}", (x - 6, h - bottom + 14), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, "m", (w - right - 12, h - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
    for k, lv in enumerate(levels):
        colour = LEVEL_COLOURS[k % len(LEVEL_COLOURS)]
        bins = by_level.get(lv) or {}
        pts = [xy(d, r) for d, r in zip(_bin_centres(bins), bins.values()) if r is not None and np.isfinite(d)]
        for a, b in zip(pts, pts[1:]):
            cv2.line(img, a, b, colour, 2, cv2.LINE_AA)
        for p in pts:
            cv2.circle(img, p, 3, colour, -1, cv2.LINE_AA)
    return img


def recall_by_distance_plot(own: dict, mixed: dict, levels: list[str]) -> np.ndarray:
    """Recall against distance, a panel per sensor (``own``/``mixed``: ``{sensor: {level: {bin label:
    recall}}}``): the top row each level's own model, the bottom row the mixed model; a colour per level."""
    xmax = max((c for by in (*own.values(), *mixed.values()) for bins in by.values()
                for c in _bin_centres(bins or {}) if np.isfinite(c)), default=50.0) * 1.15
    top = np.hstack([_panel(f"{s}: own level's model", own[s], levels, xmax) for s in own])
    bottom = np.hstack([_panel(f"{s}: mixed", mixed[s], levels, xmax) for s in mixed])
    key = np.full((40, top.shape[1], 3), 255, np.uint8)
    text = "recall (every detection) by distance: BEV the ground distance, camera the ray; a colour per level"
    cv2.putText(key, text, (8, 34), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (0, 0, 0), 1, cv2.LINE_AA)
    x = 8
    for k, lv in enumerate(levels):
        colour = LEVEL_COLOURS[k % len(LEVEL_COLOURS)]
        cv2.line(key, (x, 11), (x + 16, 11), colour, 2, cv2.LINE_AA)
        cv2.putText(key, lv, (x + 20, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (0, 0, 0), 1, cv2.LINE_AA)
        x += 28 + 8 * len(lv)
    return np.vstack([key, top, bottom])
