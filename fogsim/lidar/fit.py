"""Fit a LiDAR fog model's calibration to real foggy scans, and score any model and calibration against them.

Given clear scans and real foggy scans of one sensor (not of the same scenes), the simulated fog is
:class:`~fogsim.lidar.fog.LidarFogger` applied to every clear scan (the model named by the spec's ``model``,
the sensor under a calibration, the empty rays of each sweep), and the distance is
:func:`fogsim.lidar.scan_stats.distance` between the real and the simulated set (the statistics a detector
feels: range histogram, near-field share and range distribution, far-field survival by range, intensity
quantiles).

A fit (:func:`fit`) varies the calibration keys the model reads (:data:`MODEL_PARAMETERS`, each with its
search range in :data:`PARAMETER_SPACE`) and, when the fog's visibility is not known, β:

* **deterministic, smooth objective**: every evaluation fogs clear scan i with a fresh
  ``numpy.random.default_rng([seed, i])`` — the same draws for every parameter value (common random
  numbers), so the distance changes with the parameters, not with the noise;
* **search**: the parameters mapped to [0, 1] (log-spaced where the range spans decades); a scrambled Sobol
  sample of the box (SciPy's ``qmc``, seeded), a scan of each parameter over its range, then rounds of SciPy's
  Nelder–Mead and bounded Powell methods from the best point seen until they stop improving — at most
  ``evaluations`` fogs of the clear set in all (:data:`SOBOL_PER_PARAMETER` and the constants beside it);
* **never worse**: the start (the default calibration, or ``--lidar-calibration``'s) is the first point
  evaluated and the best point seen is the result, so the fitted distance is ≤ the start's;
* β unknown: first a scan of :data:`BETA_GRID` visibilities with the start calibration picks β's start, then
  β is searched with the rest (visibility :data:`VISIBILITY_RANGE_M`).

A model without an entry in :data:`MODEL_PARAMETERS` cannot be fitted (it can still be scored): the entry is
the list of its calibration keys, and those keys' ranges are :data:`PARAMETER_SPACE`'s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fogsim.lidar.fog import LidarFogger, lidar_fog_spec
from fogsim.lidar.points import PointCloud
from fogsim.lidar.rays import empty_rays
from fogsim.lidar.scan_stats import DEFAULT_WEIGHTS, ScanStatistics, distance, statistics
from fogsim.lidar.sensors import LidarSensor, load_sensor
from fogsim.schema.lidar import (
    CALIBRATION_KEYS,
    DEPRECATED_CALIBRATIONS,
    HAHNER_CONSTANTS,
    LidarCalibration,
    LidarFogSpec,
)

__all__ = ["BETA", "BETA_GRID", "FitProblem", "FitResult", "MODEL_PARAMETERS", "PARAMETER_SPACE", "ParameterRange",
           "VISIBILITY_RANGE_M", "beta_of_visibility", "fit", "fitted_calibration", "visibility_of_beta"]

LN20 = math.log(20.0)
#: the name β goes by among the fitted parameters (it is the fog's, not the calibration's)
BETA = "beta"
#: the visibilities (m) a fit with an unknown visibility searches between
VISIBILITY_RANGE_M = (10.0, 2000.0)
#: the visibilities (m) scanned for β's start when it is not known
BETA_GRID = (25.0, 50.0, 100.0, 200.0, 400.0, 800.0)
#: what an evaluation whose calibration is inconsistent (a ValueError from the sensor) scores
PENALTY = 1e3
#: the exploration: this many scrambled Sobol points per parameter (at most a third of the budget, rounded down to
#: a power of two); then each parameter scanned at SCAN_POINTS evenly spaced values over its whole range from the
#: best point so far (a narrow dip between plateaus — the echo scale's, below which no ray sees fog clutter and above
#: which every near ray does — escapes a line search, not a scan); then rounds of Nelder–Mead (its first simplex
#: SEARCH_STEP wide, parameters mapped to [0, 1]) and SciPy's bounded Powell method from the best point seen
SOBOL_PER_PARAMETER, SCAN_POINTS, SEARCH_STEP = 8, 9, 0.15
#: a round that finds nothing better halves SEARCH_STEP, down to MIN_SEARCH_STEP (then the fit ends, also within
#: its budget). A simplex or line search ends at SEARCH_END ([0, 1] units): the distance is a step function on a
#: finer scale (each step a few points changing outcome)
MIN_SEARCH_STEP, SEARCH_END = 0.01, 0.004


@dataclass(frozen=True)
class ParameterRange:
    """A fitted parameter's search range: ``low`` … ``high`` (× the start value when ``relative``), searched
    on a log scale when ``log``; ``meaning`` says what it does."""

    low: float
    high: float
    log: bool
    relative: bool = False
    meaning: str = ""

    def bounds(self, start: float) -> tuple[float, float]:
        """(low, high) around ``start``, widened to hold it."""
        lo, hi = (self.low * start, self.high * start) if self.relative else (self.low, self.high)
        return min(lo, start), max(hi, start)


#: the calibration keys a fit may vary, and their ranges (units as in fogsim.schema.lidar.LidarSensorSpec)
PARAMETER_SPACE: dict[str, ParameterRange] = {
    "fog_echo_scale": ParameterRange(1e-3, 1e2, True, meaning="echo scale: a factor on the fog echo's signal"),
    "pulse_half_power_ns": ParameterRange(2.0, 50.0, True, meaning="pulse width (ns): the fog echo's range and width"),
    "overlap_full_m": ParameterRange(0.2, 15.0, True, meaning="overlap: beam and receiver overlap fully from here (m)"),
    "fluctuation_sigma": ParameterRange(0.05, 2.0, False, meaning="fluctuation: σ of ln g per ray and pulse"),
    "max_range_m": ParameterRange(0.25, 4.0, True, relative=True,
                                  meaning="threshold margin: the reference target's clear-air reach (m)"),
    "min_range_m": ParameterRange(0.0, 5.0, False, meaning="the nearest reported return (m)"),
    "range_noise_at_threshold_m": ParameterRange(0.01, 2.0, True, meaning="range noise at the threshold (m)"),
    "stf_noise_level": ParameterRange(0.005, 0.5, True,
                                      meaning="STF noise level n: d_max = ln((I + g)/n)/(2β), loss 1 − √(n/(I + g))"),
    "stf_gain": ParameterRange(0.01, 2.0, True, meaning="STF gain g: the intensity offset in d_max and the loss"),
}
#: per model (LidarFogSpec ``model``), the calibration keys a fit varies by default (extended as models are added;
#: a key must be in PARAMETER_SPACE and a calibration key — fogsim.schema.lidar.CALIBRATION_KEYS, a LidarSensor
#: field that LidarSensor.calibrated replaces). stf2020: its per-sensor noise level and gain, the two numbers the
#: STF authors fitted in their chamber. hahner2021: none — it reproduces the released code, whose constants are
#: not the sensor's calibration (it reads none of its keys); only the fog's visibility is fitted, when not given
MODEL_PARAMETERS: dict[str, tuple[str, ...]] = {
    "soft-target": ("fog_echo_scale", "pulse_half_power_ns", "overlap_full_m", "fluctuation_sigma", "max_range_m"),
    "attenuation": ("fluctuation_sigma", "max_range_m"),
    "stf2020": ("stf_noise_level", "stf_gain"),
    "hahner2021": (),
}


def beta_of_visibility(visibility_m: float) -> float:
    """β = ln 20 / V (1/m; V the meteorological visibility in metres)."""
    return LN20 / visibility_m


def visibility_of_beta(beta: float) -> float | None:
    return LN20 / beta if beta > 0 else None


def _start_calibration(calibration) -> dict:
    """The keys a start calibration (``datasheet``, ``hahner-constants`` or a block) sets, with its name and
    sources."""
    calibration = DEPRECATED_CALIBRATIONS.get(calibration, calibration) if isinstance(calibration, str) else calibration
    if calibration == "datasheet":
        return {}
    if calibration == "hahner-constants":
        return dict(HAHNER_CONSTANTS)
    block = calibration if isinstance(calibration, dict) else calibration.model_dump(exclude_none=True)
    return {k: v for k, v in block.items() if v is not None}


@dataclass
class FitProblem:
    """The clear and the real foggy scans of one ``sensor`` (a name, file, dict or LidarSensor: uncalibrated),
    the fog ``spec`` (its ``model``; its ``calibration`` is the start), β (1/m; None: fitted), the
    ``parameters`` varied (None: :data:`MODEL_PARAMETERS` of the model; () scores without fitting), the
    distance's ``weights`` and the ``seed`` of the common random numbers."""

    clear: list[PointCloud]
    real: list[PointCloud]
    sensor: LidarSensor | str | dict
    spec: LidarFogSpec | dict | None = None
    beta: float | None = None
    parameters: tuple[str, ...] | None = None
    weights: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_WEIGHTS))
    seed: int = 0

    def __post_init__(self):
        if not self.clear or not self.real:
            raise ValueError("a fit needs at least one clear and one foggy scan")
        self.spec = lidar_fog_spec(self.spec)
        self.sensor = load_sensor(self.sensor)
        if self.beta is not None and not (math.isfinite(self.beta) and self.beta > 0):
            raise ValueError(f"β must be a finite number > 0 (1/m), got {self.beta}")
        if self.parameters is None:
            if self.spec.model not in MODEL_PARAMETERS:
                raise ValueError(f"model {self.spec.model!r} has no fit parameters declared (fogsim.lidar.fit."
                                 f"MODEL_PARAMETERS: {', '.join(MODEL_PARAMETERS)}); name them with --parameters")
            self.parameters = MODEL_PARAMETERS[self.spec.model]
        unknown = [p for p in self.parameters if p not in PARAMETER_SPACE or p not in CALIBRATION_KEYS]
        if unknown:
            raise ValueError(f"cannot fit {', '.join(unknown)}: the fitted parameters are "
                             f"{', '.join(PARAMETER_SPACE)}")
        self.start_block = _start_calibration(self.spec.calibration)
        start_sensor = self.sensor.calibrated(self.spec.calibration)
        unset = [p for p in self.parameters if getattr(start_sensor, p) is None]
        if unset:
            raise ValueError(f"{self.sensor.name} has no {', '.join(unset)} to start a fit from: give a start with "
                             "--lidar-calibration FILE")
        self.start = {p: float(getattr(start_sensor, p)) for p in self.parameters}
        self.empty = [empty_rays(scan, self.sensor) for scan in self.clear]
        self.real_stats = statistics(self.real)
        self.clear_stats = statistics(self.clear)
        self.last_error: str | None = None

    # ------------------------------------------------------------------ one evaluation
    def calibration(self, values: dict[str, float], name: str = "fit") -> dict:
        """The calibration block of ``values`` (calibration keys; β is not one) over the start calibration."""
        block = {k: v for k, v in self.start_block.items() if k in CALIBRATION_KEYS}
        block.update({k: float(v) for k, v in values.items() if k in CALIBRATION_KEYS})
        start_sources = self.start_block.get("sources") or {}
        sources = {k: start_sources.get(k, "the start calibration") for k in block}
        sources.update({k: "a trial value of fogsim lidar-fit" for k in values if k in CALIBRATION_KEYS})
        return {"name": name, **block, "sources": sources}

    def simulate(self, values: dict[str, float], beta: float) -> ScanStatistics:
        """The statistics of the clear scans fogged at ``beta`` under ``values`` (common random numbers)."""
        spec = self.spec.model_copy(update={"calibration": LidarCalibration.model_validate(self.calibration(values))})
        stats = ScanStatistics()
        for i, (scan, empty) in enumerate(zip(self.clear, self.empty)):
            fogged = LidarFogger(scan, self.sensor, spec, empty)(beta, np.random.default_rng([self.seed, i]))
            stats.add(fogged.cloud)
        return stats

    def evaluate(self, values: dict[str, float], beta: float) -> tuple[float, dict[str, float], ScanStatistics | None]:
        """(distance, its terms, the simulated statistics) at ``values`` and ``beta``; a calibration the sensor or
        model refuses (a ValueError) scores :data:`PENALTY`, with no statistics (its message: ``last_error``)."""
        try:
            sim = self.simulate(values, beta)
        except ValueError as exc:
            self.last_error = str(exc)
            return PENALTY, {}, None
        total, terms = distance(self.real_stats, sim, self.clear_stats, self.weights)
        return total, terms, sim


@dataclass
class FitResult:
    """A fit's outcome: ``values`` (the fitted calibration keys) and ``beta``, their ``distance`` and
    ``terms``; the ``start`` point's (``start_values``, ``start_beta``, ``start_distance``, ``start_terms``);
    ``evaluations`` used and the best distance after each (``trace``); the statistics (``simulated``,
    ``start_simulated``)."""

    values: dict[str, float]
    beta: float
    distance: float
    terms: dict[str, float]
    start_values: dict[str, float]
    start_beta: float
    start_distance: float
    start_terms: dict[str, float]
    evaluations: int
    trace: list[float]
    simulated: ScanStatistics
    start_simulated: ScanStatistics
    beta_fitted: bool


class _Budget(Exception):
    """The evaluation budget is spent (ends SciPy's search; the best point is kept)."""


@dataclass(frozen=True)
class _Space:
    """The searched parameters mapped to [0, 1]: ``names`` and per name (low, high, log)."""

    names: tuple[str, ...]
    bounds: dict[str, tuple[float, float, bool]]

    def decode(self, x) -> dict[str, float]:
        out = {}
        for k, xi in zip(self.names, np.clip(x, 0.0, 1.0)):
            lo, hi, log = self.bounds[k]
            out[k] = float(lo * (hi / lo) ** xi if log else lo + xi * (hi - lo))
        return out

    def encode(self, values: dict[str, float]) -> np.ndarray:
        x = []
        for k in self.names:
            lo, hi, log = self.bounds[k]
            v = values[k]
            x.append(0.0 if hi <= lo else math.log(v / lo) / math.log(hi / lo) if log else (v - lo) / (hi - lo))
        return np.clip(np.array(x, np.float64), 0.0, 1.0)


def _space(problem: FitProblem) -> _Space:
    bounds = {}
    for k in problem.parameters:
        rng = PARAMETER_SPACE[k]
        lo, hi = rng.bounds(problem.start[k])
        bounds[k] = (lo, hi, rng.log and lo > 0)
    if problem.beta is None:
        bounds[BETA] = (beta_of_visibility(VISIBILITY_RANGE_M[1]), beta_of_visibility(VISIBILITY_RANGE_M[0]), True)
    return _Space(tuple(bounds), bounds)


def fit(problem: FitProblem, evaluations: int = 200, progress=None) -> FitResult:
    """Fit ``problem``'s parameters (and β when it is None) within ``evaluations`` fogs of the clear set;
    ``progress(evaluations_done, best_distance)`` after each. ``evaluations`` ≥ 1; with no parameters and a
    known β the start is scored alone."""
    if evaluations < 1:
        raise ValueError(f"a fit needs at least 1 evaluation, got {evaluations}")
    from fogsim.deps import require

    optimize = require("scipy.optimize", "fit")
    qmc = require("scipy.stats.qmc", "fit")
    trace: list[float] = []
    best: dict = {}

    def record(values, beta, got, x=None):
        total, terms, sim = got
        if not best or total < best["distance"]:
            best.update(values=dict(values), beta=beta, distance=total, terms=terms, simulated=sim, x=x)
        trace.append(best["distance"])
        if progress is not None:
            progress(len(trace), best["distance"])

    # the start: β known, or the best of a grid of visibilities under the start calibration
    betas = [problem.beta] if problem.beta is not None else [beta_of_visibility(v) for v in BETA_GRID[:evaluations]]
    scored = []
    for beta in betas:
        got = problem.evaluate(problem.start, beta)
        record(problem.start, beta, got)
        scored.append((got[0], beta, got))
    _, start_beta, start = min(scored, key=lambda s: s[0])
    if start[2] is None:
        raise ValueError(f"the start calibration cannot fog these scans: {problem.last_error}")
    space = _space(problem)
    if space.names and len(trace) < evaluations:
        x0 = space.encode({**problem.start, BETA: start_beta})
        best["x"] = x0
        seen = {tuple(np.round(x0, 12)): start[0]}

        def objective(x):
            x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
            key = tuple(np.round(x, 12))
            if key not in seen:
                if len(trace) >= evaluations:
                    raise _Budget
                values = space.decode(x)
                beta = values.pop(BETA, start_beta)
                got = problem.evaluate(values, beta)
                record(values, beta, got, x)
                seen[key] = got[0]
            return seen[key]

        n = len(space.names)
        try:
            explore = min((evaluations - len(trace)) // 3, SOBOL_PER_PARAMETER * n)
            if explore >= 4:  # a power of two: Sobol points are balanced in blocks of 2^m
                for x in qmc.Sobol(n, scramble=True, seed=problem.seed).random_base2(int(math.log2(explore))):
                    objective(x)
            for k in range(n):  # each parameter along its whole range, from the best point so far
                base = best["x"].copy()
                for v in np.linspace(0.0, 1.0, SCAN_POINTS):
                    x = base.copy()
                    x[k] = v
                    objective(x)
            step = SEARCH_STEP
            while step >= MIN_SEARCH_STEP:  # rounds from the best point until they stop improving
                before = best["distance"]
                x = best["x"]
                simplex = np.vstack([x] + [np.clip(x + step * np.eye(n)[k] * (1 if x[k] <= 0.5 else -1), 0, 1)
                                           for k in range(n)])
                optimize.minimize(objective, x, method="Nelder-Mead", bounds=[(0.0, 1.0)] * n,
                                  options={"initial_simplex": simplex, "xatol": SEARCH_END, "fatol": math.inf,
                                           "maxfev": 10 * evaluations})
                optimize.minimize(objective, best["x"], method="Powell", bounds=[(0.0, 1.0)] * n,
                                  options={"xtol": SEARCH_END, "ftol": 1e-4, "maxfev": 10 * evaluations,
                                           "direc": np.eye(n) * step})
                if not best["distance"] < before:
                    step /= 2
        except _Budget:
            pass
    return FitResult(best["values"], best["beta"], best["distance"], best["terms"], dict(problem.start), start_beta,
                     start[0], start[1], len(trace), trace, best["simulated"], start[2], problem.beta is None)


def fitted_calibration(problem: FitProblem, result: FitResult, name: str, sources: dict[str, str]) -> dict:
    """The calibration file's block (checked by :class:`~fogsim.schema.lidar.LidarCalibration`): the start
    calibration's keys, the fitted ones over them, a ``name``, a description and each key's source."""
    block = problem.calibration(result.values, name)
    vis = visibility_of_beta(result.beta)
    block["description"] = (f"fitted by fogsim lidar-fit for the {problem.spec.model} model of {problem.sensor.name}: "
                            f"distance {result.start_distance:.4f} (start) → {result.distance:.4f} on "
                            f"{len(problem.clear)} clear and {len(problem.real)} foggy scans, visibility "
                            f"{vis:.0f} m ({'fitted' if result.beta_fitted else 'given'})")
    block["sources"] = {**{k: v for k, v in block["sources"].items() if k not in result.values}, **sources}
    return LidarCalibration.model_validate(block).model_dump(exclude_none=True)
