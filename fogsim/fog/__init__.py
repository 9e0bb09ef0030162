"""The fog engine: the fog record (:class:`FogSettings`: which model, airlight, space, kernel,
heterogeneity, scatter parameters — one record for every sensor), Koschmieder's law (standard and
extended form), the scatter model, fog levels, the depth a
sample brings (→ ray distance, its holes filled by :mod:`.fill`), and the batch runner that fogs
whole datasets.

Pure numpy + OpenCV: no bpy, torch or Ultralytics.
"""
from fogsim.fog.engine import FogSettings, Heterogeneity
from fogsim.fog.levels import (
                               FogLevel,
                               beta_from_visibility,
                               level_from_beta,
                               load_preset,
                               parse_levels,
                               visibility_from_beta,
)
from fogsim.fog.model import (
                               PAPER_KERNEL,
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
from fogsim.schema.vocabulary import KERNELS, SPACES

__all__ = ["FogLevel", "FogSettings", "Fogger", "Heterogeneity", "KERNELS", "Kernel", "PAPER_KERNEL", "SPACES",
           "airlight_rgb", "beta_from_visibility", "density_field", "estimate_airlight", "koschmieder",
           "koschmieder_extended", "level_from_beta", "load_preset", "parse_levels", "smooth_transmission",
           "transmission", "visibility_from_beta"]
