"""Fog as a training-time augmentation: physical (Koschmieder) fog from each sample's depth,
β drawn per sample (docs/augment.md).

* :class:`FogSpec`, :func:`apply_fog`, :func:`random_fog` — the NumPy reference (no extra needed);
* :class:`Fog` — an albumentations transform (``augment`` extra: albumentations);
* :func:`fog_batch`, :func:`draw_batch`, :class:`FogV2` — the batched torch function
  (B×3×H×W + B×1×H×W depth, per-sample β, CPU or CUDA) and a torchvision v2 transform (torch,
  torchvision).

The optional front ends are imported on first use (``fogsim.augment.Fog``); without their
library that raises :class:`~fogsim.errors.MissingDependency` with the install line.
"""
from __future__ import annotations

from fogsim.augment.spec import Draw, FogSpec, apply_fog, random_fog

__all__ = ["Draw", "FogSpec", "apply_fog", "random_fog", "Fog", "fog_batch", "draw_batch", "FogV2"]


def __getattr__(name: str):
    """The optional front ends, imported on first use (each import written out: the layer test reads it)."""
    if name == "Fog":
        from fogsim.augment.albu import Fog

        return Fog
    if name in ("fog_batch", "draw_batch", "FogV2"):
        from fogsim.augment import torch_fog

        return getattr(torch_fog, name)
    raise AttributeError(f"module 'fogsim.augment' has no attribute {name!r}")
