"""Radar detections as a first-class record, and what fog does to them.

Modules, bottom up: :mod:`.detections` (:class:`RadarScan`), :mod:`.formats` (nuScenes ``RADAR_*`` PCD,
``.npy``), :mod:`.sensors` (:class:`RadarSensor`, the bundled presets, the radar equation),
:mod:`.attenuation` (ITU-R P.840 and the visibility–liquid-water relation), :mod:`.fog` (:class:`RadarFogger`,
the outcomes), :mod:`.outcome_file` (the outcomes beside a fogged sweep).
Conventions: :mod:`.detections`; the model and its equations: ``docs/radar-fog.md``.
"""
from fogsim.radar.detections import KINDS, RadarScan
from fogsim.radar.fog import OUTCOMES, FoggedRadar, RadarFogger, fog_radar
from fogsim.radar.formats import RADAR_FORMATS, RADAR_SUFFIX, read_radar, write_radar
from fogsim.radar.sensors import RadarSensor, load_radar_sensor, radar_sensor_names

__all__ = ["FoggedRadar", "KINDS", "OUTCOMES", "RADAR_FORMATS", "RADAR_SUFFIX", "RadarFogger", "RadarScan",
           "RadarSensor", "fog_radar", "load_radar_sensor", "radar_sensor_names", "read_radar", "write_radar"]
