"""The fog engine: Koschmieder's law (standard and extended form), fog levels, the depth a
sample brings (→ ray distance, its holes filled by :mod:`.fill`), and the batch runner that fogs
whole datasets.

Pure numpy + OpenCV: no bpy, torch or Ultralytics.
"""
from fogsim.fog.levels import (
                               FogLevel,
                               beta_from_visibility,
                               level_from_beta,
                               load_preset,
                               parse_levels,
                               visibility_from_beta,
)
from fogsim.fog.model import (
                               KERNELS,
                               PAPER_KERNEL,
                               SPACES,
                               Fogger,
                               Kernel,
                               airlight_rgb,
                               density_field,
                               estimate_airlight,
                               koschmieder,
                               koschmieder_extended,
                               smooth_transmission,
                               transmission,
)

__all__ = ["FogLevel", "Fogger", "KERNELS", "Kernel", "PAPER_KERNEL", "SPACES", "airlight_rgb",
           "beta_from_visibility", "density_field", "estimate_airlight", "koschmieder", "koschmieder_extended",
           "level_from_beta", "load_preset", "parse_levels", "smooth_transmission", "transmission",
           "visibility_from_beta"]
