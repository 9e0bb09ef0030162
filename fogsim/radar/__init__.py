"""Radar detections as a first-class record, and what fog does to them.

Modules, bottom up: :mod:`.detections` (:class:`RadarScan`), :mod:`.formats` (nuScenes ``RADAR_*`` PCD,
``.npy``), :mod:`.sensors` (:class:`RadarSensor`, the bundled presets, the radar equation).
Conventions: :mod:`.detections`; the model and its equations: ``docs/radar-fog.md``.
"""
from fogsim.radar.detections import KINDS, RadarScan
from fogsim.radar.formats import RADAR_FORMATS, RADAR_SUFFIX, read_radar, write_radar
from fogsim.radar.sensors import RadarSensor, load_radar_sensor, radar_sensor_names

__all__ = ["KINDS", "RADAR_FORMATS", "RADAR_SUFFIX", "RadarScan", "RadarSensor", "load_radar_sensor",
           "radar_sensor_names", "read_radar", "write_radar"]
