"""Rays that hit nothing: the cells of a spinning sensor's beam × azimuth grid that a scan leaves empty, and
the rows of a scan that stand for a firing without a return.

A spinning LiDAR fires every beam at every azimuth step (:attr:`LidarSensor.steps_per_sweep` over 360°);
a ray whose pulse returned nothing above the threshold (sky, a far dark surface) is absent from the scan —
or, in formats that store every firing (nuScenes: 32 rings × ≈ 1 084 firings, every one a row), present
as a row without a position. In fog every ray meets the fog's own echo (:mod:`fogsim.lidar.fog`), so the
fog model needs those rays too.

**No-return rows** (:func:`no_returns`): a row nearer than the sensor's ``min_range_m`` is no return the
sensor can measure. Such a row stays a row (one row per firing: the fog model fogs it in place, outcome
``no-return`` or the fog echo's ``clutter``); its ray:

* a row nearer than :data:`PLACEHOLDER_M` holds no position (nuScenes writes a firing without an echo at
  ≈ 0 m): its ray is its ring's elevation (the median elevation of the ring's returns; for a ring without
  returns, the sensor's inclination of the same rank) at the azimuth interpolated, in file order, between
  the returns around it (nuScenes stores a sweep firing by firing, 32 rows per firing). Nothing lies in
  front of it: it may see the fog echo (``open``). Without a ring, or when the file's rows are not in
  firing order (consecutive returns more than :data:`ORDERED_STEP_DEG` apart in azimuth, too often), its
  ray is unknown: it stays a no-return;
* a row between :data:`PLACEHOLDER_M` and the minimum range is an echo from inside the sensor's blind zone
  (the vehicle's own body): its ray is its own direction, and that surface hides the fog echo behind it —
  it stays a no-return.

**Empty rays** (:func:`empty_rays`) are the grid cells no row covers, found in a scan whose sensor grid is
known (the sensor's inclinations and a 360° field of view):

* each return's beam: the file's ring (nuScenes, STF, Waymo rows) or, without one (KITTI), the nearest of
  the sensor's lasers (:meth:`PointCloud.estimated_rings`, with the lasers' vertical offsets where the
  sensor gives them); its azimuth step: ⌊(atan2(y, x) mod 2π) / Δφ⌋, Δφ = 360° / steps. No-return rows
  whose ray is known cover their own cells (they are fogged in place, never twice);
* a cell is occupied when a point falls in it **or in either azimuth neighbour** of the same beam: a
  real sensor's azimuths do not sit on the nominal grid (jitter, a slightly different firing rate), so a
  cell is called empty only inside a run of empty cells (a run of k empty cells counts k − 2; whole
  empty beams and wide sky gaps are counted exactly);
* an empty cell's direction: its beam's elevation — the median elevation of that beam's points, or
  for a beam without points the sensor's inclination of the same rank (the file's ring order, rising or
  falling, read from the beams that have points) — at the cell's centre azimuth (Δφ·(k + ½));
* a scan more than half of whose cells are empty is taken as *not* a full sweep (a cropped
  ``velodyne_reduced`` scan, a sector) and gets None: its missing rays cannot be told from a crop —
  unless the camera it was cropped to is known (:class:`CameraView`: KITTI's and STF's calibration and
  image size). Then the grid is the cells inside the camera's view: a cell is in view when its ray
  projects into the image from :data:`VIEW_NEAR_M` out to infinity (the image is convex and the projected
  ray a segment: both ends inside; OpenPCDet's crop rule, 0 ≤ u < width, 0 ≤ v < height, depth > 0, in
  the projection's pixel-centre coordinates), and the half-empty rule applies to those cells.

Renders know their empty rays exactly (:func:`fogsim.render.lidar_scan.sweep`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from fogsim.lidar.points import PointCloud
from fogsim.lidar.sensors import LidarSensor

__all__ = ["CameraView", "EmptyRays", "MAX_EMPTY_SHARE", "NoReturns", "ORDERED_STEP_DEG", "PLACEHOLDER_M",
           "VIEW_NEAR_M", "empty_rays", "laser_origins", "no_returns", "unit_directions"]

#: a scan with a larger share of empty cells is not taken as a full sweep (None: no empty rays)
MAX_EMPTY_SHARE = 0.5
#: a row nearer than this (metres) holds no position: a placeholder for a firing without an echo
PLACEHOLDER_M = 0.01
#: rows are in firing order when consecutive returns lie within this azimuth of each other (degrees) …
ORDERED_STEP_DEG = 5.0
#: … for at least this share of them
ORDERED_SHARE = 0.9
#: a cell is in a camera's view when its ray projects into the image from this range (metres) to infinity
VIEW_NEAR_M = 2.0


@dataclass(frozen=True, eq=False)
class EmptyRays:
    """Rays without a clear-air return: ``directions`` K×3 float64 unit vectors (sensor frame), ``ring``
    K int16 (the scan's beam numbering) or None, ``range_m`` K float64 — the first surface each ray hit
    (below the threshold), +inf where it hit nothing: a fog echo beyond it cannot come back; ``origins``
    K×3 float64 where each ray starts (its laser, :meth:`LidarSensor.beam_origins`; None: the origin)."""

    directions: np.ndarray
    ring: np.ndarray | None = None
    range_m: np.ndarray | None = None
    origins: np.ndarray | None = None

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
        if self.origins is not None:
            o = np.asarray(self.origins, np.float64).reshape(-1, 3)
            if len(o) != k or not np.isfinite(o).all():
                raise ValueError(f"empty rays: one finite origin per ray ({k}), got {len(o)}")
            object.__setattr__(self, "origins", o)

    def __len__(self) -> int:
        return len(self.directions)


@dataclass(frozen=True, eq=False)
class CameraView:
    """The camera a scan was cropped to: ``projection`` 3×4 (LiDAR frame → image, homogeneous; pixel-centre
    coordinates, as KITTI's P2·R0_rect·Tr_velo_to_cam), the image ``width`` × ``height`` in pixels."""

    projection: np.ndarray
    width: int
    height: int

    def sees(self, directions: np.ndarray) -> np.ndarray:
        """Per ray (unit directions N×3 from the sensor origin): it projects into the image from
        :data:`VIEW_NEAR_M` to infinity (the module docstring)."""
        m = np.asarray(self.projection, np.float64).reshape(3, 4)
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        far = d @ m[:, :3].T  # the vanishing point: the ray at infinity (homogeneous w = 0)
        near = far * VIEW_NEAR_M + m[:, 3]
        ok = np.ones(len(d), bool)
        for p in (far, near):
            with np.errstate(divide="ignore", invalid="ignore"):
                u, v = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
                ok &= (p[:, 2] > 0) & (u >= 0) & (u < self.width) & (v >= 0) & (v < self.height)
        return ok


def unit_directions(d: np.ndarray) -> np.ndarray:
    """Rows of ``d`` (K×3) scaled to length 1 (a zero row is a ValueError)."""
    d = np.asarray(d, np.float64).reshape(-1, 3)
    norm = np.linalg.norm(d, axis=1)
    if (norm <= 0).any():
        raise ValueError("empty rays: a direction of length 0")
    return d / norm[:, None]


@dataclass(frozen=True, eq=False)
class NoReturns:
    """A scan's no-return rows (:func:`no_returns`): ``rows`` M int64 (input rows, ascending),
    ``directions`` M×3 float64 (unit, sensor frame; zero where the ray is unknown) and ``open`` M bool (the
    ray is known and nothing lies in front of the fog echo: it may see fog)."""

    rows: np.ndarray
    directions: np.ndarray
    open: np.ndarray

    def __len__(self) -> int:
        return len(self.rows)

    @property
    def known(self) -> np.ndarray:
        """M bool: the ray's direction is known."""
        return np.abs(self.directions).sum(axis=1) > 0


def _ring_elevations(elevation: np.ndarray, ring: np.ndarray, beams: int, incl: np.ndarray | None) -> np.ndarray:
    """Elevation (radians) per ring number 0 … max(ring, beams − 1): the median of the ring's ``elevation``
    values where it has some; else the sensor's inclination of the same rank (``incl``; in the order the
    measured rings show, rising or falling), else NaN."""
    size = max(int(ring.max()) + 1 if len(ring) else 0, beams)
    out = np.full(size, np.nan)
    order = np.argsort(ring, kind="stable")
    r, e = ring[order], elevation[order]
    cuts = np.flatnonzero(np.diff(r)) + 1
    for group_ring, group in zip(r[np.r_[0, cuts]] if len(r) else [], np.split(e, cuts)):
        out[group_ring] = float(np.median(group))
    have = np.flatnonzero(np.isfinite(out))
    if incl is not None and len(have) < size:
        rising = len(have) < 2 or np.corrcoef(have, out[have])[0, 1] >= 0
        ranked = np.sort(incl) if rising else np.sort(incl)[::-1]
        missing = np.flatnonzero(~np.isfinite(out[:len(ranked)]))
        out[missing] = ranked[missing]
    return out


def _interpolated_azimuth(azimuth: np.ndarray, rows: np.ndarray, at: np.ndarray) -> np.ndarray | None:
    """The azimuth (radians) at rows ``at``, interpolated in file order between the returns at ``rows``
    (their ``azimuth``, unwrapped); None when the returns are not in firing order (module docstring)."""
    if len(rows) < 2:
        return None
    unwrapped = np.unwrap(azimuth)
    if (np.abs(np.diff(unwrapped)) <= np.radians(ORDERED_STEP_DEG)).mean() < ORDERED_SHARE:
        return None
    return np.interp(at, rows, unwrapped)


def no_returns(scan: PointCloud, sensor: LidarSensor) -> NoReturns | None:
    """The rows of ``scan`` nearer than ``sensor.min_range_m`` and their rays (the module docstring), or None
    when it has none."""
    r = scan.range_m
    blank = r < sensor.min_range_m
    if not blank.any():
        return None
    rows = np.flatnonzero(blank)
    rr = r[rows]
    placeholder = rr < PLACEHOLDER_M
    directions = np.zeros((len(rows), 3))
    own = ~placeholder
    directions[own] = scan.xyz[rows[own]].astype(np.float64) / rr[own, None]
    is_open = np.zeros(len(rows), bool)
    if placeholder.any() and scan.ring is not None:
        valid = np.flatnonzero(~blank)
        az = _interpolated_azimuth(scan.azimuth[valid], valid, rows[placeholder])
        if az is not None:
            incl = sensor.inclinations_rad if sensor.inclinations_deg is not None else None
            ring = scan.ring.astype(np.int64)
            el = _ring_elevations(scan.elevation[valid], ring[valid], sensor.beams, incl)[ring[rows[placeholder]]]
            known = np.isfinite(el)
            el, az = el[known], az[known]
            which = np.flatnonzero(placeholder)[known]
            directions[which] = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1)
            is_open[which] = True
    return NoReturns(rows, directions, is_open)


def empty_rays(scan: PointCloud, sensor: LidarSensor, view: CameraView | None = None) -> EmptyRays | None:
    """The empty cells of ``scan``'s sweep (the module docstring), or None when the grid is not known
    (no inclinations, a field of view below 360°) or the scan is not a full sweep — nor, given the camera
    ``view`` it was cropped to, a full sweep of the cells in that view."""
    if sensor.inclinations_deg is None or sensor.horizontal_fov_deg < 360 or not len(scan):
        return None
    incl = sensor.inclinations_rad
    beams, steps = sensor.beams, sensor.steps_per_sweep
    blank = no_returns(scan, sensor)
    is_return = np.ones(len(scan), bool)
    cover = is_return.copy()  # the rows whose ray covers its cell: returns, and no-return rows of known ray
    xyz = scan.xyz
    if blank is not None:
        is_return[blank.rows] = False
        cover[blank.rows] = blank.known
        xyz = xyz.copy()
        xyz[blank.rows[blank.known]] = blank.directions[blank.known]
    fired = replace(scan, xyz=xyz).select(cover)
    if not len(fired):
        return None
    returns = is_return[cover]
    from_file = scan.ring is not None and int(scan.ring.max()) < beams
    beam = fired.ring.astype(np.int64) if from_file else \
        fired.estimated_rings(incl, sensor.vertical_offsets_m).astype(np.int64)
    step = 2 * math.pi / steps
    col = np.floor(np.mod(fired.azimuth, 2 * math.pi) / step).astype(np.int64) % steps
    occupied = np.zeros((beams, steps), bool)
    occupied[beam, col] = True
    empty = ~(occupied | np.roll(occupied, 1, axis=1) | np.roll(occupied, -1, axis=1))
    elevation = _ring_elevations(fired.elevation[returns], beam[returns], beams, incl)[:beams] if from_file else incl
    if empty.sum() > MAX_EMPTY_SHARE * beams * steps:
        if view is None:
            return None
        el, az = np.meshgrid(elevation, (np.arange(steps) + 0.5) * step, indexing="ij")
        seen = view.sees(_directions(el.reshape(-1), az.reshape(-1))).reshape(beams, steps)
        empty &= seen
        if not seen.any() or empty.sum() > MAX_EMPTY_SHARE * seen.sum():
            return None
    b, c = np.nonzero(empty)
    az = (c + 0.5) * step
    d = _directions(elevation[b], az)
    origins = sensor.beam_origins(b, az) if sensor.vertical_offsets_m is not None and not from_file else None
    return EmptyRays(d, b.astype(np.int16) if scan.ring is not None else None, origins=origins)


def laser_origins(scan: PointCloud, sensor: LidarSensor, beams_only: bool = False) -> np.ndarray | None:
    """Where the ray of each point of ``scan`` started (N×3, sensor frame): its laser's origin
    (:meth:`LidarSensor.beam_origins`; the laser: the file's ring, else :meth:`PointCloud.estimated_rings`),
    or None for a sensor whose beams all pass through the origin (no ``vertical_offsets_m``). ``beams_only``:
    the lasers (N int64) instead."""
    if sensor.vertical_offsets_m is None or sensor.inclinations_deg is None:
        return None
    if scan.ring is not None and len(scan) and int(scan.ring.max()) < sensor.beams:
        beam = scan.ring.astype(np.int64)
    else:
        beam = scan.estimated_rings(sensor.inclinations_rad, sensor.vertical_offsets_m).astype(np.int64)
    return beam if beams_only else sensor.beam_origins(beam, towards=scan.xyz)


def _directions(elevation: np.ndarray, azimuth: np.ndarray) -> np.ndarray:
    """Unit directions (N×3) of rays at ``elevation`` and ``azimuth`` (radians)."""
    return np.stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)], 1)
