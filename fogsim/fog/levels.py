"""Fog levels: β (extinction coefficient, 1/m) ↔ visibility, named presets, CLI parsing.

Visibility is the meteorological optical range, the distance at which a black object's
contrast falls to 5 %: V = ln(20)/β ≈ 2.996/β. β = 0 is clear air (V = ∞).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

from fogsim import presets
from fogsim.errors import InputError
from fogsim.schema.base import load_json
from fogsim.schema.documents import level_key
from fogsim.schema.presets import FogPreset

LN20 = math.log(20.0)
#: The densest fog accepted, in 1/m: a visibility of ln 20 / 1000 ≈ 3 mm. Beyond it a level
#: means nothing physically (every pixel is the airlight), and is most likely a typo.
MAX_BETA = 1000.0
MIN_VISIBILITY = LN20 / MAX_BETA


def visibility_from_beta(beta: float) -> float:
    """Meteorological optical range in metres for β in 1/m (inf for β = 0)."""
    return math.inf if beta == 0 else LN20 / beta


def beta_from_visibility(visibility_m: float) -> float:
    """β in 1/m for a visibility in metres (0 for inf)."""
    if not visibility_m > 0:
        raise ValueError(f"visibility must be positive, got {visibility_m}")
    return 0.0 if math.isinf(visibility_m) else LN20 / visibility_m


@dataclass(frozen=True)
class FogLevel:
    """One fog density. ``key`` names its output folder; ``name`` is for people."""

    key: str
    name: str
    beta: float

    def __post_init__(self):
        if not (self.beta >= 0 and math.isfinite(self.beta)):
            raise ValueError(f"fog level {self.key!r}: β must be a finite number ≥ 0, got {self.beta}")
        if self.beta > MAX_BETA:
            raise ValueError(f"fog level {self.key!r}: β = {self.beta:g} 1/m is out of range (at most "
                             f"{MAX_BETA:g} 1/m, a visibility of {MIN_VISIBILITY * 1000:.0f} mm)")
        level_key(self.key)  # one folder's name (fogsim.schema.documents: the one rule)

    @property
    def visibility(self) -> float:
        return visibility_from_beta(self.beta)

    def to_dict(self) -> dict:
        vis = self.visibility
        return {"key": self.key, "name": self.name, "beta": self.beta,
                "visibility_m": None if math.isinf(vis) else round(vis, 3)}


def _number_key(value: float) -> str:
    """``value`` as it appears in a level key: ``%g`` without the exponent's ``+`` (1e+06 → 1e06)."""
    return f"{value:g}".replace("+", "")


def level_from_beta(beta: float) -> FogLevel:
    if beta == 0:
        return FogLevel("clear", "clear", 0.0)
    return FogLevel(f"beta{_number_key(beta)}", f"β={beta:g}/m", beta)


def level_from_visibility(visibility_m: float) -> FogLevel:
    beta = beta_from_visibility(visibility_m)
    if beta == 0:
        return FogLevel("clear", "clear", 0.0)
    return FogLevel(f"vis{_number_key(visibility_m)}m", f"visibility {visibility_m:g} m", beta)


def preset_names() -> list[str]:
    """Names of the bundled fog presets."""
    return presets.names("fog")


def load_preset(name_or_path: str) -> list[FogLevel]:
    """Levels of a fog preset given by name (``paper``) or path to a JSON file."""
    path = Path(name_or_path)
    if path.suffix != ".json":
        path = presets.component_path("fog", name_or_path, name_or_path)
    doc = load_json(path, FogPreset)
    try:
        return [FogLevel(d.key, d.name if d.name is not None else d.key, float(d.beta)) for d in doc.levels]
    except ValueError as exc:
        raise InputError(path, f"levels: {exc}") from None


def parse_levels(levels: str | None = None, visibility: str | None = None) -> list[FogLevel]:
    """Parse ``--levels`` (a preset name or comma-separated β) or ``--visibility`` (metres)."""
    for flag, given in (("--levels", levels), ("--visibility", visibility)):
        if given is not None and not given.strip():
            raise ValueError(f"{flag} is empty (an unset shell variable?): give a preset name or comma-separated "
                             "values, or leave the flag out for the default")
    if levels and visibility:
        raise ValueError("give either --levels or --visibility, not both")
    if visibility:
        items, make, what = visibility, level_from_visibility, "visibility"
    else:
        items, make, what = (levels or "paper").strip(), level_from_beta, "β"
        if "," not in items and not re.fullmatch(r"[\d.eE+\-]+|clear|-", items):
            return load_preset(items)
    out = []
    for tok in items.split(","):
        tok = tok.strip()
        if tok in ("clear", "-"):
            out.append(FogLevel("clear", "clear", 0.0))
            continue
        if not tok:
            raise ValueError(f"{'--visibility' if what == 'visibility' else '--levels'} {items!r} holds an empty "
                             "entry (two commas?)")
        try:
            value = float(tok)
        except ValueError:
            raise ValueError(f"{what} {tok!r} is not a number") from None
        if not math.isfinite(value) or value < 0 or (what == "visibility" and value == 0):
            raise ValueError(f"{what} must be {'> 0' if what == 'visibility' else '≥ 0'} and finite, got {tok}")
        if what == "β" and value > MAX_BETA:
            raise ValueError(f"--levels: β {tok} is out of range: at most {MAX_BETA:g} 1/m "
                             f"(a visibility of {MIN_VISIBILITY * 1000:.0f} mm)")
        if what == "visibility" and value < MIN_VISIBILITY:
            raise ValueError(f"--visibility: {tok} m is out of range: at least {MIN_VISIBILITY:.4f} m "
                             f"(β = {MAX_BETA:g} 1/m)")
        out.append(make(value))
    keys = [lv.key for lv in out]
    if len(set(keys)) != len(keys):
        raise ValueError(f"duplicate fog levels in {items!r}")
    return out
