"""fogsim's LiDAR fog models side by side on the same scans: the default (``soft-target``), Hahner et al.
2021 as their released code fogs datasets (``hahner2021``) and the STF authors' chamber-fitted rule
(``stf2020``), per β: the outcome shares, the far field by range bin, the clutter's range distribution, and
what each named calibration makes of the default — the Markdown block of ``docs/lidar-fog.md``
(``scripts/lidar_side_by_side.py`` regenerates it).

Every model runs through :class:`~fogsim.lidar.fog.LidarFogger` as at run time (sensor, spec). Deterministic:
level k of every model draws from ``numpy.random.default_rng(seed + k)``.

* **outcomes**: kept / attenuated / lost / clutter (% of the input points); stf2020's random-scatter points,
  which no input point becomes, as "+ added" (% of the input points);
* **far field**: per range bin of the clear scan (:data:`FAR_BINS`), the share of the scan's points there
  still reported as hard returns (kept or attenuated), % of all its points;
* **clutter range**: p5 / median / p95 of the clutter points' distance from the sensor (metres; hahner2021's
  signed along the ray; stf2020's added points not included);
* **calibrations**: the default model under each named calibration (:data:`~fogsim.schema.lidar.CALIBRATIONS`,
  not the deprecated names).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fogsim.bench.timing import median_ms
from fogsim.lidar.fog import LidarFogger
from fogsim.lidar.hahner import fed_intensity, hahner_fog
from fogsim.lidar.outcomes import CLUTTER, LOST, OUTCOMES
from fogsim.lidar.points import PointCloud
from fogsim.schema.lidar import CALIBRATIONS, DEPRECATED_CALIBRATIONS

__all__ = ["BEGIN", "BETAS", "END", "FAR_BINS", "Level", "MODELS", "REGENERATE", "ScanResult", "Subject",
           "markdown", "model_specs", "replace_block", "run_scan", "speed"]

#: the paper's four levels (1/m)
BETAS = (0.03, 0.06, 0.09, 0.12)
#: the models compared, the default first
MODELS = ("soft-target", "hahner2021", "stf2020")
#: the far field's range bins (metres, edges)
FAR_BINS = (30.0, 50.0, 80.0, math.inf)
#: the markers around the generated block in docs/lidar-fog.md
BEGIN, END = "<!-- side-by-side table -->", "<!-- /side-by-side table -->"
REGENERATE = "python scripts/lidar_side_by_side.py --docs docs"


@dataclass(frozen=True)
class Subject:
    """One scan to compare on: its ``label``, the ``scan`` (sensor frame), the ``sensor`` (a bundled name),
    the default model's ``calibration`` (None: its default) and ``stf`` — the stf2020 spec's calibration
    (None: the sensor's own n, g) and what the table calls it."""

    label: str
    scan: PointCloud
    sensor: str
    calibration: str | dict | None = None
    stf: tuple[dict | None, str] = (None, "the sensor's")


@dataclass(frozen=True)
class Level:
    """One model at one β: outcome shares and the added points (% of the input), the far field per bin
    (% of the input), the clutter's range p5 / p50 / p95 (metres, None without clutter)."""

    model: str
    beta: float
    shares: dict[str, float]
    added: float
    far: list[float]
    clutter_m: tuple[float, float, float] | None


@dataclass
class ScanResult:
    """What one scan gives: its size, zero-intensity share (%), clear far field per bin (%), the levels of
    each model (:data:`MODELS`), the default under each calibration, and the 0–1 trap (the released rule's
    clutter share when a 0–1 scan is fed unscaled; None for other scales)."""

    subject: Subject
    points: int
    zero: float
    clear_far: list[float]
    levels: list[Level] = field(default_factory=list)
    calibrations: dict[str, list[Level]] = field(default_factory=dict)
    trap: list[float] | None = None


def _far(ranges: np.ndarray, reported_hard: np.ndarray, n: int) -> list[float]:
    edges = np.asarray(FAR_BINS)
    return [100.0 * float((reported_hard & (ranges >= lo) & (ranges < hi)).sum()) / n
            for lo, hi in zip(edges, edges[1:])]


def level_stats(model: str, beta: float, scan: PointCloud, fogged) -> Level:
    """A :class:`Level` of one fogged scan."""
    n = len(scan)
    counts = np.bincount(fogged.outcome, minlength=len(OUTCOMES))
    shares = {name: 100.0 * float(counts[k]) / n for k, name in enumerate(OUTCOMES)}
    hard = (fogged.outcome != LOST) & (fogged.outcome != CLUTTER)
    rows = fogged.output_index[fogged.outcome == CLUTTER]
    xyz = fogged.cloud.xyz[rows].astype(np.float64)
    own = scan.xyz[fogged.outcome == CLUTTER].astype(np.float64)
    signed = np.sign(np.einsum("ij,ij->i", xyz, own)) * np.linalg.norm(xyz, axis=1)
    spread = tuple(float(v) for v in np.percentile(signed, (5, 50, 95))) if len(rows) else None
    return Level(model, float(beta), shares, 100.0 * fogged.added_points / n, _far(scan.range_m, hard, n), spread)


def model_specs(subject: Subject) -> dict[str, dict]:
    """The ``lidar_fog`` block of each model (:data:`MODELS`) for ``subject``."""
    return {"soft-target": {"calibration": subject.calibration} if subject.calibration else {},
            "hahner2021": {"model": "hahner2021"},
            "stf2020": {"model": "stf2020"} | ({"calibration": subject.stf[0]} if subject.stf[0] else {})}


def run_scan(subject: Subject, betas=BETAS, seed: int = 0) -> ScanResult:
    """Fog ``subject.scan`` at each β with every model, and the default under each calibration."""
    scan = subject.scan
    n = len(scan)
    result = ScanResult(subject, n, 100.0 * float((np.asarray(scan.raw_intensity) == 0).mean()),
                        _far(scan.range_m, np.ones(n, bool), n))
    specs = model_specs(subject)
    for model in MODELS:
        fogger = LidarFogger(scan, subject.sensor, specs[model])
        result.levels += [level_stats(model, b, scan, fogger(b, np.random.default_rng(seed + k)))
                          for k, b in enumerate(betas)]
    for name in (c for c in CALIBRATIONS if c not in DEPRECATED_CALIBRATIONS):
        fogger = LidarFogger(scan, subject.sensor, {"calibration": name})
        result.calibrations[name] = [level_stats("soft-target", b, scan, fogger(b, np.random.default_rng(seed + k)))
                                     for k, b in enumerate(betas)]
    if scan.scale == "0-1":
        raw = fed_intensity(scan, "raw")
        result.trap = [100.0 * float((hahner_fog(scan.xyz, raw, b, np.random.default_rng(seed + k)).outcome
                                      == CLUTTER).mean()) for k, b in enumerate(betas)]
    return result


# ----------------------------------------------------------------------------- Markdown
def _bin_label(lo: float, hi: float) -> str:
    return f"≥ {lo:g} m" if math.isinf(hi) else f"{lo:g}–{hi:g} m"


def _four(d: dict[str, float]) -> str:
    return " / ".join(f"{d[name]:.1f}" for name in ("kept", "attenuated", "lost", "clutter"))  # (no no-return rows)


def _spread(v) -> str:
    return "–" if v is None else f"{v[1]:.1f} ({v[0]:.1f}–{v[2]:.1f})"


def _by(levels: list[Level], model: str) -> list[Level]:
    return [lv for lv in levels if lv.model == model]


def _scan_block(r: ScanResult) -> list[str]:
    s = r.subject
    bins = " / ".join(_bin_label(lo, hi) for lo, hi in zip(FAR_BINS, FAR_BINS[1:]))
    cal = s.calibration or "datasheet (the default)"
    lines = [f"**{s.label}** — {r.points} points, {r.zero:.1f} % of them zero-intensity; sensor `{s.sensor}`; "
             f"soft-target calibration {cal}; stf2020 n, g: {s.stf[1]}.", "",
             "| β (1/m) | " + " | ".join(f"{m}: kept / attenuated / lost / clutter (%)" for m in MODELS)
             + " | stf2020 added (%) |", "|---|" + "---|" * (len(MODELS) + 1)]
    per = {m: _by(r.levels, m) for m in MODELS}
    for k in range(len(per[MODELS[0]])):
        lv = [per[m][k] for m in MODELS]
        lines.append(f"| {lv[0].beta:g} | " + " | ".join(_four(x.shares) for x in lv) + f" | {lv[-1].added:.1f} |")
    lines += ["", f"Far field, still a hard return, % of the scan ({bins}; clear: "
              + " / ".join(f"{v:.2f}" for v in r.clear_far) + "), and the clutter's range, median (p5–p95) m:", "",
              "| β (1/m) | " + " | ".join(f"{m}: far field" for m in MODELS) + " | "
              + " | ".join(f"{m}: clutter range" for m in MODELS) + " |",
              "|---|" + "---|" * (2 * len(MODELS))]
    for k in range(len(per[MODELS[0]])):
        lv = [per[m][k] for m in MODELS]
        lines.append(f"| {lv[0].beta:g} | " + " | ".join(" / ".join(f"{v:.2f}" for v in x.far) for x in lv) + " | "
                     + " | ".join(_spread(x.clutter_m) for x in lv) + " |")
    lines += ["", "soft-target by calibration — clutter (%), far field ≥ 30 m (%), clutter range median (m):", "",
              "| β (1/m) | " + " | ".join(f"`{c}`" for c in r.calibrations) + " |",
              "|---|" + "---|" * len(r.calibrations)]
    cals = list(r.calibrations.values())
    for k in range(len(cals[0])):
        lines.append(f"| {cals[0][k].beta:g} | " + " | ".join(
            f"{c[k].shares['clutter']:.1f} / {sum(c[k].far):.2f} / "
            f"{'–' if c[k].clutter_m is None else f'{c[k].clutter_m[1]:.1f}'}" for c in cals) + " |")
    if r.trap is not None:
        lines += ["", "The released rule fed this scan's 0–1 values unscaled (the trap applies only to unscaled "
                  "input) scatters " + " / ".join(f"{v:.1f}" for v in r.trap) + " % at these β."]
    return lines


def markdown(results: list[ScanResult], seed: int = 0) -> str:
    """The block ``docs/lidar-fog.md`` holds between :data:`BEGIN` and :data:`END`."""
    lines = []
    for r in results:
        lines += _scan_block(r) + [""]
    lines += [f"Models: `soft-target` fogsim's default; `hahner2021` the released code of Hahner et al. 2021 as it "
              "fogs datasets (its batch path; agreement with that code measured by "
              "`scripts/check_hahner_released.py`); `stf2020` the STF authors' chamber-fitted rule. Level k of every "
              f"model drawn from `default_rng({seed} + k)`. "
              f"Regenerate: `{REGENERATE}`."]
    return "\n".join(lines) + "\n"


def replace_block(text: str, block: str, source: str = "docs/lidar-fog.md") -> str:
    """``text`` with the part between :data:`BEGIN` and :data:`END` replaced by ``block``; a ValueError
    naming ``source`` when the markers are missing or out of order."""
    start, end = text.find(BEGIN), text.find(END)
    if start < 0 or end < start:
        raise ValueError(f"{source}: needs the markers {BEGIN} … {END} (in this order)")
    return text[:start + len(BEGIN)] + "\n" + block + text[end:]


def speed(subject: Subject, betas=BETAS, repeat: int = 5) -> dict[str, float]:
    """Median milliseconds (interleaved repeats, the calling thread) of the len(betas) levels of each model
    (:data:`MODELS`, :func:`model_specs`) on ``subject``, the set-up included (hahner2021's soft-target tables
    too: their cache is cleared before every model's run), and each model's ratio to the default
    (``"<model>/soft-target"``)."""
    from fogsim.lidar.hahner import clear_cache

    specs = model_specs(subject)

    def levels(model):
        def run():
            clear_cache()
            fogger = LidarFogger(subject.scan, subject.sensor, specs[model])
            return [fogger(b, np.random.default_rng(k)) for k, b in enumerate(betas)]
        return run

    med = median_ms({m: levels(m) for m in MODELS}, repeat)
    for m in MODELS[1:]:
        med[f"{m}/{MODELS[0]}"] = med[m] / med[MODELS[0]] if med[MODELS[0]] > 0 else math.inf
    return med
