"""The fog's words, said once: what every preset, command-line flag and document fogsim writes
calls the fog models and their options (the preset schema, the engine and the CLI read them here).

``model`` in every fogsim document (fog sidecars, ``fogsim_run.json``, a frame's ``meta["fog"]``,
render presets' ``fog_model.kind``) is one of :data:`FOG_KINDS`; Koschmieder's extended form is
``koschmieder`` with a ``kernel``. Documents written before fogsim 0.4 said ``standard`` /
``extended`` (and a scatter run's ``fogsim_run.json`` ``"model": "standard", "fog_model": "scatter"``):
:func:`model_word` reads them.
"""
from __future__ import annotations

#: The fog models: Koschmieder's law (and its extended form), the scatter model (both applied to a
#: clear image), fog path-traced by Cycles (renders only).
FOG_KINDS = ("koschmieder", "volumetric", "scatter")
#: The models applied after rendering, to any image with depth.
POST_PROCESS_KINDS = ("koschmieder", "scatter")
#: The participating media of ``fog_model.kind = "volumetric"`` (fogsim.render.blender.fog_volume).
FOG_MEDIA = ("full", "hybrid", "ea")
FOG_EXPOSURES = ("none", "auto")
#: Blend spaces (stored sRGB values, as the paper; or linear light) and the extended form's kernels.
SPACES = ("srgb", "linear")
KERNELS = ("box", "gaussian", "guided")
#: The words of older documents for today's models.
LEGACY_MODELS = {"standard": "koschmieder", "extended": "koschmieder"}


def model_word(word: str) -> str:
    """Today's word for a document's ``model`` (an older document's ``standard`` / ``extended`` too)."""
    return LEGACY_MODELS.get(word, word)


__all__ = ["FOG_EXPOSURES", "FOG_KINDS", "FOG_MEDIA", "KERNELS", "LEGACY_MODELS", "POST_PROCESS_KINDS", "SPACES",
           "model_word"]
