"""Radar in fog: which of a sweep's clear-air detections the radar still reports in fog of the camera's β.

Per detection i at range R_i (sensor frame) with RCS σ_i:

1. Clear-air SNR s_i: the record's ``snr_db`` where known, else the sensor's radar equation
   :meth:`RadarSensor.snr_db(σ_i, R_i) <fogsim.radar.sensors.RadarSensor.snr_db>`; floored at the detection
   threshold T (the detection *was* made in clear air, whatever the estimate says: such a detection sits on
   the threshold and is the first fog removes).
2. The fog's liquid water M(β) and its one-way specific attenuation γ = K_l(f, T_fog) · M dB/km
   (:mod:`fogsim.radar.attenuation`: ITU-R P.840 through ``itur``, Kunkel's visibility–LWC relation).
3. The round trip: s_fog,i = s_i − 2·γ·R_i / 1000. The detection is **kept** when s_fog,i ≥ T, else **lost**.

Outcomes (:data:`OUTCOMES`): ``kept`` — reported exactly as in clear air (bit for bit: position, RCS,
velocities, labels; the loss is ≤ 2 dB to 250 m in the thickest fog the paper uses, within the RCS
estimate's own spread, so the record's RCS is left as measured); ``lost`` — absent from the fogged sweep,
``output_index`` −1. The fogged sweep holds the kept detections in input order.

What it leaves out, and why: no fog clutter — fog droplets (≤ 50 µm) are ≈ 10⁻² of λ ≈ 3.9 mm, Rayleigh
scatterers whose backscatter ∝ D⁶/λ⁴: thick fog (M = 0.5 g/m³ of 20 µm drops) has a radar reflectivity
η = π⁵|K|²ΣD⁶/λ⁴ ≈ 10⁻⁸ m² per m³ (≈ −80 dBsm), an ARS 408 resolution cell at 50 m ≈ −66 dBsm against the
≈ −18 dBsm the sensor needs there: far below the noise; no change of the noise floor, the Doppler spectra
or the angles (liquid water only absorbs); the outcome is a deterministic threshold (the ``rng`` argument
is accepted for the LiDAR's call shape and unused). β = 0 gives the input back bit for bit. β may be one
value per detection (the mean extinction along each ray).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fogsim.radar.attenuation import (
    attenuation_db_per_km,
    itur_version,
    liquid_water_coefficient,
    lwc_from_beta,
    visibility_m,
)
from fogsim.radar.detections import RadarScan
from fogsim.radar.sensors import RadarSensor, load_radar_sensor
from fogsim.schema.base import check
from fogsim.schema.radar import RadarFogSpec

__all__ = ["FoggedRadar", "KEPT", "LOST", "OUTCOMES", "RadarFogger", "fog_radar", "radar_fog_spec"]

OUTCOMES = ("kept", "lost")
KEPT, LOST = range(2)


def radar_fog_spec(spec: RadarFogSpec | dict | None = None) -> RadarFogSpec:
    """``spec`` as a checked :class:`RadarFogSpec` (None: the defaults; a bad dict: a ValueError)."""
    if spec is None:
        return RadarFogSpec()
    if isinstance(spec, RadarFogSpec):
        return spec
    return check(spec, RadarFogSpec, prefix="radar_fog")


def _beta(beta, n: int) -> float | np.ndarray:
    if np.ndim(beta) == 0:
        b = float(beta)
        if not (math.isfinite(b) and b >= 0):
            raise ValueError(f"β must be a finite number ≥ 0 (1/m), got {beta}")
        return b
    b = np.asarray(beta, np.float64).reshape(-1)
    if b.shape != (n,):
        raise ValueError(f"a per-detection β needs one value per detection ({n}), got {b.size}")
    if not np.isfinite(b).all() or (b < 0).any():
        raise ValueError("a per-detection β must be finite and ≥ 0 (1/m) everywhere")
    return float(b[0]) if n and (b == b[0]).all() else b


@dataclass(frozen=True, eq=False)
class FoggedRadar:
    """One fog level of a sweep: ``scan`` (what the radar reports), per input detection ``outcome`` (int8,
    :data:`OUTCOMES`), ``output_index`` (int64, its row in ``scan``, −1 when lost) and ``snr_fog_db``
    (float32, its SNR in the fog), and the ``parameters`` that made it."""

    scan: RadarScan
    outcome: np.ndarray
    output_index: np.ndarray
    parameters: dict = field(default_factory=dict)
    snr_fog_db: np.ndarray | None = None

    def counts(self) -> dict[str, int]:
        """Detections per outcome."""
        got = np.bincount(self.outcome, minlength=len(OUTCOMES))
        return {name: int(got[k]) for k, name in enumerate(OUTCOMES)}

    def record(self) -> dict:
        """The parameters and the counts per outcome (what a sidecar or a report stores)."""
        return {**self.parameters, "detections_in": int(len(self.outcome)), "detections_out": int(len(self.scan)),
                "outcomes": self.counts()}


class RadarFogger:
    """Fog one sweep at many densities, sharing the work that does not depend on β::

        fogger = RadarFogger(scan, "ars408-lr")   # sensor: a name, a RadarSensor, a dict or a .json
        fogged = fogger(0.06)                     # β (1/m, scalar or one per detection)

    ``spec``: the radar's part of the fog record (:class:`~fogsim.schema.radar.RadarFogSpec`, a dict, None)."""

    def __init__(self, scan: RadarScan, sensor: RadarSensor | str | dict, spec: RadarFogSpec | dict | None = None):
        self.scan, self.sensor, self.spec = scan, load_radar_sensor(sensor), radar_fog_spec(spec)
        self.range_m = scan.range_m
        given = np.isfinite(scan.snr_db)
        estimate = self.sensor.snr_db(scan.rcs_dbsm, self.range_m) if not given.all() else None
        snr = scan.snr_db.astype(np.float64) if estimate is None else np.where(given, scan.snr_db, estimate)
        threshold = self.sensor.detection_threshold_db
        self.at_threshold = int((snr < threshold).sum())
        self.clear_snr_db = np.maximum(snr, threshold)
        self.snr_estimated = int((~given).sum())
        self.k_l = liquid_water_coefficient(self.sensor.frequency_ghz, self.spec.temperature_c)

    def parameters(self, beta) -> dict:
        """The record of one call's parameters."""
        s = self.sensor
        common = {"sensor": s.name, "frequency_ghz": s.frequency_ghz, "source": self.scan.source,
                  "temperature_c": self.spec.temperature_c, "k_l_db_per_km_per_g_m3": self.k_l,
                  "k_l_from": f"ITU-R P.840 via itur {itur_version()}",
                  "detection_threshold_db": s.detection_threshold_db, "snr_estimated": self.snr_estimated,
                  "clear_snr_at_threshold": self.at_threshold, "spec": self.spec.model_dump()}
        if np.ndim(beta) == 0:
            b = float(beta)
            lwc = float(lwc_from_beta(b, self.spec))
            return {"beta": b, "visibility_m": visibility_m(b), "lwc_g_m3": lwc,
                    "attenuation_db_per_km": self.k_l * lwc, **common}
        b = np.asarray(beta)
        return {"beta": "per detection", "beta_min": float(b.min()), "beta_mean": float(b.mean()),
                "beta_max": float(b.max()), **common}

    def snr_in_fog(self, beta) -> np.ndarray:
        """s_fog = s − 2·γ(β)·R/1000 per detection (dB, float64)."""
        gamma = attenuation_db_per_km(beta, self.sensor.frequency_ghz, self.spec)
        return self.clear_snr_db - 2.0 * gamma * self.range_m / 1000.0

    def __call__(self, beta, rng: np.random.Generator | None = None) -> FoggedRadar:
        n = len(self.scan)
        beta = _beta(beta, n)
        if np.ndim(beta) == 0 and beta == 0:
            return FoggedRadar(self.scan.copy(), np.full(n, KEPT, np.int8), np.arange(n, dtype=np.int64),
                               self.parameters(0.0), self.clear_snr_db.astype(np.float32))
        snr = self.snr_in_fog(beta)
        kept = snr >= self.sensor.detection_threshold_db
        idx = np.flatnonzero(kept)
        outcome = np.where(kept, KEPT, LOST).astype(np.int8)
        index = np.full(n, -1, np.int64)
        index[idx] = np.arange(len(idx))
        return FoggedRadar(self.scan.select(idx), outcome, index, self.parameters(beta), snr.astype(np.float32))


def fog_radar(scan: RadarScan, sensor, beta, spec: RadarFogSpec | dict | None = None) -> FoggedRadar:
    """One level: ``RadarFogger(scan, sensor, spec)(beta)``."""
    return RadarFogger(scan, sensor, spec)(beta)
