"""The scatter fog model's parameters (:mod:`fogsim.fog.scatter`), declared once, here, in named
blocks — and the parameter file ``fogsim fit-fog`` writes and fogsim ships (``fogsim/fog/scatter_params.json``).

:class:`ScatterParameters` *is* the engine's parameter record (``fogsim.fog.scatter.ScatterParams``):
each parameter's range, default, symbol, meaning, whether it is one of the model's terms (switched off
by its default: all defaults = Koschmieder's law), what ``fogsim fit-fog`` searches (its bounds and
first step, or a grid) and its name in version-1 files are declared on its field, and everything else —
the engine, :data:`TERMS`, :meth:`ScatterParameters.without`, the fit's search space
(:func:`fit_space`), the table in ``docs/fog-physics.md`` (:func:`parameter_table`) — is derived from it.

Blocks (the formula: :mod:`fogsim.fog.scatter`): ``psf`` the forward-scattered light and its point-spread
function; ``direct`` the fog-lit objects; ``airlight`` the fog's own light; ``glow`` light sources;
``night`` the day/night switch (which of the day and night rules an image gets).

The file (:class:`ScatterParamsFile`) is a small versioned JSON document: the parameters and what they
were fitted on. Version 2 holds the blocks; version 1 (fogsim ≤ 0.3: one flat object) is still read.
Checked where it is read; a malformed file is one line naming it and the key.
"""
from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, model_validator

from fogsim.schema.base import Closed, Int, Number, Text, int_in, number_in

#: the version of the parameter file this fogsim writes (it reads 1 and 2)
SCATTER_PARAMS_VERSION = 2


def param(default: float, symbol: str, meaning: str, *, v1: str, term: bool = False, fit: dict | None = None):
    """A parameter's declaration: ``default`` (a term's default switches it off), its ``symbol`` in the
    formula, ``meaning`` (with units), its name in version-1 files, whether it is a model ``term``, and
    what ``fogsim fit-fog`` searches: ``{"stage": "day" | "night", "rank": order, "low", "high", "step"}``
    (a pattern search; ``"log": True`` searches log10 of the value) or ``{"stage", "rank", "grid": [...]}``."""
    return Field(default, description=meaning,
                 json_schema_extra={"symbol": symbol, "v1": v1, "term": term, "fit": fit})


class Psf(Closed):
    """``psf``: light scattered into the droplets' forward peak arrives spread by the atmospheric PSF."""

    forward: number_in(0, 0.99) = param(
        0.0, "k", "share of β scattered into the forward peak (δ-scaling): that light still arrives, spread",
        v1="forward", term=True, fit={"stage": "day", "rank": 1, "low": 0.0, "high": 0.95, "step": 0.2})
    spread: number_in(0, 10) = param(
        0.1, "ρ", "the PSF's angular variance per unit optical depth, σ_θ² = ρ·βℓ (rad²)",
        v1="spread", fit={"stage": "day", "rank": 2, "low": -3.0, "high": 1.0, "step": 0.5, "log": True})


class Direct(Closed):
    """``direct``: objects in fog are lit by the fog's diffuse light, not by the clear sky."""

    illumination: number_in(-100, 100) = param(
        0.0, "μ", "the object light fades as e^(−μβ) (m)",
        v1="illumination", term=True, fit={"stage": "day", "rank": 3, "low": 0.0, "high": 40.0, "step": 8.0})
    exposure_key: number_in(0, 10) = param(
        0.0, "κ", "the direct term scaled so the clear image's median luminance becomes κ·A (0: off)",
        v1="exposure_key", term=True, fit={"stage": "day", "rank": 0, "low": 0.0, "high": 1.5, "step": 0.2})
    flatten: number_in(0, 0.95) = param(
        0.0, "f", "sun and shadow compressed towards the fog's even light, I → r·(I/r)^(1−f), r the median",
        v1="flatten", term=True, fit={"stage": "day", "rank": 8, "low": 0.0, "high": 0.9, "step": 0.2})


class Airlight(Closed):
    """``airlight``: the fog's own light, a·e^(−λβ)·(Ω/Ω₀)^(−ν)·A·e^(c·sin θ)."""

    level: number_in(0.05, 5) = param(
        1.0, "a", "the scene's airlight in units of the horizon radiance A",
        v1="level", term=True, fit={"stage": "day", "rank": 4, "low": 0.5, "high": 1.5, "step": 0.1})
    fade: number_in(-50, 50) = param(
        0.0, "λ", "the airlight fades as e^(−λβ), the fog layer's light from above attenuated (m)",
        v1="fade", term=True, fit={"stage": "day", "rank": 5, "low": 0.0, "high": 20.0, "step": 4.0})
    elevation: number_in(-10, 10) = param(
        0.0, "c", "the airlight × e^(c·sin θ), θ the viewing elevation",
        v1="elevation", term=True, fit={"stage": "day", "rank": 6, "low": -3.0, "high": 6.0, "step": 1.0})
    sky_exponent: number_in(-3, 3) = param(
        0.0, "ν", "the airlight × (Ω/0.15)^(−ν), Ω the share of sky in view (0: off)",
        v1="sky_exponent", term=True, fit={"stage": "day", "rank": 7, "low": -1.0, "high": 1.5, "step": 0.25})


class Glow(Closed):
    """``glow``: saturated pixels stand for sources far brighter than white; their light is scattered."""

    gain: number_in(0, 1e4) = param(
        0.0, "G", "the saturated pixels' scattered light × G",
        v1="glow", term=True, fit={"stage": "night", "rank": 0, "low": -1.0, "high": 4.0, "step": 1.0, "log": True})
    threshold: number_in(0, 1, lo_open=True) = param(
        0.9, "Y_s", "linear luminance where saturation begins", v1="glow_threshold")
    spread: number_in(0, 10) = param(
        0.0, "ρ_g", "the glow's own PSF variance per unit βℓ, the APSF's narrow core (rad²; 0: psf.spread)",
        v1="glow_spread", fit={"stage": "night", "rank": 2, "log": True,
                               "grid": [-4.0, -3.5, -3.0, -2.5, -2.0, -1.5, -1.0]})
    tail: number_in(0, 0.99) = param(
        0.0, "w", "the share of the glow spread by the wide PSF (ρ, the APSF's wings), the rest by ρ_g",
        v1="glow_tail", fit={"stage": "night", "rank": 1, "low": 0.0, "high": 0.95, "step": 0.25})
    max_area: number_in(0, 1) = param(
        0.0, "", "saturated regions over this share of the image are lit surfaces and do not glow (0: any)",
        v1="glow_max_area", fit={"stage": "night", "rank": 3, "grid": [0.0, 0.02, 0.005, 0.001]})


class Night(Closed):
    """``night``: the model's day/night switch (night weight 1/(1 + (median Y/Y_g)^8) of the clear image)."""

    luminance: number_in(0, 1) = param(
        0.0, "Y_g", "the clear image's median linear luminance that divides night from day: the glow is weighted "
        "by the night weight, κ, c and ν by 1 − it (0: no switch, every rule in every image)", v1="glow_dark")


BLOCKS = {"psf": Psf, "direct": Direct, "airlight": Airlight, "glow": Glow, "night": Night}


class ScatterParameters(Closed):
    """The model's parameters, in named blocks (each parameter declared on its field; see the module)."""

    psf: Psf = Psf()
    direct: Direct = Direct()
    airlight: Airlight = Airlight()
    glow: Glow = Glow()
    night: Night = Night()

    def value(self, path: str) -> float:
        """The parameter at ``path`` (``"psf.forward"``)."""
        block, name = path.split(".")
        return getattr(getattr(self, block), name)

    def with_values(self, values: dict[str, float]) -> "ScatterParameters":
        """A checked copy with the parameters at the paths of ``values`` replaced."""
        d = self.model_dump()
        for path, v in values.items():
            block, name = path.split(".")
            d[block][name] = float(v)
        return type(self).model_validate(d)

    def without(self, *terms: str) -> "ScatterParameters":
        """A copy with the ``terms`` (paths in :data:`TERMS`) switched off (their defaults)."""
        unknown = sorted(set(terms) - set(TERMS))
        if unknown:
            raise ValueError(f"not model terms: {unknown} (terms: {', '.join(TERMS)})")
        return self.with_values({t: DEFAULTS[t] for t in terms})

    def to_dict(self) -> dict:
        return self.model_dump()

    @classmethod
    def from_v1(cls, flat: dict) -> "ScatterParameters":
        """The parameters of a version-1 file (one flat object, names as :func:`v1_names` gives)."""
        nested = _nest_v1(flat)
        if nested is None:
            unknown = sorted(set(flat) - set(v1_names()))
            raise ValueError(f"unknown key{'s' if len(unknown) > 1 else ''} {unknown} (allowed: {sorted(v1_names())})")
        return cls.model_validate(nested)


# ----------------------------------------------------------------------------- derived from the declaration
def leaves() -> list[tuple[str, Any]]:
    """``(path, pydantic field)`` of every parameter, in declaration order."""
    return [(f"{b}.{n}", f) for b, model in BLOCKS.items() for n, f in model.model_fields.items()]


def _extra(field) -> dict:
    return field.json_schema_extra or {}


DEFAULTS = {path: f.default for path, f in leaves()}
#: the model's terms: each switched on alone makes the model differ from Koschmieder's law
TERMS = tuple(path for path, f in leaves() if _extra(f)["term"])


def v1_names() -> dict[str, str]:
    """A version-1 file's parameter name → its path."""
    return {_extra(f)["v1"]: path for path, f in leaves()}


def _nest_v1(flat: dict) -> dict | None:
    """A version-1 file's flat parameters in the blocks (None: a key that no parameter had)."""
    names = v1_names()
    if not set(flat) <= set(names):
        return None
    nested: dict = {}
    for key, v in flat.items():
        block, name = names[key].split(".")
        nested.setdefault(block, {})[name] = v
    return nested


def fit_space(stage: str) -> dict[str, dict]:
    """What ``fogsim fit-fog`` searches at ``stage`` (``"day"`` or ``"night"``): path → its fit record
    (``low``, ``high``, ``step`` or ``grid``; ``log``), in the search's order."""
    found = [(path, _extra(f)["fit"]) for path, f in leaves() if (_extra(f)["fit"] or {}).get("stage") == stage]
    return {path: dict(fit) for path, fit in sorted(found, key=lambda x: x[1]["rank"])}


def parameter_table() -> str:
    """The Markdown table of every parameter (``docs/fog-physics.md`` holds it; a test keeps it equal)."""
    rows = ["| parameter | symbol | default | range | meaning | version 1 |", "|---|---|---|---|---|---|"]
    for path, f in leaves():
        e, js = _extra(f), BLOCKS[path.split(".")[0]].model_json_schema()["properties"][path.split(".")[1]]
        lo = js.get("minimum", js.get("exclusiveMinimum"))
        hi = js.get("maximum", js.get("exclusiveMaximum"))
        span = f"{'(' if 'exclusiveMinimum' in js else '['}{lo:g}, {hi:g}{')' if 'exclusiveMaximum' in js else ']'}"
        meaning = f.description + (" — a term" if e["term"] else "")
        rows.append(f"| `{path}` | {e['symbol'] or '—'} | {f.default:g} | {span} | {meaning} | `{e['v1']}` |")
    return "\n".join(rows)


# ----------------------------------------------------------------------------- the file
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
    """``scatter_params.json``: ``{"format": "fogsim-scatter-params", "version": 2, "parameters": {…}, …}``
    (a version-1 file's flat parameters are read into the blocks, and the document is version 2)."""

    format: Literal["fogsim-scatter-params"] = "fogsim-scatter-params"
    version: Literal[1, 2] = SCATTER_PARAMS_VERSION
    parameters: ScatterParameters
    fitted_on: FittedOn = FittedOn()
    fogsim_version: Text = ""
    note: Text = ""

    @model_validator(mode="before")
    @classmethod
    def _version_1(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("version") == 1 and isinstance(data.get("parameters"), dict):
            nested = _nest_v1(data["parameters"])
            if nested is not None:  # else the blocks' own check names the unknown key
                data = {**data, "version": SCATTER_PARAMS_VERSION, "parameters": nested}
        return data


__all__ = ["BLOCKS", "DEFAULTS", "SCATTER_PARAMS_VERSION", "TERMS", "Airlight", "Direct", "FitRun", "FittedOn",
           "Glow", "Night", "Psf", "ScatterParameters", "ScatterParamsFile", "fit_space", "leaves", "parameter_table",
           "v1_names"]
