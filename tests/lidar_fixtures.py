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


# ----------------------------------------------------------------------------- a KITTI-like street sweep
#: the sweep of :func:`kitti_street_sweep`: the camera's view of an HDL-64E (±40° about +x, 0.25° steps)
#: over a street with parked and driving cars, dark and bright, 5–70 m ahead
SWEEP_AZIMUTH_DEG, SWEEP_STEP_DEG = 40.0, 0.25
SWEEP_CARS = ((5.5, -3.0, 0.05), (9.0, 2.8, 0.6), (14.0, -3.2, 0.3), (21.0, 3.0, 0.05), (27.0, -2.5, 0.9),
              (35.0, 2.6, 0.2), (46.0, -3.0, 0.05), (58.0, 3.1, 0.6), (70.0, -2.8, 0.3))
#: glass: the house fronts' windows (3 m of every 4 m along the street, 1.0–2.2 m above the road) return
#: no reflectance, as windows do in KITTI scans
WINDOW_PITCH_M, WINDOW_WIDTH_M, WINDOW_BANDS_M = 4.0, 3.0, ((1.0, 2.2),)
#: KITTI reflectance of the road and the house fronts, and the weakest non-zero reflectance reported
SWEEP_ROAD, SWEEP_HOUSE, SWEEP_ZERO_BELOW = 0.3, 0.4, 0.05


def kitti_street_sweep(seed: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """(xyz N×3 float32, KITTI reflectance N float32 in [0, 1], two decimals) of a ray-cast street sweep
    like KITTI's 000008 (its camera-view part): ≈ 20 k points, ≈ 20 % of them zero-intensity. Built
    from :func:`kitti_tree.street_scan` (ground, house fronts 9 m to each side, :data:`SWEEP_CARS`);
    reflectance = surface ρ_K (road :data:`SWEEP_ROAD`, houses :data:`SWEEP_HOUSE`, the cars' own) ×
    √|cos incidence| × a ±15 % texture, windows 0, KITTI's two decimals, and returns weaker than
    :data:`SWEEP_ZERO_BELOW` reported as 0 (the grazing far road, dark cars side-on: KITTI's zeros)."""
    import kitti_tree as kt

    rng = np.random.default_rng(seed)
    cars = [kt.Car(x, lane, kt.GROUND_Z, yaw=0.05 * k, reflectance=refl)
            for k, (x, lane, refl) in enumerate(SWEEP_CARS)]
    xyz, refl, ids = kt.street_scan(cars, rng, azimuth_deg=SWEEP_AZIMUTH_DEG, step_deg=SWEEP_STEP_DEG,
                                    max_range=120.0)
    p = xyz.astype(np.float64)
    r = np.linalg.norm(p, axis=1)
    rho = np.where(ids == -1, SWEEP_ROAD, np.where(ids == -2, SWEEP_HOUSE, refl))
    cos_inc = np.where(ids == -1, np.abs(p[:, 2]) / r, np.where(ids == -2, np.abs(p[:, 1]) / r, 0.8))
    window = (ids == -2) & ((p[:, 0] % WINDOW_PITCH_M) < WINDOW_WIDTH_M)
    height = p[:, 2] - kt.GROUND_Z
    window &= np.any([(height > lo) & (height < hi) for lo, hi in WINDOW_BANDS_M], axis=0)
    value = np.round(rho * np.sqrt(cos_inc) * rng.uniform(0.85, 1.15, len(r)), 2)
    value[window | (value < SWEEP_ZERO_BELOW)] = 0.0
    return xyz, np.clip(value, 0.0, 1.0).astype(np.float32)


#: what the side-by-side table calls the fixture scan
SWEEP_LABEL = ("the CI fixture `tests/lidar_fixtures.py: kitti_street_sweep()` (a ray-cast HDL-64E street sweep, "
               "camera view ±40°, KITTI format)")


def kitti_street_cloud(folder: Path, seed: int = 8):
    """:func:`kitti_street_sweep` written as a KITTI velodyne ``.bin`` in ``folder`` (by hand, the format's
    layout) and read back by fogsim's reader: the :class:`fogsim.lidar.PointCloud`."""
    from fogsim.lidar.formats import read_points

    xyz, refl = kitti_street_sweep(seed)
    path = Path(folder) / "street_sweep.bin"
    path.write_bytes(kitti_bin(xyz, refl))
    return read_points(path, "kitti")
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


def stf_intensities(n: int, rng: np.random.Generator) -> np.ndarray:
    """0–255 whole-number intensities distributed like a Seeing Through Fog HDL-64 S3D sweep's: bright (median
    127: log-normal about 127, σ 0.5, clipped to 1–255), 2 % at 0."""
    i = np.clip(np.round(np.exp(np.log(127.0) + 0.5 * rng.standard_normal(n))), 1, 255)
    i[rng.random(n) < 0.02] = 0.0
    return i.astype(np.float32)


def stf_sweep(folder: Path, steps: int = 400, seed: int = 0) -> Path:
    """A Seeing Through Fog-format sweep (``sweep_stf.bin``: 5 × float32 x y z intensity(0–255) ring(0–63)):
    the ``hdl64-s3d`` preset's 64 beams × ``steps`` azimuths ray-cast against the street of :func:`kitti_sweep`,
    intensities :func:`stf_intensities`, ring = the beam (0 = the highest)."""
    from fogsim.bench.lidar_fog import synthetic_scan
    from fogsim.lidar.sensors import LidarSensor

    sensor = LidarSensor.preset("hdl64-s3d")
    scan = synthetic_scan(seed, sensor, steps=steps)
    ring = scan.estimated_rings(sensor.inclinations_rad).astype(np.float32)
    path = folder / "sweep_stf.bin"
    path.write_bytes(stf_bin(scan.xyz, stf_intensities(len(scan), np.random.default_rng(seed + 1)), ring))
    return path


# ----------------------------------------------------------------------------- every firing stored (nuScenes)
#: a nuScenes LIDAR_TOP sweep: 1 084 firings × 32 rings, stored firing by firing (row = 32·firing + ring)
NUSCENES_FIRINGS, NUSCENES_RINGS = 1084, 32
#: the open street of :func:`nuscenes_firings`: road 1.84 m below the sensor, house fronts 11 m to each side
#: (9 m high, a 6 m gap every 20 m), no street ends (sky along the street), returns up to 90 m
OPEN_STREET_ROAD_M, OPEN_STREET_HOUSE_M, OPEN_STREET_HOUSE_TOP_M, OPEN_STREET_REACH_M = 1.84, 11.0, 9.0, 90.0
#: the vehicle's own roof: the two lowest rings, ±25° about straight back, echo from 0.6 m (the blind zone)
EGO_RINGS, EGO_HALF_ANGLE_DEG, EGO_RANGE_M = (30, 31), 25.0, 0.6


def open_street_hits(d: np.ndarray, origins: np.ndarray | None = None, road_m: float = OPEN_STREET_ROAD_M,
                     windows: bool = False) -> np.ndarray:
    """The range (+inf: nothing within :data:`OPEN_STREET_REACH_M`) at which rays ``d`` (N×3 unit, from
    ``origins``, N×3, default the sensor origin) meet the open street ``road_m`` below the sensor: the road,
    the house fronts with their gaps, four parked cars. ``windows``: the house fronts' windows (1–2.6 m
    above the road, 3 m of every 4 m) return nothing, as glass does in KITTI's scans."""
    o = np.zeros_like(d) if origins is None else origins
    glass = np.full(len(d), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d[:, 2] < 0, (-road_m - o[:, 2]) / d[:, 2], np.inf)
        for side in (1.0, -1.0):
            th = np.where(d[:, 1] * side > 0, (side * OPEN_STREET_HOUSE_M - o[:, 1]) / d[:, 1], np.inf)
            x, z = o[:, 0] + th * d[:, 0], o[:, 2] + th * d[:, 2] + road_m  # z: above the road
            wall = (z < OPEN_STREET_HOUSE_TOP_M) & (np.mod(x, 20.0) < 14.0)
            t = np.minimum(t, np.where(wall, th, np.inf))
            if windows:
                glass = np.minimum(glass, np.where(wall & (z > 1.0) & (z < 2.6) & (np.mod(x, 4.0) < 3.0), th, np.inf))
        for cx, cy in ((8.0, -4.0), (-12.0, 4.5), (25.0, 4.0), (-30.0, -4.0)):  # cars 4.4 × 1.8 × 1.5 m
            lo = np.array([cx - 2.2, cy - 0.9, -road_m])
            hi = np.array([cx + 2.2, cy + 0.9, -road_m + 1.5])
            t0, t1 = (lo - o) / d, (hi - o) / d
            near = np.nanmax(np.minimum(t0, t1), axis=1)
            far = np.nanmin(np.maximum(t0, t1), axis=1)
            t = np.minimum(t, np.where((near <= far) & (near > 0), near, np.inf))
    return np.where((t <= OPEN_STREET_REACH_M) & (glass > t), t, np.inf)


def nuscenes_firings(folder: Path, seed: int = 0) -> tuple[Path, dict]:
    """A nuScenes-format sweep that stores every firing (``firings.pcd.bin``: 5 × float32 x y z
    intensity(0–255) ring, :data:`NUSCENES_FIRINGS` × :data:`NUSCENES_RINGS` rows, firing by firing, the
    sensor turning clockwise): the ``hdl32e`` preset's beams (ring 0 the highest) over the open street of
    :func:`open_street_hits`. A firing without a return is a row at exactly 0 m (intensity 0); one that
    meets the vehicle's roof (:data:`EGO_RINGS`) a row at :data:`EGO_RANGE_M`. Returns (path, truth):
    ``direction`` (rows × 3, each firing's ray), ``void`` (rows at 0 m), ``ego`` (rows on the roof)."""
    from fogsim.lidar.sensors import LidarSensor

    incl = np.sort(LidarSensor.preset("hdl32e").inclinations_rad)[::-1]  # ring 0 = the highest beam
    rng = np.random.default_rng(seed)
    start = rng.uniform(-np.pi, np.pi)
    az = start - np.arange(NUSCENES_FIRINGS) * (2 * np.pi / NUSCENES_FIRINGS)  # clockwise seen from above
    az = az + rng.normal(0.0, np.radians(0.01), NUSCENES_FIRINGS)
    el, a = np.meshgrid(incl, az, indexing="xy")  # rows: firing-major, 32 rings per firing
    el, a = el.reshape(-1), a.reshape(-1)
    ring = np.tile(np.arange(NUSCENES_RINGS), NUSCENES_FIRINGS)
    d = np.stack([np.cos(el) * np.cos(a), np.cos(el) * np.sin(a), np.sin(el)], 1)
    t = open_street_hits(d)
    back = np.abs(np.angle(np.exp(1j * (a - np.pi)))) < np.radians(EGO_HALF_ANGLE_DEG)
    ego = np.isin(ring, EGO_RINGS) & back
    t = np.where(ego, EGO_RANGE_M, t)
    void = ~np.isfinite(t)
    xyz = np.where(void[:, None], 0.0, d * np.where(void, 0.0, t)[:, None])
    inten = nuscenes_intensities(len(d), rng)
    inten[void] = 0.0
    inten[ego] = np.minimum(inten[ego], 3.0)
    path = folder / "firings.pcd.bin"
    path.write_bytes(stf_bin(xyz.astype(np.float32), inten, ring.astype(np.float32)))
    return path, {"direction": d, "void": void, "ego": ego}


# ----------------------------------------------------------------------------- a cropped KITTI frame (real lasers)
#: a KITTI object frame's calibration (the 2011_09_26 drives', rounded) and image size: LiDAR → image 2
KITTI_P2 = np.array([[721.5377, 0.0, 609.5593, 44.85728], [0.0, 721.5377, 172.854, 0.2163791],
                     [0.0, 0.0, 1.0, 0.002745884]])
KITTI_R0 = np.array([[0.9999239, 0.00983776, -0.007445048], [-0.009869795, 0.9999421, -0.004278459],
                     [0.007402527, 0.004351614, 0.9999631]])
KITTI_TR = np.array([[0.007533745, -0.9999714, -0.000616602, -0.004069766],
                     [0.01480249, 0.0007280733, -0.9998902, -0.07631618],
                     [0.9998621, 0.00752379, 0.01480755, -0.2717806]])
KITTI_IMAGE = (1242, 375)
KITTI_HEIGHT_M = 1.73


def kitti_p2(scale: float = 1.0) -> np.ndarray:
    """P2 for image 2 resampled by ``scale`` (1/3: 414 × 125 pixels, the same view)."""
    p = KITTI_P2.copy()
    p[:2] *= scale
    return p


def kitti_image(scale: float = 1.0) -> tuple[int, int]:
    return round(KITTI_IMAGE[0] * scale), round(KITTI_IMAGE[1] * scale)


def kitti_projection(scale: float = 1.0) -> np.ndarray:
    """3×4: LiDAR point → image 2 (P2 · R0_rect · Tr_velo_to_cam; pixel-centre coordinates)."""
    r0, tr = np.eye(4), np.vstack([KITTI_TR, [0, 0, 0, 1]])
    r0[:3, :3] = KITTI_R0
    return kitti_p2(scale) @ r0 @ tr


def kitti_calib_text(scale: float = 1.0) -> str:
    """The calibration as a KITTI ``calib/*.txt`` (P2 for every camera; an identity IMU line)."""
    p = kitti_p2(scale)
    rows = {"P0": p, "P1": p, "P2": p, "P3": p, "R0_rect": KITTI_R0,
            "Tr_velo_to_cam": KITTI_TR, "Tr_imu_to_velo": np.hstack([np.eye(3), np.zeros((3, 1))])}
    return "".join(f"{k}: {' '.join(f'{v:.9e}' for v in m.ravel())}\n" for k, m in rows.items())


def kitti_laser_frame(folder: Path, seed: int = 0, steps: int = 2000) -> tuple[Path, dict]:
    """A KITTI velodyne scan cropped to camera 2 (``frame.bin``, KITTI's 4 × float32, the points of rays that
    project into the image, as ``velodyne_reduced`` keeps them) of the open street (:func:`open_street_hits`,
    1.73 m below), made as KITTI's HDL-64E makes it: the ``hdl64e`` preset's 64 lasers (KITTI's factory
    calibration: two blocks, each laser's line :attr:`~LidarSensor.vertical_offsets_m` off the origin),
    each firing ``steps`` times a turn at its own phase. A ray without a hit (sky, the road beyond 90 m, a
    window) leaves no point. Returns (path, truth): ``laser`` (per point), ``missing`` (unit directions of the rays
    without a return whose ray projects into the image at 20 m), ``elevation`` (theirs, radians)."""
    from fogsim.lidar.sensors import LidarSensor

    s = LidarSensor.preset("hdl64e")
    theta = s.inclinations_rad
    h = np.asarray(s.vertical_offsets_m)
    rng = np.random.default_rng(seed)
    step = 2 * np.pi / steps
    phase = rng.uniform(0, step, len(theta))
    az = np.arange(steps)[None, :] * step + phase[:, None] + rng.normal(0, step * 0.05, (len(theta), steps))
    th = np.broadcast_to(theta[:, None], az.shape)
    laser = np.broadcast_to(np.arange(len(theta))[:, None], az.shape).reshape(-1)
    az, th = az.reshape(-1), th.reshape(-1)
    d = np.stack([np.cos(th) * np.cos(az), np.cos(th) * np.sin(az), np.sin(th)], 1)
    hk = h[laser]
    origins = hk[:, None] * np.stack([-np.sin(th) * np.cos(az), -np.sin(th) * np.sin(az), np.cos(th)], 1)
    t = open_street_hits(d, origins, KITTI_HEIGHT_M, windows=True)
    m = kitti_projection()

    def inside(p):
        q = p @ m[:, :3].T + m[:, 3]
        with np.errstate(divide="ignore", invalid="ignore"):
            u, v = q[:, 0] / q[:, 2], q[:, 1] / q[:, 2]
        return (q[:, 2] > 0) & (u >= 0) & (u < KITTI_IMAGE[0]) & (v >= 0) & (v < KITTI_IMAGE[1])

    hit = np.isfinite(t)
    xyz = origins[hit] + d[hit] * t[hit, None]
    keep = inside(xyz)
    xyz, point_laser = xyz[keep], laser[hit][keep]
    i01 = np.clip(np.round(np.exp(np.log(0.25) + 0.6 * rng.standard_normal(len(xyz))), 2), 0.01, 0.99)
    i01[rng.random(len(i01)) < ZERO_INTENSITY_SHARE] = 0.0
    path = folder / "frame.bin"
    path.write_bytes(kitti_bin(xyz.astype(np.float32), i01.astype(np.float32)))
    gone = ~hit & inside(origins + 20.0 * d)
    return path, {"laser": point_laser, "missing": d[gone], "elevation": th[gone]}
