"""fogsim's LiDAR fog beside the reference simulator (Hahner et al. 2021, re-implemented from its paper in
:mod:`fogsim.lidar.hahner`) on one scan: per β the outcome shares and the mean clutter range of each, as
the Markdown table of ``docs/lidar-fog.md`` (``scripts/lidar_side_by_side.py`` regenerates it).

fogsim runs :class:`~fogsim.lidar.fog.LidarFogger` as the model is at run time (sensor, and the
calibration where :class:`~fogsim.schema.lidar.LidarFogSpec` offers a ``calibration`` field); the
reference is fed the intensities its own KITTI viewer feeds (0–1 × 255, rounded), and once more the
unscaled 0–1 values (its intensity trap). Deterministic: range noise from ``numpy.random.default_rng``
seeded per β (fogsim ``seed + k``, the reference ``seed + 100 + k``); shares do not depend on the noise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fogsim.bench.timing import median_ms
from fogsim.lidar.fog import CLUTTER, OUTCOMES, LidarFogger
from fogsim.lidar.hahner import HahnerParameters, clear_cache, fed_intensity, hahner_fog
from fogsim.lidar.points import PointCloud
from fogsim.schema.lidar import LidarFogSpec

__all__ = ["BEGIN", "BETAS", "END", "Row", "SideBySide", "calibration_spec", "markdown", "replace_block",
           "side_by_side", "speed"]

#: the paper's four levels (1/m)
BETAS = (0.03, 0.06, 0.09, 0.12)
#: the markers around the generated block in docs/lidar-fog.md
BEGIN, END = "<!-- side-by-side table -->", "<!-- /side-by-side table -->"
REGENERATE = "python scripts/lidar_side_by_side.py --docs docs"


def calibration_spec(calibration: str | None) -> tuple[dict | None, str]:
    """(the ``lidar_fog`` block for :class:`LidarFogger`, the calibration's name for the table): the
    calibration passed through when :class:`LidarFogSpec` has a ``calibration`` field (None: its
    default); a calibration asked of a model without one is a ValueError."""
    field = LidarFogSpec.model_fields.get("calibration")
    if field is None:
        if calibration is not None:
            raise ValueError(f"this fogsim's LiDAR fog model has no calibration choice (asked for {calibration!r})")
        return None, "none to choose (the model's one set of sensor constants)"
    if calibration is None:
        return None, f"{field.default} (the default)"
    return {"calibration": calibration}, str(calibration)


@dataclass(frozen=True)
class Row:
    """One β: the shares (%) per outcome of fogsim and of the reference, their mean clutter ranges
    (metres, None without clutter; the reference's is the mean distance along each point's ray), and
    the reference's clutter share (%) when fed the unscaled 0–1 values."""

    beta: float
    fogsim: dict[str, float]
    reference: dict[str, float]
    fogsim_clutter_m: float | None
    reference_clutter_m: float | None
    reference_unscaled_clutter: float | None


@dataclass(frozen=True)
class SideBySide:
    """The rows, and what made them: the scan's label and size, its zero-intensity share (%), the sensor,
    the calibration's name, the reference's constants and the seed."""

    rows: list[Row]
    scan: str
    points: int
    zero_intensity: float
    sensor: str
    calibration: str
    reference: HahnerParameters
    seed: int


def _shares(outcome: np.ndarray) -> dict[str, float]:
    counts = np.bincount(outcome, minlength=len(OUTCOMES))
    return {name: 100.0 * float(counts[k]) / len(outcome) for k, name in enumerate(OUTCOMES)}


def _mean(values: np.ndarray) -> float | None:
    return float(values.mean()) if values.size else None


def side_by_side(scan: PointCloud, sensor: str = "hdl64e", betas=BETAS, seed: int = 0, calibration: str | None = None,
                 label: str | None = None, params: HahnerParameters = HahnerParameters()) -> SideBySide:
    """Fog ``scan`` (sensor frame) at each β with fogsim and the reference (module docstring)."""
    spec, cal_name = calibration_spec(calibration)
    fogger = LidarFogger(scan, sensor, spec)
    viewer = fed_intensity(scan, "viewer")
    unscaled = fed_intensity(scan, "raw") if scan.scale == "0-1" else None
    rows = []
    for k, beta in enumerate(betas):
        level = fogger(beta, np.random.default_rng(seed + k))
        clutter_rows = level.output_index[level.outcome == CLUTTER]
        f_range = np.linalg.norm(level.cloud.xyz[clutter_rows].astype(np.float64), axis=1)
        ref = hahner_fog(scan.xyz, viewer, beta, np.random.default_rng(seed + 100 + k), params)
        trap = None
        if unscaled is not None:
            raw = hahner_fog(scan.xyz, unscaled, beta, np.random.default_rng(seed + 100 + k), params)
            trap = _shares(raw.outcome)["clutter"]
        rows.append(Row(float(beta), _shares(level.outcome), _shares(ref.outcome), _mean(f_range),
                        _mean(ref.ray_distance[ref.scattered]), trap))
    zero = 100.0 * float((np.asarray(scan.raw_intensity) == 0).mean())
    return SideBySide(rows, label or scan.source, len(scan), zero, fogger.sensor.name, cal_name, params, seed)


def _four(d: dict[str, float]) -> str:
    return " / ".join(f"{d[name]:.1f}" for name in ("kept", "attenuated", "lost", "clutter"))  # (no no-return rows)


def _metres(v: float | None) -> str:
    return "–" if v is None else f"{v:.1f}"


def markdown(result: SideBySide) -> str:
    """The table and the lines that say what made it (what ``docs/lidar-fog.md`` holds between
    :data:`BEGIN` and :data:`END`)."""
    p = result.reference
    lines = ["| β (1/m) | fogsim kept / attenuated / lost / clutter (%) | reference kept / attenuated / lost / "
             "clutter (%) | mean clutter range fogsim / reference (m) | reference fed 0–1 unscaled: clutter (%) |",
             "|---|---|---|---|---|"]
    for r in result.rows:
        trap = "–" if r.reference_unscaled_clutter is None else f"{r.reference_unscaled_clutter:.1f}"
        lines.append(f"| {r.beta:g} | {_four(r.fogsim)} | {_four(r.reference)} | "
                     f"{_metres(r.fogsim_clutter_m)} / {_metres(r.reference_clutter_m)} | {trap} |")
    lines += ["",
              f"Scan: {result.scan} — {result.points} points, {result.zero_intensity:.1f} % of them "
              f"zero-intensity. fogsim: sensor `{result.sensor}`, calibration: {result.calibration}. "
              f"Reference (`fogsim.lidar.hahner`): fed 0–1 × 255 rounded as its KITTI viewer does, "
              f"τ_H {p.pulse_half_power_ns:g} ns, overlap {p.overlap_start_m:g}–{p.overlap_full_m:g} m, "
              f"Γ {p.target_reflectivity:g}, β_b {p.backscatter_per_visibility:g}/MOR, scattered points "
              f"±{p.scatter_noise_m:g} m (its clutter range: the mean signed distance along each ray), the "
              f"integral at each β exactly"
              f"{' (nearest table)' if p.table_lookup else ''}. Seed {result.seed}. "
              f"Regenerate: `{REGENERATE}`."]
    return "\n".join(lines) + "\n"


def replace_block(text: str, block: str, source: str = "docs/lidar-fog.md") -> str:
    """``text`` with the part between :data:`BEGIN` and :data:`END` replaced by ``block``; a ValueError
    naming ``source`` when the markers are missing or out of order."""
    start, end = text.find(BEGIN), text.find(END)
    if start < 0 or end < start:
        raise ValueError(f"{source}: needs the markers {BEGIN} … {END} (in this order)")
    return text[:start + len(BEGIN)] + "\n" + block + text[end:]


def speed(scan: PointCloud, sensor: str = "hdl64e", betas=BETAS, repeat: int = 5, calibration: str | None = None,
          params: HahnerParameters = HahnerParameters()) -> dict[str, float]:
    """Median milliseconds (interleaved repeats) of the len(betas) levels by fogsim (its set-up included)
    and by the reference re-implementation (the soft-target tables included: its cache is cleared each
    run), on the calling thread."""
    spec, _ = calibration_spec(calibration)
    viewer = fed_intensity(scan, "viewer")

    def fogsim_levels():
        fogger = LidarFogger(scan, sensor, spec)
        return [fogger(b, np.random.default_rng(k)) for k, b in enumerate(betas)]

    def reference_levels():
        clear_cache()
        return [hahner_fog(scan.xyz, viewer, b, np.random.default_rng(k), params) for k, b in enumerate(betas)]

    med = median_ms({"fogsim": fogsim_levels, "reference": reference_levels}, repeat)
    med["ratio"] = med["reference"] / med["fogsim"] if med["fogsim"] > 0 else math.inf
    return med
