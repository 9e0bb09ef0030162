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

Both are computed level by level in :mod:`fogsim.lidar.soft_target_model` (over blocks of points; the outputs do
not depend on the block size); what does not depend on β (ranges, ln q, no-return rows) once per scan, here.

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

import numpy as np

from fogsim.lidar.fogged_scan import FoggedScan, clear_level
from fogsim.lidar.outcomes import ATTENUATED, CLUTTER, EMPTY_RAY_INDEX, KEPT, LOST, NO_RETURN, OUTCOMES
from fogsim.lidar.points import PointCloud
from fogsim.lidar.rays import PLACEHOLDER_M, EmptyRays, no_returns
from fogsim.lidar.scales import scale as scale_named
from fogsim.lidar.sensors import LidarSensor, load_sensor
from fogsim.lidar.soft_target import backscatter_coefficient, fog_echo
from fogsim.lidar.soft_target_model import Model as OwnModel
from fogsim.lidar.soft_target_model import blocks
from fogsim.schema.base import check
from fogsim.schema.lidar import LidarFogSpec

__all__ = ["ATTENUATED", "checked_beta", "CLUTTER", "EMPTY_RAY_INDEX", "fog_scan", "FoggedScan", "KEPT",
           "lidar_fog_spec", "LidarFogger", "LOST", "NO_RETURN", "OUTCOMES", "PUBLISHED_MODELS"]

#: the published models, each in its own module (imported when chosen)
PUBLISHED_MODELS = ("hahner2021", "stf2020")


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


class LidarFogger:
    """Fog one scan at many densities, sharing the work that does not depend on β (mirrors
    :class:`fogsim.fog.model.Fogger`)::

        fogger = LidarFogger(scan, "hdl64e")            # sensor: a name, a LidarSensor, a dict or a .json
        fogged = fogger(0.06, np.random.default_rng(7))  # β (1/m, scalar or one per point), a Generator

    ``spec``: the model's parameters (:class:`~fogsim.schema.lidar.LidarFogSpec`, a dict of it, or None
    for the defaults; its ``calibration`` is applied to the sensor). ``empty_rays``: the sweep's rays that
    returned nothing in clear air (:class:`~fogsim.lidar.rays.EmptyRays`, or K×3 directions in the sensor
    frame; :func:`fogsim.lidar.rays.empty_rays` finds them in a scan): each gains a fog-clutter point when
    its fog echo is detected. The scan must be in the sensor frame (ranges from the sensor origin). A fogger
    keeps its draw buffers from level to level: call it from one thread at a time (each level's result is its own).
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
        #: the published model's fogger (None: soft-target or attenuation, whose levels ``levels`` computes)
        self.published = self.levels = None
        if self.spec.model == "hahner2021":
            from fogsim.lidar.hahner2021 import Model
        elif self.spec.model == "stf2020":
            from fogsim.lidar.stf2020 import Model
        if self.spec.model in PUBLISHED_MODELS:
            self.published = Model(self)
            return
        self.levels = OwnModel(self)  # (fogsim.lidar.soft_target_model)
        #: ln of the modelled clear-air signal over the threshold, before the fluctuation (step 2)
        self.log_signal = np.empty(len(scan))
        with np.errstate(divide="ignore"):
            for rows in blocks(len(scan)):
                self.log_signal[rows] = np.log(self.sensor.clear_signal(self._reflectivity(rows), self.range_m[rows]))

    def linear_of(self, rows=slice(None)) -> np.ndarray:
        """The linear intensities of the input ``rows`` (float64, :mod:`fogsim.lidar.scales`)."""
        return self.scale.to_linear(np.asarray(self.scan.intensity[rows], np.float64), self.scan.raw_intensity[rows])

    def _reflectivity(self, rows=slice(None)) -> np.ndarray:
        """ρ of the input ``rows`` (step 1)."""
        rho = self.sensor.reflectivity_of(self.linear_of(rows), self.range_m[rows])
        return np.maximum(rho, self.spec.reflectivity_floor)

    @property
    def normalised(self) -> np.ndarray:
        """The normalised intensity per input point (float64)."""
        return self.scan.intensity.astype(np.float64)

    @property
    def linear(self) -> np.ndarray:
        """The linear intensity per input point (float64)."""
        return self.linear_of()

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
        return self.published(beta, rng) if self.published is not None else self.levels(beta, rng)


def fog_scan(scan: PointCloud, sensor, beta, rng: np.random.Generator | None = None,
             spec: LidarFogSpec | dict | None = None, empty_rays=None) -> FoggedScan:
    """One level: ``LidarFogger(scan, sensor, spec, empty_rays)(beta, rng)``."""
    return LidarFogger(scan, sensor, spec, empty_rays)(beta, rng)
