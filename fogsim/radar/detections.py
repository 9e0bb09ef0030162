"""The radar detection record: one sweep's detections in the sensor frame, every detection traceable to its
input row.

Conventions (every module of :mod:`fogsim.radar` keeps them):

* ``xyz``: N×3 float32, metres, sensor frame: x forward, y left, z up (nuScenes' ``RADAR_*`` files store
  it so); the origin at the antenna, so ``range_m`` = ‖xyz‖ is the one-way path. A sensor without
  elevation reports z as the file stores it (the ARS 408: 0).
* ``velocity``: N×2 float32 (vx, vy), m/s: the measured radial velocity as a vector along the
  detection's ray (the sensor sees only the radial part), **not** ego-compensated; ``velocity_comp`` the
  same with the ego motion removed (nuScenes' ``vx_comp``, ``vy_comp``).
* ``rcs_dbsm``: N float32, the radar cross section in dBsm (10·log10(σ / 1 m²)).
* ``snr_db``: N float32, the clear-air signal over noise in dB; NaN where unknown (a real nuScenes file:
  the fog model then takes it from the RCS and range through the sensor's radar equation).
* ``object_id``: N int32, the object instance (−1 none); ``kind``: N int8, :data:`KINDS` (0 object,
  1 ghost from multipath, 2 ground clutter, 3 false alarm; −1 unknown, real data).
* ``index``: N int64, the row in the input sweep (kept through selections and fog).
* ``extra``: N structured, the fields fogsim does not model (nuScenes' ``dyn_prop``, ``id``, the state
  and rms codes …), carried through so a sweep is written back with them; None when there are none.
* ``source``: what messages name (the file).

Radar sweeps may be empty (a sweep without a detection is a real sweep).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fogsim.errors import InputError

__all__ = ["FALSE_ALARM", "GHOST", "GROUND_CLUTTER", "KINDS", "OBJECT", "RadarScan", "UNKNOWN"]

#: what produced a detection (the ``kind`` column); −1 = unknown (real data)
KINDS = {0: "object", 1: "ghost", 2: "ground clutter", 3: "false alarm", -1: "unknown"}
OBJECT, GHOST, GROUND_CLUTTER, FALSE_ALARM, UNKNOWN = 0, 1, 2, 3, -1


@dataclass(frozen=True, eq=False)
class RadarScan:
    """One radar sweep's detections in the sensor frame (x forward, y left, z up; metres, m/s; see the
    module docstring). Build it with :meth:`checked` so it is validated; the arrays are not copied."""

    xyz: np.ndarray
    velocity: np.ndarray
    velocity_comp: np.ndarray
    rcs_dbsm: np.ndarray
    snr_db: np.ndarray
    object_id: np.ndarray
    kind: np.ndarray
    index: np.ndarray
    source: str = "radar"
    extra: np.ndarray | None = None

    # ------------------------------------------------------------------ construction
    @classmethod
    def checked(cls, xyz, rcs_dbsm, velocity=None, velocity_comp=None, snr_db=None, object_id=None, kind=None,
                index=None, source: str = "radar", extra=None) -> "RadarScan":
        """The record, validated: one :class:`InputError` naming ``source`` per problem. Defaults:
        ``velocity`` zeros, ``velocity_comp`` = ``velocity``, ``snr_db`` NaN (unknown), ``object_id`` −1,
        ``kind`` −1 (unknown), ``index`` 0 … N−1."""
        xyz = np.asarray(xyz)
        if xyz.ndim != 2 or xyz.shape[1] != 3:
            raise InputError(source, f"detections must be N×3 coordinates, got shape {list(xyz.shape)}")
        xyz = np.ascontiguousarray(xyz, np.float32)
        n = len(xyz)

        def column(a, default, dtype, what, width=None):
            a = np.full((n,) if width is None else (n, width), default, dtype) if a is None else np.asarray(a)
            want = (n,) if width is None else (n, width)
            if a.shape != want:
                raise InputError(source, f"{what} has shape {list(a.shape)} for {n} detections (want {list(want)})")
            return np.ascontiguousarray(a).astype(dtype, copy=False)

        velocity = column(velocity, 0.0, np.float32, "velocity (vx, vy)", 2)
        velocity_comp = velocity.copy() if velocity_comp is None else column(velocity_comp, 0.0, np.float32,
                                                                            "velocity_comp (vx_comp, vy_comp)", 2)
        rcs = column(rcs_dbsm, np.nan, np.float32, "rcs_dbsm")
        snr = column(snr_db, np.nan, np.float32, "snr_db")
        for what, a in (("coordinates", xyz), ("velocities", velocity), ("ego-compensated velocities", velocity_comp),
                        ("RCS values", rcs)):
            bad = ~np.isfinite(a).all(axis=tuple(range(1, a.ndim)))
            if bad.any():
                raise InputError(source, f"{int(bad.sum())} detections have NaN or infinite {what} "
                                         f"(the first at row {int(np.flatnonzero(bad)[0])})")
        if np.isinf(snr).any():
            raise InputError(source, "snr_db holds infinite values (NaN = unknown is allowed)")
        obj = column(object_id, -1, np.int64, "object_id")
        if n and (obj.min() < -1 or obj.max() > np.iinfo(np.int32).max):
            raise InputError(source, "object ids must be −1 (none) or 0 … 2³¹−1")
        kd = column(kind, -1, np.int64, "kind")
        if n and not np.isin(kd, list(KINDS)).all():
            raise InputError(source, f"kind must be one of {sorted(KINDS)} ({', '.join(KINDS.values())})")
        idx = np.arange(n, dtype=np.int64) if index is None else column(index, 0, np.int64, "index")
        if extra is not None:
            extra = np.asarray(extra)
            if not extra.dtype.names or extra.shape != (n,):
                raise InputError(source, f"extra fields must be a structured array of {n} rows")
        return cls(xyz, velocity, velocity_comp, rcs, snr, obj.astype(np.int32), kd.astype(np.int8), idx,
                   str(source), extra)

    @classmethod
    def empty(cls, source: str = "radar", extra_dtype: np.dtype | None = None) -> "RadarScan":
        """A sweep without detections."""
        return cls.checked(np.zeros((0, 3), np.float32), np.zeros(0, np.float32), source=source,
                           extra=None if extra_dtype is None else np.zeros(0, extra_dtype))

    # ------------------------------------------------------------------ geometry
    def __len__(self) -> int:
        return len(self.xyz)

    @property
    def range_m(self) -> np.ndarray:
        """Distance of each detection from the antenna (N float64, metres)."""
        x = self.xyz.astype(np.float64)
        return np.sqrt(np.einsum("ij,ij->i", x, x))

    @property
    def azimuth_rad(self) -> np.ndarray:
        """atan2(y, x) in radians, (−π, π], 0 = straight ahead, positive to the left."""
        return np.arctan2(self.xyz[:, 1].astype(np.float64), self.xyz[:, 0].astype(np.float64))

    @property
    def elevation_rad(self) -> np.ndarray:
        """Elevation above the sensor's horizontal plane in radians (positive up)."""
        x, y, z = (self.xyz[:, k].astype(np.float64) for k in range(3))
        return np.arctan2(z, np.hypot(x, y))

    def _radial(self, v: np.ndarray) -> np.ndarray:
        az = self.azimuth_rad
        return v[:, 0].astype(np.float64) * np.cos(az) + v[:, 1].astype(np.float64) * np.sin(az)

    @property
    def radial_velocity(self) -> np.ndarray:
        """The signed radial velocity (m/s, + = receding): ``velocity`` projected on the ray's azimuth."""
        return self._radial(self.velocity)

    @property
    def radial_velocity_comp(self) -> np.ndarray:
        """The same, ego-motion compensated (m/s, + = receding)."""
        return self._radial(self.velocity_comp)

    # ------------------------------------------------------------------ selections
    def select(self, which) -> "RadarScan":
        """The detections chosen by a boolean mask or integer indices (``index`` still names input rows)."""
        return replace(self, xyz=self.xyz[which], velocity=self.velocity[which],
                       velocity_comp=self.velocity_comp[which], rcs_dbsm=self.rcs_dbsm[which],
                       snr_db=self.snr_db[which], object_id=self.object_id[which], kind=self.kind[which],
                       index=self.index[which], extra=None if self.extra is None else self.extra[which])

    def copy(self) -> "RadarScan":
        """A deep copy (every column its own array)."""
        return replace(self, **{k: getattr(self, k).copy() for k in _COLUMNS},
                       extra=None if self.extra is None else self.extra.copy())

    def same_as(self, other: "RadarScan") -> bool:
        """Bit-for-bit equality of every column (float bits, not values: −0.0 ≠ 0.0, NaN = NaN)."""
        def same(a, b):
            if a is None or b is None:
                return a is None and b is None
            return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
        return all(same(getattr(self, k), getattr(other, k)) for k in (*_COLUMNS, "extra"))


_COLUMNS = ("xyz", "velocity", "velocity_comp", "rcs_dbsm", "snr_db", "object_id", "kind", "index")
