"""One fog level of a scan as the fog models hand it back (:class:`FoggedScan`), and its assembly: the fogged
cloud from each input row's outcome, new range and intensity (:func:`assemble`), shared by the default models
(:mod:`fogsim.lidar.fog`) and the published ones (:mod:`fogsim.lidar.hahner2021`, :mod:`fogsim.lidar.stf2020`).

Row order of the fogged cloud: the reported input rows in input order (``index`` still names the input row; ring
and return index carried over), then the empty rays' clutter points, then the points a model adds (both
``index`` :data:`~fogsim.lidar.outcomes.EMPTY_RAY_INDEX`). Coordinates and intensities are float32; kept and
no-return rows are written bit for bit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fogsim.lidar.outcomes import EMPTY_RAY_INDEX, KEPT, NO_RETURN, OUTCOMES
from fogsim.lidar.points import PointCloud

__all__ = ["FoggedScan", "assemble", "clear_level"]


@dataclass(frozen=True, eq=False)
class FoggedScan:
    """One fog level of a scan: ``cloud`` (what the sensor reports: the reported input points in input
    order, then the empty rays' clutter points, ``index`` :data:`EMPTY_RAY_INDEX`), per input point
    ``outcome`` (int8, :data:`OUTCOMES`) and ``output_index`` (int64, its row in ``cloud``, −1 when lost),
    the ``parameters`` that made it, ``empty_rays`` (how many were given), ``empty_ray_clutter`` (how
    many of them became clutter points), ``added_points`` (the points the model added after those:
    stf2020's random scatter), ``no_returns`` (the input's no-return rows) and ``no_return_clutter`` (how
    many of those became the fog echo's clutter, in place) (:meth:`record`)."""

    cloud: PointCloud
    outcome: np.ndarray
    output_index: np.ndarray
    parameters: dict = field(default_factory=dict)
    empty_rays: int = 0
    empty_ray_clutter: int = 0
    added_points: int = 0
    no_returns: int = 0
    no_return_clutter: int = 0

    def counts(self) -> dict[str, int]:
        """Points per outcome."""
        got = np.bincount(self.outcome, minlength=len(OUTCOMES))
        return {name: int(got[k]) for k, name in enumerate(OUTCOMES)}

    def record(self) -> dict:
        """The parameters and the counts per outcome (what a sidecar or a report stores)."""
        return {**self.parameters, "points_in": int(len(self.outcome)), "points_out": int(len(self.cloud)),
                "outcomes": self.counts(), "empty_rays": int(self.empty_rays),
                "empty_ray_clutter": int(self.empty_ray_clutter), "added_points": int(self.added_points),
                "no_returns": int(self.no_returns), "no_return_clutter": int(self.no_return_clutter)}


def append_empty_rays(index: np.ndarray, ring: np.ndarray | None, ret: np.ndarray | None,
                      empty_ring: np.ndarray | None, rows: np.ndarray):
    """``index``, ``ring`` and ``return_index`` columns with the empty rays ``rows``' clutter points appended:
    index −1 (no input row), the empty ray's ring (0 where the rays carry none), first return."""
    index = np.concatenate([index, np.full(len(rows), EMPTY_RAY_INDEX, np.int64)])
    if ring is not None:
        ring = np.concatenate([ring, np.zeros(len(rows), np.int16) if empty_ring is None else empty_ring[rows]])
    if ret is not None:
        ret = np.concatenate([ret, np.ones(len(rows), ret.dtype)])
    return index, ring, ret


def assemble(fogger, idx, pick, oc, new_r, norm_out, raw_out, outcome, parameters: dict, extra=None,
             placed=None, added=None) -> FoggedScan:
    """The fogged level of ``fogger``'s scan (a :class:`~fogsim.lidar.fog.LidarFogger`: its ``scan``,
    ``range_m``, ``empty`` rays and ``blank`` no-return rows) from the reported rows ``idx`` (``pick``: ``idx``,
    or ``slice(None)`` when every row is reported) and their outcomes ``oc``, new ranges ``new_r`` and
    intensities (``norm_out``, ``raw_out``): kept and no-return rows bit for bit (their factor R'/R is exactly
    1), the others moved along their ray and given their new intensity (``placed``: [(positions among them,
    xyz)] of rows placed otherwise: a no-return row's clutter on its ray, a lost firing's placeholder at 0);
    then the empty rays' clutter points (``extra``: their rows and (xyz, normalised, raw)), index −1; then the
    points the model adds (``added``: (xyz, normalised, raw, the input rows whose ring and return index they
    carry)), index −1. ``outcome``: every input row's. ``new_r`` is overwritten."""
    scan = fogger.scan
    every = isinstance(pick, slice)  # every row reported: no gathers
    base = scan.xyz if every else np.take(scan.xyz, idx, axis=0)
    factor = np.divide(new_r, fogger.range_m[pick], out=new_r)  # (new_r is the caller's scratch)
    xyz = np.empty(base.shape, np.float32)
    for k in range(3):  # column by column (numpy broadcasts over a last axis of 3 slowly), in float64
        np.multiply(base[:, k], factor, out=xyz[:, k])
    for where, at in placed or ():
        xyz[where] = at
    moved = (oc != KEPT) & (oc != NO_RETURN)
    inten, raw = (scan.intensity.copy(), scan.raw_intensity.copy()) if every else \
        (scan.intensity[idx], scan.raw_intensity[idx])
    np.copyto(inten, norm_out, where=moved)
    np.copyto(raw, raw_out, where=moved)

    def take(a):
        return None if a is None else a.copy() if every else a[idx]
    ring, ret, index = take(scan.ring), take(scan.return_index), take(scan.index)
    rows = np.zeros(0, np.int64) if extra is None else extra[0]
    if len(rows):
        exyz, enorm, eraw = extra[1]
        xyz = np.concatenate([xyz, exyz])
        inten, raw = np.concatenate([inten, enorm]), np.concatenate([raw, eraw])
        index, ring, ret = append_empty_rays(index, ring, ret, fogger.empty.ring, rows)
    n_added = 0 if added is None else len(added[0])
    if n_added:
        axyz, anorm, araw, src = added
        xyz = np.concatenate([xyz, axyz])
        inten, raw = np.concatenate([inten, anorm]), np.concatenate([raw, araw])
        index = np.concatenate([index, np.full(n_added, EMPTY_RAY_INDEX, np.int64)])
        ring = None if ring is None else np.concatenate([ring, scan.ring[src]])
        ret = None if ret is None else np.concatenate([ret, scan.return_index[src]])
    f32 = {"dtype": np.float32, "copy": False}
    cloud = PointCloud(xyz.astype(**f32), inten.astype(**f32), raw.astype(**f32), scan.scale, index, scan.source,
                       ring, ret)
    if every:
        out_index = np.arange(len(outcome), dtype=np.int64)
    else:
        out_index = np.full(len(outcome), -1, np.int64)  # (a lost firing's placeholder row: its row)
        out_index[idx] = np.arange(len(idx))
    blank = 0 if fogger.blank is None else len(fogger.blank)
    return FoggedScan(cloud, outcome, out_index, parameters, 0 if fogger.empty is None else len(fogger.empty),
                      int(len(rows)), n_added, blank, blank - int((outcome == NO_RETURN).sum()))


def clear_level(fogger, parameters: dict) -> FoggedScan:
    """β = 0: ``fogger``'s scan as it was (a copy, bit for bit), every point ``kept`` (its no-return rows
    ``no-return``)."""
    s = fogger.scan
    copy = PointCloud(s.xyz.copy(), s.intensity.copy(), s.raw_intensity.copy(), s.scale, s.index.copy(), s.source,
                      None if s.ring is None else s.ring.copy(),
                      None if s.return_index is None else s.return_index.copy())
    n = len(s)
    outcome = np.full(n, KEPT, np.int8)
    if fogger.blank is not None:
        outcome[fogger.blank.rows] = NO_RETURN
    return FoggedScan(copy, outcome, np.arange(n, dtype=np.int64), parameters,
                      0 if fogger.empty is None else len(fogger.empty), 0, 0,
                      0 if fogger.blank is None else len(fogger.blank))
