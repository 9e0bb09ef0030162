"""LiDAR in fog: what a pulsed, spinning LiDAR reports when the scene it scanned in clear air is in fog of
extinction β — every input point gets an outcome, and the fogged scan holds what the sensor would report.

Models (:class:`fogsim.schema.lidar.LidarFogSpec` ``model``):

``soft-target`` (default) — per point i at range R_i (sensor frame) with normalised intensity I_i, the
sensor under the spec's ``calibration`` (:meth:`LidarSensor.calibrated`: ``datasheet``, ``reference`` or a
block), σ = its ``fluctuation_sigma``:

0. **Fluctuation.** Every echo's received power fluctuates from pulse to pulse and beam to beam (speckle
   of the surface, the droplets' random arrangement, beam-to-beam gain spread, pulse-energy jitter): the
   hard return of ray i carries a factor g_h,i and its fog echo g_f,i, ln g ~ N(0, σ²), independent.
   This is what makes outcome shares continuous in β (no single β at which every ray's echo crosses).
1. Reflectivity from the intensity and the range: ρ_i = max(s·I_lin,i·(R_i/R_ref)^k, ρ_floor)
   (:meth:`LidarSensor.reflectivity_of`; ``reflectivity_floor`` ρ_floor, default 0.02).
2. Clear-air signal over the detection threshold: ln q0_i = max(ln q(ρ_i, R_i) + ln g_h,i, σ + |ln g_h,i|)
   with q(ρ, R) = (ρ/ρ_ref)·(R_max/R)²·ξ(R) (:meth:`LidarSensor.clear_signal`). The floor: the point
   *was* detected in clear air, so its signal is taken at least one σ above the threshold (a return at
   the threshold itself is detected on half its pulses) — whatever its intensity suggests. So a point's
   margin ln q0 ≥ σ: β → 0 gives the clear scan back continuously (nothing is lost while 2β₉₀₅R < σ).
   A floored point's margin is σ + |ln g_h,i|, not σ itself: its pulse fluctuates like every other, so
   faint returns at one range (a dark car, a row of windows) are lost over a span of β, not all at one β
   (a floor of exactly e^σ left them no fluctuation: 2β₉₀₅R = σ lost every one of them at once).
3. Two-way attenuation of the hard return: q_h,i = q0_i · e^(−2 β₉₀₅ R_i), β₉₀₅ = ``extinction_ratio``·β.
   The hard return is detected when q_h,i ≥ 1.
4. The fog's own echo (:mod:`fogsim.lidar.soft_target`): peak q_f at r_f, width w_f, when
   r_f ≥ min_range. In front of point i it is resolved from the hard return by the share
   w_i = clip((R_i − r_f)/(L/2), 0, 1) (L = c·τ_H: one when the target lies L/2 or more behind the echo's
   peak, falling linearly to zero as the two peaks merge — a taper, not a cliff, so a ring of returns at
   one range does not switch all at once): q_c,i = q_f·g_f,i·w_i; it is detected when q_c,i ≥ 1.
5. The return mode decides (``return_mode``: the spec's, else the sensor's):
   *strongest*: the hard return if detected and q_h ≥ q_c, else the fog echo if detected;
   *last*: the hard return if detected, else the fog echo if detected. Otherwise nothing: lost.
6. Range noise grows as the signal falls: σ(q)² = σ₀² + (σ₁/q)² (σ₀ = ``range_noise_m``, σ₁ =
   ``range_noise_at_threshold_m``; the timing jitter of a pulse ∝ its width / SNR). The clear scan
   already holds σ(q0), so a hard return gets the difference: δR = σ₁·√(1/q_h² − 1/q0²)·z. A fog echo
   gets σ₀² + (σ₁·(w_f / (L/2)) / q_c)² (its echo is w_f wide against the pulse's L/2).
7. **Empty rays** (``empty_rays``: the sweep's rays that returned nothing in clear air, unit directions
   and the range of what each hit below the threshold, +inf for nothing; :mod:`fogsim.lidar.rays`): each
   sees the same fog echo, q_c,k = q_f·g_f,k·w_k (w_k from its surface's range, 1 for none), and gains
   a clutter point on its ray at r_f + noise when q_c,k ≥ 1; nothing otherwise.

8. **No-return rows** (:func:`fogsim.lidar.rays.no_returns`: rows nearer than the sensor's minimum range —
   nuScenes stores every firing, a firing without an echo as a row at ≈ 0 m): no hard return. An *open*
   one (its ray known: its ring's elevation at its firing's azimuth; nothing in front of the echo) sees
   the fog echo as an empty ray does, q_c = q_f·g_f with its own row's draws, and becomes that row's
   clutter point (on its ray at r_f + noise, in place: no row is added); otherwise — a blocked one (an
   echo from inside the blind zone, the vehicle's own body, hides the fog behind it) or one whose ray
   is unknown — it stays the row it was, bit for bit: outcome ``no-return``.

Random draws from the caller's ``numpy.random.Generator`` (float32 standard normals), in this order:
z (N, range noise), ln g_h/σ (N), ln g_f/σ (N) for the input points in input order; then, with empty
rays, ln g_f/σ (K) and z (K) for the empty rays in their order. Same Generator state → the same level, bit for bit.

``attenuation`` — steps 0–3 and 6 alone: a point is lost when q_h < 1; no fog echo, no empty-ray clutter.

``hahner2021`` — Hahner et al. 2021's released code as it fogs datasets (:mod:`fogsim.lidar.hahner2021`);
``stf2020`` — the STF authors' chamber-fitted rule (:mod:`fogsim.lidar.stf2020`): each module states its
equations and its draws. Neither uses the sensor's radiometry above nor the empty rays (counted, never
fogged); stf2020's random-scatter points are appended last (``FoggedScan.added_points``). Both leave no-return
rows (step 8) as they were (``no-return``) and keep one row per firing in a scan that stores every firing
(:attr:`LidarFogger.keeps_firings`, :attr:`LidarFogger.blank_mask`).

Outcomes (per input point, :data:`OUTCOMES`):

* ``kept`` — the hard return is reported and its normalised intensity falls by less than
  ``kept_tolerance`` (half an 8-bit step): the point is written exactly as it was (bit for bit).
* ``attenuated`` — the hard return is reported with intensity I·e^(−2β₉₀₅R) (in the linear scale) and
  the range noise of step 6 along the same ray.
* ``lost`` — nothing reported: absent from the fogged scan; ``output_index`` −1. A scan that stores every
  firing (it has rings and placeholder rows at ≈ 0 m: nuScenes) keeps one row per firing: there a lost
  return becomes a placeholder row (x y z 0, intensity 0, its ring) and ``output_index`` names it.
* ``clutter`` — the fog echo is reported instead: a point on the same ray at r_f + noise (a sensor whose
  lasers sit off its axis, ``vertical_offsets_m``: on the laser's own line, r_f + noise from the laser:
  :mod:`fogsim.lidar.laser_line`), with the intensity the sensor gives an echo of that strength at that range
  (its calibrated value, without the fluctuation: ρ_app = q_f·ρ_ref·(r_f/R_max)²/ξ(r_f)); for a no-return
  row, on its ray (step 8).
* ``no-return`` — a no-return row (step 8) that still returns nothing: written exactly as it was.

Every input row has one outcome (the counts sum to the input's rows); ``FoggedScan.no_returns`` counts the
input's no-return rows and ``no_return_clutter`` those of them that became clutter (so no-return rows =
``no-return`` + ``no_return_clutter``); rows out = rows in − ``lost`` + ``empty_ray_clutter`` (a scan that
stores every firing: rows in + ``empty_ray_clutter``).

The fogged scan (:mod:`fogsim.lidar.fogged_scan`) holds the reported points in input order (``index`` still
names the input row; ring and return index carried over), then the empty rays' clutter points (``index``
:data:`EMPTY_RAY_INDEX` = −1, their ring, return index 1), intensities in the source's own scale;
``FoggedScan.empty_ray_clutter`` counts them. β = 0 gives the input back bit for bit. The same scan stored
0–1 or 0–255 gives the same outcomes (the physics reads normalised intensities).

Heterogeneous fog: β may be an array (one visible β per point: the mean extinction along that point's
ray, as the camera path's density field gives per pixel); the fog echo is then computed per point
(exact for few distinct values, else within the bound of :mod:`fogsim.lidar.soft_target`); empty rays
see the mean β.

Assumptions: fixed laser power (real HDL-64s raise it when no echo returns, so recorded intensities fall
less than e^(−2βR)); one hard target per ray (the input point); the fog is homogeneous along each ray;
the fluctuations are independent between rays and between a ray's two echoes (a beam's own gain, common
to all its pulses, is folded into σ); fog levels drawn from different Generators are different pulses.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fogsim.lidar.fogged_scan import FoggedScan, clear_level
from fogsim.lidar.laser_line import LaserLines
from fogsim.lidar.outcomes import ATTENUATED, CLUTTER, EMPTY_RAY_INDEX, KEPT, LOST, NO_RETURN, OUTCOMES
from fogsim.lidar.points import PointCloud
from fogsim.lidar.rays import PLACEHOLDER_M, EmptyRays, no_returns
from fogsim.lidar.scales import scale as scale_named
from fogsim.lidar.sensors import LidarSensor, load_sensor
from fogsim.lidar.soft_target import FogEcho, backscatter_coefficient, echo_per_point, fog_echo
from fogsim.schema.base import check
from fogsim.schema.lidar import LidarFogSpec

__all__ = ["ATTENUATED", "checked_beta", "CLUTTER", "EMPTY_RAY_INDEX", "fog_scan", "FoggedScan", "KEPT",
           "lidar_fog_spec", "LidarFogger", "LOST", "NO_RETURN", "OUTCOMES", "PUBLISHED_MODELS"]

#: the smallest range a noisy return is placed at (metres)
MIN_REPORTED_M = 0.01
#: the published models, each in its own module (imported when chosen)
PUBLISHED_MODELS = ("hahner2021", "stf2020")
#: input points per block of a level's pass: its temporaries (64 KiB a float64 column) stay in the cache and in
#: the allocator's free lists, so a level takes no fresh memory but its draws and output (docs/lidar-fog.md#speed)
BLOCK = 8192


def _blocks(n: int):
    """Slices of :data:`BLOCK` rows covering 0 … n − 1."""
    return (slice(start, min(start + BLOCK, n)) for start in range(0, n, BLOCK))


def lidar_fog_spec(spec: LidarFogSpec | dict | None = None) -> LidarFogSpec:
    """``spec`` as a checked :class:`LidarFogSpec` (None: the defaults; a bad dict: a ValueError)."""
    if spec is None:
        return LidarFogSpec()
    if isinstance(spec, LidarFogSpec):
        return spec
    return check(spec, LidarFogSpec, prefix="lidar_fog")


def checked_beta(beta, n: int, item: str = "point") -> float | np.ndarray:
    """β (1/m) as a float, or an array of one value per ``item`` (``n`` of them; one float when they are all
    equal): a ValueError for a non-finite or negative β or a per-item β of the wrong length. The one check of
    a β every sensor's fog model (LiDAR, radar) takes."""
    if np.ndim(beta) == 0:
        b = float(beta)
        if not (math.isfinite(b) and b >= 0):
            raise ValueError(f"β must be a finite number ≥ 0 (1/m), got {beta}")
        return b
    b = np.asarray(beta, np.float64).reshape(-1)
    if b.shape != (n,):
        raise ValueError(f"a per-{item} β needs one value per {item} ({n}), got {b.size}")
    if not np.isfinite(b).all() or (b < 0).any():
        raise ValueError(f"a per-{item} β must be finite and ≥ 0 (1/m) everywhere")
    return float(b[0]) if n and (b == b[0]).all() else b


@dataclass(eq=False)
class _Level:
    """One level in progress (:meth:`LidarFogger.__call__`): β, its draws (z, σ·ln g_h, σ·ln g_f per input point),
    ``coef`` −2·β₉₀₅ (1/m: ln of the two-way transmission per metre), ``e`` the scalar β's fog echo, ``echo`` its
    (q_f, r_f, w_f) when detectable (scalars, or one each per point), ``extra`` the empty rays' clutter; the output
    arrays (``xyz``, ``intensity``, ``raw``: the reported rows then the empty rays' clutter; per input row
    ``outcome`` and ``reported``), the rows ``written`` so far and the fog echo's rows (``clutter``: output rows,
    input rows, q_c) left to place."""

    beta: float | np.ndarray
    scalar: bool
    z: np.ndarray
    sh: np.ndarray
    su: np.ndarray
    coef: float | np.ndarray
    e: FogEcho | None
    echo: tuple | None
    extra: tuple | None
    xyz: np.ndarray
    intensity: np.ndarray
    raw: np.ndarray
    outcome: np.ndarray
    reported: np.ndarray
    scratch: np.ndarray  # BLOCK × 3 float64
    written: int = 0
    clutter: list = field(default_factory=list)


class LidarFogger:
    """Fog one scan at many densities, sharing the work that does not depend on β (mirrors
    :class:`fogsim.fog.model.Fogger`)::

        fogger = LidarFogger(scan, "hdl64e")            # sensor: a name, a LidarSensor, a dict or a .json
        fogged = fogger(0.06, np.random.default_rng(7))  # β (1/m, scalar or one per point), a Generator

    ``spec``: the model's parameters (:class:`~fogsim.schema.lidar.LidarFogSpec`, a dict of it, or None
    for the defaults; its ``calibration`` is applied to the sensor). ``empty_rays``: the sweep's rays that
    returned nothing in clear air (:class:`~fogsim.lidar.rays.EmptyRays`, or K×3 directions in the sensor
    frame; :func:`fogsim.lidar.rays.empty_rays` finds them in a scan): each gains a fog-clutter point when
    its fog echo is detected. The scan must be in the sensor frame (ranges from the sensor origin).
    """

    def __init__(self, scan: PointCloud, sensor: LidarSensor | str | dict, spec: LidarFogSpec | dict | None = None,
                 empty_rays: EmptyRays | np.ndarray | None = None):
        self.scan, self.spec = scan, lidar_fog_spec(spec)
        self.sensor = load_sensor(sensor).calibrated(self.spec.calibration)
        self.scale = scale_named(scan.scale)
        self.mode = self.spec.return_mode or self.sensor.return_mode
        r = scan.range_m
        if empty_rays is not None and not isinstance(empty_rays, EmptyRays):
            empty_rays = EmptyRays(empty_rays)
        self.empty = empty_rays if empty_rays is not None and len(empty_rays) else None
        self._lines = None  # the points' laser lines (fogsim.lidar.laser_line), made when a fog echo needs them
        self._draws = self._scratch = None  # a level's draws, 3 × N float32, and a block's xyz (at the first level)
        #: the scan's no-return rows (nearer than the sensor's minimum range: fogsim.lidar.rays.no_returns)
        self.blank = no_returns(scan, self.sensor) if (r < self.sensor.min_range_m).any() else None
        self.blank_mask = self.blank_open = None
        if self.blank is not None:
            self.blank_mask = np.zeros(len(scan), bool)
            self.blank_mask[self.blank.rows] = True
            self.blank_open = np.zeros(len(scan), bool)  # the open ones (their ray known, nothing in front of it)
            self.blank_open[self.blank.rows] = self.blank.open
        #: the scan stores every firing (it has rings and placeholder rows, nuScenes): a lost return keeps its row
        self.keeps_firings = bool(self.blank is not None and scan.ring is not None
                                  and (r[self.blank.rows] < PLACEHOLDER_M).any())
        self.range_m = np.maximum(r, 1e-6, out=r)
        #: the published model's fogger (None: soft-target or attenuation, here)
        self.published = None
        if self.spec.model == "hahner2021":
            from fogsim.lidar.hahner2021 import Model
        elif self.spec.model == "stf2020":
            from fogsim.lidar.stf2020 import Model
        if self.spec.model in PUBLISHED_MODELS:
            self.published = Model(self)
            return
        #: ln of the modelled clear-air signal over the threshold, before the fluctuation (step 2)
        self.log_signal = np.empty(len(scan))
        with np.errstate(divide="ignore"):
            for rows in _blocks(len(scan)):
                self.log_signal[rows] = np.log(self.sensor.clear_signal(self._reflectivity(rows), self.range_m[rows]))

    def _linear(self, rows=slice(None)) -> np.ndarray:
        """The linear intensities of the input ``rows`` (float64, :mod:`fogsim.lidar.scales`)."""
        return self.scale.to_linear(np.asarray(self.scan.intensity[rows], np.float64), self.scan.raw_intensity[rows])

    def _reflectivity(self, rows=slice(None)) -> np.ndarray:
        """ρ of the input ``rows`` (step 1)."""
        rho = self.sensor.reflectivity_of(self._linear(rows), self.range_m[rows])
        return np.maximum(rho, self.spec.reflectivity_floor)

    @property
    def normalised(self) -> np.ndarray:
        """The normalised intensity per input point (float64)."""
        return self.scan.intensity.astype(np.float64)

    @property
    def linear(self) -> np.ndarray:
        """The linear intensity per input point (float64)."""
        return self._linear()

    @property
    def reflectivity(self) -> np.ndarray:
        """ρ per input point (step 1)."""
        return self._reflectivity()

    # ------------------------------------------------------------------ the parameters
    def parameters(self, beta, echo=None) -> dict:
        """The record of one call's parameters (β: the value, or the per-point range; ``echo``: the
        scalar β's :class:`~fogsim.lidar.soft_target.FogEcho` when already computed)."""
        spec = self.spec.model_dump()
        if np.ndim(beta) == 0:
            b = float(beta)
            beta_rec = {"beta": b, "visibility_m": (math.log(20.0) / b) if b > 0 else None,
                        "beta_905": self.spec.extinction_ratio * b,
                        "backscatter_per_m_sr": float(backscatter_coefficient(b, self.spec))}
            if b > 0 and self.spec.model == "soft-target":
                e = echo or fog_echo(self.sensor, b, self.spec)
                beta_rec["fog_echo"] = {"signal_over_threshold": e.signal, "range_m": e.range_m, "width_m": e.width_m}
        else:
            b = np.asarray(beta)
            beta_rec = {"beta": "per point", "beta_min": float(b.min()), "beta_mean": float(b.mean()),
                        "beta_max": float(b.max())}
        if self.published is not None:
            beta_rec.update(self.published.parameters(beta))
        return {"model": self.spec.model, "sensor": self.sensor.name, "calibration": self.sensor.calibration,
                "return_mode": self.mode, "fluctuation_sigma": self.sensor.fluctuation_sigma,
                "source": self.scan.source, **beta_rec, "spec": spec}

    # ------------------------------------------------------------------ one level
    def __call__(self, beta, rng: np.random.Generator | None = None) -> FoggedScan:
        n = len(self.scan)
        beta = checked_beta(beta, n)
        if self.published is not None:
            self.published.check(beta)
        if np.ndim(beta) == 0 and beta == 0:
            return clear_level(self, self.parameters(0.0))
        if rng is None:
            raise ValueError("fog with β > 0 draws range noise: pass a seeded numpy.random.Generator")
        if self.published is not None:
            return self.published(beta, rng)
        level = self._level(beta, rng)
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):  # ln 0 (step 4), e^(4β₉₀₅R) (step 6)
            for rows in _blocks(n):
                self._block(level, rows)
        return self._finish(level)

    def _level(self, beta, rng: np.random.Generator) -> _Level:
        """One level's draws (the module docstring's order), fog echo, empty-ray clutter and output arrays."""
        s, n, sg = self.sensor, len(self.scan), self.sensor.fluctuation_sigma
        if self._draws is None:  # this fogger's draw and block buffers, reused level after level (one call at a time)
            self._draws, self._scratch = np.empty((3, n), np.float32), np.empty((min(n, BLOCK), 3))
        z, sh, su = self._draws
        rng.standard_normal(dtype=np.float32, out=z)  # range noise,
        rng.standard_normal(dtype=np.float32, out=sh)  # ln g_h, the hard return's fluctuation,
        sh *= sg
        rng.standard_normal(dtype=np.float32, out=su)  # ln g_f, the fog echo's; then the empty rays'
        su *= sg
        scalar, e, echo = np.ndim(beta) == 0, None, None
        if self.spec.model == "soft-target":
            if scalar:
                e = fog_echo(s, beta, self.spec)
                if e.range_m >= s.min_range_m and e.signal > 0:
                    echo = e.signal, e.range_m, e.width_m
            else:
                echo = echo_per_point(s, beta, self.spec)
        extra = self._empty_ray_clutter(beta, rng, e)
        rows = 0 if extra is None or extra[1] is None else len(extra[0])
        return _Level(beta, scalar, z, sh, su, -2.0 * self.spec.extinction_ratio * beta, e, echo, extra,
                      np.empty((n + rows, 3), np.float32), np.empty(n + rows, np.float32),
                      np.empty(n + rows, np.float32), np.empty(n, np.int8), np.empty(n, bool), self._scratch)

    def _block(self, level: _Level, rows: slice) -> None:
        """Steps 0–8 for the input ``rows`` (the module docstring): their outcomes, and the rows they report written
        at the level's next output rows (a fog echo's position and intensity are left to :meth:`_finish`)."""
        s, sg, lv = self.sensor, self.sensor.fluctuation_sigma, level
        r, sh, su = self.range_m[rows], lv.sh[rows], lv.su[rows]
        log_clear = np.abs(sh, dtype=np.float64)  # ln q0 = max(ln q + ln g_h, σ + |ln g_h|) (step 2)
        log_clear += sg
        np.maximum(log_clear, self.log_signal[rows] + sh, out=log_clear)
        nb = r * (lv.coef if lv.scalar else lv.coef[rows])  # ln of the two-way transmission
        log_qh = log_clear + nb
        hard = log_qh >= 0.0
        blank = None if self.blank_mask is None else self.blank_mask[rows]
        if blank is not None:
            hard &= ~blank  # a no-return row has no hard return (step 8)
        reported_hard, clutter = hard, None
        if lv.echo is not None:
            qf, rf, wf = lv.echo
            half_pulse = 0.5 * s.pulse_length_m
            if lv.scalar:
                q = np.add(su, math.log(qf), dtype=np.float64)  # ln q_c = ln(q_f·g_f·w), w: step 4
                near = r < rf + half_pulse
                if near.any():
                    q[near] += np.log(np.clip((r[near] - rf) / half_pulse, 0.0, 1.0))
                if blank is not None and blank.any():  # an open no-return ray sees the whole echo, a blocked one none
                    q[blank] = np.where(self.blank_open[rows][blank], np.add(su[blank], math.log(qf), dtype=np.float64),
                                        -np.inf)
                if self.mode == "strongest":
                    reported_hard = hard & (log_qh >= q)
                clutter = (q >= 0.0) & ~reported_hard
            else:
                qf, rf = qf[rows], rf[rows]
                w = np.clip((r - rf) / half_pulse, 0.0, 1.0) * (rf >= s.min_range_m)
                if blank is not None:
                    w[blank] = self.blank_open[rows][blank]
                q = qf * np.exp(su) * w  # q_c
                if self.mode == "strongest":
                    reported_hard = hard & (np.exp(log_qh) >= q)
                clutter = (q >= 1.0) & ~reported_hard
        # the reported rows, in input order, and what fog did to each
        reported = reported_hard if clutter is None else reported_hard | clutter
        gone = None
        if self.keeps_firings:  # one row per firing: a lost return becomes a no-return placeholder row
            gone = ~(reported | blank)
            reported = np.ones(len(r), bool)
        elif blank is not None:
            reported = reported | blank  # a no-return row stays a row: clutter or as it was
        lv.reported[rows] = reported
        every = bool(reported.all())  # every row reported (the common case): views, no gathers
        pick = slice(None) if every else np.flatnonzero(reported)
        rh, ri, zi = reported_hard[pick], r[pick], lv.z[rows][pick]
        nbi = nb[pick]
        norm, raw = self.scale.from_linear(self._linear(rows)[pick] * np.exp(nbi))
        kept = rh & (np.subtract(self.scan.intensity[rows][pick], norm, dtype=np.float64) < self.spec.kept_tolerance)
        outcome = lv.outcome[rows]
        oc = outcome if every else np.empty(len(rh), np.int8)  # the reported rows' outcomes
        oc.fill(CLUTTER)
        np.copyto(oc, ATTENUATED, where=rh)
        np.copyto(oc, KEPT, where=kept)
        stay = None
        if blank is not None:  # no-return rows that did not become the fog echo's clutter stay as they were
            stay = blank[pick] if clutter is None else blank[pick] & ~clutter[pick]
            oc[stay] = NO_RETURN
        if gone is not None:
            oc[gone] = LOST  # (every row is picked)
            norm[gone], raw[gone] = 0.0, 0.0
        if not every:
            outcome.fill(LOST)
            outcome[pick] = oc
        new_r = np.expm1(-2.0 * nbi)  # σ₁·√(1/q_h² − 1/q0²) = σ₁/q0·√(e^(4β₉₀₅R) − 1)
        np.sqrt(new_r, out=new_r)
        new_r *= np.exp(-log_clear[pick])
        new_r *= s.range_noise_at_threshold_m
        new_r *= zi
        new_r += ri
        np.maximum(new_r, MIN_REPORTED_M, out=new_r)
        np.copyto(new_r, ri, where=kept)  # a kept point's range as it was (bit for bit)
        if stay is not None:
            new_r[stay] = ri[stay]
        # written at the next output rows: kept and no-return rows bit for bit (their factor R'/R is exactly 1)
        at = lv.written
        lv.written += len(rh)
        xyz, factor = lv.scratch[:len(ri)], np.divide(new_r, ri, out=new_r)
        xyz[...] = self.scan.xyz[rows][pick]
        for k in range(3):  # column by column, in float64 (numpy broadcasts over a last axis of 3 slowly)
            xyz[:, k] *= factor
        if gone is not None:
            xyz[gone] = 0.0
        lv.xyz[at:lv.written] = xyz
        moved = (oc != KEPT) & (oc != NO_RETURN)
        for out, clear, fogged in ((lv.intensity, self.scan.intensity, norm), (lv.raw, self.scan.raw_intensity, raw)):
            out = out[at:lv.written]
            out[:] = clear[rows][pick]
            np.copyto(out, fogged, where=moved)
        if clutter is not None:  # the fog echo's rows: their output rows, input rows and q_c
            c = np.flatnonzero(clutter[pick])  # (= oc == CLUTTER)
            if len(c):
                i = c if every else pick[c]
                lv.clutter.append((at + c, rows.start + i, np.exp(q[i]) if lv.scalar else q[i]))

    def _finish(self, level: _Level) -> FoggedScan:
        """The level's fog-echo rows (their range, intensity and place), then the empty rays' clutter points
        (``index`` :data:`EMPTY_RAY_INDEX`), and the :class:`FoggedScan`."""
        s, scan, lv, n = self.sensor, self.scan, level, len(self.scan)
        if lv.clutter:
            at, ic, qc = (np.concatenate(a) for a in zip(*lv.clutter))
            qf, rf, wf = lv.echo
            if not lv.scalar:
                qf, rf, wf = qf[ic], rf[ic], wf[ic]
            ri = self.range_m[ic]
            on_ray = np.zeros(len(ic), bool) if self.blank is None else self.blank_mask[ic]
            new_r = self._echo_range(rf, wf, qc, lv.z[ic], np.where(on_ray, np.inf, ri))
            lv.intensity[at], lv.raw[at] = self._echo_intensity(qf, rf)  # (one value for one β)
            if self.blank is not None:  # a no-return row's clutter point: on its ray, not along its (void) position
                where = np.searchsorted(self.blank.rows, ic[on_ray])
                lv.xyz[at[on_ray]] = self.blank.directions[where] * new_r[on_ray, None]
            hard = ~on_ray
            if s.vertical_offsets_m is not None:  # the echo lies on the laser's own line (its vertical offset)
                lv.xyz[at[hard]] = self._laser_lines().place(ic[hard], new_r[hard])
            else:  # on the input point's ray
                lv.xyz[at[hard]] = scan.xyz[ic[hard]] * (new_r[hard] / ri[hard])[:, None]
        m, every = lv.written, lv.written == n
        rows = np.zeros(0, np.int64) if lv.extra is None else lv.extra[0]
        end = m + len(rows)
        if len(rows):
            lv.xyz[m:end], lv.intensity[m:end], lv.raw[m:end] = lv.extra[1]
        xyz, inten, raw = lv.xyz, lv.intensity, lv.raw
        if not every:  # lost points: the arrays end after the rows written (no copy)
            for a in (xyz, inten, raw):
                a.resize((end,) + a.shape[1:], refcheck=False)

        def take(a):
            return None if a is None else a.copy() if every else a[lv.reported]
        ring, ret, index = take(scan.ring), take(scan.return_index), take(scan.index)
        if len(rows):
            index = np.concatenate([index, np.full(len(rows), EMPTY_RAY_INDEX, np.int64)])
            if ring is not None:
                er = self.empty.ring
                ring = np.concatenate([ring, (np.zeros(len(rows), np.int16) if er is None else er[rows])])
            if ret is not None:
                ret = np.concatenate([ret, np.ones(len(rows), ret.dtype)])
        if every:
            out_index = np.arange(n, dtype=np.int64)
        else:
            out_index = np.full(n, -1, np.int64)  # (a lost firing's placeholder row: its row)
            out_index[lv.reported] = np.arange(m)
        blank = 0 if self.blank is None else len(self.blank)
        return FoggedScan(PointCloud(xyz, inten, raw, scan.scale, index, scan.source, ring, ret), lv.outcome, out_index,
                          self.parameters(lv.beta, lv.e), 0 if self.empty is None else len(self.empty), int(len(rows)),
                          0, blank, blank - int((lv.outcome == NO_RETURN).sum()))

    def _laser_lines(self) -> LaserLines:
        """The scan's laser lines (a sensor with vertical offsets: a fog echo lies on its laser's own line)."""
        if self._lines is None:
            self._lines = LaserLines(self.scan, self.sensor, self.range_m)
        return self._lines

    def _echo_range(self, rf, wf, qc, z, limit):
        """Where a detected fog echo is reported: r_f + σ_c·z, σ_c² = σ₀² + (σ₁·(w_f/(L/2))/q_c)², kept
        within [min range, ``limit``] (the ray's target, or +inf)."""
        s = self.sensor
        spread = s.range_noise_at_threshold_m * (wf / (0.5 * s.pulse_length_m)) / qc
        sigma_c = np.sqrt(s.range_noise_m ** 2 + spread ** 2)
        return np.maximum(np.clip(rf + sigma_c * z, s.min_range_m, limit), MIN_REPORTED_M)

    def _echo_intensity(self, qf, rf):
        """The intensity the sensor reports for the fog echo (its calibrated value: the echo's apparent
        reflectivity q_f·ρ_ref·(r_f/R_max)²/ξ(r_f), without the fluctuation) in the scan's scale: (normalised,
        raw), shaped as ``qf`` and ``rf`` broadcast."""
        s = self.sensor
        rho_app = qf * s.reference_reflectivity * (rf / s.max_range_m) ** 2 / s.overlap(rf)
        return self.scale.from_linear(s.intensity_of(rho_app, rf))

    def _empty_ray_clutter(self, beta, rng, echo):
        """The clutter points of the empty rays (:attr:`empty`) at ``beta`` (a per-point β: its mean), or
        None: draws σ·u (fluctuation) then z (range noise), one each per empty ray, after the points'."""
        if self.empty is None:
            return None
        k = len(self.empty)
        su = self.sensor.fluctuation_sigma * rng.standard_normal(k, np.float32)
        z = rng.standard_normal(k, np.float32)
        s = self.sensor
        if self.spec.model != "soft-target":
            return np.zeros(0, np.int64), None
        b = float(beta) if np.ndim(beta) == 0 else float(np.mean(beta))
        e = echo if echo is not None and np.ndim(beta) == 0 else fog_echo(s, b, self.spec)
        if not (e.range_m >= s.min_range_m and e.signal > 0):
            return np.zeros(0, np.int64), None
        w = np.clip((self.empty.range_m - e.range_m) / (0.5 * s.pulse_length_m), 0.0, 1.0)  # +inf: 1
        with np.errstate(divide="ignore"):
            log_qc = math.log(e.signal) + su + np.log(w)
        rows = np.flatnonzero(log_qc >= 0.0)
        qc = np.exp(log_qc[rows])
        rr = self._echo_range(e.range_m, e.width_m, qc, z[rows], self.empty.range_m[rows])
        norm, raw = (np.broadcast_to(a, rows.shape) for a in self._echo_intensity(e.signal, e.range_m))
        xyz = self.empty.directions[rows] * rr[:, None]
        if self.empty.origins is not None:  # each ray from its laser
            xyz += self.empty.origins[rows]
        return rows, (xyz, norm, raw)

def fog_scan(scan: PointCloud, sensor, beta, rng: np.random.Generator | None = None,
             spec: LidarFogSpec | dict | None = None, empty_rays=None) -> FoggedScan:
    """One level: ``LidarFogger(scan, sensor, spec, empty_rays)(beta, rng)``."""
    return LidarFogger(scan, sensor, spec, empty_rays)(beta, rng)
