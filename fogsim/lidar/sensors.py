"""LiDAR sensors: the bundled presets (``fogsim/presets/lidar/*.json``) and custom blocks, as one record.

:class:`LidarSensor` is built from a checked :class:`fogsim.schema.lidar.LidarSensorSpec` (defaults
there and nowhere else): ``LidarSensor.from_dict({...})``, ``LidarSensor.preset("hdl64e")`` or
:func:`load_sensor` (a bundled name, a JSON file, a dict, or a sensor). Bundled: ``hdl64e`` (KITTI),
``hdl64-s3d`` (Seeing Through Fog), ``hdl32e`` (nuScenes), ``waymo-top`` (inclinations from each frame's
calibration: :meth:`LidarSensor.with_inclinations`).

The radiometry every fog model shares (normalised by the detection threshold, so the sensor's
unknown constants cancel):

* overlap ξ(R) = min(1, (R / R_o)²) with R_o = ``overlap_full_m`` (ξ = 1 when R_o = 0): the share of
  the beam the receiver sees, growing as the beam enters its field of view (bistatic optics);
* the clear-air signal of a hard target of reflectivity ρ at range R, relative to the threshold:
  q(ρ, R) = (ρ / ρ_ref) · (R_max / R)² · ξ(R) — the LiDAR equation's ρ·ξ/R² over its value for the
  reference target at the maximum range, so q ≥ 1 is detected (the **calibration** of the threshold:
  ``max_range_m`` is where a target of ``reference_reflectivity`` falls to it);
* the reflectivity a reported intensity implies: ρ = s · I_linear · (R / R_ref)^k
  (``reflectivity_per_intensity``, ``intensity_range_exponent``, ``intensity_reference_range_m``), and
  its inverse for a return the fog makes (:meth:`LidarSensor.intensity_of`);
* the per-ray, per-pulse signal fluctuation: ln g ~ N(0, σ²), σ = ``fluctuation_sigma`` (the fog model
  draws g; :mod:`fogsim.lidar.fog`).

Calibrations (:meth:`LidarSensor.calibrated`): ``datasheet`` is the preset as bundled (each value's source
in its ``sources`` block), ``hahner-constants`` puts the pulse and overlap constants of Hahner et al. 2021 over
it (:data:`fogsim.schema.lidar.HAHNER_CONSTANTS`: 20 ns pulse, full overlap from 1 m; ``reference``, its old
name, is read with a DeprecationWarning), a
:class:`~fogsim.schema.lidar.LidarCalibration` block any of its keys.
"""
from __future__ import annotations

import math
import os
import warnings
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from fogsim.io.documents import MAX_DOCUMENT_BYTES, read_json
from fogsim.presets import presets_dir
from fogsim.schema.base import check, load_json
from fogsim.schema.lidar import DEPRECATED_CALIBRATIONS, HAHNER_CONSTANTS, LidarCalibration, LidarSensorSpec

__all__ = ["LIGHT_SPEED", "LidarSensor", "load_sensor", "sensor_names"]

#: metres per second (the pulse's length in range is c·τ_H)
LIGHT_SPEED = 299_792_458.0
SENSOR_DIR = "lidar"


def sensor_names() -> list[str]:
    """The bundled sensors, sorted."""
    return sorted(p.stem for p in (presets_dir() / SENSOR_DIR).glob("*.json"))


def _rotation_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


@dataclass(frozen=True)
class LidarSensor:
    """A spinning LiDAR (the fields of :class:`~fogsim.schema.lidar.LidarSensorSpec`; units and defaults
    there, and only there: build it with :meth:`from_dict`, :meth:`preset` or :func:`load_sensor`).
    ``inclinations_deg`` is None for a sensor whose beams come from the data's calibration until
    :meth:`with_inclinations` gives them; ``vertical_offsets_m`` (None: every beam through the origin) the
    beams' vertical offsets, in the same order."""

    name: str
    beams: int
    inclinations_deg: tuple[float, ...] | None
    horizontal_fov_deg: float
    steps_per_sweep: int
    min_range_m: float
    max_range_m: float
    reference_reflectivity: float
    pulse_half_power_ns: float
    overlap_full_m: float
    range_noise_m: float
    range_noise_at_threshold_m: float
    return_mode: str
    intensity_scale: str
    reflectivity_per_intensity: float
    intensity_range_exponent: float
    intensity_reference_range_m: float
    mount_xyz_m: tuple[float, float, float]
    mount_rpy_deg: tuple[float, float, float]
    description: str
    retro_reflective_from: float | None
    retro_reflectivity_max: float
    fluctuation_sigma: float
    fog_echo_scale: float = 1.0
    vertical_offsets_m: tuple[float, ...] | None = None
    calibration: str = "datasheet"
    sources: dict = field(default_factory=dict, hash=False, compare=False)
    stf_noise_level: float | None = None  # the STF chamber-fitted rule's n and g (stf2020; None: unpublished)
    stf_gain: float | None = None

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_dict(cls, d: dict, source: str | os.PathLike | None = None) -> "LidarSensor":
        """The sensor of a preset or custom block, checked (one line naming ``source``, or a
        ValueError without one); the defaults are :class:`LidarSensorSpec`'s."""
        return cls.from_spec(check(d, LidarSensorSpec, source, prefix="" if source else "lidar sensor"))

    @classmethod
    def from_spec(cls, spec: LidarSensorSpec) -> "LidarSensor":
        if spec.vertical_fov_deg is not None:
            lo, hi = spec.vertical_fov_deg
            incl = tuple(np.linspace(hi, lo, spec.beams).tolist()) if spec.beams > 1 else ((lo + hi) / 2,)
        elif spec.inclinations_deg == "calibration":
            incl = None
        else:
            incl = tuple(float(v) for v in spec.inclinations_deg)
        steps = spec.steps_per_sweep or max(1, round(spec.horizontal_fov_deg / spec.horizontal_resolution_deg))
        return cls(name=spec.name or "custom", beams=spec.beams, inclinations_deg=incl,
                   horizontal_fov_deg=spec.horizontal_fov_deg, steps_per_sweep=int(steps),
                   min_range_m=spec.min_range_m, max_range_m=spec.max_range_m,
                   reference_reflectivity=spec.reference_reflectivity, pulse_half_power_ns=spec.pulse_half_power_ns,
                   overlap_full_m=spec.overlap_full_m, range_noise_m=spec.range_noise_m,
                   range_noise_at_threshold_m=spec.range_noise_at_threshold_m, return_mode=spec.return_mode,
                   intensity_scale=spec.intensity_scale, reflectivity_per_intensity=spec.reflectivity_per_intensity,
                   intensity_range_exponent=spec.intensity_range_exponent,
                   intensity_reference_range_m=spec.intensity_reference_range_m,
                   mount_xyz_m=tuple(spec.mount.xyz_m), mount_rpy_deg=tuple(spec.mount.rpy_deg),
                   description=spec.description or "", retro_reflective_from=spec.retro_reflective_from,
                   retro_reflectivity_max=spec.retro_reflectivity_max, fluctuation_sigma=spec.fluctuation_sigma,
                   fog_echo_scale=spec.fog_echo_scale, sources=dict(spec.sources or {}),
                   stf_noise_level=spec.stf_noise_level, stf_gain=spec.stf_gain,
                   vertical_offsets_m=None if spec.vertical_offsets_m is None else tuple(spec.vertical_offsets_m))

    @classmethod
    def preset(cls, name: str) -> "LidarSensor":
        """A bundled sensor by name (:func:`sensor_names`); an unknown name is a ValueError listing them."""
        path = presets_dir() / SENSOR_DIR / f"{name}.json"
        if not isinstance(name, str) or "/" in name or "\\" in name or not path.is_file():
            raise ValueError(f"unknown LiDAR sensor {name!r} (bundled: {', '.join(sensor_names())})")
        return cls.from_spec(load_json(path, LidarSensorSpec))

    def with_inclinations(self, inclinations_rad) -> "LidarSensor":
        """The sensor with its beams' inclinations given (radians, one per beam, any order), e.g. a
        Waymo frame's ``beam_inclinations``."""
        incl = np.degrees(np.asarray(inclinations_rad, np.float64).reshape(-1))
        if incl.size != self.beams or not np.isfinite(incl).all():
            raise ValueError(f"{self.name} has {self.beams} beams; got {incl.size} inclinations")
        return replace(self, inclinations_deg=tuple(incl.tolist()), vertical_offsets_m=None)

    def calibrated(self, calibration: "str | LidarCalibration | dict" = "datasheet") -> "LidarSensor":
        """The sensor under a calibration: ``datasheet`` (as it is), ``hahner-constants`` (Hahner et al.'s
        pulse and overlap constants over it; ``reference``: its deprecated name) or a
        :class:`~fogsim.schema.lidar.LidarCalibration` (or its dict): its keys
        replace the sensor's and its ``sources`` join the sensor's. A ValueError when the result is
        inconsistent (min range ≥ max range, full overlap beyond the max range)."""
        if calibration == "datasheet":
            return self
        if isinstance(calibration, str) and calibration in DEPRECATED_CALIBRATIONS:
            new = DEPRECATED_CALIBRATIONS[calibration]
            warnings.warn(f"LiDAR calibration {calibration!r} is now called {new!r} (Hahner et al.'s pulse and "
                          "overlap constants in fogsim's model, not the reference simulator)", DeprecationWarning,
                          stacklevel=2)
            calibration = new
        if calibration == "hahner-constants":
            calibration = HAHNER_CONSTANTS
        if isinstance(calibration, dict):
            calibration = LidarCalibration.model_validate(calibration)
        if not isinstance(calibration, LidarCalibration):
            raise ValueError(f"unknown LiDAR calibration {calibration!r} (datasheet, hahner-constants or a block)")
        out = replace(self, **calibration.overrides(), calibration=calibration.name or "file",
                      sources={**self.sources, **(calibration.sources or {})})
        if not out.min_range_m < out.max_range_m or not out.overlap_full_m < out.max_range_m:
            raise ValueError(f"calibration {out.calibration}: min_range_m and overlap_full_m must be below "
                             f"max_range_m ({out.min_range_m:g}, {out.overlap_full_m:g}, {out.max_range_m:g})")
        return out

    def to_dict(self) -> dict:
        """The sensor as a record (what a fog sidecar stores)."""
        d = asdict(self)
        d["inclinations_deg"] = None if self.inclinations_deg is None else list(self.inclinations_deg)
        d["vertical_offsets_m"] = None if self.vertical_offsets_m is None else list(self.vertical_offsets_m)
        d["sources"] = dict(self.sources)
        return d

    # ------------------------------------------------------------------ geometry
    @property
    def inclinations_rad(self) -> np.ndarray:
        """The beams' inclinations in radians (float64, as stored); a ValueError until they are known."""
        if self.inclinations_deg is None:
            raise ValueError(f"{self.name}: the beam inclinations come from the data's calibration "
                             "(LidarSensor.with_inclinations)")
        return np.radians(np.asarray(self.inclinations_deg, np.float64))

    def beam_origins(self, beam: np.ndarray, azimuth: np.ndarray | None = None, towards: np.ndarray | None = None
                     ) -> np.ndarray:
        """Where the rays of ``beam`` (indices into the inclinations) at ``azimuth`` (radians; or the azimuth of
        the points ``towards``, N×3) start, in the sensor frame (N×3 float64): h·(−sin θ cos φ, −sin θ sin φ,
        cos θ), so each beam's line passes its ``vertical_offsets_m`` h from the origin (a Velodyne's lasers
        sit off its axis); zeros without offsets."""
        beam = np.asarray(beam).reshape(-1)
        if self.vertical_offsets_m is None:
            return np.zeros((len(beam), 3))
        theta = self.inclinations_rad[beam]
        h = np.asarray(self.vertical_offsets_m, np.float64)[beam]
        if towards is not None:  # cos φ, sin φ = x/ρ, y/ρ
            p = np.asarray(towards, np.float64).reshape(-1, 3)
            rho = np.maximum(np.hypot(p[:, 0], p[:, 1]), 1e-12)
            cos_phi, sin_phi = p[:, 0] / rho, p[:, 1] / rho
        else:
            azimuth = np.asarray(azimuth, np.float64).reshape(-1)
            cos_phi, sin_phi = np.cos(azimuth), np.sin(azimuth)
        hs = h * np.sin(theta)
        return np.stack([-hs * cos_phi, -hs * sin_phi, h * np.cos(theta)], 1)

    @property
    def reach_m(self) -> float:
        """How far from the sensor's origin a ray can find a return (metres): the maximum range plus the largest
        of the lasers' offsets from the origin."""
        offsets = self.vertical_offsets_m or (0.0,)
        return self.max_range_m + max(abs(h) for h in offsets)

    @property
    def horizontal_resolution_deg(self) -> float:
        return self.horizontal_fov_deg / self.steps_per_sweep

    @property
    def mount_pose(self) -> np.ndarray:
        """4×4 sensor → ego transform (p_ego = R·p + t, R = Rz(yaw)·Ry(pitch)·Rx(roll))."""
        m = np.eye(4)
        m[:3, :3] = _rotation_rpy(*np.radians(self.mount_rpy_deg))
        m[:3, 3] = self.mount_xyz_m
        return m

    @property
    def pulse_length_m(self) -> float:
        """L = c·τ_H: the range over which the sin² pulse (duration 2τ_H) spreads a soft target's echo."""
        return LIGHT_SPEED * self.pulse_half_power_ns * 1e-9

    # ------------------------------------------------------------------ radiometry
    def overlap(self, r) -> np.ndarray:
        """ξ(R) = min(1, (R / R_o)²) (float64; 1 everywhere when ``overlap_full_m`` = 0)."""
        r = np.asarray(r, np.float64)
        if self.overlap_full_m <= 0:
            return np.ones_like(r)
        return np.minimum(1.0, (r / self.overlap_full_m) ** 2)

    def clear_signal(self, reflectivity, r) -> np.ndarray:
        """q(ρ, R) = (ρ/ρ_ref)·(R_max/R)²·ξ(R): a hard target's clear-air signal over the threshold."""
        r = np.asarray(r, np.float64)
        with np.errstate(divide="ignore"):
            return (np.asarray(reflectivity, np.float64) / self.reference_reflectivity
                    * (self.max_range_m / r) ** 2 * self.overlap(r))

    def reflectivity_of(self, linear_intensity, r) -> np.ndarray:
        """ρ = s·I_linear·(R / R_ref)^k: the reflectivity a reported (linear) intensity implies. Above
        I_r = ``retro_reflective_from`` (Velodyne's calibrated scale: 0–100 diffuse, 101–255
        retro-reflectors, 255 an ideal one) ρ rises log-linearly from s·I_r (a white diffuse target) to
        ρ_max = ``retro_reflectivity_max`` at I = 1: ρ = s·I_r·(ρ_max / (s·I_r))^((I − I_r)/(1 − I_r))."""
        lin = np.asarray(linear_intensity, np.float64)
        rho = self.reflectivity_per_intensity * lin
        if self.retro_reflective_from is not None:
            ir = self.retro_reflective_from
            white = self.reflectivity_per_intensity * ir
            with np.errstate(over="ignore"):
                retro = white * (self.retro_reflectivity_max / white) ** ((lin - ir) / (1.0 - ir))
            rho = np.where(lin > ir, retro, rho)
        if self.intensity_range_exponent:
            rho = rho * (np.asarray(r, np.float64) / self.intensity_reference_range_m) ** self.intensity_range_exponent
        return rho

    def intensity_of(self, reflectivity, r) -> np.ndarray:
        """The linear intensity the sensor reports for a return of (apparent) reflectivity ρ at R."""
        rho = np.asarray(reflectivity, np.float64)
        lin = rho / self.reflectivity_per_intensity
        if self.retro_reflective_from is not None:
            ir = self.retro_reflective_from
            white = self.reflectivity_per_intensity * ir
            with np.errstate(divide="ignore", invalid="ignore"):
                retro = ir + (1.0 - ir) * np.log(rho / white) / math.log(self.retro_reflectivity_max / white)
            lin = np.where(rho > white, retro, lin)
        if self.intensity_range_exponent:
            lin = lin * (np.asarray(r, np.float64) / self.intensity_reference_range_m) ** -self.intensity_range_exponent
        return lin


def load_sensor(sensor: "LidarSensor | str | os.PathLike | dict") -> LidarSensor:
    """A sensor from a :class:`LidarSensor`, a bundled name, a ``.json`` file (a custom block; an
    :class:`InputError` naming it when malformed) or a dict (a ValueError when malformed)."""
    if isinstance(sensor, LidarSensor):
        return sensor
    if isinstance(sensor, dict):
        return LidarSensor.from_dict(sensor)
    path = Path(sensor)
    if path.suffix == ".json" or path.is_file():  # bounded (64 MiB) and nesting-checked, as every document
        return LidarSensor.from_dict(read_json(path, MAX_DOCUMENT_BYTES), path)
    return LidarSensor.preset(str(sensor))
