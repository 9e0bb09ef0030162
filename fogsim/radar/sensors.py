"""Radar sensors: the bundled presets (``fogsim/presets/radar/*.json``) and custom blocks, as one record.

:class:`RadarSensor` is built from a checked :class:`fogsim.schema.radar.RadarSensorSpec` (defaults there
and nowhere else; every parameter with its source): ``RadarSensor.from_dict({...})``,
``RadarSensor.preset("ars408-lr")`` or :func:`load_radar_sensor` (a bundled name, a JSON file, a dict, or a
sensor). Bundled: ``ars408-lr`` (Continental ARS 408-21, nuScenes' radar: 77 GHz, far scan to 250 m at ±9°,
near scan to 70 m at ±60°) and ``srr-corner`` (a 79 GHz short-range corner radar, SRR 520 style).

The radar equation (monostatic, one target, free space; every quantity in dB):

    SNR(σ, R) = P_t + G_t + G_r + 20·log10 λ + σ − 30·log10(4π) − 40·log10 R − 10·log10(k·T₀·B) − F + G_p

P_t the transmit power (dBW), G_t, G_r the antenna gains (dBi), λ = c / f, σ the RCS (dBsm), R the range (m),
k·T₀ Boltzmann's constant × 290 K, B the noise bandwidth, F the noise figure, G_p the processing gain
(the range/Doppler FFTs' coherent integration, less the system losses). A data sheet gives the range at
which a reference target is detected, not G_p: with ``processing_gain_db`` None, G_p is **calibrated** so
that SNR(``reference_rcs_dbsm``, ``max_range_m``) = ``detection_threshold_db`` — the same calibration as
the LiDAR's threshold (:mod:`fogsim.lidar.sensors`). Then SNR = threshold + (σ − σ_ref) + 40·log10(R_max / R)
whatever the unknown constants are.
"""
from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from fogsim.io.documents import MAX_DOCUMENT_BYTES, read_json
from fogsim.lidar.sensors import LIGHT_SPEED
from fogsim.presets import presets_dir
from fogsim.schema.base import check, load_json
from fogsim.schema.radar import RadarSensorSpec

__all__ = ["BOLTZMANN", "RadarSensor", "T0_K", "load_radar_sensor", "radar_sensor_names"]

BOLTZMANN = 1.380649e-23  # J/K
T0_K = 290.0  # the noise figure's reference temperature (IEEE)
SENSOR_DIR = "radar"


def radar_sensor_names() -> list[str]:
    """The bundled radar sensors, sorted."""
    return sorted(p.stem for p in (presets_dir() / SENSOR_DIR).glob("*.json"))


def _rotation_z(yaw_deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class RadarSensor:
    """An automotive FMCW radar (the fields of :class:`~fogsim.schema.radar.RadarSensorSpec`; units and
    defaults there, and only there). ``near_range``: the near scan's parameters as a dict, or None."""

    name: str
    frequency_ghz: float
    min_range_m: float
    max_range_m: float
    azimuth_fov_deg: tuple[float, float]
    elevation_fov_deg: tuple[float, float] | None
    measures_elevation: bool
    range_resolution_m: float
    range_accuracy_m: float
    azimuth_resolution_deg: float
    azimuth_accuracy_deg: float
    elevation_resolution_deg: float | None
    elevation_accuracy_deg: float | None
    velocity_range_mps: tuple[float, float]
    velocity_resolution_mps: float
    velocity_accuracy_mps: float
    rcs_range_dbsm: tuple[float, float]
    transmit_power_dbm: float
    tx_gain_dbi: float
    rx_gain_dbi: float
    noise_figure_db: float
    noise_bandwidth_mhz: float
    processing_gain_given_db: float | None
    detection_threshold_db: float
    reference_rcs_dbsm: float
    false_alarms_per_scan: float
    cycle_time_ms: float | None
    near_range: dict | None
    mount_xyz_m: tuple[float, float, float]
    mount_rpy_deg: tuple[float, float, float]
    sources: dict
    description: str = ""

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_dict(cls, d: dict, source: str | os.PathLike | None = None) -> "RadarSensor":
        """A sensor from a preset / custom block (checked: an :class:`InputError` naming ``source``, or a
        ValueError when ``source`` is None)."""
        return cls.from_spec(check(d, RadarSensorSpec, source, prefix="" if source else "radar sensor"))

    @classmethod
    def from_spec(cls, spec: RadarSensorSpec) -> "RadarSensor":
        def pair(v):
            return None if v is None else (float(v[0]), float(v[1]))
        return cls(name=spec.name or "custom", frequency_ghz=spec.frequency_ghz, min_range_m=spec.min_range_m,
                   max_range_m=spec.max_range_m, azimuth_fov_deg=pair(spec.azimuth_fov_deg),
                   elevation_fov_deg=pair(spec.elevation_fov_deg), measures_elevation=spec.measures_elevation,
                   range_resolution_m=spec.range_resolution_m, range_accuracy_m=spec.range_accuracy_m,
                   azimuth_resolution_deg=spec.azimuth_resolution_deg, azimuth_accuracy_deg=spec.azimuth_accuracy_deg,
                   elevation_resolution_deg=spec.elevation_resolution_deg,
                   elevation_accuracy_deg=spec.elevation_accuracy_deg,
                   velocity_range_mps=pair(spec.velocity_range_mps),
                   velocity_resolution_mps=spec.velocity_resolution_mps,
                   velocity_accuracy_mps=spec.velocity_accuracy_mps, rcs_range_dbsm=pair(spec.rcs_range_dbsm),
                   transmit_power_dbm=spec.transmit_power_dbm, tx_gain_dbi=spec.tx_gain_dbi,
                   rx_gain_dbi=spec.rx_gain_dbi, noise_figure_db=spec.noise_figure_db,
                   noise_bandwidth_mhz=spec.noise_bandwidth_mhz, processing_gain_given_db=spec.processing_gain_db,
                   detection_threshold_db=spec.detection_threshold_db, reference_rcs_dbsm=spec.reference_rcs_dbsm,
                   false_alarms_per_scan=spec.false_alarms_per_scan, cycle_time_ms=spec.cycle_time_ms,
                   near_range=None if spec.near_range is None else spec.near_range.model_dump(),
                   mount_xyz_m=tuple(spec.mount.xyz_m), mount_rpy_deg=tuple(spec.mount.rpy_deg),
                   sources=dict(spec.sources), description=spec.description or "")

    @classmethod
    def preset(cls, name: str) -> "RadarSensor":
        """A bundled sensor by name (:func:`radar_sensor_names`); an unknown name is a ValueError listing them."""
        path = presets_dir() / SENSOR_DIR / f"{name}.json"
        if not isinstance(name, str) or "/" in name or "\\" in name or not path.is_file():
            raise ValueError(f"unknown radar sensor {name!r} (bundled: {', '.join(radar_sensor_names())})")
        return cls.from_spec(load_json(path, RadarSensorSpec))

    def to_dict(self) -> dict:
        """The sensor as a record (what a fog sidecar stores), with ``processing_gain_db`` as used."""
        d = asdict(self)
        d["processing_gain_db"] = self.processing_gain_db
        return d

    # ------------------------------------------------------------------ geometry
    @property
    def wavelength_m(self) -> float:
        """λ = c / f (m)."""
        return LIGHT_SPEED / (self.frequency_ghz * 1e9)

    @property
    def sweep_bandwidth_mhz(self) -> float:
        """The FMCW sweep bandwidth the range resolution implies, B = c / (2·ΔR) (MHz; the far scan's)."""
        return LIGHT_SPEED / (2.0 * self.range_resolution_m) / 1e6

    @property
    def mount_height_m(self) -> float:
        """The antenna's height above the ego frame's origin (m; nuScenes' ego origin is on the ground)."""
        return float(self.mount_xyz_m[2])

    @property
    def mount_pose(self) -> np.ndarray:
        """4×4 sensor → ego transform (p_ego = R·p + t; radars are mounted level: yaw only is applied,
        roll and pitch are recorded)."""
        m = np.eye(4)
        m[:3, :3] = _rotation_z(self.mount_rpy_deg[2])
        m[:3, 3] = self.mount_xyz_m
        return m

    def in_view(self, range_m, azimuth_rad, elevation_rad=None) -> np.ndarray:
        """Whether each (range, azimuth[, elevation]) lies in the sensor's field of view: the far scan, or the
        near scan where there is one (bool array)."""
        r = np.asarray(range_m, np.float64)
        az = np.degrees(np.asarray(azimuth_rad, np.float64))
        inside = (r >= self.min_range_m) & (r <= self.max_range_m) & (az >= self.azimuth_fov_deg[0]) & (
            az <= self.azimuth_fov_deg[1])
        if self.near_range is not None:
            lo, hi = self.near_range["azimuth_fov_deg"]
            inside |= (r >= self.min_range_m) & (r <= self.near_range["max_range_m"]) & (az >= lo) & (az <= hi)
        if elevation_rad is not None and self.elevation_fov_deg is not None:
            el = np.degrees(np.asarray(elevation_rad, np.float64))
            inside &= (el >= self.elevation_fov_deg[0]) & (el <= self.elevation_fov_deg[1])
        return inside

    # ------------------------------------------------------------------ the radar equation
    def _snr_without_gain_db(self, rcs_dbsm, range_m) -> np.ndarray:
        noise_dbw = 10.0 * math.log10(BOLTZMANN * T0_K * self.noise_bandwidth_mhz * 1e6) + self.noise_figure_db
        const = (self.transmit_power_dbm - 30.0 + self.tx_gain_dbi + self.rx_gain_dbi
                 + 20.0 * math.log10(self.wavelength_m) - 30.0 * math.log10(4.0 * math.pi) - noise_dbw)
        r = np.maximum(np.asarray(range_m, np.float64), 1e-3)
        return const + np.asarray(rcs_dbsm, np.float64) - 40.0 * np.log10(r)

    @property
    def processing_gain_db(self) -> float:
        """G_p (dB): the given one, or the calibrated one (the module docstring)."""
        if self.processing_gain_given_db is not None:
            return float(self.processing_gain_given_db)
        return float(self.detection_threshold_db - self._snr_without_gain_db(self.reference_rcs_dbsm, self.max_range_m))

    def snr_db(self, rcs_dbsm, range_m) -> np.ndarray:
        """The clear-air SNR (dB, float64) of a target of RCS ``rcs_dbsm`` (dBsm) at ``range_m`` (m)."""
        return self._snr_without_gain_db(rcs_dbsm, range_m) + self.processing_gain_db

    def max_range_for(self, rcs_dbsm) -> np.ndarray:
        """The range (m) at which a target of ``rcs_dbsm`` falls to the threshold in clear air."""
        margin = self.snr_db(rcs_dbsm, 1.0) - self.detection_threshold_db
        return 10.0 ** (np.asarray(margin, np.float64) / 40.0)


def load_radar_sensor(sensor: "RadarSensor | str | os.PathLike | dict") -> RadarSensor:
    """A sensor from a :class:`RadarSensor`, a bundled name, a ``.json`` file (a custom block; an
    :class:`InputError` naming it when malformed) or a dict (a ValueError when malformed)."""
    if isinstance(sensor, RadarSensor):
        return sensor
    if isinstance(sensor, dict):
        return RadarSensor.from_dict(sensor)
    path = Path(sensor)
    if path.suffix == ".json" or path.is_file():  # bounded (64 MiB) and nesting-checked, as every document
        return RadarSensor.from_dict(read_json(path, MAX_DOCUMENT_BYTES), path)
    return RadarSensor.preset(str(sensor))
