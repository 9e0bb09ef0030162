"""The fitted parameters of the scatter fog model (:mod:`fogsim.fog.scatter`), as
``fogsim fit-fog`` writes them and fogsim ships them (``fogsim/fog/scatter_params.json``).

A small versioned JSON document: the model's parameters, and what they were fitted on (scenes,
seeds, β, the objective before and after). Checked where it is read; a malformed file is refused
with one line naming it and the key (:func:`fogsim.schema.base.load_json`).
"""
from __future__ import annotations

from typing import Literal

from fogsim.schema.base import Closed, Int, Number, Text, int_in, number_in

#: the version of the parameter file this fogsim reads and writes
SCATTER_PARAMS_VERSION = 1


class ScatterParameters(Closed):
    """The model's parameters (units and meaning: :class:`fogsim.fog.scatter.ScatterParams`)."""

    forward: number_in(0, 0.99) = 0.0       # k: share of β that is forward scattering kept near its direction
    spread: number_in(0, 10) = 0.1          # ρ (rad²): PSF angular variance per unit optical depth βℓ
    illumination: number_in(-100, 100) = 0.0  # μ (m): object radiance × exp(−μ·β) (fog-lit objects)
    level: number_in(0.05, 5) = 1.0          # a: the airlight of the scene, × the horizon radiance A
    fade: number_in(-50, 50) = 0.0           # λ (m): the airlight × exp(−λ·β)
    elevation: number_in(-10, 10) = 0.0     # c: airlight × exp(c·sin θ), θ the viewing elevation
    glow: number_in(0, 1e4) = 0.0           # G: saturated pixels' scattered light × (1 + G)
    glow_threshold: number_in(0, 1, lo_open=True) = 0.9  # linear luminance where saturation begins
    glow_spread: number_in(0, 10) = 0.0     # ρ_g (rad²): the glow's PSF variance per unit βℓ; 0 = spread
    sky_exponent: number_in(-3, 3) = 0.0    # ν: airlight × (Ω/0.15)^(−ν), Ω the share of sky in view; 0 = off
    glow_dark: number_in(0, 1) = 0.0        # Y_g: glow × 1/(1 + (median Y/Y_g)^8) — lamps only in dark images
    glow_max_area: number_in(0, 1) = 0.0    # saturated regions over this share of the image do not glow; 0 = any
    glow_tail: number_in(0, 0.99) = 0.0     # w: share of the glow spread by the wide PSF (ρ), the rest by ρ_g
    flatten: number_in(0, 0.95) = 0.0        # f: direct term I → r·(I/r)^(1−f), r the median (fog's even light)
    exposure_key: number_in(0, 10) = 0.0    # κ: direct term × κ·Y_A/median(Y_clear) (fog-lit objects); 0 = off


class FitRun(Closed):
    """One ``fogsim bench fog-physics`` folder the parameters were fitted on."""

    folder: Text = ""
    preset: Text = ""
    style: Text = ""
    seed: Int | None = None
    time_of_day: Text = ""
    frames: int_in(0) = 0
    resolution: Text = ""
    samples: int_in(0) = 0


class FittedOn(Closed):
    """What the parameters were fitted on (``runs``: each folder; the lists: their union)."""

    runs: list[FitRun] = []
    presets: list[Text] = []
    styles: list[Text] = []
    seeds: list[Int] = []
    times_of_day: list[Text] = []
    frames: int_in(0) = 0
    betas: list[Number] = []
    resolution: Text = ""
    samples: int_in(0) = 0
    objective: Text = ""
    before: Number | None = None
    after: Number | None = None


class ScatterParamsFile(Closed):
    """``scatter_params.json``: ``{"format": "fogsim-scatter-params", "version": 1, "parameters": {…}, …}``."""

    format: Literal["fogsim-scatter-params"] = "fogsim-scatter-params"
    version: Literal[SCATTER_PARAMS_VERSION] = SCATTER_PARAMS_VERSION
    parameters: ScatterParameters
    fitted_on: FittedOn = FittedOn()
    fogsim_version: Text = ""
    note: Text = ""


__all__ = ["SCATTER_PARAMS_VERSION", "FitRun", "FittedOn", "ScatterParameters", "ScatterParamsFile"]
