"""LiDAR in fog: what a pulsed, spinning LiDAR reports when the scene it scanned in clear air is in fog of
extinction β — every input point gets an outcome, and the fogged scan holds what the sensor would report.

Models (:class:`fogsim.schema.lidar.LidarFogSpec` ``model``):

``soft-target`` (default) — per point i at range R_i (sensor frame) with normalised intensity I_i:

1. Reflectivity from the intensity and the range: ρ_i = max(s·I_lin,i·(R_i/R_ref)^k, ρ_floor)
   (:meth:`LidarSensor.reflectivity_of`; ``reflectivity_floor`` ρ_floor, default 0.02).
2. Clear-air signal over the detection threshold: q0_i = max(q(ρ_i, R_i), 1) with
   q(ρ, R) = (ρ/ρ_ref)·(R_max/R)²·ξ(R) (:meth:`LidarSensor.clear_signal`); the floor 1 says the point
   *was* detected in clear air, whatever its intensity suggests.
3. Two-way attenuation of the hard return: q_h,i = q0_i · e^(−2 β₉₀₅ R_i), β₉₀₅ = ``extinction_ratio``·β.
   The hard return is detected when q_h,i ≥ 1.
4. The fog's own echo (:mod:`fogsim.lidar.soft_target`): peak q_f at r_f, width w_f. It is a separate
   echo in front of point i when min_range ≤ r_f ≤ R_i − L/2 (L = c·τ_H; closer to the target, the two
   peaks merge): q_c,i = q_f, else 0; it is detected when q_c,i ≥ 1.
5. The return mode decides (``return_mode``: the spec's, else the sensor's):
   *strongest*: the hard return if detected and q_h ≥ q_c, else the fog echo if detected;
   *last*: the hard return if detected, else the fog echo if detected. Otherwise nothing: lost.
6. Range noise grows as the signal falls: σ(q)² = σ₀² + (σ₁/q)² (σ₀ = ``range_noise_m``, σ₁ =
   ``range_noise_at_threshold_m``; the timing jitter of a pulse ∝ its width / SNR). The clear scan
   already holds σ(q0), so a hard return gets the difference: δR = σ₁·√(1/q_h² − 1/q0²)·z. A fog echo
   gets σ₀² + (σ₁·(w_f / (L/2)) / q_c)² (its echo is w_f wide against the pulse's L/2). z ~ N(0, 1)
   from the caller's ``numpy.random.Generator``, one draw per input point, in input order.

``attenuation`` — steps 1–3 and 6 alone: a point is lost when q_h < 1; no fog echo.

Outcomes (per input point, :data:`OUTCOMES`):

* ``kept`` — the hard return is reported and its normalised intensity falls by less than
  ``kept_tolerance`` (half an 8-bit step): the point is written exactly as it was (bit for bit).
* ``attenuated`` — the hard return is reported with intensity I·e^(−2β₉₀₅R) (in the linear scale) and
  the range noise of step 6 along the same ray.
* ``lost`` — nothing reported: absent from the fogged scan; ``output_index`` −1.
* ``clutter`` — the fog echo is reported instead: a point on the same ray at r_f + noise, with the
  intensity the sensor gives an echo of that strength at that range (ρ_app = q_c·ρ_ref·(r_f/R_max)²/ξ(r_f)).

The fogged scan holds the reported points in input order (``index`` still names the input row; ring and
return index carried over), intensities in the source's own scale. β = 0 gives the input back bit for bit.
The same scan stored 0–1 or 0–255 gives the same outcomes (the physics reads normalised intensities).

Heterogeneous fog: β may be an array (one visible β per point: the mean extinction along that point's
ray, as the camera path's density field gives per pixel); the fog echo is then computed per point
(exact for few distinct values, else within the bound of :mod:`fogsim.lidar.soft_target`).

Assumptions: fixed laser power (real HDL-64s raise it when no echo returns, so recorded intensities fall
less than e^(−2βR)); one hard target per ray (the input point); rays without a clear-air return (sky)
get no fog echo; the fog is homogeneous along each ray; outcomes are deterministic thresholds, only the
range noise is random.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fogsim.lidar.points import PointCloud
from fogsim.lidar.scales import scale as scale_named
from fogsim.lidar.sensors import LidarSensor, load_sensor
from fogsim.lidar.soft_target import backscatter_coefficient, echo_per_point, fog_echo
from fogsim.schema.base import check
from fogsim.schema.lidar import LidarFogSpec

__all__ = ["ATTENUATED", "CLUTTER", "FoggedScan", "KEPT", "LOST", "LidarFogger", "OUTCOMES", "fog_scan",
           "lidar_fog_spec"]

OUTCOMES = ("kept", "attenuated", "lost", "clutter")
KEPT, ATTENUATED, LOST, CLUTTER = range(4)
#: the smallest range a noisy return is placed at (metres)
MIN_REPORTED_M = 0.01


def lidar_fog_spec(spec: LidarFogSpec | dict | None = None) -> LidarFogSpec:
    """``spec`` as a checked :class:`LidarFogSpec` (None: the defaults; a bad dict: a ValueError)."""
    if spec is None:
        return LidarFogSpec()
    if isinstance(spec, LidarFogSpec):
        return spec
    return check(spec, LidarFogSpec, prefix="lidar_fog")


def _beta(beta, n: int) -> float | np.ndarray:
    if np.ndim(beta) == 0:
        b = float(beta)
        if not (math.isfinite(b) and b >= 0):
            raise ValueError(f"β must be a finite number ≥ 0 (1/m), got {beta}")
        return b
    b = np.asarray(beta, np.float64).reshape(-1)
    if b.shape != (n,):
        raise ValueError(f"a per-point β needs one value per point ({n}), got {b.size}")
    if not np.isfinite(b).all() or (b < 0).any():
        raise ValueError("a per-point β must be finite and ≥ 0 (1/m) everywhere")
    if (b == b[0]).all():
        return float(b[0])
    return b


@dataclass(frozen=True, eq=False)
class FoggedScan:
    """One fog level of a scan: ``cloud`` (what the sensor reports), per input point ``outcome`` (int8,
    :data:`OUTCOMES`) and ``output_index`` (int64, its row in ``cloud``, −1 when lost), and the
    ``parameters`` that made it (:meth:`record`)."""

    cloud: PointCloud
    outcome: np.ndarray
    output_index: np.ndarray
    parameters: dict = field(default_factory=dict)

    def counts(self) -> dict[str, int]:
        """Points per outcome."""
        got = np.bincount(self.outcome, minlength=len(OUTCOMES))
        return {name: int(got[k]) for k, name in enumerate(OUTCOMES)}

    def record(self) -> dict:
        """The parameters and the counts per outcome (what a sidecar or a report stores)."""
        return {**self.parameters, "points_in": int(len(self.outcome)), "points_out": int(len(self.cloud)),
                "outcomes": self.counts()}


class LidarFogger:
    """Fog one scan at many densities, sharing the work that does not depend on β (mirrors
    :class:`fogsim.fog.model.Fogger`)::

        fogger = LidarFogger(scan, "hdl64e")            # sensor: a name, a LidarSensor, a dict or a .json
        fogged = fogger(0.06, np.random.default_rng(7))  # β (1/m, scalar or one per point), a Generator

    ``spec``: the model's parameters (:class:`~fogsim.schema.lidar.LidarFogSpec`, a dict of it, or None
    for the defaults). The scan must be in the sensor frame (ranges from the sensor origin).
    """

    def __init__(self, scan: PointCloud, sensor: LidarSensor | str | dict, spec: LidarFogSpec | dict | None = None):
        self.scan, self.sensor, self.spec = scan, load_sensor(sensor), lidar_fog_spec(spec)
        self.scale = scale_named(scan.scale)
        self.mode = self.spec.return_mode or self.sensor.return_mode
        r = scan.range_m
        self.range_m = np.maximum(r, 1e-6)
        self.normalised = scan.intensity.astype(np.float64)
        self.linear = self.scale.to_linear(scan.intensity, scan.raw_intensity)
        rho = np.maximum(self.sensor.reflectivity_of(self.linear, self.range_m), self.spec.reflectivity_floor)
        self.reflectivity = rho
        self.clear_signal = np.maximum(self.sensor.clear_signal(rho, self.range_m), 1.0)
        self._xyz = scan.xyz.astype(np.float64)

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
        return {"model": self.spec.model, "sensor": self.sensor.name, "return_mode": self.mode,
                "source": self.scan.source, **beta_rec, "spec": spec}

    # ------------------------------------------------------------------ one level
    def __call__(self, beta, rng: np.random.Generator | None = None) -> FoggedScan:
        n = len(self.scan)
        beta = _beta(beta, n)
        if np.ndim(beta) == 0 and beta == 0:
            return self._clear()
        if rng is None:
            raise ValueError("fog with β > 0 draws range noise: pass a seeded numpy.random.Generator")
        z = rng.standard_normal(n)
        r, s, scalar = self.range_m, self.sensor, np.ndim(beta) == 0
        t2 = np.exp(r * (-2.0 * self.spec.extinction_ratio * beta))
        qh = self.clear_signal * t2
        hard = qh >= 1.0
        half_pulse = 0.5 * s.pulse_length_m
        e = qf = rf = wf = None
        clutter = None
        if self.spec.model == "soft-target":
            if scalar:
                e = fog_echo(s, beta, self.spec)
                qf, rf, wf = e.signal, e.range_m, e.width_m
                separate = r >= rf + half_pulse if (qf >= 1.0 and rf >= s.min_range_m) else None
                if separate is not None:  # a detectable fog echo in front of the targets beyond r_f + L/2
                    reported_hard = hard & ((qh >= qf) | ~separate) if self.mode == "strongest" else hard
                    clutter = separate & ~reported_hard
            else:
                qf, rf, wf = echo_per_point(s, beta, self.spec)
                qc = np.where((rf >= s.min_range_m) & (rf <= r - half_pulse), qf, 0.0)
                reported_hard = hard & (qh >= qc) if self.mode == "strongest" else hard
                clutter = (qc >= 1.0) & ~reported_hard
        if clutter is None:
            reported_hard, clutter = hard, None
        # the reported points, in input order, and what fog did to each
        reported = reported_hard if clutter is None else reported_hard | clutter
        idx = np.flatnonzero(reported)
        pick = slice(None) if len(idx) == n else idx  # every point reported: views, no gathers
        rh = reported_hard[pick]
        t2i, ri, zi = t2[pick], r[pick], z[pick]
        norm_out, raw_out = self.scale.from_linear(self.linear[pick] * t2i)
        kept = rh & (self.normalised[pick] - norm_out < self.spec.kept_tolerance)
        oc = np.where(rh, np.where(kept, KEPT, ATTENUATED), CLUTTER).astype(np.int8)
        with np.errstate(divide="ignore", invalid="ignore"):
            qi, q0 = qh[pick], self.clear_signal[pick]
            sigma = s.range_noise_at_threshold_m * np.sqrt(np.maximum(1.0 / (qi * qi) - 1.0 / (q0 * q0), 0.0))
        new_r = np.where(kept, ri, np.maximum(ri + sigma * zi, MIN_REPORTED_M))
        if clutter is not None and not rh.all():
            c = np.flatnonzero(~rh)
            qcc, rfc, wfc = (qf, rf, wf) if scalar else (qf[idx[c]], rf[idx[c]], wf[idx[c]])
            sigma_c = np.sqrt(s.range_noise_m ** 2 + (s.range_noise_at_threshold_m * (wfc / half_pulse) / qcc) ** 2)
            new_r[c] = np.maximum(np.clip(rfc + sigma_c * zi[c], s.min_range_m, ri[c]), MIN_REPORTED_M)
            rho_app = qcc * s.reference_reflectivity * (rfc / s.max_range_m) ** 2 / s.overlap(rfc)
            norm_out[c], raw_out[c] = self.scale.from_linear(np.broadcast_to(s.intensity_of(rho_app, rfc), c.shape))
        outcome = np.full(n, LOST, np.int8)
        outcome[pick] = oc
        return self._assemble(idx, pick, oc, new_r, norm_out, raw_out, outcome, self.parameters(beta, e))

    def _assemble(self, idx, pick, oc, new_r, norm_out, raw_out, outcome, parameters: dict) -> FoggedScan:
        """The fogged cloud of the reported rows ``idx`` (outcomes ``oc``): kept rows bit for bit (their
        factor R'/R is exactly 1), the others moved along their ray and given their new intensity."""
        scan = self.scan
        xyz = self._xyz.copy() if isinstance(pick, slice) else np.take(self._xyz, idx, axis=0)
        factor = new_r / self.range_m[pick]
        for k in range(3):  # column by column: numpy broadcasts over a last axis of 3 slowly
            xyz[:, k] *= factor
        moved = oc != KEPT
        inten = np.where(moved, norm_out, scan.intensity[pick])
        raw = np.where(moved, raw_out, scan.raw_intensity[pick])

        def take(a):
            return None if a is None else a[idx]
        cloud = PointCloud(xyz.astype(np.float32), inten, raw, scan.scale, take(scan.index), scan.source,
                           take(scan.ring), take(scan.return_index))
        index = np.full(len(outcome), -1, np.int64)
        index[idx] = np.arange(len(idx))
        return FoggedScan(cloud, outcome, index, parameters)

    def _clear(self) -> FoggedScan:
        s = self.scan
        copy = PointCloud(s.xyz.copy(), s.intensity.copy(), s.raw_intensity.copy(), s.scale, s.index.copy(), s.source,
                          None if s.ring is None else s.ring.copy(),
                          None if s.return_index is None else s.return_index.copy())
        n = len(s)
        return FoggedScan(copy, np.full(n, KEPT, np.int8), np.arange(n, dtype=np.int64), self.parameters(0.0))


def fog_scan(scan: PointCloud, sensor, beta, rng: np.random.Generator | None = None,
             spec: LidarFogSpec | dict | None = None) -> FoggedScan:
    """One level: ``LidarFogger(scan, sensor, spec)(beta, rng)``."""
    return LidarFogger(scan, sensor, spec)(beta, rng)
