"""What each surface of a scene reflects at 905 nm — the LiDAR's wavelength, not the camera's.

A surface's diffuse reflectivity ρ at 905 nm (a Lambertian-equivalent fraction: 1 = a white Lambertian target
seen head-on; retro-reflectors, which send the beam back to the sensor, exceed 1) is looked up here, never
taken from its visible colour: at 905 nm vegetation is bright (the near-infrared plateau of leaves), red, blue
and green car paints reflect far more than they look (their pigments are transparent in the near infrared, so
the beam sees the bright primer or basecoat), carbon-black paints, tyres and dark plastics stay black, lane
paint, plates, signs and tail-light reflex reflectors are retro-reflective.

* :data:`SURFACES` — one :class:`Reflectivity` per material slot of :mod:`fogsim.scene.materials` (every
  slot a render makes), each with its source.
* :data:`PAINT_FAMILIES` — car paint by colour family (:func:`paint_family` reads the family from the
  instance's visible colour); ``spread`` is the σ of ln ρ among real paints of that family, drawn once per
  object (:func:`instance_reflectivity`), so two black cars need not be equally dark.
* :func:`named_reflectivity` — a library model's or a user's material mapped by its name (keywords of
  :data:`NAME_KEYWORDS`, first match wins), else the fallback :data:`FALLBACK` (a mid-grey painted
  surface), the rule that matched returned beside the value; :func:`material_entry` — the same with what
  else the renderer knows of such a material (its own ``fogsim_reflectivity``, transmission, a paint's
  colour word or base colour).

Values are medians over the materials a source reports near 905 nm (±50 nm; spectra are smooth there), rounded:
JPL ECOSTRESS spectral library v1 (Meerdink et al. 2019: construction materials, rubber, metals, soils and
vegetation), USGS splib07 (Kokaly et al. 2017: vegetation, asphalt, concrete), the solar-reflectance work on
pigments and coatings (Levinson, Berdahl & Akbari 2005, Sol. Energy Mater. Sol. Cells 89: NIR reflectance of
the pigments of coloured and black coatings), automotive LiDAR measurements of paints, textiles and skin
at 905 nm (e.g. the paint makers' 'LiDAR-detectable black' studies: carbon-black blacks ≈ 5 %, NIR-transparent
blacks over a light primer ≈ 20–30 %), and for retro-reflectors their coefficient of retro-reflection (EN 12899
/ ASTM D4956 sheeting, EN 1436 road markings) as an equivalent Lambertian reflectivity π·R at the LiDAR's
near-zero observation angle. ``spread`` values are assumptions (the spread of the values those sources list).

The radar does not use this table: at 77 GHz what matters is conductivity and shape (metal bodies, corner
reflectors), not the near-infrared colour, so the radar keeps its per-class RCS (:mod:`fogsim.render.radar_rcs`).
"""
from __future__ import annotations

import colorsys
import math
import re
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

__all__ = ["FALLBACK", "NAME_KEYWORDS", "PAINT_FAMILIES", "PAINT_WORDS", "Reflectivity", "SURFACES",
           "instance_reflectivity", "material_entry", "named_reflectivity", "paint_family", "slot_entry"]

#: mixed into the hash that draws each instance's spread (:func:`instance_reflectivity`)
REFLECTIVITY_STREAM = 0x905


@dataclass(frozen=True)
class Reflectivity:
    """One surface at 905 nm: ``rho`` (median diffuse reflectivity, Lambertian-equivalent; > 1 for
    retro-reflectors), ``spread`` (σ of ln ρ between instances; 0: none), ``retro`` (a retro-reflector),
    ``source`` (where the value comes from)."""

    rho: float
    spread: float = 0.0
    retro: bool = False
    source: str = ""


_ECO = "JPL ECOSTRESS library"
_USGS = "USGS splib07"
_PIG = "pigment NIR reflectance (Levinson et al. 2005)"
#: car paint by colour family (:func:`paint_family`): median ρ at 905 nm and its spread among real paints
PAINT_FAMILIES: dict[str, Reflectivity] = {
    "white": Reflectivity(0.70, 0.15, source=f"TiO2 white basecoat under clearcoat: 0.65-0.8 ({_PIG})"),
    "silver": Reflectivity(0.45, 0.30, source="aluminium-flake metallic: 0.3-0.6 diffuse-equivalent (flakes send "
                                              "part of the beam away specularly); paint makers' 905 nm data"),
    "grey": Reflectivity(0.25, 0.40, source="dark metallic grey: carbon black with flakes, 0.1-0.4 (paint makers' "
                                            "905 nm data)"),
    "black": Reflectivity(0.06, 0.60, source="carbon-black black 0.03-0.06, NIR-transparent blacks over a light "
                                             "primer 0.2-0.3 (paint makers' 'LiDAR-detectable black' studies): the "
                                             "median of today's fleet is carbon black, the spread covers both"),
    "red": Reflectivity(0.55, 0.30, source=f"red pigments (iron oxide, organic reds) transparent/reflective in the "
                                           f"NIR: 0.4-0.7 ({_PIG})"),
    "blue": Reflectivity(0.30, 0.50, source=f"phthalocyanine and cobalt blues reflect in the NIR (0.3-0.5), dark "
                                            f"blues with carbon black less (0.1-0.2) ({_PIG})"),
    "green": Reflectivity(0.35, 0.40, source=f"phthalocyanine / chromium-oxide greens 0.25-0.5 ({_PIG})"),
    "yellow": Reflectivity(0.70, 0.15, source=f"yellow and orange pigments 0.6-0.8 in the NIR ({_PIG})"),
    "brown": Reflectivity(0.45, 0.30, source=f"iron-oxide browns and beiges 0.35-0.6 in the NIR ({_PIG})"),
}

_PLATE = ("retro-reflective sheeting (EN 12899 / ASTM D4956 class I, R_A 50-250 cd/(lx m2) at 0.2 deg "
          "observation, about 1/10 of it at the entrance angles met on a street): pi*R_A/10 ~ 20")
#: every material slot a render makes (fogsim.scene.materials.MATERIALS), body_paint: see PAINT_FAMILIES
SURFACES: dict[str, Reflectivity] = {
    "body_paint": PAINT_FAMILIES["silver"],  # the catalogue's own grey; an instance's colour picks its family
    "cargo_box": Reflectivity(0.60, 0.25, source=f"painted aluminium / GRP panels, light colours: 0.5-0.7 ({_PIG})"),
    "glass": Reflectivity(0.003, source="glass: ~4 % Fresnel per surface sent away specularly, the diffuse part "
                                        "(dust, film) well under 1 % (ECOSTRESS glass); windows return little"),
    "window": Reflectivity(0.003, source="as glass"),
    "window_lit": Reflectivity(0.003, source="as glass (the room's light is not the laser's)"),
    "tyre": Reflectivity(0.03, 0.30, source=f"carbon-black rubber 0.02-0.05 ({_ECO}: black rubber)"),
    "rim": Reflectivity(0.40, 0.30, source=f"painted / machined aluminium alloy 0.3-0.6 ({_ECO}: aluminium)"),
    "headlight": Reflectivity(0.30, 0.30, source="polycarbonate lens over a metallised reflector: assumption 0.3"),
    "taillight": Reflectivity(5.0, 0.50, retro=True, source="the rear reflex reflectors in every tail lamp (ECE R3 "
                                                            "class IA, CIL >= 300 mcd/lx): retro, assumption 5"),
    "plastic_black": Reflectivity(0.05, 0.40, source=f"carbon-black-filled PP/ABS trim 0.03-0.08 ({_ECO}: "
                                                     "black plastics)"),
    "license_plate": Reflectivity(20.0, 0.30, retro=True, source=_PLATE),
    "skin": Reflectivity(0.45, 0.30, source="human skin at 905 nm: 0.35 (dark) to 0.6 (light); melanin absorbs "
                                            "less in the NIR (automotive LiDAR skin measurements)"),
    "hair": Reflectivity(0.15, 0.50, source="dark hair 0.05-0.2, fair hair to 0.4 at 905 nm"),
    "cloth_top": Reflectivity(0.45, 0.60, source="dyed cotton/polyester: most dyes are NIR-transparent (0.4-0.7), "
                                                 "carbon-black-dyed black cloth 0.05 (LiDAR textile measurements)"),
    "cloth_bottom": Reflectivity(0.35, 0.60, source="denim and dark trousers: indigo reflects in the NIR "
                                                    "(0.3-0.5), black cloth 0.05"),
    "shoe": Reflectivity(0.10, 0.60, source="leather and rubber soles 0.05-0.3"),
    "bike_frame": Reflectivity(0.45, 0.40, source=f"painted steel/aluminium frame, mixed colours ({_PIG})"),
    "asphalt": Reflectivity(0.15, 0.25, source=f"asphalt 0.08 (new) to 0.2 (worn) near 905 nm ({_USGS}; "
                                               f"{_ECO})"),
    "lane_paint": Reflectivity(1.5, 0.40, retro=True, source="white road marking with glass beads (EN 1436 class "
                                                             "R2-R3, R_L 100-300 mcd/(m2 lx) at 30 m geometry; "
                                                             "white paint 0.7 diffuse): retro, assumption 1.5"),
    "sidewalk": Reflectivity(0.30, 0.20, source=f"concrete paving 0.25-0.4 ({_USGS}: concrete)"),
    "curb": Reflectivity(0.35, 0.20, source=f"concrete / granite kerb 0.3-0.4 ({_USGS}; {_ECO})"),
    "facade_brick": Reflectivity(0.45, 0.20, source=f"red brick 0.4-0.5 at 905 nm: iron oxide reflects in the NIR "
                                                    f"({_ECO}: brick)"),
    "facade_concrete": Reflectivity(0.35, 0.20, source=f"concrete 0.3-0.4 ({_USGS}; {_ECO})"),
    "facade_plaster": Reflectivity(0.55, 0.20, source=f"light render / plaster 0.5-0.7 ({_ECO})"),
    "window_frame": Reflectivity(0.60, 0.20, source=f"white PVC / painted frames 0.5-0.7 ({_ECO})"),
    "door": Reflectivity(0.35, 0.40, source=f"painted wood 0.3-0.5 ({_ECO}: wood)"),
    "roof": Reflectivity(0.20, 0.40, source=f"roofing (tar, dark tiles, slate) 0.1-0.3 ({_ECO})"),
    "pole_metal": Reflectivity(0.35, 0.30, source=f"galvanised / painted steel 0.3-0.5 ({_ECO}: galvanised steel)"),
    "street_lamp": Reflectivity(0.30, 0.30, source="lamp housing and lens: assumption 0.3"),
    "signal_housing": Reflectivity(0.05, 0.30, source=f"black painted aluminium / polycarbonate ({_ECO})"),
    "signal_red": Reflectivity(0.30, 0.30, source="coloured polycarbonate lenses over reflectors: assumption 0.3"),
    "signal_amber": Reflectivity(0.30, 0.30, source="as signal_red"),
    "signal_green": Reflectivity(0.30, 0.30, source="as signal_red"),
    "sign_face": Reflectivity(30.0, 0.30, retro=True, source=_PLATE.replace("~ 20", "~ 20-50 (traffic signs: "
                                                                             "higher classes)")),
    "sign_border": Reflectivity(20.0, 0.30, retro=True, source=_PLATE),
    "sign_back": Reflectivity(0.45, 0.30, source=f"bare or painted aluminium back 0.4-0.6 ({_ECO}: aluminium)"),
    "bark": Reflectivity(0.35, 0.25, source=f"tree bark 0.3-0.45 near 905 nm ({_ECO}: bark)"),
    "foliage": Reflectivity(0.50, 0.20, source=f"green leaves' NIR plateau 0.45-0.55 ({_USGS}; {_ECO})"),
}

#: a material without a rule: a mid-grey painted or plastic surface (assumption)
FALLBACK = Reflectivity(0.30, 0.40, source="fallback: a mid-grey painted surface (assumption)")
#: a user's or a library model's material name → table entry: keywords (lower case, matched as substrings
#: of the name, first match wins) in this order — glass before paint ("windscreen paint" is rare)
NAME_KEYWORDS: tuple[tuple[tuple[str, ...], str], ...] = (
    (("glass", "window", "windscreen", "windshield", "mirror"), "glass"),
    (("tyre", "tire", "rubber"), "tyre"),
    (("plate", "licen"), "license_plate"),
    (("tail", "rear_light", "reflector", "reflex"), "taillight"),
    (("headlight", "head_light", "lamp", "light"), "headlight"),
    (("chrome", "rim", "wheel", "alloy", "metal", "steel", "alum"), "rim"),
    (("trim", "plastic", "bumper", "grille", "grill"), "plastic_black"),
    (("skin", "face", "hand", "body_human"), "skin"),
    (("hair",), "hair"),
    (("shoe", "boot"), "shoe"),
    (("cloth", "shirt", "jacket", "coat", "pants", "trouser", "jeans", "fabric", "dress"), "cloth_top"),
    (("sign",), "sign_face"),
    (("leaf", "leaves", "foliage", "grass", "plant", "tree"), "foliage"),
    (("bark", "trunk", "wood"), "bark"),
    (("asphalt", "road"), "asphalt"),
    (("marking", "lane"), "lane_paint"),
    (("concrete", "cement", "sidewalk", "pavement"), "sidewalk"),
    (("brick",), "facade_brick"),
    (("pole",), "pole_metal"),
    (("paint", "body", "car", "carpaint", "coat"), "body_paint"),
)


def paint_family(linear_rgb) -> str:
    """The colour family (:data:`PAINT_FAMILIES`) of a paint from its visible linear RGB (0–1): hue,
    saturation and value of its sRGB encoding; greys by value (≥ 0.85 white, ≥ 0.5 silver, ≥ 0.2 grey,
    else black); colours by hue, dark brownish-orange as brown."""
    rgb = np.clip(np.asarray(linear_rgb, np.float64)[:3], 0.0, 1.0)
    srgb = np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * rgb ** (1 / 2.4) - 0.055)
    h, s, v = colorsys.rgb_to_hsv(*srgb)
    if s < 0.25 or v < 0.12:
        return "white" if v >= 0.85 else "silver" if v >= 0.5 else "grey" if v >= 0.2 else "black"
    deg = 360.0 * h
    if deg < 20 or deg >= 330:
        return "red"
    if deg < 50:
        return "brown" if v < 0.75 or s < 0.5 else "yellow"
    if deg < 70:
        return "yellow"
    if deg < 170:
        return "green"
    if deg < 260:
        return "blue"
    return "red"


def slot_entry(slot: str, colour=None) -> Reflectivity:
    """The table entry of a material slot (``body_paint`` with a visible ``colour``: its paint family);
    an unknown slot: :data:`FALLBACK`."""
    if slot == "body_paint" and colour is not None:
        return PAINT_FAMILIES[paint_family(colour)]
    return SURFACES.get(slot, FALLBACK)


def named_reflectivity(name: str | None) -> tuple[Reflectivity, str]:
    """(entry, rule) for a material called ``name`` (a library model's or a user's): the first keyword of
    :data:`NAME_KEYWORDS` in its lower-cased name, else (:data:`FALLBACK`, ``"fallback"``)."""
    low = (name or "").lower()
    for words, slot in NAME_KEYWORDS:
        if any(w in low for w in words):
            return SURFACES[slot], slot
    return FALLBACK, "fallback"


#: colour words in a paint's name → its family (:data:`PAINT_FAMILIES`), before its base colour is looked at
PAINT_WORDS = {"white": "white", "silver": "silver", "grey": "grey", "gray": "grey", "black": "black", "red": "red",
               "blue": "blue", "green": "green", "yellow": "yellow", "orange": "yellow", "brown": "brown",
               "beige": "brown"}


def material_entry(name: str | None, transmission: float = 0.0, colour=None, reflectivity: float | None = None
                   ) -> tuple[Reflectivity, str]:
    """(entry, rule) of a user's or a library model's material as the renderer knows it: its own
    ``fogsim_reflectivity`` (0–100, no spread; above 1 retro-reflective) wins, then a transmissive surface
    (``transmission`` ≥ 0.5: glass), then its name (:func:`named_reflectivity`); a paint (the ``body_paint``
    rule) takes its family from a colour word of its name (:data:`PAINT_WORDS`), else from its visible
    linear-RGB ``colour`` (:func:`paint_family`), else the catalogue's own (silver)."""
    if reflectivity is not None:
        r = float(reflectivity)
        return Reflectivity(r, retro=r > 1.0, source="the material's fogsim_reflectivity"), "fogsim_reflectivity"
    if transmission >= 0.5:
        return SURFACES["glass"], "glass (transmission)"
    entry, rule = named_reflectivity(name)
    if rule == "body_paint":
        words = [w for w in re.split(r"[^a-z]+", (name or "").lower()) if w in PAINT_WORDS]
        if words:
            return PAINT_FAMILIES[PAINT_WORDS[words[0]]], f"body_paint ({PAINT_WORDS[words[0]]}: its name)"
        if colour is not None:
            family = paint_family(colour)
            return PAINT_FAMILIES[family], f"body_paint ({family}: its colour)"
    return entry, rule


_MASK = (1 << 64) - 1
_STD_NORMAL = NormalDist()


def _mix(x: int) -> int:
    """SplitMix64's finaliser: a 64-bit integer hash with full avalanche."""
    x = (x + 0x9E3779B97F4A7C15) & _MASK
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & _MASK
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & _MASK
    return x ^ (x >> 31)


def _normal(seed: int, object_id: int, salt: int) -> float:
    """A standard normal value that is a fixed function of (seed, object id, salt): SplitMix64 over the three
    (and :data:`REFLECTIVITY_STREAM`) to a uniform u in (0, 1), then Φ⁻¹(u) (a few µs: no Generator per object)."""
    h = REFLECTIVITY_STREAM
    for v in (seed, object_id, salt):
        h = _mix(h ^ (v & _MASK))
    return _STD_NORMAL.inv_cdf(((h >> 11) + 0.5) / float(1 << 53))


def instance_reflectivity(entry: Reflectivity, seed: int, object_id: int, salt: int = 0) -> float:
    """One object's ρ for ``entry``: its median × e^(spread·z), z ~ N(0, 1) a hash of (seed, object id,
    ``salt``) (:func:`_normal`: the same object, the same value; ``salt`` tells an object's slots apart),
    capped at 3× the median for diffuse surfaces and never above 1 unless
    retro-reflective."""
    if entry.spread <= 0:
        return float(entry.rho)
    z = _normal(int(seed), int(object_id), int(salt))
    rho = entry.rho * math.exp(entry.spread * max(-2.5, min(2.5, z)))
    return float(rho if entry.retro else min(rho, 3 * entry.rho, 1.0))
