"""Dataset presets for the renderer: one JSON file naming a style, camera, quality and fog levels.

``presets/<name>.json`` refers to components by name — ``presets/styles/<style>.json``,
``presets/cameras/<camera>.json``, ``presets/quality/<quality>.json``, ``presets/fog/<fog>.json``
(or an inline list of β) — so a preset is short and its parts are shared. A component may
also be given inline (a JSON object instead of the name). Command-line overrides (frames,
seed, resolution, samples, levels) are applied on top.

Everything is checked when the preset is loaded, before any output folder is touched: every
key of the preset and of its components (type and range: an integer is an integer — 2.9
frames is refused, not truncated), component names (letters, digits, ``-`` and ``_``: never a
path), and the render size against :data:`MAX_PIXELS`. A problem in the preset is an
:class:`~fogsim.errors.InputError` naming the preset file and the key; a bad override is a
``ValueError`` naming the flag.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from fogsim import presets
from fogsim.errors import InputError
from fogsim.fileio import read_json
from fogsim.fog.levels import FogLevel, parse_levels
from fogsim.presets import check_component_name, preset_path

KEYS = {"name", "description", "version", "style", "camera", "resolution", "quality", "fog",
        "fog_model", "labels", "exposure", "frames", "seed", "stereo", "train_fraction", "lighting"}

#: Default bound on the render size, width × height (about 8192 × 4883; the Waymo front camera
#: is 2.5 MP). A frame's arrays, its fog levels and Cycles' buffers grow with it; raise it with
#: ``--max-pixels`` (``max_pixels=``) when a larger render is meant.
MAX_PIXELS = 40_000_000
#: Blender's own limit on each side of a render (not raisable).
MAX_SIDE = 65536
MIN_SIDE = 8
#: Cycles' limit on samples per pixel.
MAX_SAMPLES = 1 << 24
VEHICLES = ("car", "van", "truck", "bus")


@dataclass(frozen=True)
class RenderConfig:
    name: str
    source: str
    style: dict
    camera: dict
    resolution: tuple[int, int]
    quality: dict
    levels: tuple[FogLevel, ...]
    fog_model: dict = field(default_factory=dict)
    labels: dict = field(default_factory=dict)
    exposure: float = 1.0
    frames: int = 8
    seed: int = 0
    stereo_baseline: float | None = None  # metres; None = no right camera
    train_fraction: float = 0.8  # share of frames in the train split (fogsim.dataset_writer's rule)
    lighting: dict = field(default_factory=dict)  # checked "lighting" object; {} = day (see check_lighting)

    def to_dict(self) -> dict:
        d = {"name": self.name, "source": self.source, "style": self.style, "camera": self.camera,
             "resolution": list(self.resolution), "quality": self.quality,
             "levels": [lv.to_dict() for lv in self.levels], "fog_model": self.fog_model,
             "labels": self.labels, "exposure": self.exposure, "frames": self.frames, "seed": self.seed,
             "stereo_baseline_m": self.stereo_baseline, "train_fraction": self.train_fraction}
        if self.lighting:  # absent for day, so datasets rendered before lighting existed still resume
            d["lighting"] = self.lighting
        return d


# ----------------------------------------------------------------------------- value checks
# Each returns the value (integers as int) or raises ValueError naming ``key``, e.g.
# "style.lane_width must be a number > 0, got '3.4'".

def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _bounds(v, key: str, what: str, lo=None, hi=None, lo_open: bool = False):
    low_bad = lo is not None and (v <= lo if lo_open else v < lo)
    if low_bad or (hi is not None and v > hi):
        fmt = lambda x: str(x) if isinstance(x, int) else f"{x:g}"  # noqa: E731
        if lo is not None and hi is not None:
            rng = f"in {'(' if lo_open else '['}{fmt(lo)}, {fmt(hi)}]"
        elif lo is not None:
            rng = f"{'>' if lo_open else '≥'} {fmt(lo)}"
        else:
            rng = f"≤ {fmt(hi)}"
        raise ValueError(f"{key} must be {what} {rng}, got {v!r}")
    return v


def _int(v, key: str, lo=None, hi=None) -> int:
    if not _is_number(v) or not math.isfinite(v) or v != int(v):
        raise ValueError(f"{key} must be an integer, got {v!r}")
    return _bounds(int(v), key, "an integer", lo, hi)


def _num(v, key: str, lo=None, hi=None, lo_open: bool = False):
    if not _is_number(v) or not math.isfinite(v):
        raise ValueError(f"{key} must be a finite number, got {v!r}")
    return _bounds(v, key, "a number", lo, hi, lo_open)


def _prob(v, key: str):
    return _num(v, key, 0, 1)


def _range(v, key: str, check=_num, **bounds) -> list:
    """A ``[low, high]`` pair with low ≤ high, each checked by ``check``."""
    if not isinstance(v, (list, tuple)) or len(v) != 2:
        raise ValueError(f"{key} must be a [low, high] pair, got {v!r}")
    lo, hi = (check(x, f"{key}[{i}]", **bounds) for i, x in enumerate(v))
    if lo > hi:
        raise ValueError(f"{key} must be [low, high] with low ≤ high, got {v!r}")
    return [lo, hi]


def _str(v, key: str) -> str:
    if not isinstance(v, str):
        raise ValueError(f"{key} must be a string, got {v!r}")
    return v


def _bool(v, key: str) -> bool:
    if not isinstance(v, bool):
        raise ValueError(f"{key} must be true or false, got {v!r}")
    return v


def _choice(v, key: str, choices) -> str:
    if v not in choices:
        raise ValueError(f"{key} must be one of {', '.join(choices)}, got {v!r}")
    return v


def _object(d, key: str, required: dict, optional: dict) -> dict:
    """Check a JSON object key by key: ``required``/``optional`` map a key to its check."""
    if not isinstance(d, dict):
        raise ValueError(f"{key} must be a JSON object, got {d!r}")
    unknown = set(d) - set(required) - set(optional)
    if unknown:
        raise ValueError(f"unknown {key} keys {sorted(unknown)} (allowed: {sorted({*required, *optional})})")
    checks = {**required, **optional}
    checked = {k: checks[k](v, f"{key}.{k}") for k, v in d.items()}  # what is there first, then what is not
    missing = [k for k in required if k not in d]
    if missing:
        raise ValueError(f"{key} lacks {', '.join(repr(k) for k in missing)}")
    return checked


_META = {"version": lambda v, k: _int(v, k, 0), "description": _str}


def check_style(style) -> dict:
    """A street style (``presets/styles/*.json``), every key the layout reads."""
    length = lambda v, k: _num(v, k, 1, 1000)  # noqa: E731  (m; bounds the number of objects)
    spacing = lambda v, k: v if _is_number(v) and v == 0 else _num(v, k, 1, 1000)  # noqa: E731  (0 = none)
    count = lambda v, k: _range(v, k, _int, lo=0, hi=1000)  # noqa: E731
    metres = lambda v, k: _range(v, k, lo=0, hi=1000)  # noqa: E731
    size = lambda v, k: _range(v, k, lo=1, hi=1000)  # noqa: E731  (buildings: ≥ 1 m)
    s = _object(style, "style", {
        "name": _str, "lanes_per_direction": lambda v, k: _int(v, k, 1, 16),
        "lane_width": lambda v, k: _num(v, k, 0.5, 20), "parking_width": lambda v, k: _num(v, k, 0, 20),
        "sidewalk_width": metres, "setback": metres, "building_height": size, "building_width": size,
        "building_depth": size, "building_gap": _prob, "street_length": length, "parked_probability": _prob,
        "driving": count, "pedestrians": count, "cyclists": count, "pole_spacing": spacing,
        "tree_spacing": spacing, "signs": count, "crosswalk_probability": _prob,
        "vehicle_mix": _vehicle_mix, "sun_elevation_deg": lambda v, k: _range(v, k, lo=-90, hi=90),
    }, _META)
    return s


def _vehicle_mix(v, key: str) -> dict:
    mix = _object(v, key, {}, {kind: lambda x, k: _num(x, k, 0) for kind in VEHICLES})
    if not sum(mix.values()) > 0:
        raise ValueError(f"{key} must give some vehicle kind ({', '.join(VEHICLES)}) a weight > 0, got {v!r}")
    return mix


def check_camera(camera) -> dict:
    """A camera (``presets/cameras/*.json``): size, focal length (``fx`` px or ``hfov_deg``), mount."""
    side = lambda v, k: _int(v, k, MIN_SIDE, MAX_SIDE)  # noqa: E731
    c = _object(camera, "camera", {
        "name": _str, "width": side, "height": side, "height_m": lambda v, k: _num(v, k, 0, 100, lo_open=True),
        "pitch_deg": lambda v, k: _range(v, k, lo=-90, hi=90), "yaw_deg": lambda v, k: _range(v, k, lo=-180, hi=180),
        "roll_deg": lambda v, k: _range(v, k, lo=-180, hi=180),
    }, {**_META, "fx": lambda v, k: _num(v, k, 0, lo_open=True),
        "hfov_deg": lambda v, k: _num(v, k, 0, 179, lo_open=True),
        "stereo_baseline_m": lambda v, k: _num(v, k, 0, lo_open=True)})
    if ("fx" in c) == ("hfov_deg" in c):
        raise ValueError("camera needs exactly one of 'fx' (pixels at its width) and 'hfov_deg'")
    return c


def check_quality(quality) -> dict:
    """A render quality (``presets/quality/*.json``): what :func:`fogsim.render.blender.cycles.configure` reads."""
    bounce = lambda v, k: _int(v, k, 0, 1024)  # noqa: E731  (Blender's limit)
    return _object(quality, "quality", {}, {
        **_META, "name": _str, "samples": lambda v, k: _int(v, k, 1, MAX_SAMPLES),
        "adaptive_threshold": lambda v, k: _num(v, k, 0, 1), "denoise": _bool,
        "denoise_quality": lambda v, k: _choice(v, k, ("HIGH", "BALANCED", "FAST")),
        "denoise_prefilter": lambda v, k: _choice(v, k, ("ACCURATE", "FAST", "NONE")),
        "bounces": lambda v, k: _object(v, k, {}, {b: bounce for b in
                                                   ("total", "diffuse", "glossy", "transmission", "transparent")}),
    })


def check_lighting(lighting) -> dict:
    """The preset's ``lighting``: ``time_of_day`` ("day", the default, or "night") and, for night,
    overrides of :data:`fogsim.scene.lights.NIGHT` (sky and moon strength, lamp, headlight and
    tail-light powers in Cycles watts, the lit fraction of each building's windows). Returns {}
    for day (a day preset is the preset without lighting), else the object as given."""
    from fogsim.scene.lights import TIMES_OF_DAY

    watts = lambda v, k: _num(v, k, 0, 1e7)  # noqa: E731
    night_keys = {"sky_strength": lambda v, k: _num(v, k, 0, 10), "moon_strength": lambda v, k: _num(v, k, 0, 10),
                  "street_lamp_power_w": watts, "headlight_power_w": watts, "taillight_power_w": watts,
                  "lit_window_fraction": lambda v, k: _range(v, k, lo=0, hi=1)}
    light = _object(lighting, "lighting", {}, {"time_of_day": lambda v, k: _choice(v, k, TIMES_OF_DAY),
                                                **night_keys})
    if light.get("time_of_day", "day") == "day":
        extra = sorted(set(light) - {"time_of_day"})
        if extra:
            raise ValueError(f"lighting keys {extra} apply only to \"time_of_day\": \"night\"")
        return {}
    return light


COMPONENT_CHECKS = {"styles": check_style, "cameras": check_camera, "quality": check_quality}


def _component(kind: str, value, key: str, source: Path) -> dict:
    """An inline component (a JSON object) or the bundled one of that name, checked key by key."""
    if isinstance(value, dict):
        return COMPONENT_CHECKS[kind](value)
    if not isinstance(value, str):
        raise ValueError(f"{key} must be a bundled {key} name or an inline JSON object, got {value!r}")
    return COMPONENT_CHECKS[kind](read_json(presets.component_path(kind, value, source)))


def _stereo_baseline(spec, camera: dict, override: bool | None) -> float | None:
    """Baseline in metres from the preset's ``stereo`` ({"baseline_m": …} or true = the
    camera's ``stereo_baseline_m``, else Cityscapes' 0.209 m); ``override`` forces it on/off."""
    if spec is not None and not isinstance(spec, (bool, dict)):
        raise ValueError(f"stereo must be true, false or {{\"baseline_m\": …}}, got {spec!r}")
    if isinstance(spec, dict):
        spec = _object(spec, "stereo", {}, {"baseline_m": lambda v, k: _num(v, k, 0, lo_open=True)})
    on = bool(spec) if override is None else override
    if not on:
        return None
    b = spec.get("baseline_m") if isinstance(spec, dict) else None
    return float(b if b is not None else camera.get("stereo_baseline_m", 0.209))


def _resolution(value) -> tuple[int, int]:
    if isinstance(value, str):
        raise ValueError(f"resolution must be a [width, height] list of integers, e.g. [640, 426], got {value!r}")
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ValueError(f"resolution must be a [width, height] list of integers, got {value!r}")
    w, h = (_int(v, f"resolution[{i}]") for i, v in enumerate(value))
    if w < MIN_SIDE or h < MIN_SIDE:
        raise ValueError(f"resolution must be at least 8×8 pixels, got {w}×{h}")
    return w, h


def parse_resolution(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"--resolution must look like 640x426, got {text!r}") from None
    if w < MIN_SIDE or h < MIN_SIDE:
        raise ValueError(f"--resolution {text}: at least 8×8 pixels")
    return w, h


def check_size(w: int, h: int, max_pixels: int) -> str | None:
    """Why a ``w``×``h`` render is refused (Blender's side limit, ``max_pixels``), or None."""
    if w > MAX_SIDE or h > MAX_SIDE:
        return f"{w}×{h} is larger than Blender renders ({MAX_SIDE} px a side)"
    if w * h > max_pixels:
        return (f"{w}×{h} = {w * h / 1e6:.1f} MP is above the limit of {max_pixels / 1e6:g} MP "
                f"(--max-pixels {max_pixels}); raise --max-pixels to render it")
    return None


def _fog(value) -> list[FogLevel]:
    """The preset's ``fog``: a bundled fog preset's name or a list of β (1/m; 0 or "clear" = clear)."""
    if isinstance(value, str):
        check_component_name(value, "fog")
        return parse_levels(value)
    if not isinstance(value, list) or not value:
        raise ValueError(f"fog must be a fog preset name or a non-empty list of β, got {value!r}")
    items = [v if v == "clear" else _num(v, f"fog[{i}]") for i, v in enumerate(value)]  # parse_levels: ≥ 0
    return parse_levels(",".join(str(x) for x in items))


def load_render_preset(name_or_path: str | None = None, *, frames: int | None = None,
                       seed: int | None = None, resolution: str | None = None,
                       samples: int | None = None, levels: str | None = None,
                       stereo: bool | None = None, train_fraction: float | None = None,
                       max_pixels: int = MAX_PIXELS, fog: str | None = None,
                       fog_medium: str | None = None) -> RenderConfig:
    """Read a dataset preset, check all of it and apply overrides; every problem of the
    preset names the preset file (and the key), every bad override its flag.

    ``fog`` (``--fog``): "koschmieder" | "volumetric", sets ``fog_model.kind``;
    ``fog_medium`` (``--fog-medium``): "full" | "hybrid" | "ea", sets
    ``fog_model.volumetric.medium`` (and implies ``--fog volumetric``)."""
    path = preset_path(name_or_path)
    if not path.is_file():
        raise InputError(path, "preset not found")
    d = read_json(path)
    if not isinstance(d, dict):
        raise InputError(path, "a preset must be a JSON object")
    unknown = set(d) - KEYS
    if unknown:
        raise InputError(path, f"unknown preset keys {sorted(unknown)} (allowed: {sorted(KEYS)})")
    for key in ("style", "camera", "quality"):
        if key not in d:
            raise InputError(path, f"preset lacks {key!r}")
    # command-line overrides: their errors are usage errors, not the preset's
    max_pixels = _int(max_pixels, "--max-pixels", MIN_SIDE * MIN_SIDE)
    res_override = parse_resolution(resolution) if resolution else None
    if res_override and (why := check_size(*res_override, max_pixels)):
        raise ValueError(f"--resolution {why}")
    if frames is not None:
        frames = _int(frames, "--frames", 1)
    if seed is not None:
        seed = _int(seed, "--seed", 0)
    if samples is not None:
        samples = _int(samples, "--samples", 1, MAX_SAMPLES)
    lv_override = parse_levels(levels) if levels is not None else None
    if fog is not None:
        _choice(fog, "--fog", FOG_KINDS)
    if fog_medium is not None:
        _choice(fog_medium, "--fog-medium", FOG_MEDIA)
        if fog == "koschmieder":
            raise ValueError("--fog-medium needs --fog volumetric")
    if train_fraction is not None and not (_is_number(train_fraction) and 0 < train_fraction < 1):
        raise ValueError(f"--train-fraction must be between 0 and 1, got {train_fraction}")
    try:
        quality = dict(_component("quality", d["quality"], "quality", path))
        if samples is not None:
            quality["samples"] = samples
        camera = _component("cameras", d["camera"], "camera", path)
        style = _component("styles", d["style"], "style", path)
        res = res_override or _resolution(d["resolution"] if d.get("resolution") is not None
                                          else (camera["width"], camera["height"]))
        if not res_override and (why := check_size(*res, max_pixels)):
            raise InputError(path, f"resolution {why}")
        baseline = _stereo_baseline(d.get("stereo"), camera, stereo)
        lv = lv_override or _fog(d.get("fog", "paper"))
        fog_model = d.get("fog_model", {})
        labels = d.get("labels", {})
        for key, value in (("fog_model", fog_model), ("labels", labels)):
            if not isinstance(value, dict):
                raise ValueError(f"{key} must be a JSON object, got {value!r}")
        fog_model = _fog_overrides(fog_model, fog, fog_medium)
        cfg = RenderConfig(
            name=_str(d.get("name", path.stem), "name"), source=str(path),
            style=style, camera=camera, resolution=res, quality=quality, levels=tuple(lv),
            fog_model=dict(fog_model), labels=dict(labels), lighting=check_lighting(d.get("lighting", {})),
            exposure=_num(d.get("exposure", 1.0), "exposure", 0, lo_open=True),
            frames=frames if frames is not None else _int(d.get("frames", 8), "frames", 1),
            seed=seed if seed is not None else _int(d.get("seed", 0), "seed", 0), stereo_baseline=baseline,
            train_fraction=(train_fraction if train_fraction is not None
                            else _num(d.get("train_fraction", 0.8), "train_fraction")))
        for key, check in _META.items():
            if key in d:
                check(d[key], key)
        if not 0 < cfg.train_fraction < 1:
            raise ValueError(f"train_fraction must be between 0 and 1, got {cfg.train_fraction}")
        fog_settings(cfg)  # fail now, naming the preset, not after the first render
        _check_labels(cfg.labels)
        if any(lv.key == "all" for lv in cfg.levels):
            raise ValueError("a fog level may not be keyed 'all' (the name of the mixed split)")
    except InputError as exc:
        if exc.source == str(path):
            raise
        raise InputError(path, f"malformed preset ({exc})") from None  # e.g. a bad bundled fog preset
    except (TypeError, KeyError, IndexError, ValueError) as exc:
        raise InputError(path, f"malformed preset ({exc})") from None
    return cfg


def _fog_overrides(fog_model: dict, fog: str | None, medium: str | None) -> dict:
    """The preset's fog_model with ``--fog`` / ``--fog-medium`` applied (a new dict)."""
    fog_model = dict(fog_model)
    if medium is not None:
        fog = "volumetric"
    if fog is not None:
        fog_model["kind"] = fog
    if medium is not None:
        spec = fog_model.get("volumetric", {})
        fog_model["volumetric"] = {**(spec if isinstance(spec, dict) else {}), "medium": medium}
    return fog_model


def fog_settings(config: RenderConfig) -> dict:
    """The preset's ``fog_model`` as Fogger arguments: airlight (8-bit units), blend space, kernel."""
    from fogsim.fog.model import SPACES, Kernel, airlight_rgb

    m = config.fog_model
    unknown = set(m) - {"extended", "kernel", "kernel_size", "sigma", "eps", "airlight", "space", "kind",
                        "volumetric"}
    if unknown:
        raise ValueError(f"unknown fog_model keys {sorted(unknown)}")
    volumetric_settings(config)  # the kind and, for "volumetric", its medium: checked here too
    kernel = None
    if _bool(m.get("extended", False), "fog_model.extended"):
        kernel = Kernel(_str(m.get("kernel", "box"), "fog_model.kernel"),
                        _int(m.get("kernel_size", 19), "fog_model.kernel_size", 1, 4095),
                        float(_num(m.get("sigma", 5.0), "fog_model.sigma")),
                        float(_num(m.get("eps", 1e-3), "fog_model.eps")))
    airlight = m.get("airlight", 255)
    if not (_is_number(airlight) or (isinstance(airlight, list) and len(airlight) == 3
                                     and all(_is_number(a) for a in airlight))):
        raise ValueError(f"fog_model.airlight must be a number or [R, G, B] in [0, 255], got {airlight!r}")
    airlight_rgb(airlight)  # validates: a number or R,G,B in [0, 255]
    space = m.get("space", "srgb")
    if space not in SPACES:
        raise ValueError(f"fog_model.space must be one of {', '.join(SPACES)}, got {space!r}")
    return {"airlight": airlight, "space": space, "kernel": kernel}


FOG_KINDS = ("koschmieder", "volumetric")
#: The participating media of ``fog_model.kind = "volumetric"`` (fogsim.render.blender.fog_volume).
FOG_MEDIA = ("full", "hybrid", "ea")
FOG_EXPOSURES = ("none", "auto")
#: A fog render's box domain must lie inside the camera's clip_end (2000 m): half-width ≤ this.
MAX_FOG_EXTENT_M = 1400.0
_WORLD_VOLUME = ("a world volume cannot be used for fog: Cycles then ignores the world background and the "
                 "sun entirely (the image is black); fogsim renders fog in a closed box domain around camera "
                 "and scene (fog_model.volumetric.domain = \"box\", the default)")
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


def volumetric_settings(config: RenderConfig) -> dict | None:
    """``fog_model.volumetric`` with every default filled in, or None for Koschmieder fog.

    Checked key by key (unknown keys refused, types and ranges); a world-volume domain is
    refused with the reason. ValueError names the key.
    """
    m = config.fog_model
    kind = _choice(m.get("kind", "koschmieder"), "fog_model.kind", FOG_KINDS)
    spec = m.get("volumetric", {})
    if isinstance(spec, dict) and spec.get("domain") == "world":
        raise ValueError(f"fog_model.volumetric.domain: {_WORLD_VOLUME}")
    checks = {
        "medium": lambda v, k: _choice(v, k, FOG_MEDIA), "g": lambda v, k: _num(v, k, -0.99, 0.99),
        "phase": lambda v, k: _choice(v, k, ("HG", "MIE")), "diameter_um": lambda v, k: _num(v, k, 0.01, 50),
        "scatter_fraction": _prob,
        "emission": _emission,
        "layer_height_m": lambda v, k: _num(v, k, 1, 1000),
        "extent_m": lambda v, k: None if v is None else _num(v, k, 10, MAX_FOG_EXTENT_M),
        "volume_bounces": lambda v, k: _int(v, k, 1, 1024),
        "samples": lambda v, k: None if v is None else _int(v, k, 1, MAX_SAMPLES), "denoise": _bool,
        "exposure": lambda v, k: _choice(v, k, FOG_EXPOSURES), "keep_linear": _bool,
        "noise_seed": lambda v, k: _int(v, k, 0, 2**31 - 1), "domain": lambda v, k: _choice(v, k, ("box",)),
    }
    assert set(checks) == set(VOLUMETRIC_DEFAULTS)
    settings = _object(spec, "fog_model.volumetric", {}, checks)
    if kind != "volumetric":  # a volumetric block is still checked, so --fog can switch models
        return None
    settings = {**VOLUMETRIC_DEFAULTS, **settings}
    if settings["extent_m"] is None:
        betas = [lv.beta for lv in config.levels if lv.beta > 0]
        settings["extent_m"] = min(MAX_FOG_EXTENT_M, max(400.0, 12.0 / min(betas))) if betas else 400.0
    return settings


def _emission(value, key: str):
    """``"sky"`` or a scene-linear radiance ≥ 0."""
    if value == "sky":
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= 1e6:
        raise ValueError(f"{key} must be \"sky\" or a number in [0, 1e6] (scene-linear radiance), got {value!r}")
    return float(value)


def frame_volumetric(settings: dict, desc: dict) -> dict:
    """The volumetric settings of one frame: ``emission: "sky"`` becomes the frame's sky
    strength (``desc["lighting"]["sky_strength"]``: 0.3 by day, 0.01 at night), so the
    emitting part of a hybrid medium follows the scene's light instead of glowing white at night."""
    if settings.get("emission") != "sky":
        return settings
    return {**settings, "emission": float(desc.get("lighting", {}).get("sky_strength", 0.3))}


def _check_labels(labels: dict) -> None:
    unknown = set(labels) - {"min_pixels", "min_visible_fraction"}
    if unknown:
        raise ValueError(f"unknown labels keys {sorted(unknown)}")
    if "min_pixels" in labels:
        _int(labels["min_pixels"], "labels.min_pixels", 1)
    if "min_visible_fraction" in labels:
        _prob(labels["min_visible_fraction"], "labels.min_visible_fraction")
