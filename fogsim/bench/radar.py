"""Radar fog speed: detections per second through :class:`~fogsim.radar.fog.RadarFogger` at the paper's four
fog levels, one core, against per-detection loops of the same model in the same run.

The sweeps are drawn from the radar equation (:func:`synthetic_sweep`): an ARS 408 far scan (±9°, 1–250 m)
of cars (RCS ~ N(10, 5) dBsm), pedestrians (N(−5, 3)) and poles and rails (N(0, 5)), kept where the clear-air
SNR clears the threshold (what the sensor would have reported), SNR unknown (NaN, as in a real nuScenes file:
the fogger estimates it from RCS and range).

Timed, interleaved, medians (:func:`fogsim.bench.timing.median_ms`):

* **one big sweep** (``--detections``, default 100 000): the four levels by one fogger (set-up included);
* **many real-sized sweeps** (``--sweeps`` × 125 detections, nuScenes' typical RADAR_FRONT sweep): a fogger
  per sweep, four levels each — what ``fogsim fog --points`` does per file;
* **baselines** on a ``--loop-detections`` subsample, scaled: the model transcribed per detection in plain
  Python with K_l from ``itur`` per detection (how one would write it from P.840), and the same loop with K_l
  computed once.

Also printed: per level the attenuation (dB/km), the liquid water, the shares kept, and the share kept within
100 m. ``fogsim bench radar [--repeat 5] [--detections 100000] [--sweeps 200] [--loop-detections 2000]``
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.bench.timing import median_ms
from fogsim.deps import require
from fogsim.radar.detections import RadarScan
from fogsim.radar.fog import KEPT, RadarFogger
from fogsim.radar.sensors import RadarSensor
from fogsim.schema.radar import RadarFogSpec

__all__ = ["PAPER_BETAS", "SWEEP_DETECTIONS", "run", "synthetic_sweep"]

PAPER_BETAS = (0.03, 0.06, 0.09, 0.12)
#: detections in one real-sized sweep (nuScenes' RADAR_FRONT: ≈ 100–130 after the devkit's filters)
SWEEP_DETECTIONS = 125
#: the mix of targets: (share, RCS mean dBsm, RCS spread dBsm) for cars, pedestrians, poles and rails
TARGETS = ((0.5, 10.0, 5.0), (0.2, -5.0, 3.0), (0.3, 0.0, 5.0))


def synthetic_sweep(n: int, seed: int = 0, sensor: RadarSensor | None = None) -> RadarScan:
    """About ``n`` detections of an ARS 408 far scan drawn as the module docstring says (fewer: those the
    radar equation puts below the threshold are not detections)."""
    sensor = sensor or RadarSensor.preset("ars408-lr")
    rng = np.random.default_rng(seed)
    m = int(n * 1.6)  # draw more: about a third fall below the threshold
    kind = rng.choice(len(TARGETS), m, p=[t[0] for t in TARGETS])
    rcs = np.choose(kind, [rng.normal(mu, sd, m) for _, mu, sd in TARGETS])
    r = rng.uniform(1.0, sensor.max_range_m, m)
    lo, hi = sensor.azimuth_fov_deg
    az = np.radians(rng.uniform(lo, hi, m))
    seen = np.flatnonzero(sensor.snr_db(rcs, r) >= sensor.detection_threshold_db)[:n]
    xyz = np.stack([r * np.cos(az), r * np.sin(az), np.zeros(m)], 1)[seen]
    v = rng.normal(0, 5, (len(seen), 1)) * np.stack([np.cos(az[seen]), np.sin(az[seen])], 1)
    return RadarScan.checked(xyz, rcs[seen], velocity=v, source=f"synthetic ARS 408 sweep (seed {seed})")


def loop_fog(scan: RadarScan, sensor: RadarSensor, beta: float, spec: RadarFogSpec, k_l: float | None = None):
    """The model per detection in plain Python (the baseline): K_l from ``itur`` per detection unless given."""
    itur = require("itur", "radar")

    c = 299_792_458.0
    lam = c / (sensor.frequency_ghz * 1e9)
    noise = 10 * math.log10(1.380649e-23 * 290.0 * sensor.noise_bandwidth_mhz * 1e6) + sensor.noise_figure_db
    const = (sensor.transmit_power_dbm - 30 + sensor.tx_gain_dbi + sensor.rx_gain_dbi + 20 * math.log10(lam)
             - 30 * math.log10(4 * math.pi) - noise + sensor.processing_gain_db)
    lwc = (1000 * beta / spec.lwc_coefficient) ** (1 / spec.lwc_exponent)
    out = []
    for i in range(len(scan)):
        x, y, z = (float(v) for v in scan.xyz[i])
        r = math.sqrt(x * x + y * y + z * z)
        snr = float(scan.snr_db[i])
        if math.isnan(snr):
            snr = const + float(scan.rcs_dbsm[i]) - 40 * math.log10(max(r, 1e-3))
        snr = max(snr, sensor.detection_threshold_db)
        k = k_l if k_l is not None else float(itur.models.itu840.specific_attenuation_coefficients(
            sensor.frequency_ghz, spec.temperature_c))
        out.append(snr - 2 * k * lwc * r / 1000 >= sensor.detection_threshold_db)
    return out


def run(repeat: int = 5, detections: int = 100_000, sweeps: int = 200, loop_detections: int = 2000,
        seed: int = 0) -> int:
    """Measure and print; returns 0."""
    sensor = RadarSensor.preset("ars408-lr")
    spec = RadarFogSpec()
    big = synthetic_sweep(detections, seed, sensor)
    small = [synthetic_sweep(SWEEP_DETECTIONS, seed + 1 + k, sensor) for k in range(sweeps)]
    n_small = sum(len(s) for s in small)
    sub = big.select(np.arange(min(loop_detections, len(big))))

    def vectorised():
        fogger = RadarFogger(big, sensor, spec)
        return [fogger(b) for b in PAPER_BETAS]

    def per_sweep():
        for s in small:
            fogger = RadarFogger(s, sensor, spec)
            for b in PAPER_BETAS:
                fogger(b)

    k_l = RadarFogger(sub, sensor, spec).k_l

    def loop_itur():
        return [loop_fog(sub, sensor, b, spec) for b in PAPER_BETAS]

    def loop_once():
        return [loop_fog(sub, sensor, b, spec, k_l) for b in PAPER_BETAS]

    levels = vectorised()
    for lv, want in zip(levels, loop_once()):  # the baseline is the same model
        assert np.array_equal(lv.outcome[: len(sub)] == KEPT, np.array(want))
    med = median_ms({"vectorised": vectorised, "per_sweep": per_sweep, "loop_itur": loop_itur,
                     "loop_once": loop_once}, repeat)
    n = len(big)
    scale = n / len(sub)
    rate = 4 * n / (med["vectorised"] / 1000)
    rate_small = 4 * n_small / (med["per_sweep"] / 1000)
    rate_itur = 4 * len(sub) / (med["loop_itur"] / 1000)
    rate_once = 4 * len(sub) / (med["loop_once"] / 1000)
    print(f"radar fog benchmark: sensor {sensor.name} ({sensor.frequency_ghz:g} GHz), β = "
          f"{', '.join(f'{b:g}' for b in PAPER_BETAS)} 1/m, ITU-R P.840 at {spec.temperature_c:g} °C, one core, "
          f"medians of {repeat} interleaved repeats")
    print(f"  {f'one sweep of {n} detections, 4 levels':<52}{med['vectorised']:9.1f} ms  {rate / 1e6:8.2f} M det/s "
          f"({med['vectorised'] / 4:.1f} ms per level)")
    print(f"  {f'{sweeps} sweeps × ≈{SWEEP_DETECTIONS} ({n_small}), a fogger each, 4 levels':<52}"
          f"{med['per_sweep']:9.1f} ms  {rate_small / 1e6:8.2f} M det/s "
          f"({1000 * med['per_sweep'] / sweeps / 4:.0f} µs per sweep and level)")
    print(f"  {f'loop, itur per detection, {len(sub)} × {scale:.0f}':<52}{med['loop_itur'] * scale:9.1f} ms  "
          f"{rate_itur / 1e6:8.3f} M det/s  (ratio {rate / rate_itur:,.0f}×)")
    print(f"  {f'loop, K_l once, {len(sub)} × {scale:.0f}':<52}{med['loop_once'] * scale:9.1f} ms  "
          f"{rate_once / 1e6:8.3f} M det/s  (ratio {rate / rate_once:,.0f}×)")
    near = big.range_m <= 100
    for b, lv in zip(PAPER_BETAS, levels):
        p = lv.parameters
        kept = lv.outcome == KEPT
        print(f"    β = {b:<5g} V {p['visibility_m']:5.1f} m  M {p['lwc_g_m3']:.3f} g/m³  "
              f"γ {p['attenuation_db_per_km']:.3f} dB/km  kept {100 * kept.mean():5.1f} %  "
              f"within 100 m {100 * kept[near].mean():6.2f} %")
    print(f"bench radar: {rate / 1e6:.1f} M detections/s over 4 levels ({med['vectorised'] / 4:.1f} ms per level of "
          f"{n}), {rate_small / 1e6:.2f} M/s in {SWEEP_DETECTIONS}-detection sweeps, {rate / rate_itur:,.0f}× the "
          f"per-detection loop with itur")  # the summary line (--quiet)
    return 0
