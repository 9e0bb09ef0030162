"""A quality preset (:class:`fogsim.schema.presets.Quality`) → the Cycles settings it asks for.

Pure Python, so what a preset renders with is testable without Blender; the schema holds every
default (a quality that omits ``bounces.transparent`` renders with the schema's 8), and
:func:`fogsim.render.blender.cycles.configure` only applies this record. Besides the preset's
keys the record holds fogsim's fixed choices: no volume bounces and no caustics in the clear
render (fog is added afterwards), indirect light clamped at 10 (fireflies).
"""
from __future__ import annotations

from fogsim.schema.base import check
from fogsim.schema.presets import Quality

#: Cycles settings fogsim fixes for every clear render (not preset keys).
FIXED = {"volume_bounces": 0, "caustics_reflective": False, "caustics_refractive": False,
         "sample_clamp_indirect": 10.0}


def quality_model(quality: dict | Quality, source=None) -> Quality:
    """``quality`` (a preset's block as given, or already checked) with every default filled in."""
    return quality if isinstance(quality, Quality) else check(quality, Quality, source, prefix="quality")


def cycles_settings(quality: dict | Quality, source=None) -> dict:
    """The ``scene.cycles`` attributes of a clear render at this quality, by their Blender names
    (``use_denoising`` is what the preset asks for; the renderer turns it off where Blender was
    built without OpenImageDenoise), plus ``denoising_quality`` / ``denoising_prefilter`` for
    :func:`fogsim.render.blender.compat.set_denoiser_speed`."""
    q = quality_model(quality, source)
    b = q.bounces
    return {"samples": q.samples, "use_adaptive_sampling": q.adaptive_threshold > 0,
            "adaptive_threshold": q.adaptive_threshold, "use_denoising": q.denoise,
            "denoising_quality": q.denoise_quality, "denoising_prefilter": q.denoise_prefilter,
            "max_bounces": b.total, "diffuse_bounces": b.diffuse, "glossy_bounces": b.glossy,
            "transmission_bounces": b.transmission, "transparent_max_bounces": b.transparent, **FIXED}
