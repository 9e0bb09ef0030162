"""The BEV study's report: every model on every level per variant (the paper's cross-density layout: rows
trained on, columns evaluated on, the best of each column in bold), the sensors side by side with the
camera study's table when OUT holds one, the LiDAR fog models against each other, recall by distance,
training times and the pictures (``OUT/bev/report``).

Files: ``cross_density_<variant>.{json,csv,md}``, ``<variant>_{ap,ap_car,recall}_heatmap.png``,
``fog_models.json`` (with ``--fog-models``), ``sensors.json`` (the side-by-side rows), ``bev_contact_sheet.png``,
``recall_by_distance.png`` and ``report.md``.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from fogsim.dataset.layout import MIXED_MODEL
from fogsim.detection.bev.build import Variant
from fogsim.detection.bev.evaluate import IOU_THRESHOLDS, LOOSE_IOU_THRESHOLDS, distance_bins, evaluate_level
from fogsim.detection.bev.pictures import contact_sheet, recall_by_distance_plot
from fogsim.detection.bev.study import ORACLE, BevStudy
from fogsim.detection.table import TRAINING_SECONDS, heatmap, markdown, training_header, training_row
from fogsim.errors import InputError
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.documents import write_json
from fogsim.io.images import write_image
from fogsim.schema.base import load_json
from fogsim.schema.bev import CameraTable
from fogsim.schema.documents import DoneFile

#: the tables' metrics: name → cell key, and what each is
METRICS = {"BEV AP": "ap", "BEV AP car": "ap_car", "BEV AP (loose)": "ap_loose", "recall": "recall",
           "recall_seen": "recall_seen"}
NOTES = {"BEV AP": "AP|R40, mean over the classes with objects",
         "BEV AP car": "cars alone at IoU 0.7, KITTI's headline: pedestrians and cyclists are a few cells wide",
         "BEV AP (loose)": "the same at IoU 0.5 for cars, 0.25 for pedestrians and cyclists",
         "recall": "Ultralytics' recall at the max-F1 confidence",
         "recall_seen": "the same over the objects the LiDAR still sees: ≥ 5 points in the box at that level"}
#: how ``difficulty="auto"`` is decided: KITTI's headline for real data; every object for a render, whose small
#: images make KITTI's pixel-height rule drop most objects
AUTO_DIFFICULTY = {True: "all", False: "moderate"}


def resolve_difficulty(study: BevStudy, difficulty: str) -> str:
    return AUTO_DIFFICULTY[study.source.is_render] if difficulty == "auto" else difficulty


def variant_table(study: BevStudy, v: Variant, difficulty: str) -> dict:
    """``{row: {level: cell}}``: each level's model, ``mixed`` and ``oracle`` (each level's own model)."""
    truths = study.truths(v)
    bins = distance_bins(float(np.hypot(study.grid.x_range[1], max(map(abs, study.grid.y_range)))))
    table = {}
    for model in (*study.levels, MIXED_MODEL):
        table[model] = {lv: evaluate_level(truths, study.read_predictions(study.files.prediction(v, model, lv)), lv,
                                           difficulty, bins) for lv in study.levels}
    table[ORACLE] = {lv: table[lv][lv] for lv in study.levels}
    return table


def fog_model_table(study: BevStudy, difficulty: str) -> dict:
    """``{trained on: {evaluated on: {level: cell}}}`` of the fog-model variants' ``mixed`` models."""
    out = {}
    for train_v in study.fog_variants:
        out[train_v.fog_model] = {}
        for eval_v in study.fog_variants:
            truths = study.truths(eval_v)
            out[train_v.fog_model][eval_v.fog_model] = {
                lv: evaluate_level(truths, study.read_predictions(study.files.prediction(train_v, MIXED_MODEL, lv,
                                                                                         eval_v)), lv, difficulty)
                for lv in study.levels}
    return out


def camera_table(out: Path) -> dict | None:
    """The camera study's table in the same OUT (``report/cross_density.json``), None when there is none."""
    path = out / "report" / "cross_density.json"
    if not path.is_file():
        return None
    return load_json(path, CameraTable).model_dump()


def sensors_rows(tables: dict[str, dict], camera: dict | None, levels: list[str]) -> dict:
    """The side-by-side rows ``{row: {level: value}}``: per sensor its own-level models (oracle) and mixed,
    by AP (camera: mAP@50) and by recall."""
    rows = {}
    if camera is not None and ORACLE in camera and MIXED_MODEL in camera:
        for row, label in ((ORACLE, "own level's model"), (MIXED_MODEL, "mixed")):
            rows[f"camera, {label}: mAP@50 (2D)"] = {lv: camera[row].get(lv, {}).get("ap50") for lv in levels}
            rows[f"camera, {label}: recall"] = {lv: camera[row].get(lv, {}).get("recall_all") for lv in levels}
    for name, table in tables.items():
        for row, label in ((ORACLE, "own level's model"), (MIXED_MODEL, "mixed")):
            rows[f"{name}, {label}: BEV AP"] = {lv: table[row][lv]["ap"] for lv in levels}
            rows[f"{name}, {label}: BEV AP car"] = {lv: table[row][lv]["ap_car"] for lv in levels}
            rows[f"{name}, {label}: BEV AP (loose)"] = {lv: table[row][lv]["ap_loose"] for lv in levels}
            rows[f"{name}, {label}: recall"] = {lv: table[row][lv]["recall"] for lv in levels}
    return rows


def _fmt(v) -> str:
    return "—" if v is None or not np.isfinite(v) else f"{v:.3f}"


def _csv(table: dict) -> bytes:
    buf = io.StringIO()
    w = csv.writer(buf)
    keys = ["ap", "ap_car", "ap_pedestrian", "ap_cyclist", "ap_loose", "recall", "recall_max", "recall_seen",
            "objects"]
    w.writerow(["model", "level", *keys])
    for m, row in table.items():
        for lv, cell in row.items():
            w.writerow([m, lv, *("" if cell.get(k) is None else f"{cell[k]:.6f}" if isinstance(cell[k], float)
                                 else cell[k] for k in keys)])
    return buf.getvalue().encode()


def _distance_lines(table: dict) -> list[str]:
    bins = list(next(iter(table[ORACLE].values()))["recall_by_distance"])
    lines = ["| row | level | " + " | ".join(bins) + " |", "|---" * (len(bins) + 2) + "|"]
    for row in (ORACLE, MIXED_MODEL):
        for lv, cell in table[row].items():
            lines.append(f"| {row} | {lv} | " + " | ".join(_fmt(v) for v in cell["recall_by_distance"].values()) + " |")
    return lines


def write_bev_report(study: BevStudy, difficulty: str = "auto") -> dict:
    """Evaluate every model on every level, write OUT/bev/report (the module docstring); returns the tables."""
    missing = study.missing_predictions()
    if missing:
        raise InputError(missing[0], f"{len(missing)} prediction files are missing: run the remaining models "
                                     "(shards) first")
    cfg = study.stored_config()
    difficulty = resolve_difficulty(study, difficulty)
    tables = {v.name: variant_table(study, v, difficulty) for v in study.variants}
    fog = fog_model_table(study, difficulty) if study.fog_variants else None
    camera = camera_table(study.files.out)
    rows = sensors_rows(tables, camera, study.levels)
    out = study.files.report()
    for v in study.variants:
        table = tables[v.name]
        write_json(out / f"cross_density_{v.folder}.json", table)
        atomic_write_bytes(out / f"cross_density_{v.folder}.csv", _csv(table))
        atomic_write_bytes(out / f"cross_density_{v.folder}.md", markdown(table, METRICS, NOTES).encode())
        for metric in ("ap", "ap_car", "recall"):
            write_image(out / f"{v.folder}_{metric}_heatmap.png", heatmap(
                table, metric, title=f"{v.name}: {metric} (row: trained on, column: evaluated on)", key=metric))
    write_json(out / "sensors.json", rows)
    if fog is not None:
        write_json(out / "fog_models.json", fog)
    write_image(out / "bev_contact_sheet.png", contact_sheet(study, tables))
    curves = {name: {lv: t[ORACLE][lv]["recall_by_distance"] for lv in study.levels} for name, t in tables.items()}
    mixed = {name: {lv: t[MIXED_MODEL][lv]["recall_by_distance"] for lv in study.levels} for name, t in tables.items()}
    if camera is not None and ORACLE in camera and MIXED_MODEL in camera:
        curves = {"camera": {lv: camera[ORACLE][lv]["recall_by_distance"] for lv in study.levels}} | curves
        mixed = {"camera": {lv: camera[MIXED_MODEL][lv]["recall_by_distance"] for lv in study.levels}} | mixed
    write_image(out / "recall_by_distance.png", recall_by_distance_plot(curves, mixed, study.levels))
    md = report_markdown(study, cfg, difficulty, tables, rows, fog, camera is not None)
    atomic_write_bytes(out / "report.md", md.encode())
    return {"tables": tables, "sensors": rows, "fog_models": fog}


def report_markdown(study: BevStudy, cfg, difficulty: str, tables: dict, rows: dict, fog: dict | None,
                    with_camera: bool) -> str:
    src, grid = study.source, study.grid
    first = next(iter(tables.values()))
    per_class = first[ORACLE][study.levels[0]]["objects_per_class"]
    scratch = " from scratch" if cfg.model.endswith((".yaml", ".yml")) else ""
    lines = ["# Cross-density detection study: LiDAR and radar, bird's-eye view", "",
             f"Dataset `{src.root}`: {len(src.split['train'])} training / {len(src.split['val'])} validation frames "
             f"per level ({', '.join(f'{lv} β {src.betas[lv]:g}' for lv in study.levels)}). BEV grid "
             f"{grid.describe()}, the camera's field of view only. Channels: "
             + "; ".join(f"{v.name}: {', '.join(v.channels)}" for v in study.all_variants()) + ".", "",
             f"Detector: Ultralytics OBB `{cfg.model}`{scratch}, {cfg.epochs} epochs per level model, "
             f"{cfg.epochs_for(MIXED_MODEL)} for `mixed` over every level's rasters (the level models' compute "
             f"together when equal), {cfg.imgsz} px, batch {cfg.batch}, seed {cfg.seed}.", "",
             f"Scores on the validation frames: BEV AP|R40 with rotated IoU ≥ {IOU_THRESHOLDS['car']:g} (car), "
             f"{IOU_THRESHOLDS['pedestrian']:g} (pedestrian, cyclist) — *loose*: {LOOSE_IOU_THRESHOLDS['car']:g}, "
             f"{LOOSE_IOU_THRESHOLDS['pedestrian']:g} — the exact polygon overlap (stricter than the ProbIoU of "
             f"Ultralytics' own validation); KITTI difficulty **{difficulty}**; Van and "
             "Person_sitting ignored; detections in DontCare regions ignored. Counted objects: "
             + ", ".join(f"{k} {n}" for k, n in per_class.items()) + ". Rows: trained on (oracle = each level's own "
             "model); columns: evaluated on; the best of each column in bold.", ""]
    for v in study.variants:
        lines += [f"## {v.name}", "", markdown(tables[v.name], METRICS, NOTES),
                  f"**recall by distance** ({v.name}; every detection)", "", *_distance_lines(tables[v.name]), ""]
    lines += ["## The sensors side by side", "",
              ("Camera rows from this folder's camera study (`report/cross_density.json`: 2D boxes, mAP@50 — not the "
               "same score as BEV AP, so compare each sensor's rows across levels, not the numbers across sensors)."
               if with_camera else "No camera study in this folder: run `fogsim study --out OUT --dataset "
               f"{src.root}` to add its rows."), "",
              "| row | " + " | ".join(study.levels) + " |", "|---" * (len(study.levels) + 1) + "|"]
    lines += [f"| {row} | " + " | ".join(_fmt(vals[lv]) for lv in study.levels) + " |" for row, vals in rows.items()]
    lines.append("")
    if fog is not None:
        lines += ["## LiDAR fog models against each other", "",
                  "Each model's `mixed` detector is trained on the clear scans fogged again by one LiDAR fog model "
                  "(rows) and evaluated on the scans of every model (columns: model · level); BEV AP, the best of "
                  "each column in bold.", ""]
        cols = [(e, lv) for e in fog for lv in study.levels]
        best = {c: max((fog[t][c[0]][c[1]]["ap"] for t in fog), default=0.0) for c in cols}
        lines += ["| trained on | " + " | ".join(f"{e} · {lv}" for e, lv in cols) + " |",
                  "|---" * (len(cols) + 1) + "|"]
        for t in fog:
            cells = [(f"**{_fmt(fog[t][e][lv]['ap'])}**" if fog[t][e][lv]["ap"] == best[(e, lv)] else
                      _fmt(fog[t][e][lv]["ap"])) for e, lv in cols]
            lines.append(f"| {t} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["## Training", "", f"Seconds: {TRAINING_SECONDS}.", "", *training_header(["variant", "model"])]
    for u in study.units:
        done = study.files.run_done(u.variant, u.model)
        info = load_json(done, DoneFile) if done.is_file() else DoneFile()
        lines.append(training_row([u.variant.name, u.model], cfg.epochs_for(u.model), info))
    lines += ["", "![BEV contact sheet: ground truth green, the level's own model red](bev_contact_sheet.png)", "",
              "![recall by distance per sensor](recall_by_distance.png)", ""]
    lines += [f"![{v.name} BEV AP heatmap]({v.folder}_ap_heatmap.png)" for v in study.variants]
    return "\n".join(lines) + "\n"
