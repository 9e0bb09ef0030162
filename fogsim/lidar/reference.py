"""A literal per-point transcription of the LiDAR fog model (:mod:`fogsim.lidar.fog`), for the tests
(vectorised == loop) and the benchmark's baseline (``fogsim bench lidar-fog``).

Written independently of the vectorised code, from its docstring: one Python loop over the points with
``math`` functions, the fog echo's integral by a direct convolution (``numpy.convolve``) instead of the
running sums, the peak found by its own parabola. Same inputs, same random draws (float32 standard
normals: per input point one for the range noise, then one per point for the hard return's fluctuation,
then one per point for the fog echo's; then per empty ray one for the fluctuation and one for the range
noise) → the same outcomes, and coordinates and intensities equal to float rounding. Slow on purpose
(≈ 10⁵ points/s); not for production use.
"""
from __future__ import annotations

import math

import numpy as np

from fogsim.lidar.points import PointCloud
from fogsim.lidar.rays import PLACEHOLDER_M, laser_origins, no_returns
from fogsim.lidar.scales import scale as scale_named
from fogsim.lidar.sensors import LidarSensor, load_sensor
from fogsim.lidar.soft_target import STEPS_PER_PULSE
from fogsim.schema.lidar import LidarFogSpec

__all__ = ["reference_echo", "reference_fog"]


def reference_echo(sensor: LidarSensor, beta: float, spec: LidarFogSpec) -> tuple[float, float, float]:
    """(q_f, r_f, w_f) of visible β: J by direct convolution on the midpoint grid, peak by parabola."""
    ext = spec.extinction_ratio * beta
    bb = (spec.backscatter_coefficient * beta / math.log(20.0) if spec.backscatter_rule == "visibility"
          else ext / spec.lidar_ratio_sr)
    length = sensor.pulse_length_m
    m = STEPS_PER_PULSE
    step = length / m
    n = int(math.ceil(4.0 * (length + sensor.overlap_full_m + sensor.min_range_m) / step)) + m
    start = 0.0 if sensor.overlap_full_m > 0 else sensor.min_range_m
    r = (np.arange(n) + 0.5) * step
    xi = np.ones(n) if sensor.overlap_full_m <= 0 else np.minimum(1.0, (r / sensor.overlap_full_m) ** 2)
    w = np.where(r < start, 0.0, xi * np.exp(-2.0 * ext * r) / r ** 2)
    kernel = np.sin(np.pi * (np.arange(m) + 0.5) / m) ** 2  # u = k − j − 0.5 for j = k − 1 … k − m
    j = step * np.convolve(w, kernel)[: n + 1]
    j = np.concatenate([[0.0], j[:n]])  # J at R_t = k·step sums w_j for j < k
    k = int(np.argmax(j))
    value, pos = j[k], k * step
    a, b, c = j[k - 1], j[k], j[k + 1]
    if a - 2 * b + c < 0:
        d = 0.5 * (a - c) / (a - 2 * b + c)
        value, pos = b - 0.25 * (a - c) * d, (k + d) * step
    half = value / 2
    i0 = k
    while i0 > 0 and j[i0] >= half:
        i0 -= 1
    left = i0 * step + (half - j[i0]) / (j[i0 + 1] - j[i0]) * step if j[i0] < half else 0.0
    i1 = k
    while i1 < len(j) - 1 and j[i1] >= half:
        i1 += 1
    right = (i1 - 1) * step + (half - j[i1 - 1]) / (j[i1] - j[i1 - 1]) * step if j[i1] < half else i1 * step
    signal = sensor.fog_echo_scale * math.pi * bb * value * sensor.max_range_m ** 2 / sensor.reference_reflectivity
    return signal, pos, right - left


def _echo_point(s: LidarSensor, sc, qc: float, qf: float, rf: float, wf: float, z: float, limit: float):
    """(range, normalised, raw) of a detected fog echo of signal ``qc`` (peak ``qf`` at ``rf``, width ``wf``)."""
    half_pulse = s.pulse_length_m / 2
    sigma = math.sqrt(s.range_noise_m ** 2 + (s.range_noise_at_threshold_m * (wf / half_pulse) / qc) ** 2)
    rn = max(min(max(rf + sigma * z, s.min_range_m), limit), 0.01)
    xi_f = 1.0 if s.overlap_full_m <= 0 else min(1.0, (rf / s.overlap_full_m) ** 2)
    rho_app = qf * s.reference_reflectivity * (rf / s.max_range_m) ** 2 / xi_f
    lin_c = rho_app / s.reflectivity_per_intensity
    if s.retro_reflective_from is not None and rho_app > s.reflectivity_per_intensity * s.retro_reflective_from:
        ir, white = s.retro_reflective_from, s.reflectivity_per_intensity * s.retro_reflective_from
        lin_c = ir + (1.0 - ir) * math.log(rho_app / white) / math.log(s.retro_reflectivity_max / white)
    if s.intensity_range_exponent:
        lin_c *= (rf / s.intensity_reference_range_m) ** -s.intensity_range_exponent
    if sc.name == "tanh":
        return rn, math.tanh(lin_c), lin_c
    norm_c = min(lin_c, 1.0)
    return rn, norm_c, (norm_c if sc.name == "0-1" else norm_c * 255.0)


def reference_fog(scan: PointCloud, sensor, beta, rng: np.random.Generator, spec: LidarFogSpec = LidarFogSpec(),
                  empty_rays=None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(outcome int8, output xyz ×3 float64 (NaN where lost), normalised intensity, raw intensity) of one
    level, point by point: N rows for the input points (no-return rows: :func:`fogsim.lidar.rays.no_returns`;
    a clutter point of a sensor whose lasers sit off its axis on the laser's line,
    :func:`~fogsim.lidar.rays.laser_origins`; in a scan that stores every firing a lost row's output is its
    placeholder: 0, 0, 0, intensity 0), then (``empty_rays``: K×3 directions from the origin, +inf range) K
    rows for the empty rays (outcome clutter or lost).
    ``beta``: a number or one per point (each point's echo exact; the empty rays use the mean)."""
    s = load_sensor(sensor).calibrated(spec.calibration)
    sc = scale_named(scan.scale)
    mode = spec.return_mode or s.return_mode
    n = len(scan)
    dirs = [] if empty_rays is None else [tuple(float(v) / float(np.linalg.norm(d)) for v in d)
                                          for d in np.asarray(empty_rays, np.float64).reshape(-1, 3)]
    k = len(dirs)
    betas = [float(beta)] * n if np.ndim(beta) == 0 else [float(b) for b in np.asarray(beta).reshape(-1)]
    sigma_g = s.fluctuation_sigma
    fog = any(b > 0 for b in betas)
    z = rng.standard_normal(n, np.float32) if fog else np.zeros(n)
    uh = rng.standard_normal(n, np.float32) if fog else np.zeros(n)
    u = rng.standard_normal(n, np.float32) if fog else np.zeros(n)
    blank = no_returns(scan, s)
    rays = {} if blank is None else {int(row): (tuple(blank.directions[j]), bool(blank.open[j]))
                                     for j, row in enumerate(blank.rows)}
    lasers = laser_origins(scan, s)  # a sensor whose lasers sit off its axis: the echo on the laser's line
    echoes: dict[float, tuple[float, float, float]] = {}
    outcome = np.zeros(n + k, np.int8)
    xyz_out = np.full((n + k, 3), np.nan)
    norm_out = np.full(n + k, np.nan)
    raw_out = np.full(n + k, np.nan)
    half_pulse = s.pulse_length_m / 2
    for i in range(n):
        x, y, zc = (float(v) for v in scan.xyz[i])
        norm, raw = float(scan.intensity[i]), float(scan.raw_intensity[i])
        b = betas[i]
        if b == 0:
            outcome[i], xyz_out[i], norm_out[i], raw_out[i] = 4 if i in rays else 0, (x, y, zc), norm, raw
            continue
        if i in rays:  # a no-return row: the fog echo on its ray when open (w = 1), else as it was
            (dx, dy, dz), is_open = rays[i]
            qc = 0.0
            if spec.model == "soft-target" and is_open:
                if b not in echoes:
                    echoes[b] = reference_echo(s, b, spec)
                qf, rf, wf = echoes[b]
                if s.min_range_m <= rf:
                    qc = qf * math.exp(float(np.float32(sigma_g) * u[i]))
            if qc >= 1.0:
                rn, norm_out[i], raw_out[i] = _echo_point(s, sc, qc, qf, rf, wf, z[i], math.inf)
                outcome[i], xyz_out[i] = 3, (dx * rn, dy * rn, dz * rn)
            else:
                outcome[i], xyz_out[i], norm_out[i], raw_out[i] = 4, (x, y, zc), norm, raw
            continue
        r = max(math.sqrt(x * x + y * y + zc * zc), 1e-6)
        lin = raw if sc.name == "tanh" else norm
        rho = s.reflectivity_per_intensity * lin
        if s.retro_reflective_from is not None and lin > s.retro_reflective_from:
            ir, white = s.retro_reflective_from, s.reflectivity_per_intensity * s.retro_reflective_from
            rho = white * (s.retro_reflectivity_max / white) ** ((lin - ir) / (1.0 - ir))
        if s.intensity_range_exponent:
            rho *= (r / s.intensity_reference_range_m) ** s.intensity_range_exponent
        rho = max(rho, spec.reflectivity_floor)
        xi = 1.0 if s.overlap_full_m <= 0 else min(1.0, (r / s.overlap_full_m) ** 2)
        g = math.exp(float(np.float32(sigma_g) * u[i]))  # the fog echo's fluctuation (ln g in float32)
        log_gh = float(np.float32(sigma_g) * uh[i])  # the hard return's (ln g_h)
        q0 = max(rho / s.reference_reflectivity * (s.max_range_m / r) ** 2 * xi * math.exp(log_gh),
                 math.exp(sigma_g + abs(log_gh)))  # the clear-air floor: a margin of σ + |ln g_h|
        t2 = math.exp(-2.0 * spec.extinction_ratio * b * r)
        qh = q0 * t2
        hard = qh >= 1.0
        qc = qf = 0.0
        rf = wf = 0.0
        if spec.model == "soft-target":
            if b not in echoes:
                echoes[b] = reference_echo(s, b, spec)
            qf, rf, wf = echoes[b]
            if s.min_range_m <= rf:  # the resolvable share w = clip((R − r_f)/(L/2), 0, 1)
                qc = qf * g * min(max((r - rf) / half_pulse, 0.0), 1.0)
        fog_seen = qc >= 1.0
        if mode == "strongest":
            report_hard = hard and qh >= qc
        else:
            report_hard = hard
        lin_h = lin * t2
        if sc.name == "tanh":
            norm_h, raw_h = math.tanh(lin_h), lin_h
        else:
            norm_h = min(lin_h, 1.0)
            raw_h = norm_h if sc.name == "0-1" else norm_h * 255.0
        if report_hard:
            if norm - float(np.float32(norm_h)) < spec.kept_tolerance:
                outcome[i], xyz_out[i], norm_out[i], raw_out[i] = 0, (x, y, zc), norm, raw
                continue
            var = max(1.0 / (qh * qh) - 1.0 / (q0 * q0), 0.0)
            rn = max(r + s.range_noise_at_threshold_m * math.sqrt(var) * z[i], 0.01)
            outcome[i] = 1
            xyz_out[i] = (x / r * rn, y / r * rn, zc / r * rn)
            norm_out[i], raw_out[i] = norm_h, raw_h
        elif fog_seen:
            rn, norm_out[i], raw_out[i] = _echo_point(s, sc, qc, qf, rf, wf, z[i], r)
            outcome[i] = 3
            if lasers is None:
                xyz_out[i] = (x / r * rn, y / r * rn, zc / r * rn)
            else:  # from the laser's origin o (⊥ its line) along the line through the point: √(R² − |o|²) to it
                o = lasers[i]
                t = math.sqrt(max(r * r - float(o @ o), 1e-12))
                xyz_out[i] = o + (np.array([x, y, zc]) - o) * (rn / t)
        else:
            outcome[i] = 2
    if blank is not None and scan.ring is not None and (scan.range_m[blank.rows] < PLACEHOLDER_M).any():
        gone = np.flatnonzero(outcome[:n] == 2)  # every firing is a row: a lost one is a placeholder row
        xyz_out[gone], norm_out[gone], raw_out[gone] = 0.0, 0.0, 0.0
    if k:
        ue = rng.standard_normal(k, np.float32)
        ze = rng.standard_normal(k, np.float32)
        b = sum(betas) / n if n else 0.0
        qf, rf, wf = reference_echo(s, b, spec) if (spec.model == "soft-target" and b > 0) else (0.0, 0.0, 0.0)
        for j, (dx, dy, dz) in enumerate(dirs):
            qc = qf * math.exp(float(np.float32(sigma_g) * ue[j]))  # an empty ray: nothing in front, w = 1
            if qf > 0 and rf >= s.min_range_m and qc >= 1.0:
                rn, norm_out[n + j], raw_out[n + j] = _echo_point(s, sc, qc, qf, rf, wf, ze[j], math.inf)
                outcome[n + j] = 3
                xyz_out[n + j] = (dx * rn, dy * rn, dz * rn)
            else:
                outcome[n + j] = 2
    return outcome, xyz_out, norm_out, raw_out
