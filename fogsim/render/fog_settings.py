"""The preset's ``fog_model`` block: which fog model, and its settings (pure Python, no bpy).

``fog_model.kind`` is ``"koschmieder"`` (the default: fog added after rendering by
:class:`fogsim.fog.model.Fogger`, see :func:`fog_settings`) or ``"volumetric"`` (fog
path-traced by Cycles in a participating medium, :mod:`fogsim.render.blender.fog_volume`,
settings in ``fog_model.volumetric``, see :func:`volumetric_settings` and
:data:`VOLUMETRIC_DEFAULTS`). Both blocks are always checked, whichever kind is chosen, so
``--fog`` / ``--fog-medium`` (:func:`fog_overrides`) can switch models on any preset.

Units: β in 1/m (from the preset's fog levels, not from here); lengths in metres; airlight in
8-bit units [0, 255]; volumetric emission in scene-linear radiance. Problems are
``ValueError`` naming the key; :func:`fogsim.render.preset.load_render_preset` calls
:func:`fog_settings` at load time so they name the preset file before anything renders.
"""
from __future__ import annotations

from fogsim.presets.checks import boolean, choice, integer, is_number, json_object, number, prob, string

FOG_KINDS = ("koschmieder", "volumetric")
#: The participating media of ``fog_model.kind = "volumetric"`` (fogsim.render.blender.fog_volume).
FOG_MEDIA = ("full", "hybrid", "ea")
FOG_EXPOSURES = ("none", "auto")
#: Cycles' limit on samples per pixel (re-exported as :data:`fogsim.render.preset.MAX_SAMPLES`).
MAX_SAMPLES = 1 << 24
#: A fog render's box domain must lie inside the camera's clip_end (2000 m): half-width ≤ this.
MAX_FOG_EXTENT_M = 1400.0
_WORLD_VOLUME = ("a world volume cannot be used for fog: Cycles then ignores the world background and the "
                 "sun entirely (the image is black); fogsim renders fog in a closed box domain around camera "
                 "and scene (fog_model.volumetric.domain = \"box\", the default)")
_KEYS = {"extended", "kernel", "kernel_size", "sigma", "eps", "airlight", "space", "kind", "volumetric"}
#: Defaults of ``fog_model.volumetric`` (units: β 1/m from the fog levels; metres; linear radiance).
VOLUMETRIC_DEFAULTS = {
    "medium": "full",          # full: pure scattering; hybrid: part absorption+emission; ea: camera-only EA
    "g": 0.85,                 # Henyey–Greenstein anisotropy (droplet fog ≈ 0.85)
    "phase": "HG",             # "MIE" (Blender 4.3+ only) uses diameter_um instead of g
    "diameter_um": 10.0,
    "scatter_fraction": 0.5,   # hybrid: σ_s = β·w, σ_a = β·(1 − w) with emission σ_a·emission
    "emission": "sky",         # hybrid / ea: the radiance L = A, scene-linear; "sky" = the frame's sky strength
    "layer_height_m": 100.0,   # fog layer thickness H above the ground
    "extent_m": None,          # domain half-width R; None = max(400, 12/β_min) capped at 1400 m
    "volume_bounces": 64,
    "samples": None,           # None = the quality preset's samples
    "denoise": True,           # OpenImageDenoise where this Blender has it
    "exposure": "none",        # none | auto (median luminance of the clear render, see fog_volume)
    "keep_linear": False,      # also write linear/<level>/<frame>.exr (scene-linear float renders)
    "noise_seed": 0,           # added to Cycles' seed of the fog renders only
    "domain": "box",
}


def fog_overrides(fog_model: dict, fog: str | None, medium: str | None) -> dict:
    """The preset's fog_model with ``--fog`` (a kind) / ``--fog-medium`` (a medium, implying
    ``--fog volumetric``) applied, as a new dict; the values are checked by the caller."""
    fog_model = dict(fog_model)
    if medium is not None:
        fog = "volumetric"
    if fog is not None:
        fog_model["kind"] = fog
    if medium is not None:
        spec = fog_model.get("volumetric", {})
        fog_model["volumetric"] = {**(spec if isinstance(spec, dict) else {}), "medium": medium}
    return fog_model


def fog_settings(config) -> dict:
    """A :class:`~fogsim.render.preset.RenderConfig`'s ``fog_model`` as Fogger arguments:
    ``{"airlight": 8-bit units (a number or [R, G, B]), "space": blend space, "kernel": Kernel | None}``.

    Checks the whole block, the volumetric part included (:func:`volumetric_settings`)."""
    from fogsim.fog.model import SPACES, Kernel, airlight_rgb

    m = config.fog_model
    unknown = set(m) - _KEYS
    if unknown:
        raise ValueError(f"unknown fog_model keys {sorted(unknown)}")
    volumetric_settings(config)  # the kind and, for "volumetric", its medium: checked here too
    kernel = None
    if boolean(m.get("extended", False), "fog_model.extended"):
        kernel = Kernel(string(m.get("kernel", "box"), "fog_model.kernel"),
                        integer(m.get("kernel_size", 19), "fog_model.kernel_size", 1, 4095),
                        float(number(m.get("sigma", 5.0), "fog_model.sigma")),
                        float(number(m.get("eps", 1e-3), "fog_model.eps")))
    airlight = m.get("airlight", 255)
    if not (is_number(airlight) or (isinstance(airlight, list) and len(airlight) == 3
                                    and all(is_number(a) for a in airlight))):
        raise ValueError(f"fog_model.airlight must be a number or [R, G, B] in [0, 255], got {airlight!r}")
    airlight_rgb(airlight)  # validates: a number or R,G,B in [0, 255]
    space = m.get("space", "srgb")
    if space not in SPACES:
        raise ValueError(f"fog_model.space must be one of {', '.join(SPACES)}, got {space!r}")
    return {"airlight": airlight, "space": space, "kernel": kernel}


def volumetric_settings(config) -> dict | None:
    """``fog_model.volumetric`` of a RenderConfig with every default filled in, or None for
    Koschmieder fog. ``extent_m`` None becomes max(400, 12/β_min) m, capped at
    :data:`MAX_FOG_EXTENT_M` (β_min: the smallest β > 0 of ``config.levels``).

    Checked key by key (unknown keys refused, types and ranges); a world-volume domain is
    refused with the reason. ValueError names the key.
    """
    m = config.fog_model
    kind = choice(m.get("kind", "koschmieder"), "fog_model.kind", FOG_KINDS)
    spec = m.get("volumetric", {})
    if isinstance(spec, dict) and spec.get("domain") == "world":
        raise ValueError(f"fog_model.volumetric.domain: {_WORLD_VOLUME}")
    checks = {
        "medium": lambda v, k: choice(v, k, FOG_MEDIA), "g": lambda v, k: number(v, k, -0.99, 0.99),
        "phase": lambda v, k: choice(v, k, ("HG", "MIE")), "diameter_um": lambda v, k: number(v, k, 0.01, 50),
        "scatter_fraction": prob,
        "emission": _emission,
        "layer_height_m": lambda v, k: number(v, k, 1, 1000),
        "extent_m": lambda v, k: None if v is None else number(v, k, 10, MAX_FOG_EXTENT_M),
        "volume_bounces": lambda v, k: integer(v, k, 1, 1024),
        "samples": lambda v, k: None if v is None else integer(v, k, 1, MAX_SAMPLES), "denoise": boolean,
        "exposure": lambda v, k: choice(v, k, FOG_EXPOSURES), "keep_linear": boolean,
        "noise_seed": lambda v, k: integer(v, k, 0, 2**31 - 1), "domain": lambda v, k: choice(v, k, ("box",)),
    }
    assert set(checks) == set(VOLUMETRIC_DEFAULTS)
    settings = json_object(spec, "fog_model.volumetric", {}, checks)
    if kind != "volumetric":  # a volumetric block is still checked, so --fog can switch models
        return None
    settings = {**VOLUMETRIC_DEFAULTS, **settings}
    if settings["extent_m"] is None:
        betas = [lv.beta for lv in config.levels if lv.beta > 0]
        settings["extent_m"] = min(MAX_FOG_EXTENT_M, max(400.0, 12.0 / min(betas))) if betas else 400.0
    return settings


def _emission(value, key: str):
    """``"sky"`` or a scene-linear radiance in [0, 1e6] (as float)."""
    if value == "sky":
        return value
    if not is_number(value) or not 0 <= value <= 1e6:
        raise ValueError(f"{key} must be \"sky\" or a number in [0, 1e6] (scene-linear radiance), got {value!r}")
    return float(value)


def frame_volumetric(settings: dict, desc: dict) -> dict:
    """The volumetric settings of one frame: ``emission: "sky"`` becomes the frame's sky
    strength (``desc["lighting"]["sky_strength"]``: 0.3 by day, 0.01 at night), so the
    emitting part of a hybrid medium follows the scene's light instead of glowing white at night."""
    if settings.get("emission") != "sky":
        return settings
    return {**settings, "emission": float(desc.get("lighting", {}).get("sky_strength", 0.3))}
