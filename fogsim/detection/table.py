"""The cross-density table: every model × every fog level → Recall and mAP@50.

Rows are models (one per training level, plus e.g. ``mixed`` and ``routed``), columns the
validation levels, as in the paper's Table 2. Written as JSON (every metric of every cell),
CSV, a markdown table in the paper's layout (the best value of each column in bold) and a
heatmap PNG per metric.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path

import cv2
import numpy as np

from fogsim.detection.coco_eval import evaluate
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.documents import write_json
from fogsim.io.images import write_image

#: table metric → cell key. Recall is shown both ways: over every object within the distance
#: limit, and over the visible ones only (invisible objects ignored, as ``visible_only``).
METRICS = {"recall": "recall_all", "recall_visible": "recall_visible", "map50": "ap50"}
METRIC_NOTES = {"recall": "every object within the distance limit",
                "recall_visible": "visible objects only: contrast ≥ 5 % in that level's image; the invisible ignored"}


def evaluate_both(gt: dict, dets: list, visible_only: bool = False, **kw) -> dict:
    """:func:`evaluate` under the headline policy (``visible_only``) plus Ultralytics' recall
    both ways: ``recall_all`` (every object within the distance limit) and ``recall_visible``
    (invisible objects ignored), with ``objects_visible`` (the objects the latter counts)."""
    cell = evaluate(gt, dets, visible_only=visible_only, **kw)
    other = evaluate(gt, dets, visible_only=not visible_only, **kw)
    every, visible = (other, cell) if visible_only else (cell, other)
    return cell | {"recall_all": every["ultralytics_R"], "recall_visible": visible["ultralytics_R"],
                   "objects_visible": visible["objects"]}


def cross_density(gt_by_level: dict[str, dict], predictions: dict[str, dict[str, list]], **kw) -> dict:
    """``{model: {level: evaluate_both(...)}}`` for every model and every level it has predictions for."""
    return {model: {lv: evaluate_both(gt_by_level[lv], dets, **kw) for lv, dets in by_level.items()}
            for model, by_level in predictions.items()}


def _grid(table: dict, metric: str, key: str | None = None) -> tuple[list[str], list[str], np.ndarray]:
    models = list(table)
    levels = list(dict.fromkeys(lv for m in models for lv in table[m]))
    key = key or METRICS.get(metric, metric)
    grid = np.array([[table[m].get(lv, {}).get(key, np.nan) for lv in levels] for m in models], float)
    return models, levels, grid


def markdown(table: dict, metrics: dict[str, str] | None = None, notes: dict | None = None) -> str:
    """The paper's layout: one block per metric, rows = trained model, columns = validation level
    (``metrics``: {name shown: cell key}, default :data:`METRICS`; ``notes``: a line per metric, default
    :data:`METRIC_NOTES`)."""
    lines = []
    notes = METRIC_NOTES if notes is None else notes
    for metric, key in (METRICS if metrics is None else metrics).items():
        models, levels, g = _grid(table, metric, key)
        with np.errstate(all="ignore"):
            best = np.nanmax(np.where(np.isfinite(g), g, -np.inf), axis=0) if g.size else []
        note = f"{notes[metric]}; " if metric in notes else ""
        lines += [f"**{metric}** ({note}rows: trained on; columns: validated on)", "",
                  "| model | " + " | ".join(levels) + " |", "|---" * (len(levels) + 1) + "|"]
        for i, m in enumerate(models):
            cells = [("**%.3f**" if np.isfinite(v) and v == best[j] else "%.3f") % v if np.isfinite(v) else "—"
                     for j, v in enumerate(g[i])]
            lines.append(f"| {m} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def heatmap(table: dict, metric: str, cell: int = 90, title: str | None = None, key: str | None = None) -> np.ndarray:
    """RGB image of one metric (the cell key ``key``, default the metric's): a cell per (row, column), value
    written in it, darker = higher."""
    models, levels, g = _grid(table, metric, key)
    left = 16 + max([110] + [cv2.getTextSize(m, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)[0][0] for m in models])
    top = 40
    img = np.full((top + cell * len(models) + 10, max(360, left + cell * len(levels) + 10), 3), 255, np.uint8)
    cv2.putText(img, title or f"{metric} (row: trained on, column: validated on)", (8, 20), cv2.FONT_HERSHEY_SIMPLEX,
                0.42, (0, 0, 0), 1, cv2.LINE_AA)
    for j, lv in enumerate(levels):
        cv2.putText(img, lv, (left + j * cell + 6, top - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
    for i, m in enumerate(models):
        cv2.putText(img, m, (6, top + i * cell + cell // 2), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
        for j in range(len(levels)):
            v = g[i, j]
            shade = 255 if not np.isfinite(v) else int(255 - 200 * np.clip(v, 0, 1))
            x0, y0 = left + j * cell, top + i * cell
            cv2.rectangle(img, (x0, y0), (x0 + cell - 2, y0 + cell - 2), (shade, shade, 255), -1)
            text = "-" if not np.isfinite(v) else f"{v:.3f}"
            colour = (255, 255, 255) if np.isfinite(v) and v > 0.6 else (0, 0, 0)
            cv2.putText(img, text, (x0 + 14, y0 + cell // 2 + 5), cv2.FONT_HERSHEY_SIMPLEX, 0.5, colour, 1, cv2.LINE_AA)
    return img


def write_report(table: dict, out: str | Path) -> None:
    """``cross_density.json``, ``.csv``, ``.md`` and ``<metric>_heatmap.png`` under ``out``."""
    out = Path(out)
    write_json(out / "cross_density.json", table)
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["model", "level", *METRICS])
    for m, row in table.items():
        for lv, cell in row.items():
            w.writerow([m, lv, *(f"{cell.get(k, float('nan')):.6f}" for k in METRICS.values())])
    atomic_write_bytes(out / "cross_density.csv", buf.getvalue().encode())
    atomic_write_bytes(out / "cross_density.md", markdown(table).encode())
    for metric in METRICS:
        write_image(out / f"{metric}_heatmap.png", heatmap(table, metric))


TRAINING_SECONDS = ("training, over every run that resumed the model (Ultralytics' results.csv); this run, of "
                    "the run that finished it (0 when an earlier run had trained it)")


def training_header(keys: list[str]) -> list[str]:
    """The header lines of a report's training table, its first columns ``keys``."""
    cols = [*keys, "epochs", "training s", "this run s", "state"]
    return ["| " + " | ".join(cols) + " |", "|---" * len(cols) + "|"]


def training_row(keys: list[str], epochs: int, info) -> str:
    """One model's row of :func:`training_header`'s table from its ``fogsim_done.json`` (a ``DoneFile``)."""
    def num(v):
        return "—" if v is None else f"{v:.1f}"
    return "| " + " | ".join([*keys, str(epochs), num(info.seconds_training), num(info.seconds_this_run),
                              info.state or "—"]) + " |"
