"""LiDAR scans as a first-class record, and what fog does to them.

Modules, bottom up: :mod:`.scales` (intensity scales), :mod:`.points` (:class:`PointCloud`), :mod:`.formats`
(KITTI/nuScenes/STF ``.bin``, PLY, ``.npy``), :mod:`.sensors` (:class:`LidarSensor`, the bundled presets),
:mod:`.rays` (a sweep's rays without a return), :mod:`.soft_target` (the fog's own echo), :mod:`.outcomes` (the
outcome codes every model shares), :mod:`.laser_line` (points on their laser's own line), :mod:`.fogged_scan`
(:class:`FoggedScan`, one level, and its assembly), :mod:`.fog` (:class:`LidarFogger`, the outcomes),
:mod:`.soft_target_model` (the default models' levels), :mod:`.outcome_file` (the outcomes beside a fogged scan),
:mod:`.reference` (the per-point transcription), :mod:`.hahner` (Hahner et al. 2021's simulation from its paper),
:mod:`.hahner2021` and :mod:`.stf2020` (the published models as fog models: Hahner et al.'s released code, the STF
authors' chamber-fitted rule), :mod:`.boxes` (points in 3D boxes), :mod:`.objects` (per-object counts and the
cross-sensor table), :mod:`.pictures` (bird's-eye views).
Conventions: :mod:`.points`; the model and its equations: :mod:`.fog` and ``docs/lidar-fog.md``.
"""
from fogsim.lidar.fog import LidarFogger, fog_scan
from fogsim.lidar.fogged_scan import FoggedScan
from fogsim.lidar.formats import FORMATS, read_points, write_points
from fogsim.lidar.outcomes import OUTCOMES
from fogsim.lidar.points import PointCloud
from fogsim.lidar.sensors import LidarSensor, load_sensor, sensor_names

__all__ = ["FORMATS", "OUTCOMES", "FoggedScan", "LidarFogger", "LidarSensor", "PointCloud", "fog_scan", "load_sensor",
           "read_points", "sensor_names", "write_points"]
