"""Camera geometry: intrinsics, planar depth → ray distance, stereo disparity ↔ depth.

Conventions (OpenCV): K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]; integer pixel coordinates
are pixel centres, so a centred principal point is cx = (W − 1)/2. ``depth`` is planar Z
along the optical axis in metres (what Cycles' Depth pass and stereo give); the fog model
needs the *ray distance* ℓ = Z·sqrt(1 + ((u−cx)/fx)² + ((v−cy)/fy)²). This module is the
one place where that conversion, and disparity decoding, happen. It holds geometry only:
dataset files are read in :mod:`fogsim.readers` (Cityscapes' camera JSON and disparity PNG in
:mod:`fogsim.readers.cityscapes`, the paper's 8-bit depth in :mod:`fogsim.readers.paper`).

Depth maps use two special values: 0 = hole (unknown, to be filled) and +inf = no hit (sky).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from functools import lru_cache

import numpy as np

from fogsim.errors import InputError


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels for an image of ``width``×``height``."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def __post_init__(self):
        if not all(math.isfinite(v) for v in (self.fx, self.fy, self.cx, self.cy)):
            raise ValueError(f"intrinsics need finite fx, fy, cx, cy, got fx={self.fx}, fy={self.fy}, "
                             f"cx={self.cx}, cy={self.cy}")
        if not (self.fx > 0 and self.fy > 0 and self.width > 0 and self.height > 0):
            raise ValueError(f"intrinsics need fx, fy, width, height > 0, got fx={self.fx}, fy={self.fy}, "
                             f"{self.width}×{self.height}")

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1]], dtype=np.float64)

    @classmethod
    def from_K(cls, K, width: int, height: int) -> "Intrinsics":
        K = np.asarray(K, dtype=np.float64)
        return cls(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]), int(width), int(height))

    @classmethod
    def from_hfov(cls, hfov_deg: float, width: int, height: int) -> "Intrinsics":
        """Square pixels, centred principal point, horizontal field of view in degrees."""
        fx = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        return cls(fx, fx, (width - 1) / 2.0, (height - 1) / 2.0, width, height)

    def scaled(self, width: int, height: int) -> "Intrinsics":
        """The same camera resampled to another resolution (pixel-centre convention kept)."""
        sx, sy = width / self.width, height / self.height
        return Intrinsics(self.fx * sx, self.fy * sy, (self.cx + 0.5) * sx - 0.5,
                          (self.cy + 0.5) * sy - 0.5, width, height)

    def to_dict(self) -> dict:
        return asdict(self) | {"K": self.K.tolist()}

    @classmethod
    def from_dict(cls, d: dict, source: str = "intrinsics") -> "Intrinsics":
        """Intrinsics from ``{fx, fy, cx, cy, width, height}`` or ``{K, width, height}``; any
        problem (missing, not a number, non-finite, fx ≤ 0 …) is an InputError naming ``source``."""
        try:
            if "K" in d and "fx" not in d:
                K = np.asarray(d["K"], dtype=np.float64)
                values = (K[0, 0], K[1, 1], K[0, 2], K[1, 2])
            else:
                values = (d["fx"], d["fy"], d["cx"], d["cy"])
            values = tuple(float(v) for v in values)
            width, height = int(d["width"]), int(d["height"])
        except (KeyError, TypeError, ValueError, IndexError, OverflowError) as exc:
            raise InputError(source, f"malformed intrinsics ({exc}); need fx, fy, cx, cy, "
                                     "width, height or K, width, height") from None
        try:
            return cls(*values, width, height)
        except ValueError as exc:
            raise InputError(source, f"unusable intrinsics: {exc}") from None


#: depths at or beyond this are "no hit" (Cycles writes 1e10 where a ray hits nothing) → +inf
NO_HIT_DEPTH = 1e9


@lru_cache(maxsize=16)
def _ray_factor(fx: float, fy: float, cx: float, cy: float, width: int, height: int) -> np.ndarray:
    x = ((np.arange(width, dtype=np.float64) - cx) / fx) ** 2
    y = ((np.arange(height, dtype=np.float64) - cy) / fy) ** 2
    factor = np.sqrt(1.0 + y[:, None] + x[None, :]).astype(np.float32)
    factor.flags.writeable = False
    return factor


def clear_ray_cache() -> None:
    """Forget the cached ray-factor maps (benchmarks measure the uncached cost with it)."""
    _ray_factor.cache_clear()


def ray_factor(K: Intrinsics) -> np.ndarray:
    """H×W float32 map ℓ/Z = sqrt(1 + ((u−cx)/fx)² + ((v−cy)/fy)²), cached per camera."""
    return _ray_factor(K.fx, K.fy, K.cx, K.cy, K.width, K.height)


def planar_to_ray(depth: np.ndarray, K: Intrinsics) -> np.ndarray:
    """Planar depth Z (metres) → ray distance ℓ (metres). 0 stays 0, inf stays inf."""
    if depth.shape != (K.height, K.width):
        raise ValueError(f"depth is {depth.shape[1]}×{depth.shape[0]} but the camera is "
                         f"{K.width}×{K.height}")
    return np.multiply(depth, ray_factor(K), dtype=np.float32)


# ----------------------------------------------------------------------------- stereo
def decode_disparity_png(raw: np.ndarray) -> np.ndarray:
    """Cityscapes 16-bit encoding → disparity in pixels: d = (p − 1)/256, p = 0 → 0 (invalid)."""
    d = (raw.astype(np.float32) - 1.0) / 256.0
    d[raw == 0] = 0.0
    return d


def encode_disparity_png(disparity: np.ndarray) -> np.ndarray:
    """Disparity in pixels → Cityscapes uint16 p = round(256·d + 1); d ≤ 0 or non-finite → 0."""
    d = np.asarray(disparity, dtype=np.float64)
    valid = np.isfinite(d) & (d > 0)
    p = np.zeros(d.shape, dtype=np.uint16)
    p[valid] = np.clip(np.rint(256.0 * d[valid] + 1.0), 1, 65535).astype(np.uint16)
    return p


def disparity_to_depth(disparity: np.ndarray, baseline_m: float, fx: float) -> np.ndarray:
    """Z = baseline·fx/d in metres; d ≤ 0 (invalid) → 0 (a hole)."""
    d = np.asarray(disparity, dtype=np.float32)
    z = np.zeros(d.shape, dtype=np.float32)
    valid = d > 0
    z[valid] = np.float32(baseline_m * fx) / d[valid]
    return z


def depth_to_disparity(depth: np.ndarray, baseline_m: float, fx: float) -> np.ndarray:
    """d = baseline·fx/Z in pixels; Z = inf → 0 disparity, Z ≤ 0 (hole) → 0 (invalid)."""
    z = np.asarray(depth, dtype=np.float32)
    d = np.zeros(z.shape, dtype=np.float32)
    valid = (z > 0) & np.isfinite(z)
    d[valid] = np.float32(baseline_m * fx) / z[valid]
    return d


#: Cityscapes' stereo baseline in metres (its camera JSON's ``extrinsic.baseline`` ≈ 0.209 m): the
#: right camera's offset when a rendering preset's camera gives none
CITYSCAPES_BASELINE_M = 0.209


@dataclass(frozen=True)
class StereoCamera:
    """A rectified stereo rig as Cityscapes' ``camera/*.json`` describes it (read by
    :func:`fogsim.readers.cityscapes.load_cityscapes_camera`)."""

    baseline: float  # metres
    intrinsics: Intrinsics

    def to_cityscapes_json(self) -> dict:
        K = self.intrinsics
        return {"extrinsic": {"baseline": self.baseline},
                "intrinsic": {"fx": K.fx, "fy": K.fy, "u0": K.cx, "v0": K.cy},
                "sensor": {"width": K.width, "height": K.height}}


# ----------------------------------------------------------------------------- sparse points
def pixel_index(uv: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row, column (int) of each point's pixel and the mask of points inside the
    ``width``×``height`` image. ``uv`` is in pixel-edge coordinates (0 = the left/top edge of
    the first pixel, Waymo's camera-projection convention and fogsim's box convention), so a
    point's pixel is ``floor(uv)``."""
    uv = np.asarray(uv, np.float64).reshape(-1, 2)
    col = np.floor(uv[:, 0])
    row = np.floor(uv[:, 1])
    inside = np.isfinite(col) & np.isfinite(row) & (col >= 0) & (col < width) & (row >= 0) & (row < height)
    return np.where(inside, row, 0).astype(np.int64), np.where(inside, col, 0).astype(np.int64), inside


def sparse_image(uv: np.ndarray, ray: np.ndarray, width: int, height: int) -> np.ndarray:
    """H×W float32 sparse ray distance: each point at its pixel, **min**-pooled where several
    land on one (as Waymo's ``build_camera_depth_image``); 0 = no point. Points outside the
    image or with ray ≤ 0 / non-finite are dropped."""
    ray = np.asarray(ray, np.float32).reshape(-1)
    row, col, inside = pixel_index(uv, width, height)
    if len(ray) != len(row):
        raise ValueError(f"{len(row)} pixel positions but {len(ray)} distances")
    keep = inside & np.isfinite(ray) & (ray > 0)
    flat = np.full(height * width, np.inf, np.float32)
    np.minimum.at(flat, row[keep] * width + col[keep], ray[keep])
    flat[~np.isfinite(flat)] = 0
    return flat.reshape(height, width)
