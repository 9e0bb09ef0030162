"""``soft-target`` and ``attenuation``, fogsim's own LiDAR fog models, one level at a time: the steps 0–8 and the
draws that :mod:`fogsim.lidar.fog` states, on a :class:`~fogsim.lidar.fog.LidarFogger`'s scan (its ranges, ln q
and no-return rows, computed once per scan).

A level runs over blocks of :data:`BLOCK` input points: each block's steps use small temporaries (64 KiB a
float64 column: they stay in the cache and in the allocator's free lists), and the rows it reports are written
straight into the level's output arrays — the reported input rows in input order, then the empty rays' clutter
points; the arrays end early (shrunk in place) when points are lost. A fog echo's rows get their range,
intensity and place once per level, after the pass (on the laser's own line: :mod:`fogsim.lidar.laser_line`). The
draws go into one 3 × N float32 buffer a model keeps from level to level. What a level returns depends on
neither the block size nor the buffers: bit for bit the same (``tests/test_lidar_fog_blocks.py``;
``docs/lidar-fog.md#speed``).
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field

import numpy as np

from fogsim.lidar.fogged_scan import FoggedScan, append_empty_rays
from fogsim.lidar.laser_line import LaserLines
from fogsim.lidar.outcomes import ATTENUATED, CLUTTER, KEPT, LOST, NO_RETURN
from fogsim.lidar.points import PointCloud
from fogsim.lidar.soft_target import FogEcho, echo_per_point, fog_echo

__all__ = ["BLOCK", "MIN_REPORTED_M", "Model", "blocks"]

#: the smallest range a noisy return is placed at (metres)
MIN_REPORTED_M = 0.01
#: input points per block of a level's pass (the module docstring)
BLOCK = 8192


def blocks(n: int):
    """Slices of :data:`BLOCK` rows covering 0 … n − 1."""
    return (slice(start, min(start + BLOCK, n)) for start in range(0, n, BLOCK))


@dataclass(eq=False)
class Level:
    """One level in progress (:meth:`Model.__call__`): β, its draws (z, σ·ln g_h, σ·ln g_f per input point),
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


class Model:
    """``soft-target`` or ``attenuation`` (the spec's ``model``) on a :class:`~fogsim.lidar.fog.LidarFogger`'s scan
    (``owner``: its scan, sensor, spec, scale, ranges, ln q, no-return rows and empty rays); ``model(β, rng)`` one
    level (β > 0: a number, or one per point). It keeps its draw buffers from level to level: one call at a time."""

    def __init__(self, owner):
        self.owner = weakref.proxy(owner)  # (no reference cycle: a fogger's arrays go when the fogger goes)
        self._draws = self._scratch = None  # a level's draws, 3 × N float32, and a block's xyz (at the first level)
        self._lines = None  # the points' laser lines, made when a fog echo first needs them

    def __call__(self, beta, rng: np.random.Generator) -> FoggedScan:
        level = self._level(beta, rng)
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):  # ln 0 (step 4), e^(4β₉₀₅R) (step 6)
            for rows in blocks(len(self.owner.scan)):
                self._block(level, rows)
        return self._finish(level)

    def _level(self, beta, rng: np.random.Generator) -> Level:
        """One level's draws (in :mod:`fogsim.lidar.fog`'s order), fog echo, empty-ray clutter and output arrays."""
        o = self.owner
        s, n, sg = o.sensor, len(o.scan), o.sensor.fluctuation_sigma
        if self._draws is None:  # the draw and block buffers, reused level after level (one call at a time)
            self._draws, self._scratch = np.empty((3, n), np.float32), np.empty((min(n, BLOCK), 3))
        z, sh, su = self._draws
        rng.standard_normal(dtype=np.float32, out=z)  # range noise,
        rng.standard_normal(dtype=np.float32, out=sh)  # ln g_h, the hard return's fluctuation,
        sh *= sg
        rng.standard_normal(dtype=np.float32, out=su)  # ln g_f, the fog echo's; then the empty rays'
        su *= sg
        scalar, e, echo = np.ndim(beta) == 0, None, None
        if o.spec.model == "soft-target":
            if scalar:
                e = fog_echo(s, beta, o.spec)
                if e.range_m >= s.min_range_m and e.signal > 0:
                    echo = e.signal, e.range_m, e.width_m
            else:
                echo = echo_per_point(s, beta, o.spec)
        extra = self._empty_ray_clutter(beta, rng, e)
        rows = 0 if extra is None or extra[1] is None else len(extra[0])
        return Level(beta, scalar, z, sh, su, -2.0 * o.spec.extinction_ratio * beta, e, echo, extra,
                     np.empty((n + rows, 3), np.float32), np.empty(n + rows, np.float32),
                     np.empty(n + rows, np.float32), np.empty(n, np.int8), np.empty(n, bool), self._scratch)

    def _block(self, level: Level, rows: slice) -> None:
        """Steps 0–8 (:mod:`fogsim.lidar.fog`) for the input ``rows``: their outcomes, and the rows they report written
        at the level's next output rows (a fog echo's position and intensity are left to :meth:`_finish`)."""
        o = self.owner
        s, sg, lv = o.sensor, o.sensor.fluctuation_sigma, level
        r, sh, su = o.range_m[rows], lv.sh[rows], lv.su[rows]
        log_clear = np.abs(sh, dtype=np.float64)  # ln q0 = max(ln q + ln g_h, σ + |ln g_h|) (step 2)
        log_clear += sg
        np.maximum(log_clear, o.log_signal[rows] + sh, out=log_clear)
        nb = r * (lv.coef if lv.scalar else lv.coef[rows])  # ln of the two-way transmission
        log_qh = log_clear + nb
        hard = log_qh >= 0.0
        blank = None if o.blank_mask is None else o.blank_mask[rows]
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
                    q[blank] = np.where(o.blank_open[rows][blank], np.add(su[blank], math.log(qf), dtype=np.float64),
                                        -np.inf)
                if o.mode == "strongest":
                    reported_hard = hard & (log_qh >= q)
                clutter = (q >= 0.0) & ~reported_hard
            else:
                qf, rf = qf[rows], rf[rows]
                w = np.clip((r - rf) / half_pulse, 0.0, 1.0) * (rf >= s.min_range_m)
                if blank is not None:
                    w[blank] = o.blank_open[rows][blank]
                q = qf * np.exp(su) * w  # q_c
                if o.mode == "strongest":
                    reported_hard = hard & (np.exp(log_qh) >= q)
                clutter = (q >= 1.0) & ~reported_hard
        # the reported rows, in input order, and what fog did to each
        reported = reported_hard if clutter is None else reported_hard | clutter
        gone = None
        if o.keeps_firings:  # one row per firing: a lost return becomes a no-return placeholder row
            gone = ~(reported | blank)
            reported = np.ones(len(r), bool)
        elif blank is not None:
            reported = reported | blank  # a no-return row stays a row: clutter or as it was
        lv.reported[rows] = reported
        every = bool(reported.all())  # every row reported (the common case): views, no gathers
        pick = slice(None) if every else np.flatnonzero(reported)
        rh, ri, zi = reported_hard[pick], r[pick], lv.z[rows][pick]
        nbi = nb[pick]
        norm, raw = o.scale.from_linear(o.linear_of(rows)[pick] * np.exp(nbi))
        kept = rh & (np.subtract(o.scan.intensity[rows][pick], norm, dtype=np.float64) < o.spec.kept_tolerance)
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
        xyz[...] = o.scan.xyz[rows][pick]
        for k in range(3):  # column by column, in float64 (numpy broadcasts over a last axis of 3 slowly)
            xyz[:, k] *= factor
        if gone is not None:
            xyz[gone] = 0.0
        lv.xyz[at:lv.written] = xyz
        moved = (oc != KEPT) & (oc != NO_RETURN)
        for out, clear, fogged in ((lv.intensity, o.scan.intensity, norm), (lv.raw, o.scan.raw_intensity, raw)):
            out = out[at:lv.written]
            out[:] = clear[rows][pick]
            np.copyto(out, fogged, where=moved)
        if clutter is not None:  # the fog echo's rows: their output rows, input rows and q_c
            c = np.flatnonzero(clutter[pick])  # (= oc == CLUTTER)
            if len(c):
                i = c if every else pick[c]
                lv.clutter.append((at + c, rows.start + i, np.exp(q[i]) if lv.scalar else q[i]))

    def _finish(self, level: Level) -> FoggedScan:
        """The level's fog-echo rows (their range, intensity and place), then the empty rays' clutter points
        (``index`` :data:`EMPTY_RAY_INDEX`), and the :class:`FoggedScan`."""
        o = self.owner
        s, scan, lv, n = o.sensor, o.scan, level, len(o.scan)
        if lv.clutter:
            at, ic, qc = (np.concatenate(a) for a in zip(*lv.clutter))
            qf, rf, wf = lv.echo
            if not lv.scalar:
                qf, rf, wf = qf[ic], rf[ic], wf[ic]
            ri = o.range_m[ic]
            on_ray = np.zeros(len(ic), bool) if o.blank is None else o.blank_mask[ic]
            new_r = self._echo_range(rf, wf, qc, lv.z[ic], np.where(on_ray, np.inf, ri))
            lv.intensity[at], lv.raw[at] = self._echo_intensity(qf, rf)  # (one value for one β)
            if o.blank is not None:  # a no-return row's clutter point: on its ray, not along its (void) position
                where = np.searchsorted(o.blank.rows, ic[on_ray])
                lv.xyz[at[on_ray]] = o.blank.directions[where] * new_r[on_ray, None]
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
            index, ring, ret = append_empty_rays(index, ring, ret, o.empty.ring, rows)
        if every:
            out_index = np.arange(n, dtype=np.int64)
        else:
            out_index = np.full(n, -1, np.int64)  # (a lost firing's placeholder row: its row)
            out_index[lv.reported] = np.arange(m)
        blank = 0 if o.blank is None else len(o.blank)
        return FoggedScan(PointCloud(xyz, inten, raw, scan.scale, index, scan.source, ring, ret), lv.outcome, out_index,
                          o.parameters(lv.beta, lv.e), 0 if o.empty is None else len(o.empty), int(len(rows)),
                          0, blank, blank - int((lv.outcome == NO_RETURN).sum()))

    def _laser_lines(self) -> LaserLines:
        """The scan's laser lines (a sensor with vertical offsets: a fog echo lies on its laser's own line)."""
        o = self.owner
        if self._lines is None:
            self._lines = LaserLines(o.scan, o.sensor, o.range_m)
        return self._lines

    def _echo_range(self, rf, wf, qc, z, limit):
        """Where a detected fog echo is reported: r_f + σ_c·z, σ_c² = σ₀² + (σ₁·(w_f/(L/2))/q_c)², kept
        within [min range, ``limit``] (the ray's target, or +inf)."""
        s = self.owner.sensor
        spread = s.range_noise_at_threshold_m * (wf / (0.5 * s.pulse_length_m)) / qc
        sigma_c = np.sqrt(s.range_noise_m ** 2 + spread ** 2)
        return np.maximum(np.clip(rf + sigma_c * z, s.min_range_m, limit), MIN_REPORTED_M)

    def _echo_intensity(self, qf, rf):
        """The intensity the sensor reports for the fog echo (its calibrated value: the echo's apparent
        reflectivity q_f·ρ_ref·(r_f/R_max)²/ξ(r_f), without the fluctuation) in the scan's scale: (normalised,
        raw), shaped as ``qf`` and ``rf`` broadcast."""
        o = self.owner
        s = o.sensor
        rho_app = qf * s.reference_reflectivity * (rf / s.max_range_m) ** 2 / s.overlap(rf)
        return o.scale.from_linear(s.intensity_of(rho_app, rf))

    def _empty_ray_clutter(self, beta, rng, echo):
        """The clutter points of the owner's empty rays at ``beta`` (a per-point β: its mean), or
        None: draws σ·u (fluctuation) then z (range noise), one each per empty ray, after the points'."""
        o = self.owner
        if o.empty is None:
            return None
        k = len(o.empty)
        su = o.sensor.fluctuation_sigma * rng.standard_normal(k, np.float32)
        z = rng.standard_normal(k, np.float32)
        s = o.sensor
        if o.spec.model != "soft-target":
            return np.zeros(0, np.int64), None
        b = float(beta) if np.ndim(beta) == 0 else float(np.mean(beta))
        e = echo if echo is not None and np.ndim(beta) == 0 else fog_echo(s, b, o.spec)
        if not (e.range_m >= s.min_range_m and e.signal > 0):
            return np.zeros(0, np.int64), None
        w = np.clip((o.empty.range_m - e.range_m) / (0.5 * s.pulse_length_m), 0.0, 1.0)  # +inf: 1
        with np.errstate(divide="ignore"):
            log_qc = math.log(e.signal) + su + np.log(w)
        rows = np.flatnonzero(log_qc >= 0.0)
        qc = np.exp(log_qc[rows])
        rr = self._echo_range(e.range_m, e.width_m, qc, z[rows], o.empty.range_m[rows])
        norm, raw = (np.broadcast_to(a, rows.shape) for a in self._echo_intensity(e.signal, e.range_m))
        xyz = o.empty.directions[rows] * rr[:, None]
        if o.empty.origins is not None:  # each ray from its laser
            xyz += o.empty.origins[rows]
        return rows, (xyz, norm, raw)
