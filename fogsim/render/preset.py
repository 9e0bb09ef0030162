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

The checks live beside what they check and are re-exported here (callers import from this
module): the value checks in :mod:`fogsim.presets.checks`, the ``fog_model`` block
(Koschmieder arguments and volumetric settings) in :mod:`fogsim.render.fog_settings`, the
``lighting`` object in :func:`fogsim.scene.lights.check_lighting`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from fogsim import presets
from fogsim.camera import CITYSCAPES_BASELINE_M
from fogsim.dataset.writer import TRAIN_FRACTION
from fogsim.errors import InputError
from fogsim.fileio import read_json
from fogsim.fog.levels import FogLevel, parse_levels
from fogsim.presets import check_component_name, preset_path
from fogsim.presets.checks import boolean, choice, integer, is_number, json_object, number, pair, prob, string
from fogsim.render.fog_settings import (
    FOG_EXPOSURES,
    FOG_KINDS,
    FOG_MEDIA,
    MAX_FOG_EXTENT_M,
    MAX_SAMPLES,
    VOLUMETRIC_DEFAULTS,
    fog_overrides,
    fog_settings,
    frame_volumetric,
    volumetric_settings,
)
from fogsim.scene.lights import check_lighting

__all__ = ["KEYS", "MAX_PIXELS", "MAX_SIDE", "MIN_SIDE", "MAX_SAMPLES", "VEHICLES", "RenderConfig",
           "check_style", "check_camera", "check_quality", "check_lighting", "check_size", "parse_resolution",
           "load_render_preset", "fog_settings", "volumetric_settings", "frame_volumetric", "FOG_KINDS",
           "FOG_MEDIA", "FOG_EXPOSURES", "MAX_FOG_EXTENT_M", "VOLUMETRIC_DEFAULTS", "COMPONENT_CHECKS"]

KEYS = {"name", "description", "version", "style", "camera", "resolution", "quality", "fog",
        "fog_model", "labels", "exposure", "frames", "seed", "stereo", "train_fraction", "lighting"}

#: Default bound on the render size, width × height (about 8192 × 4883; the Waymo front camera
#: is 2.5 MP). A frame's arrays, its fog levels and Cycles' buffers grow with it; raise it with
#: ``--max-pixels`` (``max_pixels=``) when a larger render is meant.
MAX_PIXELS = 40_000_000
#: Blender's own limit on each side of a render (not raisable).
MAX_SIDE = 65536
MIN_SIDE = 8
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
    train_fraction: float = TRAIN_FRACTION  # share of frames in the train split (fogsim.dataset.writer's rule)
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


_META = {"version": lambda v, k: integer(v, k, 0), "description": string}


def check_style(style) -> dict:
    """A street style (``presets/styles/*.json``), every key the layout reads."""
    length = lambda v, k: number(v, k, 1, 1000)  # noqa: E731  (m; bounds the number of objects)
    spacing = lambda v, k: v if is_number(v) and v == 0 else number(v, k, 1, 1000)  # noqa: E731  (0 = none)
    count = lambda v, k: pair(v, k, integer, lo=0, hi=1000)  # noqa: E731
    metres = lambda v, k: pair(v, k, lo=0, hi=1000)  # noqa: E731
    size = lambda v, k: pair(v, k, lo=1, hi=1000)  # noqa: E731  (buildings: ≥ 1 m)
    s = json_object(style, "style", {
        "name": string, "lanes_per_direction": lambda v, k: integer(v, k, 1, 16),
        "lane_width": lambda v, k: number(v, k, 0.5, 20), "parking_width": lambda v, k: number(v, k, 0, 20),
        "sidewalk_width": metres, "setback": metres, "building_height": size, "building_width": size,
        "building_depth": size, "building_gap": prob, "street_length": length, "parked_probability": prob,
        "driving": count, "pedestrians": count, "cyclists": count, "pole_spacing": spacing,
        "tree_spacing": spacing, "signs": count, "crosswalk_probability": prob,
        "vehicle_mix": _vehicle_mix, "sun_elevation_deg": lambda v, k: pair(v, k, lo=-90, hi=90),
    }, _META)
    return s


def _vehicle_mix(v, key: str) -> dict:
    mix = json_object(v, key, {}, {kind: lambda x, k: number(x, k, 0) for kind in VEHICLES})
    if not sum(mix.values()) > 0:
        raise ValueError(f"{key} must give some vehicle kind ({', '.join(VEHICLES)}) a weight > 0, got {v!r}")
    return mix


def check_camera(camera) -> dict:
    """A camera (``presets/cameras/*.json``): size, focal length (``fx`` px or ``hfov_deg``), mount."""
    side = lambda v, k: integer(v, k, MIN_SIDE, MAX_SIDE)  # noqa: E731
    c = json_object(camera, "camera", {
        "name": string, "width": side, "height": side, "height_m": lambda v, k: number(v, k, 0, 100, lo_open=True),
        "pitch_deg": lambda v, k: pair(v, k, lo=-90, hi=90), "yaw_deg": lambda v, k: pair(v, k, lo=-180, hi=180),
        "roll_deg": lambda v, k: pair(v, k, lo=-180, hi=180),
    }, {**_META, "fx": lambda v, k: number(v, k, 0, lo_open=True),
        "hfov_deg": lambda v, k: number(v, k, 0, 179, lo_open=True),
        "stereo_baseline_m": lambda v, k: number(v, k, 0, lo_open=True)})
    if ("fx" in c) == ("hfov_deg" in c):
        raise ValueError("camera needs exactly one of 'fx' (pixels at its width) and 'hfov_deg'")
    return c


def check_quality(quality) -> dict:
    """A render quality (``presets/quality/*.json``): what :func:`fogsim.render.blender.cycles.configure` reads."""
    bounce = lambda v, k: integer(v, k, 0, 1024)  # noqa: E731  (Blender's limit)
    return json_object(quality, "quality", {}, {
        **_META, "name": string, "samples": lambda v, k: integer(v, k, 1, MAX_SAMPLES),
        "adaptive_threshold": lambda v, k: number(v, k, 0, 1), "denoise": boolean,
        "denoise_quality": lambda v, k: choice(v, k, ("HIGH", "BALANCED", "FAST")),
        "denoise_prefilter": lambda v, k: choice(v, k, ("ACCURATE", "FAST", "NONE")),
        "bounces": lambda v, k: json_object(v, k, {}, {b: bounce for b in
                                                   ("total", "diffuse", "glossy", "transmission", "transparent")}),
    })


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
    camera's ``stereo_baseline_m``, else Cityscapes' :data:`~fogsim.camera.CITYSCAPES_BASELINE_M`);
    ``override`` forces it on/off."""
    if spec is not None and not isinstance(spec, (bool, dict)):
        raise ValueError(f"stereo must be true, false or {{\"baseline_m\": …}}, got {spec!r}")
    if isinstance(spec, dict):
        spec = json_object(spec, "stereo", {}, {"baseline_m": lambda v, k: number(v, k, 0, lo_open=True)})
    on = bool(spec) if override is None else override
    if not on:
        return None
    b = spec.get("baseline_m") if isinstance(spec, dict) else None
    return float(b if b is not None else camera.get("stereo_baseline_m", CITYSCAPES_BASELINE_M))


def _resolution(value) -> tuple[int, int]:
    if isinstance(value, str):
        raise ValueError(f"resolution must be a [width, height] list of integers, e.g. [640, 426], got {value!r}")
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ValueError(f"resolution must be a [width, height] list of integers, got {value!r}")
    w, h = (integer(v, f"resolution[{i}]") for i, v in enumerate(value))
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
    items = [v if v == "clear" else number(v, f"fog[{i}]") for i, v in enumerate(value)]  # parse_levels: ≥ 0
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
    max_pixels = integer(max_pixels, "--max-pixels", MIN_SIDE * MIN_SIDE)
    res_override = parse_resolution(resolution) if resolution else None
    if res_override and (why := check_size(*res_override, max_pixels)):
        raise ValueError(f"--resolution {why}")
    if frames is not None:
        frames = integer(frames, "--frames", 1)
    if seed is not None:
        seed = integer(seed, "--seed", 0)
    if samples is not None:
        samples = integer(samples, "--samples", 1, MAX_SAMPLES)
    lv_override = parse_levels(levels) if levels is not None else None
    if fog is not None:
        choice(fog, "--fog", FOG_KINDS)
    if fog_medium is not None:
        choice(fog_medium, "--fog-medium", FOG_MEDIA)
        if fog == "koschmieder":
            raise ValueError("--fog-medium needs --fog volumetric")
    if train_fraction is not None and not (is_number(train_fraction) and 0 < train_fraction < 1):
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
        fog_model = fog_overrides(fog_model, fog, fog_medium)
        cfg = RenderConfig(
            name=string(d.get("name", path.stem), "name"), source=str(path),
            style=style, camera=camera, resolution=res, quality=quality, levels=tuple(lv),
            fog_model=dict(fog_model), labels=dict(labels), lighting=check_lighting(d.get("lighting", {})),
            exposure=number(d.get("exposure", 1.0), "exposure", 0, lo_open=True),
            frames=frames if frames is not None else integer(d.get("frames", 8), "frames", 1),
            seed=seed if seed is not None else integer(d.get("seed", 0), "seed", 0), stereo_baseline=baseline,
            train_fraction=(train_fraction if train_fraction is not None
                            else number(d.get("train_fraction", TRAIN_FRACTION), "train_fraction")))
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


def _check_labels(labels: dict) -> None:
    unknown = set(labels) - {"min_pixels", "min_visible_fraction"}
    if unknown:
        raise ValueError(f"unknown labels keys {sorted(unknown)}")
    if "min_pixels" in labels:
        integer(labels["min_pixels"], "labels.min_pixels", 1)
    if "min_visible_fraction" in labels:
        prob(labels["min_visible_fraction"], "labels.min_visible_fraction")
