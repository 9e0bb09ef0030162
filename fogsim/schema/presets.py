"""The preset schema: every key of a dataset preset and of its components — its type, range
and default — declared once, here.

A dataset preset (``fogsim/presets/<name>.json``, or the user's own file) is :class:`DatasetPreset`;
its ``style``, ``camera`` and ``quality`` are a bundled component's name (letters, digits,
``-``, ``_``: never a path) or the component inline (:class:`Style`, :class:`Camera`,
:class:`Quality`); ``fog`` is a bundled fog preset's name (:class:`FogPreset`) or a list of β
(1/m; 0 or ``"clear"`` = clear air). ``fog_model`` (:class:`FogModel`, with its
:class:`Volumetric` block), ``labels`` (:class:`Labels`) and ``lighting`` (:class:`Lighting`)
carry their defaults. Every model is :class:`~fogsim.schema.base.Closed`: an unknown key is
refused, named with the allowed ones. A preset may name this schema in ``"$schema"`` (the
JSON Schema that :func:`preset_json_schema` generates and ``fogsim schema preset`` writes, shipped
as ``fogsim/presets/preset.schema.json``), so an editor completes and checks it as it is typed.

Units: metres, degrees, β in 1/m, airlight in 8-bit units [0, 255], light powers in Cycles
watts, volumetric emission in scene-linear radiance. The renderer reads these checked values;
:mod:`fogsim.render.preset` composes them into a ``RenderConfig``.
"""
from __future__ import annotations

import re
from typing import Annotated, Literal

from pydantic import AfterValidator, BeforeValidator, Field, StringConstraints, model_validator

from fogsim.schema.base import (
    Bool,
    Closed,
    NonNegInt,
    Number,
    Tag,
    Text,
    by_type,
    int_in,
    is_list,
    is_object,
    items,
    number_in,
    pair,
    word,
)

#: What a component name may hold: a name, never a path (no '/', '..', '.json').
COMPONENT_NAME = re.compile(r"[A-Za-z0-9_-]+")
#: Cycles' limit on samples per pixel.
MAX_SAMPLES = 1 << 24
#: Blender's own limit on each side of a render (not raisable), and the smallest side fogsim renders.
MAX_SIDE, MIN_SIDE = 65536, 8
#: The share of frames in the train split unless a preset or ``--train-fraction`` says otherwise.
TRAIN_FRACTION = 0.8
#: Labels: objects below this many visible pixels, or this visible fraction, are ignore regions.
MIN_PIXELS, MIN_VISIBLE_FRACTION = 25, 0.1
VEHICLES = ("car", "van", "truck", "bus")
FOG_KINDS = ("koschmieder", "volumetric")
#: The participating media of ``fog_model.kind = "volumetric"`` (fogsim.render.blender.fog_volume).
FOG_MEDIA = ("full", "hybrid", "ea")
FOG_EXPOSURES = ("none", "auto")
#: Koschmieder blend spaces and airlight kernels (fogsim.fog.model implements them).
SPACES = ("srgb", "linear")
KERNELS = ("box", "gaussian", "guided")
#: A fog render's box domain must lie inside the camera's clip_end (2000 m): half-width ≤ this.
MAX_FOG_EXTENT_M = 1400.0
TIMES_OF_DAY = ("day", "night")
WORLD_VOLUME = ("a world volume cannot be used for fog: Cycles then ignores the world background and the "
                "sun entirely (the image is black); fogsim renders fog in a closed box domain around camera "
                "and scene (fog_model.volumetric.domain = \"box\", the default)")


def _name(v: str) -> str:
    if not COMPONENT_NAME.fullmatch(v):
        raise ValueError("may hold only letters, digits, '-' and '_' (a bundled name, never a path)")
    return v


ComponentName = Annotated[str, StringConstraints(strict=True), AfterValidator(_name)]
Prob = number_in(0, 1)
Metres = pair(number_in(0, 1000))
Count = pair(int_in(0, 1000))


def _spacing(v: float) -> float:
    if v != 0 and not 1 <= v <= 1000:
        raise ValueError("must be 0 (none) or in [1, 1000] m")
    return v


class _Meta(Closed):
    """Keys every component may carry (not read by the renderer)."""

    name: Text | None = None
    description: Text | None = None
    version: NonNegInt | None = None


class VehicleMix(Closed):
    """Relative weights of the vehicle kinds (≥ 0, some > 0)."""

    car: number_in(0) | None = None
    van: number_in(0) | None = None
    truck: number_in(0) | None = None
    bus: number_in(0) | None = None

    @model_validator(mode="after")
    def _some(self):
        if not sum(v or 0 for v in (self.car, self.van, self.truck, self.bus)) > 0:
            raise ValueError(f"must give some vehicle kind ({', '.join(VEHICLES)}) a weight > 0")
        return self


class Style(_Meta):
    """A street style (``presets/styles/*.json``): every key the layout reads (metres)."""

    name: Text
    lanes_per_direction: int_in(1, 16)
    lane_width: number_in(0.5, 20)
    parking_width: number_in(0, 20)
    sidewalk_width: Metres
    setback: Metres
    building_height: pair(number_in(1, 1000))
    building_width: pair(number_in(1, 1000))
    building_depth: pair(number_in(1, 1000))
    building_gap: Prob
    street_length: number_in(1, 1000)  # bounds the number of objects
    parked_probability: Prob
    driving: Count
    pedestrians: Count
    cyclists: Count
    pole_spacing: Annotated[Number, AfterValidator(_spacing)]  # 0 = none
    tree_spacing: Annotated[Number, AfterValidator(_spacing)]
    signs: Count
    crosswalk_probability: Prob
    vehicle_mix: VehicleMix
    sun_elevation_deg: pair(number_in(-90, 90))


class Camera(_Meta):
    """A camera (``presets/cameras/*.json``): size (px), focal length (``fx`` px at its width, or
    ``hfov_deg``: exactly one), mount height (m) and ranges of pitch / yaw / roll (degrees)."""

    name: Text
    width: int_in(MIN_SIDE, MAX_SIDE)
    height: int_in(MIN_SIDE, MAX_SIDE)
    height_m: number_in(0, 100, lo_open=True)
    pitch_deg: pair(number_in(-90, 90))
    yaw_deg: pair(number_in(-180, 180))
    roll_deg: pair(number_in(-180, 180))
    fx: number_in(0, lo_open=True) | None = None
    hfov_deg: number_in(0, 179, lo_open=True) | None = None
    stereo_baseline_m: number_in(0, lo_open=True) | None = None

    @model_validator(mode="after")
    def _one_focal(self):
        if (self.fx is None) == (self.hfov_deg is None):
            raise ValueError("needs exactly one of 'fx' (pixels at its width) and 'hfov_deg'")
        return self


Bounce = int_in(0, 1024)  # Blender's limit


class Bounces(Closed):
    total: Bounce = 4
    diffuse: Bounce = 2
    glossy: Bounce = 2
    transmission: Bounce = 2
    transparent: Bounce = 8


class Quality(_Meta):
    """A render quality (``presets/quality/*.json``): what ``render.blender.cycles.configure`` reads."""

    samples: int_in(1, MAX_SAMPLES) = 16
    adaptive_threshold: number_in(0, 1) = 0.0  # 0 = adaptive sampling off
    denoise: Bool = True
    denoise_quality: Literal["HIGH", "BALANCED", "FAST"] = "HIGH"
    denoise_prefilter: Literal["ACCURATE", "FAST", "NONE"] = "ACCURATE"
    bounces: Bounces = Bounces()


class Labels(Closed):
    """Which objects get a box: fewer visible pixels or a smaller visible fraction → ignore region."""

    min_pixels: int_in(1) = MIN_PIXELS
    min_visible_fraction: Prob = MIN_VISIBLE_FRACTION


class Stereo(Closed):
    baseline_m: number_in(0, lo_open=True) | None = None


_EMISSION = '"sky" or a number in [0, 1e6] (scene-linear radiance)'
Emission = Annotated[Annotated[word("sky", _EMISSION), Tag("<sky>")] | Annotated[number_in(0, 1e6), Tag("<radiance>")],
                     by_type({"<sky>": lambda v: isinstance(v, str), "<radiance>": lambda v: True}, _EMISSION)]


def _no_world(v):
    if v == "world":
        raise ValueError(WORLD_VOLUME)
    return v


class Volumetric(Closed):
    """``fog_model.volumetric``: fog path-traced by Cycles in a box domain (β from the fog levels)."""

    medium: Literal[FOG_MEDIA] = "full"  # full: pure scattering; hybrid: part absorption+emission; ea: camera-only EA
    g: number_in(-0.99, 0.99) = 0.85  # Henyey–Greenstein anisotropy (droplet fog ≈ 0.85)
    phase: Literal["HG", "MIE"] = "HG"  # "MIE" (Blender 4.3+ only) uses diameter_um instead of g
    diameter_um: number_in(0.01, 50) = 10.0
    scatter_fraction: Prob = 0.5  # hybrid: σ_s = β·w, σ_a = β·(1 − w) with emission σ_a·emission
    emission: Emission = "sky"  # hybrid / ea: the radiance L = A; "sky" = the frame's sky strength
    layer_height_m: number_in(1, 1000) = 100.0  # fog layer thickness H above the ground
    extent_m: number_in(10, MAX_FOG_EXTENT_M) | None = None  # None = max(400, 12/β_min) capped at 1400 m
    volume_bounces: int_in(1, 1024) = 64
    samples: int_in(1, MAX_SAMPLES) | None = None  # None = the quality preset's samples
    denoise: Bool = True  # OpenImageDenoise where this Blender has it
    exposure: Literal[FOG_EXPOSURES] = "none"  # none | auto (median luminance of the clear render)
    keep_linear: Bool = False  # also write linear/<level>/<frame>.exr
    noise_seed: int_in(0, 2**31 - 1) = 0  # added to Cycles' seed of the fog renders only
    domain: Annotated[Literal["box"], BeforeValidator(_no_world)] = "box"


Airlight = Annotated[Annotated[number_in(0, 255), Tag("<number>")]
                     | Annotated[items(number_in(0, 255), 3, "[R, G, B] list"), Tag("<rgb>")],
                     by_type({"<number>": lambda v: not is_list(v), "<rgb>": is_list},
                             "a number or [R, G, B] in [0, 255]")]


class FogModel(Closed):
    """``fog_model``: which fog model, and its settings. Both blocks are checked whichever kind
    is chosen, so ``--fog`` / ``--fog-medium`` can switch models on any preset."""

    kind: Literal[FOG_KINDS] = "koschmieder"
    extended: Bool = False  # Koschmieder with a spatially varying airlight (kernel below)
    kernel: Literal[KERNELS] = "box"
    kernel_size: int_in(1, 4095) = 19
    sigma: Number = 5.0
    eps: Number = 1e-3
    airlight: Airlight = 255.0  # 8-bit units, a number or [R, G, B]
    space: Literal[SPACES] = "srgb"
    volumetric: Volumetric = Volumetric()

    @model_validator(mode="after")
    def _kernel(self):
        if self.extended and self.kernel_size % 2 == 0:
            raise ValueError(f"kernel_size must be a positive odd number, got {self.kernel_size}")
        if self.extended and self.kernel == "gaussian" and not self.sigma > 0:
            raise ValueError(f"sigma of the Gaussian kernel must be > 0, got {self.sigma}")
        return self


class Lighting(Closed):
    """``lighting``: the time of day; for night, the light sources' settings (defaults below)."""

    time_of_day: Literal[TIMES_OF_DAY] = "day"
    sky_strength: number_in(0, 10) = 0.01  # world background strength (day: 0.3)
    moon_strength: number_in(0, 10) = 0.0  # the sun lamp at night (W/m²; day: 3–5); 0 = no moon
    street_lamp_power_w: number_in(0, 1e7) = 1500.0  # per lamp head
    headlight_power_w: number_in(0, 1e7) = 1000.0  # per headlight (low beam)
    taillight_power_w: number_in(0, 1e7) = 8.0  # per tail light
    lit_window_fraction: pair(number_in(0, 1)) = [0.15, 0.45]  # per building, uniform in [low, high]

    @model_validator(mode="after")
    def _night_keys(self):
        extra = sorted(set(self.model_fields_set) - {"time_of_day"})
        if self.time_of_day == "day" and extra:
            raise ValueError(f"lighting keys {extra} apply only to \"time_of_day\": \"night\"")
        return self

    @classmethod
    def night_defaults(cls) -> dict:
        """The night settings when a preset sets none (every key but ``time_of_day``)."""
        return {k: f.default for k, f in cls.model_fields.items() if k != "time_of_day"}


def check_lighting(lighting) -> dict:
    """A preset's ``lighting`` object checked: {} for day (a day preset is the preset without
    lighting), else the keys as given (the defaults: :meth:`Lighting.night_defaults`)."""
    from fogsim.schema.base import check

    light = lighting if isinstance(lighting, Lighting) else check(lighting, Lighting, prefix="lighting")
    return {} if light.time_of_day == "day" else light.given()


class FogLevelSpec(Closed):
    key: Text
    name: Text | None = None
    beta: number_in(0)  # 1/m


class FogPreset(_Meta):
    """A fog preset (``presets/fog/*.json``): named β levels, used by ``fogsim render`` and ``fogsim fog``."""

    levels: Annotated[list[FogLevelSpec], Field(min_length=1)]


def _style(kind):
    return Annotated[Annotated[ComponentName, Tag("<name>")] | Annotated[kind, Tag("<inline>")],
                     by_type({"<name>": lambda v: isinstance(v, str), "<inline>": is_object},
                             f"a bundled {kind.__name__.lower()} name or an inline JSON object")]


_BETA = 'a β ≥ 0 (1/m, a number) or "clear"'
Beta = Annotated[Annotated[word("clear", _BETA), Tag("<clear>")] | Annotated[number_in(0), Tag("<beta>")],
                 by_type({"<clear>": lambda v: isinstance(v, str), "<beta>": lambda v: True}, _BETA)]
FogLevels = Annotated[Annotated[ComponentName, Tag("<name>")]
                      | Annotated[Annotated[list[Beta], Field(min_length=1)], Tag("<list>")],
                      by_type({"<name>": lambda v: isinstance(v, str), "<list>": is_list},
                              "a fog preset name or a non-empty list of β")]
StereoSpec = Annotated[Annotated[Bool, Tag("<bool>")] | Annotated[Stereo, Tag("<object>")],
                       by_type({"<bool>": lambda v: isinstance(v, bool), "<object>": is_object},
                               'true, false or {"baseline_m": …}')]


class DatasetPreset(_Meta):
    """A dataset preset for ``fogsim render`` (``presets/*.json`` or the user's own)."""

    schema_: Text | None = Field(None, alias="$schema")  # the JSON Schema an editor checks this file against
    style: _style(Style)
    camera: _style(Camera)
    quality: _style(Quality)
    #: [width, height] in pixels; None = the camera's size
    resolution: items(int_in(MIN_SIDE), 2, "[width, height] list of integers, e.g. [640, 426]") | None = None
    fog: FogLevels = "paper"
    fog_model: FogModel = FogModel()
    labels: Labels = Labels()
    lighting: Lighting = Lighting()
    exposure: number_in(0, lo_open=True) = 1.0
    frames: int_in(1) = 8
    seed: int_in(0) = 0
    stereo: StereoSpec | None = None  # true = the camera's stereo_baseline_m, else Cityscapes'
    train_fraction: number_in(0, 1, lo_open=True, hi_open=True) = TRAIN_FRACTION


def preset_json_schema() -> dict:
    """The JSON Schema of a dataset preset (what ``fogsim schema preset`` writes)."""
    schema = DatasetPreset.model_json_schema(by_alias=True)
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "fogsim dataset preset"
    return schema
