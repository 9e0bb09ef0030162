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
#: the LiDAR fog models: the full LiDAR equation with the fog's own echo, attenuation + threshold alone, and
#: the two published models (Hahner et al. 2021's released code: fogsim.lidar.hahner2021; the STF authors'
#: chamber-fitted rule, Bijelic et al. 2020: fogsim.lidar.stf2020)
LIDAR_FOG_MODELS = ("soft-target", "attenuation", "hahner2021", "stf2020")
#: hahner2021's variants: the released code's batch path (the backscatter frozen at α 0.06) or its viewer's
HAHNER_VARIANTS = ("batch", "viewer")
#: stf2020's β: one β for every ray (one fog for every sensor) or the STF authors' random β field
STF_BETA_FIELDS = ("homogeneous", "random")
BACKSCATTER_RULES = ("visibility", "lidar-ratio")
#: the visibility rule's default: backscatter β_b = 0.046 / V sr⁻¹ (V = ln 20 / β, the camera's visibility)
BACKSCATTER_PER_VISIBILITY = 0.046
#: half an 8-bit step of the normalised intensity: a detected return whose intensity falls by less is "kept"
KEPT_TOLERANCE = 0.5 / 255
#: the per-ray, per-pulse signal fluctuation's default σ (of its natural log): see LidarSensorSpec
FLUCTUATION_SIGMA = 0.5
#: the most rays one sweep may fire (beams × azimuth steps; a render casts each, the fog model's empty-ray
#: grid holds each): 4 × the densest spinning LiDAR sold (128 beams at 0.1°: 460,800)
MAX_SWEEP_RAYS = 2_000_000
#: the named calibrations ``--lidar-calibration`` chooses between (or a file: :class:`LidarCalibration`);
#: ``reference`` is the deprecated name of ``hahner-constants`` (:data:`DEPRECATED_CALIBRATIONS`)
CALIBRATIONS = ("datasheet", "hahner-constants", "reference")
#: old calibration names still read, and the name each now has (the old one promised the reference
#: simulator's behaviour; it is Hahner et al.'s pulse and overlap constants inside fogsim's own model)
DEPRECATED_CALIBRATIONS = {"reference": "hahner-constants"}
#: the constants Hahner et al. (ICCV 2021, "Fog Simulation on Real LiDAR Point Clouds") publish for their
#: HDL-64, applied over any sensor by the ``hahner-constants`` calibration; each with its source
HAHNER_CONSTANTS = {
    "name": "hahner-constants",
    "pulse_half_power_ns": 20.0,
    "overlap_full_m": 1.0,
    "sources": {
        "pulse_half_power_ns": "Hahner et al. 2021, sec. 3 (the transmitted sin² pulse, half-power width 20 ns)",
        "overlap_full_m": "Hahner et al. 2021, sec. 3 (beam and receiver fully overlap from about 1 m)",
    },
}
#: the deprecated name of :data:`HAHNER_CONSTANTS`
REFERENCE_CALIBRATION = HAHNER_CONSTANTS
#: the sensor keys a calibration may set
CALIBRATION_KEYS = ("min_range_m", "max_range_m", "reference_reflectivity", "pulse_half_power_ns", "overlap_full_m",
                    "fog_echo_scale", "fluctuation_sigma", "range_noise_m", "range_noise_at_threshold_m",
                    "reflectivity_per_intensity", "intensity_range_exponent", "intensity_reference_range_m",
                    "retro_reflectivity_max", "stf_noise_level", "stf_gain")

_INCLINATIONS = 'a list of beam inclinations in degrees or "calibration" (read from the data)'
Inclinations = Annotated[Annotated[word("calibration", _INCLINATIONS), Tag("<calibration>")]
                         | Annotated[Annotated[list[number_in(-90, 90)], Field(min_length=1)], Tag("<list>")],
                         by_type({"<calibration>": lambda v: isinstance(v, str), "<list>": is_list}, _INCLINATIONS)]


def check_sources(model, bookkeeping: tuple[str, ...], what: str = "the sensor") -> None:
    """Every parameter a document gives (its fields set, less ``bookkeeping``) has a ``sources`` entry (dotted
    names for nested keys, or the block's name), and every entry names a parameter: a number without its
    origin is refused (a ValueError, the schema's one line)."""
    given = model.model_fields_set - set(bookkeeping)
    sources = model.sources or {}
    if not given:
        return

    def sourced(key: str) -> bool:
        return key in sources or any(s.startswith(key + ".") for s in sources)
    missing = sorted(k for k in given if not sourced(k))
    if missing:
        raise ValueError(f"sources: no entry for {', '.join(missing)} (every parameter says where it comes "
                         "from: a data sheet, a paper, or 'assumed: why')")
    known = set(type(model).model_fields) - set(bookkeeping)
    unknown = sorted(k for k in sources if k.split(".")[0] not in known)
    if unknown:
        raise ValueError(f"sources: {', '.join(unknown)} is not a parameter of {what}")


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
    # a factor on the fog echo's signal (fogsim.lidar.soft_target): 1 = the LiDAR equation with the backscatter
    # rule as it is; a calibration fitted to real fog (fogsim lidar-fit) sets it
    fog_echo_scale: number_in(0, 1e6) = 1.0
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
    # the STF authors' chamber-fitted noise level n and gain g (stf2020; None: not published for this sensor)
    stf_noise_level: number_in(0, 1, lo_open=True) | None = None
    stf_gain: number_in(0, 10, lo_open=True) | None = None
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
        steps = self.steps_per_sweep or max(1, round(self.horizontal_fov_deg / self.horizontal_resolution_deg))
        if self.beams * steps > MAX_SWEEP_RAYS:
            given = (f"steps_per_sweep {steps:,}" if self.steps_per_sweep else
                     f"horizontal_resolution_deg {self.horizontal_resolution_deg:g} over "
                     f"{self.horizontal_fov_deg:g}°: {steps:,} steps")
            raise ValueError(f"{self.beams} beams × {given} = {self.beams * steps:,} rays a sweep, more than the "
                             f"{MAX_SWEEP_RAYS:,} a sweep may fire (128 beams at 0.1° fire 460,800)")
        if not self.min_range_m < self.max_range_m:
            raise ValueError(f"min_range_m ({self.min_range_m:g}) must be below max_range_m ({self.max_range_m:g})")
        if not self.overlap_full_m < self.max_range_m:
            raise ValueError(f"overlap_full_m ({self.overlap_full_m:g}) must be below max_range_m "
                             f"({self.max_range_m:g}): the threshold is calibrated at full overlap")
        return self


class LidarCalibration(Closed):
    """A calibration file (``--lidar-calibration FILE``): sensor parameters that replace the preset's
    (any of :data:`CALIBRATION_KEYS`, units as in :class:`LidarSensorSpec`), with a ``name`` and the
    ``sources`` of its values (key → source): every value it gives has one, and every source names a value
    (:func:`check_sources`, the radar sensor's rule)."""

    name: Text | None = None
    description: Text | None = None
    sources: dict[str, Text] | None = None
    min_range_m: number_in(0, 100) | None = None
    max_range_m: number_in(1, 2000) | None = None
    reference_reflectivity: number_in(0, 100, lo_open=True) | None = None
    pulse_half_power_ns: number_in(0.1, 1000) | None = None
    overlap_full_m: number_in(0, 100) | None = None
    fog_echo_scale: number_in(0, 1e6) | None = None
    fluctuation_sigma: number_in(0, 3) | None = None
    range_noise_m: number_in(0, 10) | None = None
    range_noise_at_threshold_m: number_in(0, 100) | None = None
    reflectivity_per_intensity: number_in(0, 1e6, lo_open=True) | None = None
    intensity_range_exponent: number_in(0, 4) | None = None
    intensity_reference_range_m: number_in(0, 1e4, lo_open=True) | None = None
    retro_reflectivity_max: number_in(1, 1e6) | None = None
    stf_noise_level: number_in(0, 1, lo_open=True) | None = None
    stf_gain: number_in(0, 10, lo_open=True) | None = None

    @model_validator(mode="after")
    def _sourced(self):
        check_sources(self, ("name", "description", "sources"), "a calibration")
        return self

    def overrides(self) -> dict:
        """The sensor parameters this calibration sets (the keys given)."""
        return {k: getattr(self, k) for k in CALIBRATION_KEYS if getattr(self, k) is not None}


_CALIBRATION = f'one of {", ".join(CALIBRATIONS)} or a calibration block'
Calibration = Annotated[Annotated[Literal[CALIBRATIONS], Tag("<name>")] | Annotated[LidarCalibration, Tag("<block>")],
                        by_type({"<name>": lambda v: isinstance(v, str), "<block>": is_object}, _CALIBRATION)]


class LidarFogSpec(Closed):
    """``lidar_fog``: the LiDAR fog model (:mod:`fogsim.lidar.fog`) and its parameters.

    ``model``: ``soft-target`` (two-way attenuation + the fog's own echo + threshold + return mode),
    ``attenuation`` (attenuation + threshold, no fog echo), ``hahner2021`` (Hahner et al. 2021's released code
    as it fogs datasets, :mod:`fogsim.lidar.hahner2021`; ``hahner_variant`` ``viewer``: its viewer's backscatter)
    or ``stf2020`` (the STF authors' chamber-fitted rule, :mod:`fogsim.lidar.stf2020`; ``stf_beta_field``
    ``random``: their random β field over the level's β). ``backscatter_rule``: ``visibility``
    (β_b = ``backscatter_coefficient`` / V, V = ln 20 / β the camera's visibility) or ``lidar-ratio``
    (β_b = β_905 / ``lidar_ratio_sr``). ``extinction_ratio``: β at 905 nm / β in the visible (1 for fog
    droplets much larger than the wavelength). ``return_mode``: overrides the sensor's. ``reflectivity_floor``:
    the darkest reflectivity an estimate may give. ``kept_tolerance``: a detected return whose normalised
    intensity falls by less than this is reported unchanged (``kept``). ``calibration``: the sensor
    parameters used — ``datasheet`` (the preset's own values, each with its source), ``hahner-constants``
    (Hahner et al. 2021's pulse and overlap constants over them, in fogsim's model: :data:`HAHNER_CONSTANTS`;
    ``reference`` is its deprecated name) or a :class:`LidarCalibration` block."""

    model: Literal[LIDAR_FOG_MODELS] = "soft-target"
    backscatter_rule: Literal[BACKSCATTER_RULES] = "visibility"
    backscatter_coefficient: number_in(0, 100) = BACKSCATTER_PER_VISIBILITY
    lidar_ratio_sr: number_in(0, 1e4, lo_open=True) = math.log(20.0) / BACKSCATTER_PER_VISIBILITY
    extinction_ratio: number_in(0, 100, lo_open=True) = 1.0
    return_mode: Literal[RETURN_MODES] | None = None
    reflectivity_floor: number_in(0, 10) = 0.02
    kept_tolerance: number_in(0, 1) = KEPT_TOLERANCE
    calibration: Calibration = "datasheet"
    hahner_variant: Literal[HAHNER_VARIANTS] = "batch"
    stf_beta_field: Literal[STF_BETA_FIELDS] = "homogeneous"


class LidarOutcomes(Open):
    """``<frame>.outcomes.npz`` beside a fogged scan (:mod:`fogsim.lidar.outcome_file`): per input point
    its ``outcome`` (0 kept, 1 attenuated, 2 lost, 3 clutter, 4 no-return) and ``output_index`` (its row in the
    fogged scan, −1 when lost), of equal length."""

    document: ClassVar[str] = "LiDAR outcome file"

    model_config = ConfigDict(arbitrary_types_allowed=True, extra="ignore", frozen=True)

    outcome: Vector
    output_index: Vector


__all__ = ["BACKSCATTER_PER_VISIBILITY", "BACKSCATTER_RULES", "CALIBRATIONS", "CALIBRATION_KEYS",
           "DEPRECATED_CALIBRATIONS", "FLUCTUATION_SIGMA", "HAHNER_CONSTANTS", "HAHNER_VARIANTS",
           "KEPT_TOLERANCE", "LIDAR_FOG_MODELS", "LidarCalibration", "LidarFogSpec", "LidarOutcomes", "LidarSensorSpec",
           "MAX_SWEEP_RAYS", "Mount", "REFERENCE_CALIBRATION", "RETURN_MODES", "SCALES", "STF_BETA_FIELDS",
           "check_sources"]
