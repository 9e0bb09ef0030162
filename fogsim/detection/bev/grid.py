"""The bird's-eye-view grid and the rasters drawn on it.

Frame: the LiDAR's (x forward, y left, z up; metres). The grid covers x ∈ [x0, x1) × y ∈ [y0, y1) in
square cells of ``cell`` metres. Image coordinates (pixel edges, as fogsim's boxes): u = (y1 − y)/cell
(columns: the left, +y, on the image's left), v = (x1 − x)/cell (rows: the far edge at the top), so the
picture is the scene seen from above with the car driving up the page; the cell of a point is
(row, col) = (⌊v⌋, ⌊u⌋).

Channels, each 8-bit (0 = nothing there):

* LiDAR (:func:`lidar_raster`, Complex-YOLO's three, Simon et al. 2018): ``height`` — the highest point
  of the cell, 1–255 linear over ``z_range`` (points outside it are dropped); ``intensity`` — the largest
  normalised intensity (0–1 → 0–255); ``density`` — min(1, ln(n + 1)/ln 64) of the cell's n points.
* radar (:func:`radar_raster`): ``rcs`` — 1–255 linear over :data:`RCS_RANGE_DBSM`; ``radial_velocity``
  — the ego-compensated radial velocity, 1–255 linear over :data:`VELOCITY_RANGE_MS` (128 ≈ standing
  still). A detection is drawn as a disc of :data:`RADAR_RADIUS_M` (radar positions are metres off and
  few), the strongest last, so where discs overlap the strongest detection's values win.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

LIDAR_CHANNELS = ("height", "intensity", "density")
RADAR_CHANNELS = ("rcs", "radial_velocity")
DENSITY_SATURATION = 64  # points per cell at which the density channel saturates (Complex-YOLO's ln 64)
RCS_RANGE_DBSM = (-20.0, 40.0)
VELOCITY_RANGE_MS = (-20.0, 20.0)
RADAR_RADIUS_M = 1.0


def _scale(values: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """1–255 linear over [lo, hi] (clipped): 0 stays free for "nothing here"."""
    return np.round(1 + 254 * np.clip((np.asarray(values, np.float64) - lo) / (hi - lo), 0, 1)).astype(np.uint8)


@dataclass(frozen=True)
class BevGrid:
    """The grid (the module docstring): extents in metres of the LiDAR frame, ``cell`` metres per pixel."""

    x_range: tuple[float, float] = (0.0, 50.0)
    y_range: tuple[float, float] = (-25.0, 25.0)
    z_range: tuple[float, float] = (-2.73, 1.27)  # Complex-YOLO's, for a LiDAR 1.73 m above the road
    cell: float = 0.15625

    def __post_init__(self):
        for name in ("x_range", "y_range", "z_range"):
            lo, hi = getattr(self, name)
            if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
                raise ValueError(f"BEV grid: {name} must be two finite numbers, low < high, got {lo:g}, {hi:g}")
        if not (math.isfinite(self.cell) and self.cell > 0):
            raise ValueError(f"BEV grid: the cell must be > 0 m, got {self.cell:g}")
        if self.width * self.height > 8192 * 8192:
            raise ValueError(f"BEV grid: {self.width} × {self.height} cells is too many (cell {self.cell:g} m)")

    @classmethod
    def for_image(cls, size_px: int, x_range=(0.0, 50.0), y_range=(-25.0, 25.0), **kw) -> "BevGrid":
        """The grid whose longer side is ``size_px`` cells (the detector's input size: no resampling)."""
        extent = max(x_range[1] - x_range[0], y_range[1] - y_range[0])
        return cls(tuple(map(float, x_range)), tuple(map(float, y_range)), cell=extent / size_px, **kw)

    @property
    def width(self) -> int:
        return int(round((self.y_range[1] - self.y_range[0]) / self.cell))

    @property
    def height(self) -> int:
        return int(round((self.x_range[1] - self.x_range[0]) / self.cell))

    def to_pixels(self, xy: np.ndarray) -> np.ndarray:
        """LiDAR-frame (x, y) (N×2, metres) → image (u, v) (N×2, pixel edges)."""
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        return np.stack([(self.y_range[1] - xy[:, 1]) / self.cell, (self.x_range[1] - xy[:, 0]) / self.cell], 1)

    def to_metres(self, uv: np.ndarray) -> np.ndarray:
        """Image (u, v) → LiDAR-frame (x, y): the inverse of :meth:`to_pixels`."""
        uv = np.asarray(uv, np.float64).reshape(-1, 2)
        return np.stack([self.x_range[1] - uv[:, 1] * self.cell, self.y_range[1] - uv[:, 0] * self.cell], 1)

    def inside(self, xy: np.ndarray) -> np.ndarray:
        """Which (x, y) lie in the grid (half-open extents)."""
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        return ((xy[:, 0] >= self.x_range[0]) & (xy[:, 0] < self.x_range[1])
                & (xy[:, 1] >= self.y_range[0]) & (xy[:, 1] < self.y_range[1]))

    def cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) of points inside the grid (callers select them with :meth:`inside` first)."""
        uv = self.to_pixels(xy)
        col = np.clip(np.floor(uv[:, 0]).astype(np.int64), 0, self.width - 1)
        row = np.clip(np.floor(uv[:, 1]).astype(np.int64), 0, self.height - 1)
        return row, col

    @classmethod
    def from_dict(cls, d: dict) -> "BevGrid":
        """The grid of :meth:`to_dict`'s record."""
        return cls(tuple(d["x_range_m"]), tuple(d["y_range_m"]), tuple(d["z_range_m"]), float(d["cell_m"]))

    def to_dict(self) -> dict:
        return {"x_range_m": list(self.x_range), "y_range_m": list(self.y_range), "z_range_m": list(self.z_range),
                "cell_m": self.cell, "width_px": self.width, "height_px": self.height}

    def describe(self) -> str:
        return (f"x {self.x_range[0]:g}–{self.x_range[1]:g} m × y {self.y_range[0]:g}–{self.y_range[1]:g} m, "
                f"{self.cell:.4g} m cells ({self.width} × {self.height} px), heights {self.z_range[0]:g}–"
                f"{self.z_range[1]:g} m")


def _cell_max(flat: np.ndarray, values: np.ndarray, size: int) -> np.ndarray:
    """The largest value per cell (cells without a point: 0)."""
    out = np.zeros(size, values.dtype)
    order = np.argsort(values, kind="stable")
    out[flat[order]] = values[order]  # ascending: each cell's last write is its maximum
    return out


def lidar_raster(grid: BevGrid, xyz: np.ndarray, intensity: np.ndarray) -> np.ndarray:
    """H × W × 3 uint8: height, intensity, density (the module docstring) of the points ``xyz`` (N×3,
    LiDAR frame) with normalised intensities ``intensity`` (N, 0–1)."""
    xyz = np.asarray(xyz, np.float64).reshape(-1, 3)
    intensity = np.asarray(intensity, np.float64).reshape(-1)
    keep = grid.inside(xyz[:, :2]) & (xyz[:, 2] >= grid.z_range[0]) & (xyz[:, 2] < grid.z_range[1])
    xyz, intensity = xyz[keep], intensity[keep]
    size = grid.width * grid.height
    out = np.zeros((grid.height, grid.width, 3), np.uint8)
    if not len(xyz):
        return out
    row, col = grid.cells(xyz[:, :2])
    flat = row * grid.width + col
    height = _cell_max(flat, _scale(xyz[:, 2], *grid.z_range), size)
    inten = _cell_max(flat, np.round(255 * np.clip(intensity, 0, 1)).astype(np.uint8), size)
    n = np.bincount(flat, minlength=size)
    density = np.round(255 * np.minimum(1.0, np.log1p(n) / math.log(DENSITY_SATURATION))).astype(np.uint8)
    out[..., 0], out[..., 1], out[..., 2] = (c.reshape(grid.height, grid.width) for c in (height, inten, density))
    return out


def radar_raster(grid: BevGrid, xyz: np.ndarray, rcs_dbsm: np.ndarray, radial_velocity: np.ndarray,
                 radius_m: float = RADAR_RADIUS_M) -> np.ndarray:
    """H × W × 2 uint8: RCS and radial velocity (the module docstring) of radar detections ``xyz`` (N×3,
    LiDAR frame), drawn as discs of ``radius_m``."""
    out = np.zeros((grid.height, grid.width, 2), np.uint8)
    xy = np.asarray(xyz, np.float64).reshape(-1, 3)[:, :2]
    if not len(xy):
        return out
    rcs, vel = _scale(rcs_dbsm, *RCS_RANGE_DBSM), _scale(radial_velocity, *VELOCITY_RANGE_MS)
    uv = grid.to_pixels(xy)
    radius = max(0.5, radius_m / grid.cell)
    rows, cols = np.mgrid[0:grid.height, 0:grid.width]
    for i in np.argsort(rcs, kind="stable"):  # weakest first: the strongest is drawn last
        u, v = uv[i]
        if not (-radius <= u <= grid.width + radius and -radius <= v <= grid.height + radius):
            continue
        r0, r1 = max(0, int(v - radius) - 1), min(grid.height, int(v + radius) + 2)
        c0, c1 = max(0, int(u - radius) - 1), min(grid.width, int(u + radius) + 2)
        disc = (cols[r0:r1, c0:c1] + 0.5 - u) ** 2 + (rows[r0:r1, c0:c1] + 0.5 - v) ** 2 <= radius ** 2
        out[r0:r1, c0:c1, 0][disc] = rcs[i]
        out[r0:r1, c0:c1, 1][disc] = vel[i]
    return out


def false_colour(channels: np.ndarray) -> np.ndarray:
    """An RGB picture of a raster for people: the LiDAR's density as grey, its height as a warm tint,
    radar discs (channels 3–4, when present) in cyan over it."""
    h, w = channels.shape[:2]
    lidar = channels[..., :3].astype(np.float64) / 255 if channels.shape[2] >= 3 else np.zeros((h, w, 3))
    grey = np.clip(0.25 + 0.75 * lidar[..., 2], 0, 1) * (lidar[..., 2] > 0)
    rgb = np.stack([grey, grey * (1 - 0.5 * lidar[..., 0]), grey * (1 - 0.8 * lidar[..., 0])], -1)
    if channels.shape[2] >= 5:
        radar = channels[..., 3] > 0
        rgb[radar] = 0.5 * rgb[radar] + 0.5 * np.array([0.1, 0.8, 0.9])
    return np.round(255 * rgb).astype(np.uint8)

