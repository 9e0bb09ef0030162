"""fogsim — labeled images in fog: Koschmieder fog for rendered and real datasets.

The public fog API is re-exported here::

    from fogsim import koschmieder, Fogger, Kernel, Intrinsics, planar_to_ray, load_preset

Subpackages, one per concern (CONTRIBUTING.md draws their layers):
``fog`` (the engine and its hole fill), ``readers`` (Waymo, Cityscapes, folders), ``scene``
(procedural street scenes), ``dataset`` (fogsim's on-disk format and its COCO record), ``render``
(frames → dataset; ``render.blender`` is the only code that imports bpy), ``depth`` (stereo, ILA,
LiDAR completion, metrics), ``detection`` (YOLO training, COCO evaluation, the cross-density
study), ``bench`` (the benchmarks) and ``cli``.
"""

from fogsim._version import __version__
from fogsim.camera import Intrinsics, StereoCamera, planar_to_ray
from fogsim.fog import (
                        Fogger,
                        FogLevel,
                        FogSettings,
                        Kernel,
                        beta_from_visibility,
                        estimate_airlight,
                        koschmieder,
                        koschmieder_extended,
                        load_preset,
                        parse_levels,
                        transmission,
                        visibility_from_beta,
)

__all__ = ["__version__", "FogLevel", "FogSettings", "Fogger", "Intrinsics", "Kernel", "StereoCamera",
           "beta_from_visibility", "estimate_airlight", "koschmieder", "koschmieder_extended", "load_preset",
           "parse_levels", "planar_to_ray", "transmission", "visibility_from_beta"]
