"""Rays that hit nothing: the cells of a spinning sensor's beam × azimuth grid that a scan leaves empty.

A spinning LiDAR fires every beam at every azimuth step (:attr:`LidarSensor.steps_per_sweep` over 360°);
a ray whose pulse returned nothing above the threshold (sky, a far dark surface) is absent from the scan.
In fog every ray meets the fog's own echo (:mod:`fogsim.lidar.fog`), so the fog model needs those rays
too: :class:`EmptyRays` (unit directions in the sensor frame, beam, azimuth, and the range of what the
ray hit beyond the threshold, +inf for nothing).

:func:`empty_rays` finds them in a scan whose sensor grid is known (the sensor's inclinations and a 360°
field of view):

* each point's beam: the file's ring (nuScenes, STF, Waymo rows) or, without one (KITTI), the nearest of
  the sensor's inclinations (:meth:`PointCloud.estimated_rings`); its azimuth step:
  ⌊(atan2(y, x) mod 2π) / Δφ⌋, Δφ = 360° / steps;
* a cell is occupied when a point falls in it **or in either azimuth neighbour** of the same beam: a
  real sensor's azimuths do not sit on the nominal grid (jitter, a slightly different firing rate), so a
  cell is called empty only inside a run of empty cells (a run of k empty cells counts k − 2; whole
  empty beams and wide sky gaps are counted exactly);
* an empty cell's direction: its beam's elevation — the median elevation of that beam's points, or
  for a beam without points the sensor's inclination of the same rank (the file's ring order, rising or
  falling, read from the beams that have points) — at the cell's centre azimuth (Δφ·(k + ½));
* a scan more than half of whose cells are empty is taken as *not* a full sweep (a cropped
  ``velodyne_reduced`` scan, a sector) and gets None: its missing rays cannot be told from a crop.

Renders know their empty rays exactly (:func:`fogsim.render.lidar_scan.sweep`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fogsim.lidar.points import PointCloud
from fogsim.lidar.sensors import LidarSensor

__all__ = ["EmptyRays", "MAX_EMPTY_SHARE", "empty_rays", "unit_directions"]

#: a scan with a larger share of empty cells is not taken as a full sweep (None: no empty rays)
MAX_EMPTY_SHARE = 0.5


@dataclass(frozen=True, eq=False)
class EmptyRays:
    """Rays without a clear-air return: ``directions`` K×3 float64 unit vectors (sensor frame), ``ring``
    K int16 (the scan's beam numbering) or None, ``range_m`` K float64 — the first surface each ray hit
    (below the threshold), +inf where it hit nothing: a fog echo beyond it cannot come back."""

    directions: np.ndarray
    ring: np.ndarray | None = None
    range_m: np.ndarray | None = None

    def __post_init__(self):
        d = np.asarray(self.directions, np.float64).reshape(-1, 3)
        if not np.isfinite(d).all():
            raise ValueError("empty rays: directions must be finite")
        object.__setattr__(self, "directions", unit_directions(d))
        k = len(d)
        r = np.full(k, np.inf) if self.range_m is None else np.asarray(self.range_m, np.float64).reshape(-1)
        if r.shape != (k,) or np.isnan(r).any() or (r <= 0).any():
            raise ValueError(f"empty rays: one range > 0 (or +inf) per ray ({k}), got {r.size}")
        object.__setattr__(self, "range_m", r)
        if self.ring is not None:
            ring = np.asarray(self.ring).reshape(-1)
            if ring.shape != (k,):
                raise ValueError(f"empty rays: one ring per ray ({k}), got {ring.size}")
            object.__setattr__(self, "ring", ring.astype(np.int16))

    def __len__(self) -> int:
        return len(self.directions)


def unit_directions(d: np.ndarray) -> np.ndarray:
    """Rows of ``d`` (K×3) scaled to length 1 (a zero row is a ValueError)."""
    d = np.asarray(d, np.float64).reshape(-1, 3)
    norm = np.linalg.norm(d, axis=1)
    if (norm <= 0).any():
        raise ValueError("empty rays: a direction of length 0")
    return d / norm[:, None]


def _beam_elevations(scan: PointCloud, beam: np.ndarray, beams: int, incl: np.ndarray, from_file: bool) -> np.ndarray:
    """Each beam's elevation (radians): measured (median of its points) where it has points; else the
    sensor's inclination of the same rank (file rings: in the order the measured beams show)."""
    if not from_file:
        return incl.copy()
    el = scan.elevation
    out = np.full(beams, np.nan)
    for b in np.unique(beam):
        out[b] = float(np.median(el[beam == b]))
    have = np.flatnonzero(np.isfinite(out))
    if len(have) < beams:
        rising = len(have) < 2 or np.corrcoef(have, out[have])[0, 1] >= 0
        ranked = np.sort(incl) if rising else np.sort(incl)[::-1]
        missing = ~np.isfinite(out)
        out[missing] = ranked[missing]
    return out


def empty_rays(scan: PointCloud, sensor: LidarSensor) -> EmptyRays | None:
    """The empty cells of ``scan``'s sweep (the module docstring), or None when the grid is not known
    (no inclinations, a field of view below 360°) or the scan is not a full sweep."""
    if sensor.inclinations_deg is None or sensor.horizontal_fov_deg < 360 or not len(scan):
        return None
    incl = sensor.inclinations_rad
    beams, steps = sensor.beams, sensor.steps_per_sweep
    from_file = scan.ring is not None and int(scan.ring.max()) < beams
    beam = scan.ring.astype(np.int64) if from_file else scan.estimated_rings(incl).astype(np.int64)
    step = 2 * math.pi / steps
    col = np.floor(np.mod(scan.azimuth, 2 * math.pi) / step).astype(np.int64) % steps
    occupied = np.zeros((beams, steps), bool)
    occupied[beam, col] = True
    near = occupied | np.roll(occupied, 1, axis=1) | np.roll(occupied, -1, axis=1)
    b, c = np.nonzero(~near)
    if len(b) > MAX_EMPTY_SHARE * beams * steps:
        return None
    el = _beam_elevations(scan, beam, beams, incl, from_file)[b]
    az = (c + 0.5) * step
    d = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1)
    return EmptyRays(d, b.astype(np.int16) if scan.ring is not None else None)
