"""LiDAR scans built from geometry for the tests, written in the formats' own byte layouts by hand (from
their specs, not with fogsim's writers): surfaces at known ranges and reflectivities.

Every point of a *surface* lies at exactly its range (a small patch of a sphere around the sensor, one
ray per point), so its outcome in fog is a function of (ρ, R, β) alone. Intensities are the ones the
``hdl64e`` / ``hdl64-s3d`` presets read back as the surface's reflectivity: ρ = 2.55 · I_normalised,
i.e. KITTI I = ρ / 2.55 (0–1), STF I = 100·ρ (0–255).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: the presets' intensity → reflectivity factor (Velodyne: 100 = a white diffuse target, of 255)
REFLECTIVITY_PER_INTENSITY = 2.55


@dataclass(frozen=True)
class Surface:
    range_m: float
    reflectivity: float
    points: int = 8


def ray_directions(count: int, azimuth_deg: float, elevation_deg: float = -1.0, spread_deg: float = 1.0,
                   ) -> np.ndarray:
    """``count`` unit rays (float64) in a small patch around one direction."""
    k = np.arange(count)
    az = np.radians(azimuth_deg + spread_deg * (k % 4) / 4.0)
    el = np.radians(elevation_deg + spread_deg * (k // 4) / 4.0)
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1)


def surfaces_scan(surfaces: list[Surface]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(xyz N×3 float32, reflectivity N, range N, surface id N) of the surfaces, each at its own azimuth."""
    xyz, rho, rng_m, sid = [], [], [], []
    for i, s in enumerate(surfaces):
        d = ray_directions(s.points, azimuth_deg=-170.0 + (340.0 * i) / max(1, len(surfaces)))
        xyz.append(d * s.range_m)
        rho += [s.reflectivity] * s.points
        rng_m += [s.range_m] * s.points
        sid += [i] * s.points
    return (np.concatenate(xyz).astype(np.float32), np.asarray(rho), np.asarray(rng_m), np.asarray(sid))


def kitti_bin(xyz: np.ndarray, intensity_01: np.ndarray) -> bytes:
    """KITTI velodyne: float32 × 4 per point, little-endian (x, y, z, reflectance 0–1)."""
    rec = np.empty((len(xyz), 4), "<f4")
    rec[:, :3], rec[:, 3] = xyz, intensity_01
    return rec.tobytes()


def stf_bin(xyz: np.ndarray, intensity_255: np.ndarray, ring: np.ndarray) -> bytes:
    """STF / nuScenes: float32 × 5 per point, little-endian (x, y, z, intensity 0–255, ring)."""
    rec = np.empty((len(xyz), 5), "<f4")
    rec[:, :3], rec[:, 3], rec[:, 4] = xyz, intensity_255, ring
    return rec.tobytes()


def write_surfaces(folder: Path, surfaces: list[Surface]) -> tuple[Path, Path, np.ndarray, np.ndarray, np.ndarray]:
    """The surfaces as a KITTI scan (``scan.bin``, I = ρ/2.55) and an STF scan (``scan_stf.bin``,
    I = 255·ρ/2.55, rings 0–63): (kitti path, stf path, reflectivity, range, surface id)."""
    xyz, rho, rng_m, sid = surfaces_scan(surfaces)
    kitti = folder / "scan.bin"
    stf = folder / "scan_stf.bin"
    kitti.write_bytes(kitti_bin(xyz, (rho / REFLECTIVITY_PER_INTENSITY).astype(np.float32)))
    stf.write_bytes(stf_bin(xyz, (255.0 * rho / REFLECTIVITY_PER_INTENSITY).astype(np.float32),
                            (np.arange(len(xyz)) % 64).astype(np.float32)))
    return kitti, stf, rho, rng_m, sid


# ----------------------------------------------------------------------------- whole sweeps
#: the share of a KITTI sweep's points with reflectance exactly 0 (a real KITTI scan, 000008: 19.8 %)
ZERO_INTENSITY_SHARE = 0.2


def kitti_sweep(folder: Path, steps: int = 400, seed: int = 0) -> Path:
    """A KITTI-format sweep (``sweep.bin``): the ``hdl64e`` preset's 64 beams × ``steps`` azimuths ray-cast
    against a street (road, buildings, street ends, cars: :func:`fogsim.bench.lidar_fog.synthetic_scan`),
    every ray a return, reflectances spread like a real KITTI scan's (log-normal about 0.25, two decimals,
    0.01–0.99), and :data:`ZERO_INTENSITY_SHARE` of the points, drawn at random, at reflectance 0."""
    from fogsim.bench.lidar_fog import synthetic_scan

    scan = synthetic_scan(seed, steps=steps)
    rng = np.random.default_rng(seed + 1)
    # KITTI-like reflectances: log-normal about 0.25 (σ 0.6), two decimals as KITTI stores them, 0.01–0.99
    i01 = np.clip(np.round(np.exp(np.log(0.25) + 0.6 * rng.standard_normal(len(scan))), 2), 0.01, 0.99)
    i01[rng.random(len(i01)) < ZERO_INTENSITY_SHARE] = 0.0
    path = folder / "sweep.bin"
    path.write_bytes(kitti_bin(scan.xyz, i01))
    return path


def nuscenes_intensities(n: int, rng: np.random.Generator) -> np.ndarray:
    """0–255 whole-number intensities distributed like a nuScenes LIDAR_TOP sweep's: mostly small
    (log-normal, median 6, clipped to 0–100: the HDL-32E's diffuse 0–100 %), 2 % retro-reflectors 101–255."""
    i = np.clip(np.round(np.exp(np.log(6.0) + 0.9 * rng.standard_normal(n))), 0, 100)
    bright = rng.random(n) < 0.02
    i[bright] = rng.integers(101, 256, int(bright.sum()))
    return i.astype(np.float32)


def nuscenes_sweep(folder: Path, seed: int = 0) -> Path:
    """A nuScenes-format sweep (``sweep.pcd.bin``: 5 × float32 x y z intensity(0–255) ring(0–31)): the
    ``hdl32e`` preset's 32 beams (−30.67° … +10.67°) × 1090 azimuths (0.33°) ray-cast against the street
    of :func:`kitti_sweep`, intensities :func:`nuscenes_intensities`, ring = the beam (0 = the highest)."""
    from fogsim.bench.lidar_fog import synthetic_scan
    from fogsim.lidar.sensors import LidarSensor

    sensor = LidarSensor.preset("hdl32e")
    scan = synthetic_scan(seed, sensor, steps=1090)
    ring = scan.estimated_rings(sensor.inclinations_rad).astype(np.float32)
    path = folder / "sweep.pcd.bin"
    path.write_bytes(stf_bin(scan.xyz, nuscenes_intensities(len(scan), np.random.default_rng(seed + 1)), ring))
    return path
