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

from pydantic import AfterValidator, BeforeValidator, Field, StringConstraints, Tag, model_validator

from fogsim.schema.base import (
    Bool,
    Closed,
    NonNegInt,
    Number,
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
from fogsim.schema.lidar import LidarFogSpec, LidarSensorSpec
from fogsim.schema.radar import RadarFogSpec
from fogsim.schema.vocabulary import FOG_EXPOSURES, FOG_KINDS, FOG_MEDIA, KERNELS, SPACES

#: What a component name may hold: a name, never a path (no '/', '..', '.json').
COMPONENT_NAME = re.compile(r"[A-Za-z0-9_-]+")
#: Cycles' limit on samples per pixel.
MAX_SAMPLES = 1 << 24
#: The most frames one dataset holds (the paper's 12,900 × 77): the frame list, the split and the
#: finalize report are as long as this.
MAX_FRAMES = 1_000_000
#: Blender's own limit on each side of a render (not raisable), and the smallest side fogsim renders.
MAX_SIDE, MIN_SIDE = 65536, 8
#: The share of frames in the train split unless a preset or ``--train-fraction`` says otherwise.
TRAIN_FRACTION = 0.8
#: Labels: objects below this many visible pixels, or this visible fraction, are ignore regions.
MIN_PIXELS, MIN_VISIBLE_FRACTION = 25, 0.1
VEHICLES = ("car", "van", "truck", "bus")
#: The widest airlight kernel (k × k pixels, k odd): its weights and the filter's buffers grow with it.
MAX_KERNEL_SIZE = 4095
#: A fog render's box domain must lie inside the camera's clip_end (2000 m): half-width ≤ this.
MAX_FOG_EXTENT_M = 1400.0
TIMES_OF_DAY = ("day", "night")
#: The world background strength of the default day sky (the layout's; ``lighting.strength`` None).
DAY_SKY_STRENGTH = 0.3
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
    # fog renders at this fraction of width and height, rebuilt at full size from the clear
    # render (fogsim.render.fog_rebuild): 0.5 = a quarter of the pixels; 1 = full resolution
    resolution_scale: number_in(0.1, 1) = 1.0
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
    kernel_size: int_in(1, MAX_KERNEL_SIZE) = 19
    sigma: Number = 5.0
    eps: Number = 1e-3
    airlight: Airlight = 255.0  # 8-bit units, a number or [R, G, B]
    space: Literal[SPACES] = "srgb"  # Koschmieder's blend space (kind "scatter" always blends linear light)
    scatter_params: Text | None = None  # kind "scatter": a fogsim fit-fog parameter file (None: the shipped one)
    volumetric: Volumetric = Volumetric()
    lidar: LidarFogSpec = LidarFogSpec()  # the LiDAR's part of the same fog (a preset with a "lidar" sensor)
    radar: RadarFogSpec = RadarFogSpec()  # the radar's part of the same fog (ITU-R P.840, fogsim.radar.fog)

    @model_validator(mode="after")
    def _kernel(self):
        if self.extended and self.kernel_size % 2 == 0:
            raise ValueError(f"kernel_size must be a positive odd number, got {self.kernel_size}")
        if self.extended and self.kernel == "gaussian" and not self.sigma > 0:
            raise ValueError(f"sigma of the Gaussian kernel must be > 0, got {self.sigma}")
        return self


SKIES = ("procedural", "hdri")
#: The CC0 world HDRIs shipped with Blender (``datafiles/studiolights/world/<name>.exr``, in the
#: bpy module and the Debian binary alike; :func:`fogsim.scene.sky.hdri_file` resolves a name).
WORLD_HDRIS = ("city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset")
#: The file types an HDRI may be (Blender reads both).
HDRI_SUFFIXES = (".exr", ".hdr")
NIGHT_KEYS = ("sky_strength", "moon_strength", "street_lamp_power_w", "headlight_power_w", "taillight_power_w",
              "lit_window_fraction")
#: The outdoor-light keys (day only): the sky, its strength and rotation, the sun, overcast.
SKY_KEYS = ("sky", "hdri", "strength", "rotation_deg", "sun_elevation_deg", "sun_azimuth_deg", "overcast")


def _hdri(v: str) -> str:
    if v in WORLD_HDRIS or v.lower().endswith(HDRI_SUFFIXES):
        return v
    raise ValueError(f"must be a Blender world HDRI ({', '.join(WORLD_HDRIS)}) or a path to an "
                     f"{' or '.join(HDRI_SUFFIXES)} file, got {v!r}")


HdriName = Annotated[str, StringConstraints(strict=True, min_length=1), AfterValidator(_hdri)]
_HDRI = "an HDRI name or path, or a non-empty list of them"
Hdri = Annotated[Annotated[HdriName, Tag("<one>")]
                 | Annotated[Annotated[list[HdriName], Field(min_length=1)], Tag("<list>")],
                 by_type({"<one>": lambda v: isinstance(v, str), "<list>": is_list}, _HDRI)]
_OVERCAST = "true, false or a probability in [0, 1]"
Overcast = Annotated[Annotated[Bool, Tag("<bool>")] | Annotated[Prob, Tag("<p>")],
                     by_type({"<bool>": lambda v: isinstance(v, bool), "<p>": lambda v: True}, _OVERCAST)]


class Lighting(Closed):
    """``lighting``: the time of day; for night, the light sources' settings (defaults below);
    by day, the sky (:mod:`fogsim.scene.sky`): procedural (Blender's sky texture and a sun lamp,
    the default) or an HDRI (a Blender world HDRI by name, or the user's .exr/.hdr; a list = one
    per frame, seeded), its strength and rotation (uniform in the ranges, per frame), the sun's
    elevation and azimuth ranges, and ``overcast`` (a probability per frame, true = 1): an
    overcast frame has no sun and a CIE overcast sky (soft shadows — what a foggy day looks like)."""

    time_of_day: Literal[TIMES_OF_DAY] = "day"
    sky_strength: number_in(0, 10) = 0.01  # world background strength at night (day: DAY_SKY_STRENGTH)
    moon_strength: number_in(0, 10) = 0.0  # the sun lamp at night (W/m²; day: 3–5); 0 = no moon
    street_lamp_power_w: number_in(0, 1e7) = 1500.0  # per lamp head
    headlight_power_w: number_in(0, 1e7) = 1000.0  # per headlight (low beam)
    taillight_power_w: number_in(0, 1e7) = 8.0  # per tail light
    lit_window_fraction: pair(number_in(0, 1)) = [0.15, 0.45]  # per building, uniform in [low, high]
    sky: Literal[SKIES] = "procedural"
    hdri: Hdri = "city"  # sky "hdri": a name in WORLD_HDRIS or a path (relative: to the preset's folder)
    #: world strength (uniform per frame); None = procedural 0.3, HDRI 1.0, overcast [1.0, 1.6]
    strength: pair(number_in(0, 100)) | None = None
    rotation_deg: pair(number_in(-360, 360)) = [0.0, 360.0]  # HDRI turn about the vertical axis
    sun_elevation_deg: pair(number_in(-90, 90)) | None = None  # None = the style's range
    sun_azimuth_deg: pair(number_in(-360, 360)) = [0.0, 360.0]
    overcast: Overcast = False  # probability per frame (true = every frame)

    @model_validator(mode="after")
    def _night_keys(self):
        given = set(self.model_fields_set) - {"time_of_day"}
        if self.time_of_day == "day" and (extra := sorted(given & set(NIGHT_KEYS))):
            raise ValueError(f"lighting keys {extra} apply only to \"time_of_day\": \"night\"")
        if self.time_of_day == "night" and (extra := sorted(given & set(SKY_KEYS))):
            raise ValueError(f"lighting keys {extra} apply only to \"time_of_day\": \"day\" (the night has "
                             f"its own sky and lights)")
        if self.sky == "procedural" and "hdri" in given:
            raise ValueError('lighting.hdri needs "sky": "hdri"')
        return self

    @classmethod
    def night_defaults(cls) -> dict:
        """The night settings when a preset sets none."""
        return {k: cls.model_fields[k].default for k in NIGHT_KEYS}


def check_lighting(lighting) -> dict:
    """A preset's ``lighting`` object checked: {} for the default day (a day preset is the preset
    without lighting), else the keys as given (the defaults: :meth:`Lighting.night_defaults`,
    :mod:`fogsim.scene.sky`)."""
    from fogsim.schema.base import check

    light = lighting if isinstance(lighting, Lighting) else check(lighting, Lighting, prefix="lighting")
    given = light.given()
    return {} if light.time_of_day == "day" and not set(given) - {"time_of_day"} else given


class Noise(Closed):
    """``sensor.noise``: shot noise (Poisson in electrons, white = ``full_well_e``) + Gaussian read noise."""

    full_well_e: number_in(1, 1e7) = 1000.0  # electrons at linear white
    read_noise_e: number_in(0, 1e5) = 2.0  # electrons (standard deviation)


class MotionBlur(Closed):
    """``sensor.motion_blur``: Cycles motion blur over the shutter time; the camera moves forward
    at the ego speed, every driving vehicle along its heading (speeds uniform per frame, m/s)."""

    shutter_s: number_in(0, 1, lo_open=True) = 1 / 60
    ego_speed_mps: pair(number_in(0, 100)) = [8.0, 14.0]
    traffic_speed_mps: pair(number_in(0, 100)) = [5.0, 14.0]


class SensorSpec(Closed):
    """``sensor`` (off when absent): the camera model applied to every fog level's image after the
    fog (:mod:`fogsim.sensor`): exposure in EV, vignetting exponent (cos^a law; 4 = natural),
    OpenCV lens distortion ``[k1, k2, p1, p2, k3]`` (1–5 coefficients, the rest 0; masks and
    depth are resampled with it, boxes come from the distorted mask), sensor noise, JPEG quality, and
    Cycles motion blur (:mod:`fogsim.scene.motion`)."""

    exposure_ev: number_in(-16, 16) = 0.0
    vignetting: number_in(0, 16) = 0.0
    distortion: Annotated[list[number_in(-1, 1)], Field(min_length=1, max_length=5)] | None = None
    noise: Noise | None = None
    jpeg_quality: int_in(1, 100) | None = None
    motion_blur: MotionBlur | None = None  # a second, Combined-only Cycles render (labels stay sharp)


#: The classes an asset library may hold models of (``assets``), each with a real-size range
#: (:data:`fogsim.scene.library.SIZE_RANGES`).
ASSET_CLASSES = ("car", "van", "truck", "bus", "pedestrian", "cyclist", "traffic_light", "traffic_sign")
#: Model units → metres (``assets.units``; glTF is metres by its spec, FBX and .blend carry their
#: own scale, which Blender's importers apply: this factor comes on top).
ASSET_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}
#: A model's front after Blender imports it (z up). Blender's front view and glTF's spec (+Z front,
#: which the importer turns into −y) both face −y.
ASSET_FORWARD = ("-y", "+y", "-x", "+x")


class AssetMix(Closed):
    """``assets.mix``: the share of library models per class in [0, 1] (the rest procedural);
    a class with a library and no share here is all library (1)."""

    car: Prob | None = None
    van: Prob | None = None
    truck: Prob | None = None
    bus: Prob | None = None
    pedestrian: Prob | None = None
    cyclist: Prob | None = None
    traffic_light: Prob | None = None
    traffic_sign: Prob | None = None


class Assets(Closed):
    """``assets``: the user's own models for the procedural streets, per class a folder (searched
    recursively) or a glob of .glb/.gltf/.obj/.fbx/.blend files (relative to the preset's folder).
    A model outside its class's real-size range is refused, or scaled into it with
    ``out_of_range: "scale"``."""

    car: Text | None = None
    van: Text | None = None
    truck: Text | None = None
    bus: Text | None = None
    pedestrian: Text | None = None
    cyclist: Text | None = None
    traffic_light: Text | None = None
    traffic_sign: Text | None = None
    mix: AssetMix = AssetMix()
    units: Literal[tuple(ASSET_UNITS)] = "m"
    forward: Literal[ASSET_FORWARD] = "-y"
    out_of_range: Literal["refuse", "scale"] = "refuse"

    @model_validator(mode="after")
    def _mix_needs_library(self):
        lonely = sorted(k for k, v in self.mix.given().items() if v is not None and getattr(self, k) is None)
        if lonely:
            raise ValueError(f"mix gives a share to {lonely} but no library folder or glob for it")
        return self


class FogLevelSpec(Closed):
    key: Text
    name: Text | None = None
    beta: number_in(0)  # 1/m


class FogPreset(_Meta):
    """A fog preset (``presets/fog/*.json``): named β levels, used by ``fogsim render`` and ``fogsim fog``."""

    levels: Annotated[list[FogLevelSpec], Field(min_length=1)]


def _style(kind, what: str | None = None):
    return Annotated[Annotated[ComponentName, Tag("<name>")] | Annotated[kind, Tag("<inline>")],
                     by_type({"<name>": lambda v: isinstance(v, str), "<inline>": is_object},
                             f"a bundled {what or kind.__name__.lower()} name or an inline JSON object")]


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
    sensor: SensorSpec | None = None  # the camera model after the fog; None = a perfect pinhole
    assets: Assets = Assets()  # the user's own models (none: procedural only)
    #: a LiDAR on the ego vehicle: a bundled sensor's name (presets/lidar/) or a custom block; None = none
    lidar: _style(LidarSensorSpec, "LiDAR sensor") | None = None
    exposure: number_in(0, lo_open=True) = 1.0
    frames: int_in(1, MAX_FRAMES) = 8
    seed: int_in(0) = 0
    stereo: StereoSpec | None = None  # true = the camera's stereo_baseline_m, else Cityscapes'
    train_fraction: number_in(0, 1, lo_open=True, hi_open=True) = TRAIN_FRACTION


def preset_json_schema() -> dict:
    """The JSON Schema of a dataset preset (what ``fogsim schema preset`` writes)."""
    schema = DatasetPreset.model_json_schema(by_alias=True)
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "fogsim dataset preset"
    return schema
