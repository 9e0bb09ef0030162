"""The preset's ``fog_model`` block turned into what the renderer uses (pure Python, no bpy).

``fog_model.kind`` is one of :data:`fogsim.schema.vocabulary.FOG_KINDS`: ``"koschmieder"`` (the
default) and ``"scatter"`` are added after rendering, from the clear render and its depth, by the
fog record :func:`fog_settings` returns (:class:`fogsim.fog.engine.FogSettings`); ``"volumetric"``
is fog path-traced by Cycles in a participating medium (:mod:`fogsim.render.blender.fog_volume`,
settings in ``fog_model.volumetric``, see :func:`volumetric_settings`). Every key's type, range
and default is declared in :class:`fogsim.schema.presets.FogModel` (and ``Volumetric``); both
blocks are checked whichever kind is chosen, so ``--fog`` / ``--fog-medium``
(:func:`fog_overrides`) can switch models on any preset.

Units: β in 1/m (from the preset's fog levels, not from here); lengths in metres; airlight in
8-bit units [0, 255]; volumetric emission in scene-linear radiance. A problem is an
:class:`~fogsim.errors.InputError` naming the preset and the key (``fog_model.…``).
"""
from __future__ import annotations

from fogsim.fog.engine import FogSettings
from fogsim.schema.base import check
from fogsim.schema.presets import DAY_SKY_STRENGTH, MAX_FOG_EXTENT_M, FogModel, Volumetric

__all__ = ["VOLUMETRIC_DEFAULTS", "fog_model", "fog_overrides", "fog_settings", "frame_volumetric",
           "volumetric_settings"]

#: Defaults of ``fog_model.volumetric`` (declared in :class:`fogsim.schema.presets.Volumetric`).
VOLUMETRIC_DEFAULTS = Volumetric().model_dump()


def fog_overrides(fog_model: dict, fog: str | None, medium: str | None, scale: float | None = None) -> dict:
    """The preset's fog_model with ``--fog`` (a kind), ``--fog-medium`` (a medium) and
    ``--fog-scale`` (the fog renders' resolution_scale) applied, as a new dict (either of the last
    two implies ``--fog volumetric``); the values are checked by the caller."""
    fog_model = dict(fog_model)
    given = {k: v for k, v in (("medium", medium), ("resolution_scale", scale)) if v is not None}
    if given:
        fog = "volumetric"
        spec = fog_model.get("volumetric", {})
        fog_model["volumetric"] = {**(spec if isinstance(spec, dict) else {}), **given}
    if fog is not None:
        fog_model["kind"] = fog
    return fog_model


def fog_model(config) -> FogModel:
    """A :class:`~fogsim.render.preset.RenderConfig`'s ``fog_model`` checked, defaults filled in."""
    return check(config.fog_model, FogModel, config.source, prefix="fog_model")


def fog_settings(config) -> FogSettings:
    """A RenderConfig's ``fog_model`` as the fog record (:class:`fogsim.fog.engine.FogSettings`:
    kind ``"scatter"`` always blends linear light, where it was fitted; ``space`` is Koschmieder's).

    Checks the whole block, the volumetric part included."""
    return FogSettings.from_preset(fog_model(config))


def volumetric_settings(config) -> dict | None:
    """``fog_model.volumetric`` of a RenderConfig with every default filled in, or None for
    Koschmieder fog. ``extent_m`` None becomes max(400, 12/β_min) m, capped at
    :data:`MAX_FOG_EXTENT_M` (β_min: the smallest β > 0 of ``config.levels``). Checked (an
    InputError naming the preset and the key)."""
    m = fog_model(config)
    if m.kind != "volumetric":  # the volumetric block is still checked, so --fog can switch models
        return None
    settings = m.volumetric.model_dump()
    if settings["extent_m"] is None:
        betas = [lv.beta for lv in config.levels if lv.beta > 0]
        settings["extent_m"] = min(MAX_FOG_EXTENT_M, max(400.0, 12.0 / min(betas))) if betas else 400.0
    return settings


def frame_volumetric(settings: dict, desc: dict) -> dict:
    """The volumetric settings of one frame: ``emission: "sky"`` becomes the frame's sky
    strength (``desc["lighting"]["sky_strength"]``: 0.3 by day, 0.01 at night), so the
    emitting part of a hybrid medium follows the scene's light instead of glowing white at night."""
    if settings.get("emission") != "sky":
        return settings
    light = desc.get("lighting")  # a user's scene (scene mode) has no lighting record: the default day's
    return {**settings, "emission": float(light["sky_strength"] if light else DAY_SKY_STRENGTH)}
