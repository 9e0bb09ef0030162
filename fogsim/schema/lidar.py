"""The LiDAR schema: a sensor (``presets/lidar/*.json`` or a custom block) and the LiDAR fog model's
parameters — every key's type, range and default, declared once, here.

:class:`LidarSensorSpec` is what :class:`fogsim.lidar.sensors.LidarSensor` is built from
(``LidarSensor.from_dict``); :class:`LidarFogSpec` is the block a preset or a fog record carries for
:class:`fogsim.lidar.fog.LidarFogger`. Both are :class:`~fogsim.schema.base.Closed`: an unknown key is
refused, naming the allowed ones; a bad value is one line ``FIELD: problem (got VALUE)``.

Units: metres, degrees, nanoseconds, β in 1/m, reflectivities as fractions (1 = a white Lambertian
target), backscatter coefficients per steradian. Conventions of the sensor frame and the intensity
scales: :mod:`fogsim.lidar.points`, :mod:`fogsim.lidar.scales`.
"""
from __future__ import annotations

import math
from typing import Annotated, ClassVar, Literal

from pydantic import ConfigDict, Field, Tag, model_validator

from fogsim.schema.base import (
    Closed,
    NonNegInt,
    Number,
    Open,
    Text,
    by_type,
    int_in,
    is_list,
    is_object,
    items,
    number_in,
    pair,
    word,
)
from fogsim.schema.documents import Vector

#: the intensity scales (their conversions: fogsim.lidar.scales)
SCALES = ("0-1", "0-255", "tanh")
RETURN_MODES = ("strongest", "last")
#: the LiDAR fog models: the full LiDAR equation with the fog's own echo, and attenuation + threshold alone
LIDAR_FOG_MODELS = ("soft-target", "attenuation")
BACKSCATTER_RULES = ("visibility", "lidar-ratio")
#: the visibility rule's default: backscatter β_b = 0.046 / V sr⁻¹ (V = ln 20 / β, the camera's visibility)
BACKSCATTER_PER_VISIBILITY = 0.046
#: half an 8-bit step of the normalised intensity: a detected return whose intensity falls by less is "kept"
KEPT_TOLERANCE = 0.5 / 255
#: the per-ray, per-pulse signal fluctuation's default σ (of its natural log): see LidarSensorSpec
FLUCTUATION_SIGMA = 0.5
#: the named calibrations ``--lidar-calibration`` chooses between (or a file: :class:`LidarCalibration`)
CALIBRATIONS = ("datasheet", "reference")
#: the constants Hahner et al. (ICCV 2021, "Fog Simulation on Real LiDAR Point Clouds") publish for their
#: HDL-64, applied over any sensor by the ``reference`` calibration; each with its source
REFERENCE_CALIBRATION = {
    "name": "reference",
    "pulse_half_power_ns": 20.0,
    "overlap_full_m": 1.0,
    "sources": {
        "pulse_half_power_ns": "Hahner et al. 2021, sec. 3 (the transmitted sin² pulse, half-power width 20 ns)",
        "overlap_full_m": "Hahner et al. 2021, sec. 3 (beam and receiver fully overlap from about 1 m)",
    },
}
#: the sensor keys a calibration may set
CALIBRATION_KEYS = ("min_range_m", "max_range_m", "reference_reflectivity", "pulse_half_power_ns", "overlap_full_m",
                    "fluctuation_sigma", "range_noise_m", "range_noise_at_threshold_m", "reflectivity_per_intensity",
                    "intensity_range_exponent", "intensity_reference_range_m", "retro_reflectivity_max")

_INCLINATIONS = 'a list of beam inclinations in degrees or "calibration" (read from the data)'
Inclinations = Annotated[Annotated[word("calibration", _INCLINATIONS), Tag("<calibration>")]
                         | Annotated[Annotated[list[number_in(-90, 90)], Field(min_length=1)], Tag("<list>")],
                         by_type({"<calibration>": lambda v: isinstance(v, str), "<list>": is_list}, _INCLINATIONS)]


class Mount(Closed):
    """``mount``: the sensor's pose in the ego vehicle's frame (x forward, y left, z up, metres;
    roll, pitch, yaw in degrees, R = Rz(yaw)·Ry(pitch)·Rx(roll)): p_ego = R·p_sensor + xyz."""

    xyz_m: items(Number, 3, "[x, y, z] list") = [0.0, 0.0, 0.0]
    rpy_deg: items(number_in(-360, 360), 3, "[roll, pitch, yaw] list") = [0.0, 0.0, 0.0]


class LidarSensorSpec(Closed):
    """A spinning LiDAR (``presets/lidar/*.json``, or a custom block): its geometry, its detection
    threshold (``max_range_m`` reached by a target of ``reference_reflectivity`` in clear air), its pulse
    and overlap, range noise, return mode, and how its intensity relates to reflectivity
    (ρ = ``reflectivity_per_intensity`` · I_linear · (R / ``intensity_reference_range_m``)^k with k =
    ``intensity_range_exponent``; k = 0: the sensor already reports a range-compensated reflectivity; above
    ``retro_reflective_from`` the scale is Velodyne's retro-reflector range, log-linear up to
    ``retro_reflectivity_max``: :meth:`fogsim.lidar.sensors.LidarSensor.reflectivity_of`)."""

    name: Text | None = None
    description: Text | None = None
    version: NonNegInt | None = None
    beams: int_in(1, 1024)
    vertical_fov_deg: pair(number_in(-90, 90)) | None = None  # [lowest, highest] beam, uniform between
    inclinations_deg: Inclinations | None = None  # explicit beams (any order) or "calibration"
    # each beam's vertical offset (m, Velodyne's vertOffsetCorrection), in the order of inclinations_deg: the
    # beam's line passes this far from the origin, so a point's elevation is the beam's + asin(offset / range)
    vertical_offsets_m: Annotated[list[number_in(-1, 1)], Field(min_length=1)] | None = None
    horizontal_fov_deg: number_in(0, 360, lo_open=True) = 360.0
    horizontal_resolution_deg: number_in(0, 10, lo_open=True) | None = None
    steps_per_sweep: int_in(1, 1_000_000) | None = None
    min_range_m: number_in(0, 100) = 1.0
    max_range_m: number_in(1, 2000)
    reference_reflectivity: number_in(0, 100, lo_open=True) = 0.8
    pulse_half_power_ns: number_in(0.1, 1000) = 10.0  # τ_H: the sin² pulse's full width at half power
    overlap_full_m: number_in(0, 100) = 5.0  # ξ(R) = min(1, (R / this)²); 0 = full overlap everywhere
    range_noise_m: number_in(0, 10) = 0.02  # 1σ at high signal
    range_noise_at_threshold_m: number_in(0, 100) = 0.10  # 1σ added at the detection threshold (see fog model)
    return_mode: Literal[RETURN_MODES] = "strongest"
    intensity_scale: Literal[SCALES]
    reflectivity_per_intensity: number_in(0, 1e6, lo_open=True) = 1.0
    intensity_range_exponent: number_in(0, 4) = 0.0
    intensity_reference_range_m: number_in(0, 1e4, lo_open=True) = 1.0
    # Velodyne's calibrated reflectivity: linear intensities above this are retro-reflectors (None: none)
    retro_reflective_from: number_in(0, 1, lo_open=True, hi_open=True) | None = None
    retro_reflectivity_max: number_in(1, 1e6) = 100.0  # the equivalent reflectivity of the top of the scale
    # σ of ln g, g the received-signal factor of one ray's pulse (pulse-energy jitter, beam-to-beam gain)
    fluctuation_sigma: number_in(0, 3) = FLUCTUATION_SIGMA
    mount: Mount = Mount()
    sources: dict[str, Text] | None = None  # where each parameter's value comes from (key → source)

    @model_validator(mode="after")
    def _consistent(self):
        if (self.vertical_fov_deg is None) == (self.inclinations_deg is None):
            raise ValueError("needs exactly one of 'vertical_fov_deg' ([lowest, highest] beam) and "
                             "'inclinations_deg' (a list, or \"calibration\")")
        if isinstance(self.inclinations_deg, list) and len(self.inclinations_deg) != self.beams:
            raise ValueError(f"inclinations_deg has {len(self.inclinations_deg)} values for {self.beams} beams")
        if self.vertical_offsets_m is not None and (not isinstance(self.inclinations_deg, list)
                                                     or len(self.vertical_offsets_m) != self.beams):
            raise ValueError(f"vertical_offsets_m needs inclinations_deg as a list and one offset per beam "
                             f"({self.beams}), got {len(self.vertical_offsets_m)}")
        if (self.horizontal_resolution_deg is None) == (self.steps_per_sweep is None):
            raise ValueError("needs exactly one of 'horizontal_resolution_deg' and 'steps_per_sweep'")
        if not self.min_range_m < self.max_range_m:
            raise ValueError(f"min_range_m ({self.min_range_m:g}) must be below max_range_m ({self.max_range_m:g})")
        if not self.overlap_full_m < self.max_range_m:
            raise ValueError(f"overlap_full_m ({self.overlap_full_m:g}) must be below max_range_m "
                             f"({self.max_range_m:g}): the threshold is calibrated at full overlap")
        return self


class LidarCalibration(Closed):
    """A calibration file (``--lidar-calibration FILE``): sensor parameters that replace the preset's
    (any of :data:`CALIBRATION_KEYS`, units as in :class:`LidarSensorSpec`), with a ``name`` and the
    ``sources`` of its values (key → source)."""

    name: Text | None = None
    description: Text | None = None
    sources: dict[str, Text] | None = None
    min_range_m: number_in(0, 100) | None = None
    max_range_m: number_in(1, 2000) | None = None
    reference_reflectivity: number_in(0, 100, lo_open=True) | None = None
    pulse_half_power_ns: number_in(0.1, 1000) | None = None
    overlap_full_m: number_in(0, 100) | None = None
    fluctuation_sigma: number_in(0, 3) | None = None
    range_noise_m: number_in(0, 10) | None = None
    range_noise_at_threshold_m: number_in(0, 100) | None = None
    reflectivity_per_intensity: number_in(0, 1e6, lo_open=True) | None = None
    intensity_range_exponent: number_in(0, 4) | None = None
    intensity_reference_range_m: number_in(0, 1e4, lo_open=True) | None = None
    retro_reflectivity_max: number_in(1, 1e6) | None = None

    def overrides(self) -> dict:
        """The sensor parameters this calibration sets (the keys given)."""
        return {k: getattr(self, k) for k in CALIBRATION_KEYS if getattr(self, k) is not None}


_CALIBRATION = f'one of {", ".join(CALIBRATIONS)} or a calibration block'
Calibration = Annotated[Annotated[Literal[CALIBRATIONS], Tag("<name>")] | Annotated[LidarCalibration, Tag("<block>")],
                        by_type({"<name>": lambda v: isinstance(v, str), "<block>": is_object}, _CALIBRATION)]


class LidarFogSpec(Closed):
    """``lidar_fog``: the LiDAR fog model (:mod:`fogsim.lidar.fog`) and its parameters.

    ``model``: ``soft-target`` (two-way attenuation + the fog's own echo + threshold + return mode) or
    ``attenuation`` (attenuation + threshold, no fog echo). ``backscatter_rule``: ``visibility``
    (β_b = ``backscatter_coefficient`` / V, V = ln 20 / β the camera's visibility) or ``lidar-ratio``
    (β_b = β_905 / ``lidar_ratio_sr``). ``extinction_ratio``: β at 905 nm / β in the visible (1 for fog
    droplets much larger than the wavelength). ``return_mode``: overrides the sensor's. ``reflectivity_floor``:
    the darkest reflectivity an estimate may give. ``kept_tolerance``: a detected return whose normalised
    intensity falls by less than this is reported unchanged (``kept``). ``calibration``: the sensor
    parameters used — ``datasheet`` (the preset's own values, each with its source), ``reference`` (the
    constants of Hahner et al. 2021 over them: :data:`REFERENCE_CALIBRATION`) or a
    :class:`LidarCalibration` block."""

    model: Literal[LIDAR_FOG_MODELS] = "soft-target"
    backscatter_rule: Literal[BACKSCATTER_RULES] = "visibility"
    backscatter_coefficient: number_in(0, 100) = BACKSCATTER_PER_VISIBILITY
    lidar_ratio_sr: number_in(0, 1e4, lo_open=True) = math.log(20.0) / BACKSCATTER_PER_VISIBILITY
    extinction_ratio: number_in(0, 100, lo_open=True) = 1.0
    return_mode: Literal[RETURN_MODES] | None = None
    reflectivity_floor: number_in(0, 10) = 0.02
    kept_tolerance: number_in(0, 1) = KEPT_TOLERANCE
    calibration: Calibration = "datasheet"


class LidarOutcomes(Open):
    """``<frame>.outcomes.npz`` beside a fogged scan (:mod:`fogsim.lidar.outcome_file`): per input point
    its ``outcome`` (0 kept, 1 attenuated, 2 lost, 3 clutter, 4 no-return) and ``output_index`` (its row in the
    fogged scan, −1 when lost), of equal length."""

    document: ClassVar[str] = "LiDAR outcome file"

    model_config = ConfigDict(arbitrary_types_allowed=True, extra="ignore", frozen=True)

    outcome: Vector
    output_index: Vector


__all__ = ["BACKSCATTER_PER_VISIBILITY", "BACKSCATTER_RULES", "CALIBRATIONS", "CALIBRATION_KEYS", "FLUCTUATION_SIGMA",
           "KEPT_TOLERANCE", "LIDAR_FOG_MODELS", "LidarCalibration", "LidarFogSpec", "LidarOutcomes", "LidarSensorSpec",
           "Mount", "REFERENCE_CALIBRATION", "RETURN_MODES", "SCALES"]
