"""The point-cloud record: one LiDAR scan in its sensor's frame, every point traceable to its input row.

Conventions (every module of :mod:`fogsim.lidar` keeps them):

* ``xyz``: N×3 float32, metres, in the **sensor frame** as the source stores it: x forward, y left,
  z up for KITTI's Velodyne, STF and Waymo's lidar frame (nuScenes' lidar frame has x right, y
  forward: its sensor's mount turns it, :attr:`fogsim.lidar.sensors.LidarSensor.mount_pose`); the
  origin at the sensor's optical centre, so ``range_m`` = ‖xyz‖ is the distance the pulse travelled one way.
* ``intensity``: N float32 normalised to [0, 1] by the source's scale (:mod:`fogsim.lidar.scales`:
  ``0-1`` KITTI, ``0-255`` nuScenes / STF, ``tanh`` Waymo); ``raw_intensity``: the values as the file
  stores them (kept, so writing a scan back is bit-identical); ``scale`` names the scale.
* ``ring``: N int16 beam index as the format stores it (nuScenes 0–31, STF 0–63, Waymo the range-image
  row, 0 = the highest beam), or None where the format has none (KITTI);
  :meth:`PointCloud.estimated_rings` guesses one from a sensor's inclinations.
* ``return_index``: N int8, 1 = first/strongest … as the source numbers them, or None.
* ``index``: N int64, the row of each point in the input scan (kept through selections and fog).
* ``source``: what messages name (the file).

A record is checked when built (:meth:`PointCloud.checked`): N×3 finite coordinates, intensities the
declared scale admits, columns of one length, at least one point — else an
:class:`~fogsim.errors.InputError` naming ``source``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fogsim.errors import InputError
from fogsim.lidar.scales import scale as scale_named

__all__ = ["PointCloud", "nearest_offset_beams"]


@dataclass(frozen=True, eq=False)
class PointCloud:
    """One scan (see the module docstring for units and conventions). Build it with :meth:`checked`
    (or :meth:`from_raw`) so it is validated; the arrays are not copied."""

    xyz: np.ndarray
    intensity: np.ndarray
    raw_intensity: np.ndarray
    scale: str
    index: np.ndarray
    source: str = "points"
    ring: np.ndarray | None = None
    return_index: np.ndarray | None = None

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_raw(cls, xyz, raw_intensity, scale: str, source: str, ring=None, return_index=None,
                 index=None, allow_empty: bool = False) -> "PointCloud":
        """A checked record from coordinates and the intensities as stored (``scale`` normalises them)."""
        raw = np.asarray(raw_intensity, np.float32).reshape(-1)
        return cls.checked(xyz, scale_named(scale).normalise(raw), raw, scale, source, ring, return_index,
                           index, allow_empty)

    @classmethod
    def checked(cls, xyz, intensity, raw_intensity, scale: str, source: str, ring=None, return_index=None,
                index=None, allow_empty: bool = False) -> "PointCloud":
        """The record, validated: one :class:`InputError` naming ``source`` per problem."""
        sc = scale_named(scale)
        xyz = np.asarray(xyz)
        if xyz.ndim != 2 or xyz.shape[1] != 3:
            raise InputError(source, f"points must be N×3 coordinates, got shape {list(xyz.shape)}")
        xyz = np.ascontiguousarray(xyz, np.float32)
        n = len(xyz)
        if n == 0 and not allow_empty:
            raise InputError(source, "empty scan: no points")
        bad = ~np.isfinite(xyz).all(axis=1)
        if bad.any():
            first = int(np.flatnonzero(bad)[0])
            raise InputError(source, f"{int(bad.sum())} points have NaN or infinite coordinates "
                                     f"(the first at row {first})")
        raw = np.asarray(raw_intensity, np.float32).reshape(-1)
        inten = np.asarray(intensity, np.float32).reshape(-1)
        columns = {"intensity": inten, "raw intensity": raw}
        if ring is not None:
            ring = np.asarray(ring)
            columns["ring"] = ring
        if return_index is not None:
            return_index = np.asarray(return_index)
            columns["return index"] = return_index
        index = np.arange(n, dtype=np.int64) if index is None else np.asarray(index, np.int64)
        columns["index"] = index
        for what, col in columns.items():
            if col.shape != (n,):
                raise InputError(source, f"{what} has {col.size} values for {n} points")
        if (problem := sc.problem(raw)) is not None:
            raise InputError(source, problem)
        if ring is not None:
            if ring.dtype.kind == "f" and not np.all(ring == np.round(ring)):
                raise InputError(source, "ring (beam) numbers must be whole numbers")
            if ring.size and (ring.min() < 0 or ring.max() > 1023):
                raise InputError(source, f"ring (beam) numbers span {ring.min():g} … {ring.max():g}, "
                                         "outside [0, 1023]")
            ring = ring.astype(np.int16)
        if return_index is not None:
            return_index = return_index.astype(np.int8)
        return cls(xyz, inten, raw, sc.name, index, str(source), ring, return_index)

    # ------------------------------------------------------------------ geometry
    def __len__(self) -> int:
        return len(self.xyz)

    @property
    def range_m(self) -> np.ndarray:
        """Distance of each point from the sensor origin (N float64, metres)."""
        p = self.xyz.astype(np.float64)
        return np.sqrt(np.einsum("ij,ij->i", p, p))

    @property
    def azimuth(self) -> np.ndarray:
        """Azimuth atan2(y, x) in radians, (−π, π], 0 = straight ahead, positive to the left."""
        return np.arctan2(self.xyz[:, 1].astype(np.float64), self.xyz[:, 0].astype(np.float64))

    @property
    def elevation(self) -> np.ndarray:
        """Elevation above the sensor's horizontal plane in radians (positive up)."""
        x, y, z = (self.xyz[:, k].astype(np.float64) for k in range(3))
        return np.arctan2(z, np.hypot(x, y))

    def estimated_rings(self, inclinations_rad: np.ndarray, vertical_offsets_m=None) -> np.ndarray:
        """The beam of each point from its elevation: the index of the nearest of the sensor's
        ``inclinations_rad`` (any order; the result indexes them as given), N int16. With the beams'
        ``vertical_offsets_m`` h_k (a Velodyne's lasers sit 0.1–0.2 m off the origin), the beam whose line
        passes nearest the point: min over k of |z·cos θ_k − ρ·sin θ_k − h_k| (ρ = √(x² + y²)), the
        point's distance from beam k's line — so a near point is not taken for a beam ``asin(h_k / R)``
        above its own."""
        incl = np.asarray(inclinations_rad, np.float64).reshape(-1)
        if vertical_offsets_m is not None:
            return nearest_offset_beams(self.xyz, incl, np.asarray(vertical_offsets_m, np.float64).reshape(-1))
        order = np.argsort(incl)
        s = incl[order]
        el = self.elevation
        k = np.clip(np.searchsorted(s, el), 1, len(s) - 1) if len(s) > 1 else np.zeros(len(el), np.int64)
        if len(s) > 1:
            k = np.where(np.abs(el - s[k - 1]) <= np.abs(el - s[k]), k - 1, k)
        return order[k].astype(np.int16)

    def transformed(self, pose: np.ndarray) -> "PointCloud":
        """The scan with ``xyz`` mapped by the 4×4 rigid ``pose`` (p' = R·p + t, in float64); all
        else unchanged (its ranges are then no longer sensor ranges: fog needs the sensor frame)."""
        m = np.asarray(pose, np.float64)
        if m.shape != (4, 4) or not np.isfinite(m).all():
            raise ValueError(f"a pose must be a finite 4×4 matrix, got shape {list(m.shape)}")
        xyz = self.xyz.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
        return replace(self, xyz=xyz.astype(np.float32))

    def select(self, which) -> "PointCloud":
        """The points chosen by a boolean mask or integer indices (``index`` still names input rows)."""
        def take(a):
            return None if a is None else a[which]
        return replace(self, xyz=self.xyz[which], intensity=self.intensity[which],
                       raw_intensity=self.raw_intensity[which], index=self.index[which],
                       ring=take(self.ring), return_index=take(self.return_index))

    def same_as(self, other: "PointCloud") -> bool:
        """Bit-for-bit equality of every column (float bits, not values: −0.0 ≠ 0.0, NaN = NaN)."""
        def same(a, b):
            if a is None or b is None:
                return a is None and b is None
            return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
        return (self.scale == other.scale and same(self.xyz, other.xyz) and same(self.intensity, other.intensity)
                and same(self.raw_intensity, other.raw_intensity) and same(self.index, other.index)
                and same(self.ring, other.ring) and same(self.return_index, other.return_index))


def nearest_offset_beams(xyz: np.ndarray, incl: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """The beam of each point (rows of ``xyz``, N×3, sensor frame): argmin over k of |g_k|,
    g_k = z·cos θ_k − ρ·sin θ_k − h_k (a point's signed distance from beam k's line). With the beams sorted
    by θ and h rising together (a Velodyne's), g_k falls with k: a binary search for its sign change, then
    the nearer of the two beams around it; otherwise every beam."""
    if offsets.shape != incl.shape:
        raise ValueError(f"{len(offsets)} vertical offsets for {len(incl)} inclinations")
    x, y, z = (xyz[:, k].astype(np.float64) for k in range(3))
    rho = np.hypot(x, y)
    order = np.argsort(incl, kind="stable")
    th, h = incl[order], offsets[order]
    cos, sin = np.cos(th), np.sin(th)
    if len(th) > 1 and np.all(np.diff(h) >= 0):
        # g_k ≥ 0 ⇔ elevation − θ_k ≥ asin(h_k / R) ≈ h_k / R (to 10⁻⁴ rad beyond 2 m): search on that
        el, inv_r = np.arctan2(z, rho), 1.0 / np.maximum(np.hypot(rho, z), 1e-6)
        lo, hi = np.zeros(len(z), np.int64), np.full(len(z), len(th) - 1)
        for _ in range(int(np.ceil(np.log2(len(th))))):  # invariant: lo = 0 or g_lo ≥ 0; hi = K − 1 or g_hi < 0
            mid = (lo + hi) // 2
            up = el - th[mid] >= h[mid] * inv_r
            lo, hi = np.where(up, mid, lo), np.where(up, hi, mid)
        g_lo = np.abs(z * cos[lo] - rho * sin[lo] - h[lo])
        g_hi = np.abs(z * cos[hi] - rho * sin[hi] - h[hi])
        return order[np.where(g_hi < g_lo, hi, lo)].astype(np.int16)
    best = np.full(len(z), np.inf)
    out = np.zeros(len(z), np.int64)
    for k in range(len(th)):
        d = np.abs(z * cos[k] - rho * sin[k] - h[k])
        closer = d < best
        best[closer], out[closer] = d[closer], k
    return order[out].astype(np.int16)
