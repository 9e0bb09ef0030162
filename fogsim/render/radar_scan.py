"""A synthetic radar sweep of a rendered frame: rays cast against the triangles the renderer drew (the
LiDAR's :class:`~fogsim.render.lidar_scan.Geometry` and Embree :class:`~fogsim.render.lidar_scan.RayCaster`),
clustered into the detections an automotive FMCW radar reports (pure Python, numpy).

Conventions: the sensor frame is x forward, y left, z up (metres); azimuth φ from x towards y, elevation
from the horizontal plane (up positive); radial velocity v_r = (v_target − v_radar)·u, u the unit vector
from the sensor to the detection, **positive receding** (m/s). RCS in dBsm, SNR in dB.

The sweep, step by step (:func:`radar_sweep`):

1. **Rays** on a fine grid over the sensor's field of view (:func:`ray_grid`: azimuth steps of
   :data:`RAY_STEP_DEG` or a tenth of the azimuth resolution, whichever is finer; elevation steps of
   :data:`ELEVATION_STEP_DEG` over the elevation field of view, default ±:data:`DEFAULT_HALF_ELEVATION_DEG`:
   a pedestrian 100 m away still meets four rows).
   A hit belongs to the **near scan** when the sensor has one and the hit is within its range and azimuth,
   else to the far scan (within its field); the scan gives the resolutions and accuracies.
2. **Clusters**: an object's hits are grouped by resolution cell of their scan (range cell ⌊R/ΔR⌋, azimuth
   cell ⌊φ/Δφ⌋), each cell holding a power (3.). As a radar's peak search over its range–azimuth map, a
   cell is a detection when no neighbouring cell (3×3) of the same object outdoes it; it lies at the mean of
   its hits (a point on or inside the object's tight box) and carries the power of its neighbourhood — one
   detection far away, a few near.
3. **RCS** (:mod:`fogsim.render.radar_rcs`): a point target's σ(aspect) is shared among its cells by their
   share of its hits (the powers sum to the object's σ); an area target (building, tree, an unlabelled
   surface of a user's scene) has σ = σ⁰ · the cell's area (hits × the rays' footprint R²·δφ·δθ).
4. **SNR** from the sensor's radar equation (:meth:`fogsim.radar.sensors.RadarSensor.snr_db`); a detection
   is reported in clear air when SNR ≥ the detection threshold.
5. **Noise**: range and azimuth errors drawn from a normal with σ = accuracy / 2, clipped at ± the accuracy
   (the data sheet's ± read as a 2σ bound); elevation likewise when the sensor measures it (else the true
   elevation of the cell's mean hit is kept: the labels stay 3D although the sensor reports none).
6. **Velocity**: the object's world velocity (:func:`fogsim.scene.motion.frame_motion`) and the radar's
   (the ego's) projected on u, quantised to the sensor's velocity resolution (the error is at most half a
   resolution step); the ego-compensated value adds the ego's part back.
7. **Multipath ghosts** (kind 1): each vehicle's strongest detection mirrored through the road plane
   (world z → −z: the path radar → road → vehicle → radar is as long as the line to the mirror image),
   :data:`GHOST_LOSS_DB` weaker (one bounce off asphalt); reported when its SNR reaches the threshold.
8. **Ground clutter** (kind 2): the ground's resolution cells (road, sidewalk, … hits) with σ = σ⁰·ΔR·R·Δφ
   (:data:`~fogsim.render.radar_rcs.GROUND_SIGMA0_DB`); each cell whose SNR reaches the threshold is reported
   with probability :data:`CLUTTER_CELL_PROBABILITY` (stated, not sourced: a CFAR detector raises its
   threshold over road clutter, which a ray caster does not model; the rate keeps a few clutter detections
   per sweep, as real sweeps show).
9. **False alarms** (kind 3): Poisson(``false_alarms_per_scan``) detections uniform over the far scan's
   range and azimuth, SNR = the threshold plus an exponential excess of noise power (T + Exp(1), linear),
   their RCS from the radar equation, radial velocity uniform over the sensor's velocity range.

One instant per sweep (no motion during the cycle). Labels: ``object_id`` the mask id of the object a
kind-0 detection lies on (−1 for ghosts, clutter and false alarms; a ghost's mirrored object in
``source_id``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fogsim.radar.detections import FALSE_ALARM, GHOST, KINDS, OBJECT
from fogsim.radar.detections import GROUND_CLUTTER as CLUTTER
from fogsim.render.lidar_scan import RayCaster
from fogsim.render.radar_rcs import AREA_SIGMA0_DB, GROUND_CLASSES, GROUND_SIGMA0_DB, aspect_rad, object_rcs_dbsm
from fogsim.scene.lights import VEHICLE_CLASSES
from fogsim.schema.radar import DEFAULT_HALF_ELEVATION_DEG, ELEVATION_STEP_DEG, RAY_STEP_DEG, ray_grid_shape

#: multipath ghost: one bounce off the road, dB below the detection it mirrors (stated: asphalt's
#: reflectivity at 77 GHz and grazing incidence, |Γ|² ≈ −3 … −10 dB)
GHOST_LOSS_DB = 6.0
#: the chance a ground resolution cell above the threshold is reported (stated; the module docstring)
CLUTTER_CELL_PROBABILITY = 0.005
#: which scan of the sensor a detection comes from
FAR, NEAR = 0, 1

__all__ = ["CLUTTER_CELL_PROBABILITY", "ELEVATION_STEP_DEG", "GHOST_LOSS_DB", "RAY_STEP_DEG", "Motion",
           "SyntheticRadar", "radar_sweep", "ray_grid"]


@dataclass(frozen=True)
class Motion:
    """World velocities (m/s, z up) at the frame's instant: the radar's (the ego vehicle's) and the moving
    objects' by mask id (an object not listed stands still)."""

    radar: np.ndarray
    objects: dict

    @classmethod
    def of(cls, record: dict | None) -> "Motion":
        """From :func:`fogsim.scene.motion.frame_motion`'s record (None: nothing moves)."""
        if not record:
            return cls(np.zeros(3), {})
        return cls(np.asarray(record["camera_velocity_mps"], np.float64),
                   {int(k): np.asarray(v, np.float64) for k, v in record["object_velocity_mps"].items()})


@dataclass(frozen=True)
class SyntheticRadar:
    """One sweep's reported detections (sensor frame; the module docstring's conventions): ``xyz`` N×3
    (measured), ``xyz_true`` N×3 (the scattering centre before the measurement noise; a false alarm's: its
    measured one),
    ``range_m``, ``azimuth_rad``, ``elevation_rad``, ``radial_velocity`` and ``radial_velocity_comp`` (m/s,
    + receding; raw and ego-compensated), ``rcs_dbsm``, ``snr_db``, ``object_id`` (−1: none), ``kind``
    (:data:`fogsim.radar.detections.KINDS`), ``source_id`` (a ghost's mirrored object, else −1), ``scan`` (:data:`FAR` /
    :data:`NEAR`); ``rays`` cast, ``hits`` within range, ``candidates`` (cells before the threshold)."""

    xyz: np.ndarray
    xyz_true: np.ndarray
    range_m: np.ndarray
    azimuth_rad: np.ndarray
    elevation_rad: np.ndarray
    radial_velocity: np.ndarray
    radial_velocity_comp: np.ndarray
    rcs_dbsm: np.ndarray
    snr_db: np.ndarray
    object_id: np.ndarray
    kind: np.ndarray
    source_id: np.ndarray
    scan: np.ndarray
    rays: int
    hits: int
    candidates: int

    def __len__(self) -> int:
        return len(self.range_m)

    def counts(self) -> dict:
        return {name: int((self.kind == k).sum()) for k, name in KINDS.items() if k >= 0}

    def record(self) -> dict:
        return {"rays": self.rays, "hits_in_range": self.hits, "cells": self.candidates, "detections": len(self),
                "kinds": self.counts()}


def _fov(sensor) -> tuple[tuple[float, float], tuple[float, float]]:
    """(azimuth [lo, hi], elevation [lo, hi]) in degrees covering the far and near scans."""
    az = [float(v) for v in sensor.azimuth_fov_deg]
    near = sensor.near_range
    if near is not None:
        az = [min(az[0], float(near["azimuth_fov_deg"][0])), max(az[1], float(near["azimuth_fov_deg"][1]))]
    el = sensor.elevation_fov_deg
    el = [float(v) for v in el] if el is not None else [-DEFAULT_HALF_ELEVATION_DEG, DEFAULT_HALF_ELEVATION_DEG]
    return (az[0], az[1]), (el[0], el[1])


def ray_grid(sensor) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """(unit directions N×3 in the sensor frame, azimuth N rad, elevation N rad, azimuth step rad,
    elevation step rad) of the fine grid over the sensor's field of view (cell centres)."""
    (a0, a1), (e0, e1) = _fov(sensor)
    resolutions = [float(sensor.azimuth_resolution_deg)]
    if sensor.near_range is not None:
        resolutions.append(float(sensor.near_range["azimuth_resolution_deg"]))
    na, ne = ray_grid_shape((a0, a1), (e0, e1), resolutions)  # bounded where the sensor is read (the schema)
    az = np.radians(a0 + (np.arange(na) + 0.5) * (a1 - a0) / na)
    el = np.radians(e0 + (np.arange(ne) + 0.5) * (e1 - e0) / ne)
    a, e = np.meshgrid(az, el, indexing="ij")
    d = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], -1).reshape(-1, 3)
    return d, a.reshape(-1), e.reshape(-1), math.radians((a1 - a0) / na), math.radians((e1 - e0) / ne)


def _scan_params(sensor) -> list[dict]:
    """Per scan (index FAR, NEAR): range limits, azimuth limits (rad), resolutions and accuracies."""
    def block(s: dict):
        return {"min_r": float(sensor.min_range_m), "max_r": float(s["max_range_m"]),
                "az": np.radians([float(v) for v in s["azimuth_fov_deg"]]), "dr": float(s["range_resolution_m"]),
                "da": math.radians(float(s["azimuth_resolution_deg"])), "acc_r": float(s["range_accuracy_m"]),
                "acc_a": math.radians(float(s["azimuth_accuracy_deg"]))}
    keys = ("max_range_m", "azimuth_fov_deg", "range_resolution_m", "azimuth_resolution_deg", "range_accuracy_m",
            "azimuth_accuracy_deg")
    out = [block({k: getattr(sensor, k) for k in keys})]
    if sensor.near_range is not None:
        out.append(block(sensor.near_range))
    return out


def _clipped_normal(rng: np.random.Generator, accuracy, n: int) -> np.ndarray:
    """Errors ~ N(0, (accuracy/2)²) clipped at ± accuracy (accuracy: a number or n of them)."""
    acc = np.broadcast_to(np.asarray(accuracy, np.float64), (n,))
    return np.clip(rng.normal(0.0, 1.0, n) * acc / 2, -acc, acc)


def _quantised(v: np.ndarray, step: float) -> np.ndarray:
    return np.round(v / step) * step


def _cells(oid, scan, rcell, acell) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct (object, scan, range cell, azimuth cell) rows (M×4, sorted), each hit's row and the hits
    per row — np.unique over one int64 key (cells are < 2¹⁶ on either axis: ranges < 2¹⁶ resolution steps,
    azimuth steps ≥ 0.01°, as :class:`fogsim.schema.radar.RadarSensorSpec` holds every sensor to)."""
    key = ((np.asarray(oid, np.int64) * 2 + scan) << 32) | (np.asarray(rcell, np.int64) << 16) | acell
    uniq, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    rows = np.stack([(uniq >> 32) // 2, (uniq >> 32) % 2, (uniq >> 16) & 0xFFFF, uniq & 0xFFFF], 1)
    return rows, inverse.reshape(-1), counts


def _peaks(cells: np.ndarray, power: np.ndarray) -> list[tuple[int, float]]:
    """The peaks of each object's range–azimuth map: (row of ``cells`` — (object, scan, range cell, azimuth
    cell) — and the power summed over its 3×3 neighbourhood) for every cell no neighbour of the same object
    and scan outdoes (ties: the first row wins)."""
    at = {tuple(int(v) for v in c): j for j, c in enumerate(cells)}
    out = []
    for j, (i, k, r, a) in enumerate(cells):
        total, peak = 0.0, True
        for dr in (-1, 0, 1):
            for da in (-1, 0, 1):
                n = at.get((int(i), int(k), int(r) + dr, int(a) + da))
                if n is None:
                    continue
                total += power[n]
                if n != j and (power[n] > power[j] or (power[n] == power[j] and n < j)):
                    peak = False
        if peak:
            out.append((j, total))
    return out


def radar_sweep(caster: RayCaster, radar_to_world: np.ndarray, sensor, classes: dict, headings: dict,
                motion: Motion, rng: np.random.Generator) -> SyntheticRadar:
    """The clear-air sweep of ``sensor`` (:class:`fogsim.radar.sensors.RadarSensor`) at ``radar_to_world``
    (4×4) over the caster's geometry (the module docstring). ``classes``: mask id → class; ``headings``:
    mask id → the object's heading (world, horizontal; for its aspect); ``motion``: the world velocities;
    ``rng``: every random draw of the sweep (noise, clutter, false alarms), in a fixed order."""
    T = np.asarray(radar_to_world, np.float64)
    R, origin = T[:3, :3], T[:3, 3]
    d, az, el, dphi, dtheta = ray_grid(sensor)
    dirs = d @ R.T
    t, prim, _ = caster.cast(np.broadcast_to(origin, dirs.shape), dirs)
    scans = _scan_params(sensor)
    scan = np.full(len(d), -1, np.int8)
    for k in range(len(scans) - 1, -1, -1):  # the near scan wins where both see
        s = scans[k]
        inside = np.isfinite(t) & (t >= s["min_r"]) & (t <= s["max_r"]) & (az >= s["az"][0]) & (az <= s["az"][1])
        scan[(scan < 0) & inside] = k
    hit = np.flatnonzero(scan >= 0)
    r, oid, sc = t[hit], caster.geometry.face_id[prim[hit]].astype(np.int64), scan[hit].astype(np.int64)
    p_world = origin + dirs[hit] * r[:, None]
    normal_up = np.abs(caster.normals(prim[hit])[:, 2]) > 0.9
    ground_ids = [i for i, c in classes.items() if c in GROUND_CLASSES]
    ground = np.isin(oid, ground_ids) | ((oid == 0) & normal_up)
    dr, da = (np.array([s[key] for s in scans])[sc] for key in ("dr", "da"))
    rcell = np.floor(r / dr).astype(np.int64)
    acell = np.floor((az[hit] + math.pi) / da).astype(np.int64)
    footprint = r ** 2 * dphi * dtheta  # each ray's share of the surface facing it (m²)

    rows: list[tuple] = []  # (world point, object id, kind, source id, scan, rcs dBsm)
    # objects: one detection per (object, scan, range cell, azimuth cell)
    target = ~ground
    if target.any():
        uniq, inverse, counts = _cells(oid[target], sc[target], rcell[target], acell[target])
        sums = np.zeros((len(uniq), 3))
        np.add.at(sums, inverse, p_world[target])
        area = np.bincount(inverse, footprint[target], len(uniq))
        per_object = {int(i): int(n) for i, n in zip(*np.unique(oid[target], return_counts=True))}
        power = np.zeros(len(uniq))
        for j, (i, _, _, _) in enumerate(uniq):
            i = int(i)
            c = classes.get(i, "")
            if i == 0 or c in AREA_SIGMA0_DB:
                power[j] = 10 ** (AREA_SIGMA0_DB.get(c, AREA_SIGMA0_DB["building"]) / 10) * area[j]
            else:
                heading = headings.get(i)
                aspect = aspect_rad(heading, sums[j] / counts[j] - origin) if heading is not None else 0.0
                power[j] = 10 ** (object_rcs_dbsm(c, aspect) / 10) * counts[j] / per_object[i]
        for j, total in _peaks(uniq, power):
            i, k = int(uniq[j, 0]), int(uniq[j, 1])
            rows.append((sums[j] / counts[j], i if i != 0 else -1, OBJECT if i != 0 else CLUTTER, -1, k,
                         10 * math.log10(max(total, 1e-12))))
    # ground clutter: one candidate per (scan, range cell, azimuth cell) of ground hits
    if ground.any():
        uniq, inverse, counts = _cells(np.zeros(int(ground.sum()), np.int64), sc[ground], rcell[ground], acell[ground])
        sums = np.zeros((len(uniq), 3))
        np.add.at(sums, inverse, p_world[ground])
        for j, (_, k, _, _) in enumerate(uniq):
            centre = sums[j] / counts[j]
            rng_m = float(np.linalg.norm(centre - origin))
            cell = scans[int(k)]["dr"] * rng_m * scans[int(k)]["da"]
            rows.append((centre, -1, CLUTTER, -1, int(k), GROUND_SIGMA0_DB + 10 * math.log10(max(cell, 1e-6))))
    candidates = len(rows)

    pts = np.array([row[0] for row in rows], np.float64).reshape(-1, 3)
    ids = np.array([row[1] for row in rows], np.int64)
    kind = np.array([row[2] for row in rows], np.int64)
    source = np.array([row[3] for row in rows], np.int64)
    which = np.array([row[4] for row in rows], np.int64)
    rcs = np.array([row[5] for row in rows], np.float64)
    rng_true = np.linalg.norm(pts - origin, axis=1)
    snr = np.asarray(sensor.snr_db(rcs, rng_true), np.float64) if len(rows) else np.zeros(0)
    seen = snr >= sensor.detection_threshold_db
    clutter_draw = rng.random(len(rows)) < CLUTTER_CELL_PROBABILITY
    seen &= (kind != CLUTTER) | (ids >= 0) | clutter_draw  # ground / background cells: the stated rate
    pts, ids, kind, source, which, rcs, snr = (a[seen] for a in (pts, ids, kind, source, which, rcs, snr))

    # multipath ghosts: each vehicle's strongest detection mirrored through the road plane
    ghosts = []
    for i in np.unique(ids[kind == OBJECT]):
        if classes.get(int(i)) not in VEHICLE_CLASSES:
            continue
        j = np.flatnonzero((ids == i) & (kind == OBJECT))
        j = j[np.argmax(snr[j])]
        mirror = pts[j] * np.array([1.0, 1.0, -1.0])
        g_rcs = rcs[j] - GHOST_LOSS_DB
        g_snr = float(np.asarray(sensor.snr_db(np.array([g_rcs]), np.array([np.linalg.norm(mirror - origin)])))[0])
        local = (mirror - origin) @ R
        g_az = math.atan2(local[1], local[0])
        s = scans[int(which[j])]
        if g_snr >= sensor.detection_threshold_db and s["az"][0] <= g_az <= s["az"][1]:
            ghosts.append((mirror, int(i), int(which[j]), g_rcs, g_snr))
    if ghosts:
        pts = np.vstack([pts, np.array([g[0] for g in ghosts])])
        ids = np.concatenate([ids, np.full(len(ghosts), -1)])
        kind = np.concatenate([kind, np.full(len(ghosts), GHOST)])
        source = np.concatenate([source, [g[1] for g in ghosts]])
        which = np.concatenate([which, [g[2] for g in ghosts]])
        rcs = np.concatenate([rcs, [g[3] for g in ghosts]])
        snr = np.concatenate([snr, [g[4] for g in ghosts]])

    # true geometry in the sensor frame, then the velocities (from the true point) and the noise
    local = (pts - origin) @ R
    true_r = np.linalg.norm(local, axis=1)
    u_world = (pts - origin) / np.maximum(true_r, 1e-9)[:, None]
    v_obj = np.array([motion.objects.get(int(i if k != GHOST else s), np.zeros(3))
                      for i, k, s in zip(ids, kind, source)], np.float64).reshape(-1, 3)
    if len(u_world):
        v_obj[kind == GHOST] *= np.array([1.0, 1.0, -1.0])  # the mirror image moves mirrored
    vres = float(sensor.velocity_resolution_mps)
    v_ego = np.einsum("ij,j->i", u_world, motion.radar)
    vr = _quantised(np.einsum("ij,ij->i", u_world, v_obj) - v_ego, vres)
    a_true = np.arctan2(local[:, 1], local[:, 0])
    e_true = np.arcsin(np.clip(local[:, 2] / np.maximum(true_r, 1e-9), -1, 1))
    acc_r, acc_a = (np.array([s[key] for s in scans])[which] for key in ("acc_r", "acc_a"))
    meas_r = np.maximum(true_r + _clipped_normal(rng, acc_r, len(true_r)), float(sensor.min_range_m))
    meas_a = a_true + _clipped_normal(rng, acc_a, len(a_true))
    meas_e = e_true
    if sensor.measures_elevation and sensor.elevation_accuracy_deg:
        meas_e = e_true + _clipped_normal(rng, math.radians(sensor.elevation_accuracy_deg), len(e_true))

    # false alarms: uniform over the far scan, SNR just over the threshold
    far = scans[FAR]
    n_fa = int(rng.poisson(float(sensor.false_alarms_per_scan)))
    if n_fa:
        fa_r = rng.uniform(far["min_r"], far["max_r"], n_fa)
        fa_a = rng.uniform(far["az"][0], far["az"][1], n_fa)
        (e0, e1) = _fov(sensor)[1]
        fa_e = np.radians(rng.uniform(e0, e1, n_fa)) if sensor.measures_elevation \
            else np.zeros(n_fa)
        fa_snr = 10 * np.log10(10 ** (sensor.detection_threshold_db / 10) + rng.exponential(1.0, n_fa))
        fa_rcs = fa_snr - np.asarray(sensor.snr_db(np.zeros(n_fa), fa_r), np.float64)  # SNR is linear in σ
        lo, hi = (float(v) for v in sensor.velocity_range_mps)
        fa_v = _quantised(rng.uniform(lo, hi, n_fa), vres)
        fa_dir = np.stack([np.cos(fa_e) * np.cos(fa_a), np.cos(fa_e) * np.sin(fa_a), np.sin(fa_e)], 1) @ R.T
        meas_r, meas_a, meas_e = (np.concatenate(p) for p in ((meas_r, fa_r), (meas_a, fa_a), (meas_e, fa_e)))
        local = np.vstack([local, fa_dir @ R * fa_r[:, None]])
        vr = np.concatenate([vr, fa_v])
        v_ego = np.concatenate([v_ego, fa_dir @ motion.radar])
        rcs, snr = np.concatenate([rcs, fa_rcs]), np.concatenate([snr, fa_snr])
        ids, source = np.concatenate([ids, np.full(n_fa, -1)]), np.concatenate([source, np.full(n_fa, -1)])
        kind, which = np.concatenate([kind, np.full(n_fa, FALSE_ALARM)]), np.concatenate([which, np.zeros(n_fa, int)])

    xyz = np.stack([meas_r * np.cos(meas_e) * np.cos(meas_a), meas_r * np.cos(meas_e) * np.sin(meas_a),
                    meas_r * np.sin(meas_e)], 1) if len(meas_r) else np.zeros((0, 3))
    return SyntheticRadar(xyz.astype(np.float32), local.reshape(-1, 3).astype(np.float32), meas_r.astype(np.float32),
                          meas_a.astype(np.float32),
                          meas_e.astype(np.float32), vr.astype(np.float32),
                          _quantised(vr + v_ego, vres).astype(np.float32), rcs.astype(np.float32),
                          snr.astype(np.float32), ids.astype(np.int32), kind.astype(np.int8),
                          source.astype(np.int32), which.astype(np.int8), rays=len(d), hits=len(hit),
                          candidates=candidates)
