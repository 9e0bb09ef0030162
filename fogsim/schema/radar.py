"""The radar schema: a sensor (``presets/radar/*.json`` or a custom block), the radar fog model's parameters
and the outcome file beside a fogged sweep — every key's type, range and default, declared once, here.

:class:`RadarSensorSpec` is what :class:`fogsim.radar.sensors.RadarSensor` is built from; every parameter a
document gives must have a ``sources`` entry (a data sheet, a paper, or the words "assumed: …"), so a
number without its origin is refused. :class:`RadarFogSpec` is the fog record's ``radar`` block
(:class:`fogsim.radar.fog.RadarFogger`). Both are :class:`~fogsim.schema.base.Closed`.

Units: GHz, metres, degrees, m/s, dBm (power), dBi (antenna gain), dB (noise figure, SNR, gains), dBsm
(radar cross section), MHz (bandwidth), °C, g/m³ (liquid water), β in 1/km where the fog relation says so.
"""
from __future__ import annotations

import math
from typing import ClassVar

from pydantic import ConfigDict, Field, model_validator

from fogsim.schema.base import Bool, Closed, NonNegInt, Open, Text, number_in, pair
from fogsim.schema.documents import Vector
from fogsim.schema.lidar import MAX_SWEEP_RAYS, Mount, check_sources

#: the visibility–liquid-water relations a radar fog record may name (fogsim.radar.attenuation)
LWC_RELATIONS = ("kunkel-1984",)
#: the render's ray grid (fogsim.render.radar_scan.ray_grid): azimuth and elevation steps in degrees (the
#: azimuth step a tenth of the finest azimuth resolution when that is finer), the elevation half-FOV of a
#: sensor that gives none
RAY_STEP_DEG, ELEVATION_STEP_DEG, DEFAULT_HALF_ELEVATION_DEG = 0.1, 0.25, 7.0
#: the finest azimuth resolution a sensor may state: the clustering packs azimuth cells (360° of them) in 16 bits
MIN_AZIMUTH_RESOLUTION_DEG = 0.01
#: the most range cells (max range / range resolution) a scan may have: the clustering packs them in 16 bits
MAX_RANGE_CELLS = (1 << 16) - 1
#: fields of a sensor block that are bookkeeping, not parameters (they need no ``sources`` entry)
BOOKKEEPING = ("name", "description", "version", "sources")


def ray_grid_shape(azimuth_fov_deg, elevation_fov_deg, azimuth_resolutions_deg) -> tuple[int, int]:
    """(azimuth rays, elevation rays) of the render's ray grid over ``azimuth_fov_deg`` × ``elevation_fov_deg``
    ([lo, hi] degrees; None: ±:data:`DEFAULT_HALF_ELEVATION_DEG`): azimuth steps of :data:`RAY_STEP_DEG` or a
    tenth of the finest resolution, elevation steps of :data:`ELEVATION_STEP_DEG`."""
    (a0, a1) = (float(v) for v in azimuth_fov_deg)
    e0, e1 = (-DEFAULT_HALF_ELEVATION_DEG, DEFAULT_HALF_ELEVATION_DEG) if elevation_fov_deg is None else \
        (float(v) for v in elevation_fov_deg)
    da = min(RAY_STEP_DEG, min(float(r) for r in azimuth_resolutions_deg) / 10)
    return max(1, math.ceil((a1 - a0) / da)), max(1, math.ceil((e1 - e0) / ELEVATION_STEP_DEG))


class NearRange(Closed):
    """``near_range``: a second, wide and short scan of the same sensor (the ARS 408's near range)."""

    max_range_m: number_in(0, 2000, lo_open=True)
    azimuth_fov_deg: pair(number_in(-180, 180))
    range_resolution_m: number_in(0, 100, lo_open=True)
    range_accuracy_m: number_in(0, 100)
    azimuth_resolution_deg: number_in(0, 180, lo_open=True)
    azimuth_accuracy_deg: number_in(0, 180)


class RadarSensorSpec(Closed):
    """An automotive FMCW radar (``presets/radar/*.json`` or a custom block): what it sees (frequency,
    range, azimuth / elevation field of view — the far scan's, plus an optional ``near_range`` scan),
    how finely (resolutions, accuracies, velocity), and its radar equation (transmit power, antenna gains,
    noise figure, noise bandwidth, processing gain, detection threshold). ``processing_gain_db`` None:
    calibrated so a target of ``reference_rcs_dbsm`` at ``max_range_m`` is exactly at the threshold (the
    data sheets give the range, not the gain). ``sources``: one entry per parameter given (dotted names
    for nested keys, e.g. ``near_range.max_range_m``, or the block's name for all of it)."""

    name: Text | None = None
    description: Text | None = None
    version: NonNegInt | None = None
    frequency_ghz: number_in(1, 300)
    min_range_m: number_in(0, 100) = 0.2
    max_range_m: number_in(1, 2000)
    azimuth_fov_deg: pair(number_in(-180, 180))
    elevation_fov_deg: pair(number_in(-90, 90)) | None = None
    measures_elevation: Bool = False
    range_resolution_m: number_in(0, 100, lo_open=True)
    range_accuracy_m: number_in(0, 100)
    azimuth_resolution_deg: number_in(0, 180, lo_open=True)
    azimuth_accuracy_deg: number_in(0, 180)
    elevation_resolution_deg: number_in(0, 180, lo_open=True) | None = None
    elevation_accuracy_deg: number_in(0, 180) | None = None
    velocity_range_mps: pair(number_in(-1000, 1000))
    velocity_resolution_mps: number_in(0, 100, lo_open=True)
    velocity_accuracy_mps: number_in(0, 100)
    rcs_range_dbsm: pair(number_in(-100, 100)) = [-64.0, 64.0]
    transmit_power_dbm: number_in(-30, 60)
    tx_gain_dbi: number_in(-10, 50)
    rx_gain_dbi: number_in(-10, 50)
    noise_figure_db: number_in(0, 40)
    noise_bandwidth_mhz: number_in(0, 1e5, lo_open=True)
    processing_gain_db: number_in(0, 120) | None = None
    detection_threshold_db: number_in(-10, 60)
    reference_rcs_dbsm: number_in(-60, 60)
    false_alarms_per_scan: number_in(0, 1e4) = 0.0
    cycle_time_ms: number_in(0, 1e4, lo_open=True) | None = None
    near_range: NearRange | None = None
    mount: Mount = Mount()
    sources: dict[str, Text] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _consistent(self):
        if not self.min_range_m < self.max_range_m:
            raise ValueError(f"min_range_m ({self.min_range_m:g}) must be below max_range_m ({self.max_range_m:g})")
        if self.measures_elevation and (self.elevation_resolution_deg is None or self.elevation_fov_deg is None):
            raise ValueError("a sensor that measures elevation needs elevation_fov_deg and elevation_resolution_deg")
        if self.near_range is not None and self.near_range.max_range_m > self.max_range_m:
            raise ValueError("near_range.max_range_m must not exceed max_range_m (the far scan's)")
        check_sources(self, BOOKKEEPING)  # a document that gives parameters says where each comes from
        self._grids()
        return self

    def _grids(self) -> None:
        """The render's grids stay bounded: the ray grid (:func:`ray_grid_shape`) ≤ the LiDAR's
        :data:`~fogsim.schema.lidar.MAX_SWEEP_RAYS`, each scan's azimuth and range cells within the
        clustering's 16-bit packing."""
        scans = [("", self)] + ([("near_range.", self.near_range)] if self.near_range is not None else [])
        for where, scan in scans:
            if scan.azimuth_resolution_deg < MIN_AZIMUTH_RESOLUTION_DEG:
                raise ValueError(f"{where}azimuth_resolution_deg {scan.azimuth_resolution_deg:g} is finer than the "
                                 f"{MIN_AZIMUTH_RESOLUTION_DEG:g}° a sensor may resolve (an ARS 408 resolves 1.6°)")
            cells = scan.max_range_m / scan.range_resolution_m
            if cells > MAX_RANGE_CELLS:
                raise ValueError(f"{where}range_resolution_m {scan.range_resolution_m:g} m over {scan.max_range_m:g} m "
                                 f"is {cells:,.0f} range cells, more than the {MAX_RANGE_CELLS:,} a scan may have")
        az = list(self.azimuth_fov_deg)
        if self.near_range is not None:
            az = [min(az[0], self.near_range.azimuth_fov_deg[0]), max(az[1], self.near_range.azimuth_fov_deg[1])]
        na, ne = ray_grid_shape(az, self.elevation_fov_deg, [s.azimuth_resolution_deg for _, s in scans])
        if na * ne > MAX_SWEEP_RAYS:
            raise ValueError(f"azimuth_resolution_deg {min(s.azimuth_resolution_deg for _, s in scans):g} over "
                             f"{az[1] - az[0]:g}° makes a render cast {na:,} × {ne:,} = {na * ne:,} rays a sweep, "
                             f"more than the {MAX_SWEEP_RAYS:,} it may cast")


class RadarFogSpec(Closed):
    """``radar_fog`` (a fog record's ``radar`` block): the radar's part of the fog (:mod:`fogsim.radar.fog`).

    ``lwc_relation``: how the camera's β gives the fog's liquid water content M (g/m³) — ``kunkel-1984``:
    β = ``lwc_coefficient`` · M^``lwc_exponent`` (β in 1/km; Kunkel 1984: 144.7 and 0.88).
    ``temperature_c``: the fog's temperature for ITU-R P.840's K_l(f, T). ``lwc_g_m3``: a fixed M that
    overrides the relation (None: from β). ``detected_margin_db``: a detection the sweep holds was made in clear
    air, so an estimated SNR below threshold + margin is raised to it (a reported detection has some margin
    over the threshold; with none, every detection estimated at or below it would vanish at the first β > 0)."""

    lwc_relation: Text = "kunkel-1984"
    lwc_coefficient: number_in(0, 1e4, lo_open=True) = 144.7
    lwc_exponent: number_in(0, 10, lo_open=True) = 0.88
    temperature_c: number_in(-40, 40) = 10.0
    lwc_g_m3: number_in(0, 50) | None = None
    detected_margin_db: number_in(0, 30) = 1.0

    @model_validator(mode="after")
    def _relation(self):
        if self.lwc_relation not in LWC_RELATIONS:
            raise ValueError(f"lwc_relation must be one of {', '.join(LWC_RELATIONS)}, got {self.lwc_relation!r}")
        return self


class RadarOutcomes(Open):
    """``<name>.outcomes.npz`` beside a fogged sweep (:mod:`fogsim.radar.outcome_file`): per input detection
    its ``outcome`` (0 kept, 1 lost), ``output_index`` (its row in the fogged sweep, −1 when lost) and
    ``snr_fog_db`` (its SNR in the fog, dB), of equal length."""

    document: ClassVar[str] = "radar outcome file"

    model_config = ConfigDict(arbitrary_types_allowed=True, extra="ignore", frozen=True)

    outcome: Vector
    output_index: Vector
    snr_fog_db: Vector


__all__ = ["BOOKKEEPING", "DEFAULT_HALF_ELEVATION_DEG", "ELEVATION_STEP_DEG", "LWC_RELATIONS", "MAX_RANGE_CELLS",
           "MIN_AZIMUTH_RESOLUTION_DEG", "NearRange", "RAY_STEP_DEG", "RadarFogSpec", "RadarOutcomes",
           "RadarSensorSpec", "ray_grid_shape"]
