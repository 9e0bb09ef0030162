"""What a detector feels of a set of LiDAR scans, as numbers: the statistics :mod:`fogsim.lidar.fit` matches
between real foggy scans and simulated ones, and the one distance between two sets of them.

Statistics of a set of scans (:class:`ScanStatistics`, pooled over the set; ranges from the sensor origin in
metres, intensities normalised 0–1 as :class:`~fogsim.lidar.points.PointCloud` gives them):

* **range histogram** — the share of all returns per bin of :data:`RANGE_EDGES_M` (finer near the sensor);
* **near field** — the share of returns closer than :data:`NEAR_M` (where fog clutter lands), and its range
  distribution: the share of the near returns per :data:`NEAR_STEP_M` bin;
* **far-field survival by range** — the returns per scan in each bin of :data:`FAR_EDGES_M` over the same in
  the *clear* scans (so a set of foggy scans is read against clear scans of the same sensor, not of the same
  scenes): 1 = fog took nothing there; a bin the clear scans hold fewer than :data:`MIN_CLEAR_PER_BIN`
  returns in is left out;
* **intensity quantiles** — :data:`INTENSITY_QUANTILES` of the returns' normalised intensity (from a
  :data:`INTENSITY_BINS`-bin histogram, linear within a bin).

The distance between a real and a simulated set (:func:`distance`; every term in [0, 1] but the survival,
which can exceed 1 where a set holds more than the clear scans) is the weighted root sum of squares
D = √(Σ w_k·d_k²) of:

=================  ==================================================================================
``range``          Wasserstein-1 between the two range histograms, in bins (each bin one unit) / (bins − 1)
``near_share``     |share near − share near|
``near_range``     Wasserstein-1 between the near-field range distributions, in metres / :data:`NEAR_M`
``far_survival``   the mean over the far bins of |survival − survival|
``intensity``      the mean over the quantiles of |quantile − quantile|
=================  ==================================================================================

weights :data:`DEFAULT_WEIGHTS` (all 1) unless given. A deterministic function of the two sets' counts: no
sampling, no tolerance. Squares, not a plain sum: each term is V-shaped about its own best parameters (an
absolute difference), and their plain sum a polyhedral cone whose sharp, diagonal valleys stall a
derivative-free search; the sum of squares is a smooth bowl there with the same zero.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fogsim.lidar.points import PointCloud

__all__ = ["DEFAULT_WEIGHTS", "FAR_EDGES_M", "INTENSITY_BINS", "INTENSITY_QUANTILES", "MIN_CLEAR_PER_BIN", "NEAR_M",
           "NEAR_STEP_M", "RANGE_EDGES_M", "ScanStatistics", "TERMS", "distance", "parse_weights", "statistics"]

#: the range histogram's bin edges (m): 1 m steps to 8 m (the fog echo's shell), coarser beyond
RANGE_EDGES_M = (0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 10.0, 12.5, 15.0, 20.0, 25.0, 30.0, 40.0, 50.0, 60.0,
                 80.0, 100.0, 120.0, math.inf)
#: the near field: returns closer than this (m), binned every NEAR_STEP_M
NEAR_M, NEAR_STEP_M = 10.0, 0.5
#: the far field's survival bins (m)
FAR_EDGES_M = (10.0, 20.0, 30.0, 50.0, 80.0, math.inf)
#: a far bin enters the survival only when the clear scans hold at least this many returns in it (all scans)
MIN_CLEAR_PER_BIN = 20
INTENSITY_QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)
INTENSITY_BINS = 1024
TERMS = ("range", "near_share", "near_range", "far_survival", "intensity")
DEFAULT_WEIGHTS = {t: 1.0 for t in TERMS}
_NEAR_EDGES = np.arange(0.0, NEAR_M + NEAR_STEP_M / 2, NEAR_STEP_M)


@dataclass
class ScanStatistics:
    """Counts pooled over a set of scans (``add`` one scan at a time): ``scans``, ``returns``, returns per
    :data:`RANGE_EDGES_M` bin (``range_counts``), per near bin (``near_counts``), per far bin
    (``far_counts``), per intensity bin (``intensity_counts``, :data:`INTENSITY_BINS` over [0, 1])."""

    scans: int = 0
    returns: int = 0
    range_counts: np.ndarray = field(default_factory=lambda: np.zeros(len(RANGE_EDGES_M) - 1, np.int64))
    near_counts: np.ndarray = field(default_factory=lambda: np.zeros(len(_NEAR_EDGES) - 1, np.int64))
    far_counts: np.ndarray = field(default_factory=lambda: np.zeros(len(FAR_EDGES_M) - 1, np.int64))
    intensity_counts: np.ndarray = field(default_factory=lambda: np.zeros(INTENSITY_BINS, np.int64))

    def add(self, cloud: PointCloud) -> "ScanStatistics":
        """Pool one scan's returns in (every row of ``cloud`` is a return)."""
        r = cloud.range_m
        self.scans += 1
        self.returns += len(r)
        self.range_counts += np.bincount(np.searchsorted(RANGE_EDGES_M, r, "right") - 1,
                                         minlength=len(self.range_counts))[: len(self.range_counts)]
        near = r[r < NEAR_M]
        self.near_counts += np.bincount(np.minimum((near / NEAR_STEP_M).astype(np.int64), len(self.near_counts) - 1),
                                        minlength=len(self.near_counts))
        k = np.searchsorted(FAR_EDGES_M, r[r >= FAR_EDGES_M[0]], "right") - 1
        self.far_counts += np.bincount(k, minlength=len(self.far_counts))[: len(self.far_counts)]
        i = np.clip((np.asarray(cloud.intensity, np.float64) * INTENSITY_BINS).astype(np.int64), 0, INTENSITY_BINS - 1)
        self.intensity_counts += np.bincount(i, minlength=INTENSITY_BINS)
        return self

    # ------------------------------------------------------------------ the statistics
    @property
    def range_share(self) -> np.ndarray:
        return self.range_counts / max(1, self.returns)

    @property
    def near_share(self) -> float:
        return float(self.near_counts.sum() / max(1, self.returns))

    @property
    def near_distribution(self) -> np.ndarray:
        return self.near_counts / max(1, int(self.near_counts.sum()))

    @property
    def far_per_scan(self) -> np.ndarray:
        return self.far_counts / max(1, self.scans)

    def survival(self, clear: "ScanStatistics") -> np.ndarray:
        """Returns per scan per far bin over ``clear``'s (NaN where ``clear`` holds too few)."""
        ok = clear.far_counts >= MIN_CLEAR_PER_BIN
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(ok, self.far_per_scan / np.where(ok, clear.far_per_scan, 1.0), np.nan)

    def intensity_quantiles(self) -> np.ndarray:
        """:data:`INTENSITY_QUANTILES` of the normalised intensity (linear within a histogram bin)."""
        return self.quantiles(INTENSITY_QUANTILES)

    def quantiles(self, q) -> np.ndarray:
        """Quantiles ``q`` (in [0, 1]) of the normalised intensity, linear within a histogram bin (NaN: none)."""
        total = int(self.intensity_counts.sum())
        if not total:
            return np.full(len(q), np.nan)
        cdf = np.cumsum(self.intensity_counts) / total  # at each bin's right edge
        q = np.asarray(q, np.float64)
        k = np.minimum(np.searchsorted(cdf, q), INTENSITY_BINS - 1)  # the bin each quantile falls in
        below = np.where(k > 0, cdf[k - 1], 0.0)
        share = (q - below) / np.maximum(cdf[k] - below, 1e-300)
        return (k + np.clip(share, 0.0, 1.0)) / INTENSITY_BINS

    def summary(self, clear: "ScanStatistics | None" = None) -> dict:
        """The statistics as a record (what a report stores)."""
        out = {"scans": self.scans, "returns_per_scan": self.returns / max(1, self.scans),
               "range_edges_m": [e if math.isfinite(e) else None for e in RANGE_EDGES_M],
               "range_share": self.range_share.tolist(), "near_m": NEAR_M, "near_share": self.near_share,
               "near_step_m": NEAR_STEP_M, "near_distribution": self.near_distribution.tolist(),
               "far_edges_m": [e if math.isfinite(e) else None for e in FAR_EDGES_M],
               "far_per_scan": self.far_per_scan.tolist(), "intensity_quantiles": dict(zip(
                   (f"p{round(100 * q)}" for q in INTENSITY_QUANTILES), self.intensity_quantiles().tolist()))}
        if clear is not None:
            out["far_survival"] = [None if np.isnan(v) else float(v) for v in self.survival(clear)]
        return out


def statistics(clouds) -> ScanStatistics:
    """The statistics of an iterable of :class:`PointCloud` scans."""
    stats = ScanStatistics()
    for cloud in clouds:
        stats.add(cloud)
    return stats


def _wasserstein_bins(p: np.ndarray, q: np.ndarray) -> float:
    """W1 between two histograms on the same bins, in bins: Σ |CDF_p − CDF_q| (each normalised to sum 1)."""
    p = p / p.sum() if p.sum() else p
    q = q / q.sum() if q.sum() else q
    return float(np.abs(np.cumsum(p) - np.cumsum(q))[:-1].sum())


def distance(real: ScanStatistics, simulated: ScanStatistics, clear: ScanStatistics,
             weights: dict[str, float] | None = None) -> tuple[float, dict[str, float]]:
    """(√(Σ w_k·d_k²), {term: d_k}) between the ``real`` and ``simulated`` sets (the module docstring), the far
    survival of both read against ``clear``."""
    w = DEFAULT_WEIGHTS if weights is None else weights
    nr = len(real.range_counts)
    d = {"range": _wasserstein_bins(real.range_share, simulated.range_share) / (nr - 1),
         "near_share": abs(real.near_share - simulated.near_share),
         "near_range": _wasserstein_bins(real.near_distribution, simulated.near_distribution) * NEAR_STEP_M / NEAR_M}
    a, b = real.survival(clear), simulated.survival(clear)
    ok = ~(np.isnan(a) | np.isnan(b))
    d["far_survival"] = float(np.abs(a[ok] - b[ok]).mean()) if ok.any() else 0.0
    qa, qb = real.intensity_quantiles(), simulated.intensity_quantiles()
    d["intensity"] = float(np.abs(qa - qb).mean()) if not (np.isnan(qa).any() or np.isnan(qb).any()) else 1.0
    return math.sqrt(sum(w.get(k, 0.0) * v * v for k, v in d.items())), d


def parse_weights(text: str | None) -> dict[str, float]:
    """``range=1,near_share=2,…`` (terms not named keep weight 1) as weights; a ValueError naming the problem."""
    weights = dict(DEFAULT_WEIGHTS)
    for part in (text or "").split(","):
        if not part.strip():
            continue
        key, _, value = part.partition("=")
        key = key.strip()
        if key not in TERMS:
            raise ValueError(f"unknown distance term {key!r} in --weights (terms: {', '.join(TERMS)})")
        try:
            weights[key] = float(value)
        except ValueError:
            raise ValueError(f"--weights {key}= needs a number, got {value.strip()!r}") from None
        if not (math.isfinite(weights[key]) and weights[key] >= 0):
            raise ValueError(f"--weights {key} must be a finite number ≥ 0, got {value.strip()}")
    if not any(weights.values()):
        raise ValueError("--weights gives every term weight 0: nothing to match")
    return weights
