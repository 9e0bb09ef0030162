"""Points placed on their laser's own line: a sensor whose lasers sit off its axis (``vertical_offsets_m``, a
Velodyne's two blocks) fires each ray from its laser's origin, not the sensor's, so a fog echo at range r from
the laser lies on the line through that origin and the point the laser hit — not on the ray from the sensor's
origin through the point (:mod:`fogsim.lidar.fog`'s clutter points).

Laser k (inclination θ_k, offset h_k) at the azimuth of a point p (ρ = √(x² + y²), R = |p|) has its origin
o = h_k·(−sin θ_k·x/ρ, −sin θ_k·y/ρ, cos θ_k) (:meth:`LidarSensor.beam_origins`), ⊥ the line; p lies
t = √(R² − h_k²) along it. The point at r from the laser: q = o + (p − o)·r/t, i.e. x and y scaled by
f − h_k sin θ_k (1 − f)/ρ and z = z·f + h_k cos θ_k (1 − f), f = r/t.
"""
from __future__ import annotations

import numpy as np

from fogsim.lidar.points import PointCloud, nearest_offset_beams
from fogsim.lidar.sensors import LidarSensor

__all__ = ["LaserLines"]


class LaserLines:
    """The laser lines of ``scan``'s points for ``sensor`` (which has ``vertical_offsets_m``); ``range_m``: the
    points' ranges from the sensor origin (N, metres). A point's laser — its ring, else the one whose line passes
    nearest (:func:`~fogsim.lidar.points.nearest_offset_beams`) — is found once, when first needed."""

    def __init__(self, scan: PointCloud, sensor: LidarSensor, range_m: np.ndarray):
        self.scan, self.sensor, self.range_m = scan, sensor, range_m
        h, theta = np.asarray(sensor.vertical_offsets_m, np.float64), sensor.inclinations_rad
        #: per laser: h sin θ, h cos θ, h²
        self.tables = h * np.sin(theta), h * np.cos(theta), h * h
        #: per point, its laser (−1 until found)
        self.laser = np.full(len(scan), -1, np.int16)

    def lasers(self, rows: np.ndarray) -> np.ndarray:
        """The lasers of input points ``rows`` (found and kept where not yet known)."""
        s, laser = self.sensor, self.laser
        k = laser[rows]
        unknown = k < 0
        if unknown.any():
            u, ring = rows[unknown], self.scan.ring
            k[unknown] = ring[u] if ring is not None and int(ring.max()) < s.beams else \
                nearest_offset_beams(self.scan.xyz[u], s.inclinations_rad, np.asarray(s.vertical_offsets_m))
            laser[u] = k[unknown]
        return k

    def place(self, rows: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Points (len(rows)×3 float64, sensor frame) at range ``r`` from their laser along the line of input
        points ``rows`` (the module docstring)."""
        hs, hc, hh = self.tables
        k = self.lasers(rows)
        p, rr = self.scan.xyz[rows].astype(np.float64), self.range_m[rows]
        f = r / np.sqrt(np.maximum(rr * rr - hh[k], 1e-12))
        rest = 1.0 - f
        g = f - hs[k] * rest / np.maximum(np.hypot(p[:, 0], p[:, 1]), 1e-9)
        p[:, 0] *= g
        p[:, 1] *= g
        p[:, 2] *= f
        p[:, 2] += hc[k] * rest
        return p
