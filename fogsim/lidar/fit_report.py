"""The report of ``fogsim lidar-fit`` and ``fogsim lidar-compare``: the statistics of the clear scans, the real
fog, the default (start) fog and the fitted fog side by side (:func:`markdown` of the record the command
writes as JSON), one PNG with the overlaid histograms (:func:`histogram_figure`) and one distance figure
(:func:`distance_figure`: each term of the distance, default vs fitted, and the best distance per evaluation).

Pictures are RGB uint8 arrays drawn with OpenCV (:mod:`fogsim.viz` style); ASCII captions (OpenCV's fonts
have no β).
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from fogsim.lidar.scan_stats import (
    FAR_EDGES_M,
    INTENSITY_BINS,
    INTENSITY_QUANTILES,
    NEAR_M,
    NEAR_STEP_M,
    RANGE_EDGES_M,
    TERMS,
    ScanStatistics,
)

__all__ = ["DISTANCE_DEFINITION", "SERIES_COLOURS", "SIMULATED", "distance_figure", "histogram_figure", "markdown",
           "report_record"]

#: the sets drawn, their colours (RGB) and captions
SERIES_COLOURS = {"clear": (150, 150, 150), "real": (20, 20, 20), "default": (31, 119, 180),
                  "simulated": (31, 119, 180), "fitted": (230, 100, 0)}
#: the simulated sets a report may hold: the start calibration of a fit, the scored one of a comparison, the fit
SIMULATED = ("default", "simulated", "fitted")
INK, GRID = (0, 0, 0), (228, 228, 228)
FONT = cv2.FONT_HERSHEY_SIMPLEX


def _edge(v: float) -> str:
    return "inf" if not math.isfinite(v) else f"{v:g}"


def _bin_labels(edges) -> list[str]:
    return [f"{_edge(a)}-{_edge(b)}" for a, b in zip(edges[:-1], edges[1:])]


def _panel(title: str, labels: list[str], series: dict[str, np.ndarray], size=(560, 300), ymax: float | None = None,
           ylabel: str = "share", steps: bool = True) -> np.ndarray:
    """One panel: each series drawn over the same bins (equal widths, ``labels`` under them) as a step line
    (``steps``) or as points joined by lines; a legend of the series."""
    w, h = size
    left, right, top, bottom = 52, 12, 26, 46
    img = np.full((h, w, 3), 255, np.uint8)
    nb = len(labels)
    finite = [np.asarray(v, np.float64) for v in series.values()]
    top_value = ymax or max([float(np.nanmax(v)) for v in finite if np.isfinite(v).any()] + [1e-9]) * 1.1
    px = (w - left - right) / max(1, nb)

    def y_of(v):
        return int(round(h - bottom - (min(v, top_value) / top_value) * (h - top - bottom)))
    for k in range(5):
        v = top_value * k / 4
        y = y_of(v)
        cv2.line(img, (left, y), (w - right, y), GRID, 1)
        cv2.putText(img, f"{v:.2g}", (4, y + 4), FONT, 0.33, INK, 1, cv2.LINE_AA)
    cv2.rectangle(img, (left, top), (w - right, h - bottom), INK, 1)
    every = max(1, math.ceil(nb / 12))
    for i, lab in enumerate(labels):
        if i % every == 0:
            x = int(left + (i + 0.5) * px)
            cv2.putText(img, lab, (x - 4 * len(lab) // 2 - 4, h - bottom + 14 + 12 * ((i // every) % 2)), FONT, 0.3,
                        INK, 1, cv2.LINE_AA)
    cv2.putText(img, title, (left, 17), FONT, 0.45, INK, 1, cv2.LINE_AA)
    cv2.putText(img, ylabel, (left + 4, top + 12), FONT, 0.33, INK, 1, cv2.LINE_AA)
    for k, (name, values) in enumerate(series.items()):
        colour = SERIES_COLOURS.get(name, (120, 0, 160))
        width = 4 if name == "real" else 2  # the real fog's line drawn wide, under the others: seen where they match
        v = np.asarray(values, np.float64)
        pts = []
        for i, value in enumerate(v):
            if not np.isfinite(value):
                pts.append(None)
                continue
            y = y_of(value)
            x0, x1 = int(left + i * px), int(left + (i + 1) * px)
            pts.append((x0, x1, y))
        prev = None
        for p in pts:
            if p is None:
                prev = None
                continue
            x0, x1, y = p
            if steps:
                cv2.line(img, (x0, y), (x1, y), colour, width, cv2.LINE_AA)
                if prev is not None:
                    cv2.line(img, (x0, prev[2]), (x0, y), colour, width, cv2.LINE_AA)
            else:
                xc = (x0 + x1) // 2
                cv2.circle(img, (xc, y), width + 1, colour, -1, cv2.LINE_AA)
                if prev is not None:
                    cv2.line(img, ((prev[0] + prev[1]) // 2, prev[2]), (xc, y), colour, width - 1, cv2.LINE_AA)
            prev = p
        cv2.putText(img, name, (w - right - 70, top + 14 + 13 * k), FONT, 0.4, colour, 1, cv2.LINE_AA)
    return img


def _intensity_histogram(stats: ScanStatistics, top: float, bins: int = 32) -> np.ndarray:
    """The share of all returns per bin of [0, ``top``) (``top`` 2^-k: whole fine bins per bin)."""
    fine = stats.intensity_counts[: round(INTENSITY_BINS * top)]
    return fine.reshape(bins, -1).sum(1) / max(1, stats.returns)


def histogram_figure(sets: dict[str, ScanStatistics], clear: ScanStatistics) -> np.ndarray:
    """Four panels of the sets (``clear``, ``real``, ``default``, ``fitted`` — those given) overlaid: the range
    histogram, the near field's range distribution, the far-field survival by range, the intensity histogram."""
    rng = _panel("range histogram: share of returns per range bin (m)", _bin_labels(RANGE_EDGES_M),
                 {k: s.range_share for k, s in sets.items()})
    near_edges = np.arange(0.0, NEAR_M + NEAR_STEP_M / 2, NEAR_STEP_M)
    near = _panel(f"near field (< {NEAR_M:g} m): share of near returns per {NEAR_STEP_M:g} m",
                  [f"{a:g}" for a in near_edges[:-1]],
                  {k: s.near_distribution * s.near_share for k, s in sets.items()}, ylabel="share of all")
    far = _panel("far field: returns per scan / the clear scans' (survival)", _bin_labels(FAR_EDGES_M),
                 {k: s.survival(clear) for k, s in sets.items()}, ylabel="survival", steps=False)
    bins, p95 = 32, max(float(s.quantiles((0.95,))[0]) for s in sets.values())
    top = next(t for t in (1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0) if t >= p95 or t == 1.0)  # where 95 % of them lie
    inten = _panel(f"intensity (normalised, 0-{top:g}): share of returns per bin",
                   [f"{top * i / bins:.3g}" for i in range(bins)],
                   {k: _intensity_histogram(s, top, bins) for k, s in sets.items()})
    gap = np.full((rng.shape[0], 6, 3), 255, np.uint8)
    return np.vstack([np.hstack([rng, gap, near]), np.full((6, 2 * rng.shape[1] + 6, 3), 255, np.uint8),
                      np.hstack([far, gap, inten])])


def distance_figure(scored: dict[str, dict], trace: list[float] | None = None, size=(760, 320)) -> np.ndarray:
    """Bars per distance term and the total of each scored set (``{"default": {"total": D, "terms": {…}},
    "fitted": …}``), and, with a ``trace``, the best distance after each evaluation."""
    w, h = size
    bars_w = int(w * 0.62) if trace else w
    img = np.full((h, w, 3), 255, np.uint8)
    left, top, bottom = 48, 28, 40
    names = [*TERMS, "total"]

    def values(rec):
        return [rec["terms"].get(t, 0.0) for t in TERMS] + [rec["total"]]
    series = {name: values(rec) for name, rec in scored.items()}
    vmax = max(max(v) for v in series.values()) * 1.1 or 1.0
    slot = (bars_w - left - 10) / len(names)
    cv2.putText(img, "distance per term (sqrt of the weighted sum of squares = total)", (left, 17), FONT, 0.42, INK, 1,
                cv2.LINE_AA)
    cv2.line(img, (left, h - bottom), (bars_w - 10, h - bottom), INK, 1)
    for k in range(5):
        v = vmax * k / 4
        y = int(h - bottom - v / vmax * (h - top - bottom))
        cv2.putText(img, f"{v:.2g}", (4, y + 4), FONT, 0.33, INK, 1, cv2.LINE_AA)
        cv2.line(img, (left, y), (bars_w - 10, y), GRID, 1)
    bw = slot / (len(series) + 1)
    for i, name in enumerate(names):
        x = left + i * slot
        for j, (sname, vals) in enumerate(series.items()):
            y = int(h - bottom - vals[i] / vmax * (h - top - bottom))
            x0 = int(x + (j + 0.5) * bw)
            cv2.rectangle(img, (x0, y), (int(x0 + bw) - 1, h - bottom), SERIES_COLOURS[sname], -1)
        label = name.replace("_", " ")
        cv2.putText(img, label, (int(x + 2), h - bottom + 14 + 12 * (i % 2)), FONT, 0.3, INK, 1, cv2.LINE_AA)
    for j, sname in enumerate(series):
        cv2.putText(img, f"{sname}: {series[sname][-1]:.4f}", (int(left + slot + 6), top + 14 + 14 * j), FONT, 0.4,
                    SERIES_COLOURS[sname], 1, cv2.LINE_AA)
    if trace:
        x0, x1, y0, y1 = bars_w + 40, w - 10, top, h - bottom
        cv2.rectangle(img, (x0, y0), (x1, y1), INK, 1)
        cv2.putText(img, "best distance per evaluation (log)", (x0, 17), FONT, 0.4, INK, 1, cv2.LINE_AA)
        t = np.asarray(trace, np.float64)
        hi, lo = float(t.max()), float(t.min())
        lt = np.log(np.maximum(t, 1e-12))
        span = float(lt.max() - lt.min()) or 1.0
        xs = x0 + (np.arange(len(t)) / max(1, len(t) - 1)) * (x1 - x0)
        ys = y1 - (lt - lt.min()) / span * (y1 - y0 - 4) - 2
        cv2.polylines(img, [np.stack([xs, ys], 1).astype(np.int32)], False, SERIES_COLOURS["fitted"], 2, cv2.LINE_AA)
        cv2.putText(img, f"{hi:.3g}", (x0 - 36, y0 + 10), FONT, 0.33, INK, 1, cv2.LINE_AA)
        cv2.putText(img, f"{lo:.3g}", (x0 - 36, y1), FONT, 0.33, INK, 1, cv2.LINE_AA)
        cv2.putText(img, f"1 .. {len(t)} evaluations", (x0, y1 + 14), FONT, 0.33, INK, 1, cv2.LINE_AA)
    return img


# ----------------------------------------------------------------------------- markdown
def _pct(v) -> str:
    return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{100 * v:.2f} %"


def _num(v, fmt="{:.4g}") -> str:
    return "–" if v is None else fmt.format(v)


def markdown(record: dict) -> str:
    """The report (the command's JSON record) as a Markdown page."""
    stats = record["statistics"]
    cols = [c for c in ("clear", "real", *SIMULATED) if stats.get(c)]
    scored = [k for k in SIMULATED if k in record["distance"]]
    out = [f"# {record['command']}: {record['model']} on {record['sensor']}", ""]
    vis = record["visibility_m"]
    out += [f"{record['scans']['clear']} clear and {record['scans']['foggy']} real foggy scans; visibility "
            f"{vis['value']:.0f} m ({vis['source']}), β = {record['beta']:.5f} 1/m; start calibration: "
            f"{record['start_calibration']}; seed {record['seed']}.", ""]
    d = record["distance"]
    out += ["## Distance", "", d["definition"], "", "| term | weight | " + " | ".join(scored) + " |",
            "|---|---|" + "---|" * len(scored)]
    for t in TERMS:
        out.append(f"| {t} | {d['weights'][t]:g} | " + " | ".join(
            f"{d[k]['terms'].get(t, float('nan')):.4f}" for k in scored) + " |")
    out.append("| **total** | | " + " | ".join(f"**{d[k]['total']:.4f}**" for k in scored) + " |")
    if record.get("parameters"):
        out += ["", "## Parameters", "", "| parameter | meaning | start | fitted | search range |",
                "|---|---|---|---|---|"]
        for k, p in record["parameters"].items():
            out.append(f"| `{k}` | {p['meaning']} | {p['start']:.4g} | {p['fitted']:.4g} | "
                       f"{p['low']:.3g} – {p['high']:.3g} |")
        out += ["", f"{record['evaluations']} evaluations (fogs of the clear set), {record['elapsed_s']:.1f} s."]
    out += ["", "## Statistics", "", "| statistic | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]
    out.append("| returns per scan | " + " | ".join(f"{stats[c]['returns_per_scan']:.0f}" for c in cols) + " |")
    out.append(f"| near field (< {NEAR_M:g} m) | " + " | ".join(_pct(stats[c]["near_share"]) for c in cols) + " |")
    labels = _bin_labels(RANGE_EDGES_M)
    for i, lab in enumerate(labels):
        out.append(f"| range {lab} m | " + " | ".join(_pct(stats[c]["range_share"][i]) for c in cols) + " |")
    for i, lab in enumerate(_bin_labels(FAR_EDGES_M)):
        out.append(f"| survival {lab} m | " + " | ".join(
            _num((stats[c].get("far_survival") or [None] * 9)[i], "{:.3f}") for c in cols) + " |")
    for q in INTENSITY_QUANTILES:
        key = f"p{round(100 * q)}"
        out.append(f"| intensity {key} | " + " | ".join(_num(stats[c]["intensity_quantiles"][key], "{:.3f}")
                                                        for c in cols) + " |")
    near_edges = np.arange(0.0, NEAR_M, NEAR_STEP_M)
    out += ["", f"Near field by range (share of all returns per {NEAR_STEP_M:g} m):", "",
            "| range (m) | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]
    for i, a in enumerate(near_edges):
        out.append(f"| {a:g}–{a + NEAR_STEP_M:g} | " + " | ".join(
            _pct(stats[c]["near_distribution"][i] * stats[c]["near_share"]) for c in cols) + " |")
    return "\n".join(out) + "\n"


# ----------------------------------------------------------------------------- the record and the files
DISTANCE_DEFINITION = ("D = sqrt(sum_k w_k d_k^2) over the terms of fogsim.lidar.scan_stats: range (Wasserstein-1 "
                       "between the range histograms, in bins / (bins - 1)), near_share (|difference| of the share of "
                       f"returns within {NEAR_M:g} m), near_range (Wasserstein-1 between the near-field range "
                       f"distributions / {NEAR_M:g} m), far_survival (mean |difference| of the survival per far bin), "
                       "intensity (mean |difference| of the intensity quantiles)")


def report_record(problem, result=None, *, command: str, start_beta: float, start_distance: float,
                  start_terms: dict, start_sim: ScanStatistics, inputs: dict, elapsed_s: float,
                  calibration_file: str | None = None) -> dict:
    """The JSON record of a fit (``result``: a :class:`fogsim.lidar.fit.FitResult`; its start is ``default``)
    or of a comparison (``result`` None: the calibration scored alone, ``simulated``), :func:`markdown`'s
    input."""
    start = "default" if result is not None else "simulated"
    from fogsim._version import __version__
    from fogsim.lidar.fit import PARAMETER_SPACE, VISIBILITY_RANGE_M, beta_of_visibility, visibility_of_beta

    clear = problem.clear_stats
    beta = result.beta if result else start_beta
    fitted_beta = bool(result and result.beta_fitted)
    statistics = {"clear": clear.summary(clear), "real": problem.real_stats.summary(clear),
                  start: start_sim.summary(clear) if start_sim is not None else None}
    if result is not None and result.simulated is not None:
        statistics["fitted"] = result.simulated.summary(clear)
    distance = {"definition": DISTANCE_DEFINITION, "weights": dict(problem.weights),
                start: {"total": start_distance, "terms": start_terms}}
    if result is not None:
        distance["fitted"] = {"total": result.distance, "terms": result.terms}
    calibration = problem.spec.calibration
    record = {"command": command, "fogsim_version": __version__, "model": problem.spec.model,
              "sensor": problem.sensor.name,
              "start_calibration": calibration if isinstance(calibration, str) else (calibration.name or "file"),
              "inputs": inputs, "scans": {"clear": len(problem.clear), "foggy": len(problem.real)},
              "visibility_m": {"value": visibility_of_beta(beta), "source": "fitted" if fitted_beta else "given"},
              "beta": beta, "seed": problem.seed, "distance": distance, "statistics": statistics,
              "elapsed_s": elapsed_s}
    if result is not None:
        params = {}
        for k in problem.parameters:
            lo, hi = PARAMETER_SPACE[k].bounds(result.start_values[k])
            params[k] = {"meaning": PARAMETER_SPACE[k].meaning, "start": result.start_values[k],
                         "fitted": result.values[k], "low": lo, "high": hi}
        if fitted_beta:
            params["beta"] = {"meaning": "the fog's extinction (1/m), visibility unknown", "start": result.start_beta,
                              "fitted": result.beta, "low": beta_of_visibility(VISIBILITY_RANGE_M[1]),
                              "high": beta_of_visibility(VISIBILITY_RANGE_M[0])}
        record |= {"parameters": params, "evaluations": result.evaluations, "trace": result.trace,
                   "calibration_file": calibration_file}
    return record
