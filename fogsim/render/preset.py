"""Dataset presets for the renderer: one JSON file naming a style, camera, quality and fog levels.

``presets/<name>.json`` refers to components by name — ``presets/styles/<style>.json``,
``presets/cameras/<camera>.json``, ``presets/quality/<quality>.json``, ``presets/fog/<fog>.json``
(or an inline list of β) — so a preset is short and its parts are shared. A component may
also be given inline (a JSON object instead of the name). Command-line overrides (frames,
seed, resolution, samples, levels, fog kind and medium) are applied on top.

Every key's type, range and default is declared once, in :mod:`fogsim.schema.presets`; this module
checks the overrides (:func:`check_overrides`: a bad one is a ``ValueError`` naming the flag) and
composes the checked preset, its components and the overrides into a :class:`RenderConfig`
(:func:`load_render_preset`: a problem of the preset is an :class:`~fogsim.errors.InputError`
naming the preset file — or the bundled component's file — and the key), before any output folder
is touched. The render size is bounded by :data:`MAX_PIXELS` (``--max-pixels``).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Literal

from fogsim import presets
from fogsim.camera import CITYSCAPES_BASELINE_M
from fogsim.errors import InputError
from fogsim.fog.levels import FogLevel, parse_levels
from fogsim.io.pixel_bound import MAX_PIXELS, pixel_limit_problem
from fogsim.lidar.sensors import LidarSensor
from fogsim.presets import preset_path
from fogsim.radar.sensors import RadarSensor
from fogsim.render.fog_settings import (
    fog_model,
    fog_overrides,
    fog_settings,
)
from fogsim.scene.library import assets_dir, library_files
from fogsim.schema.base import Closed, check, int_in, load_json, number_in
from fogsim.schema.lidar import LidarSensorSpec
from fogsim.schema.presets import (
    ASSET_CLASSES,
    MAX_FRAMES,
    MAX_SAMPLES,
    MAX_SIDE,
    MIN_SIDE,
    TRAIN_FRACTION,
    Assets,
    Camera,
    DatasetPreset,
    Labels,
    Lighting,
    Quality,
    Style,
    check_lighting,
)
from fogsim.schema.radar import RadarSensorSpec
from fogsim.schema.vocabulary import FOG_KINDS, FOG_MEDIA

__all__ = ["RenderConfig", "Overrides", "check_overrides", "check_size", "parse_resolution", "load_render_preset",
           "COMPONENTS"]

#: The component models by preset key, and the bundled folder of each.
COMPONENTS = {"style": ("styles", Style), "camera": ("cameras", Camera), "quality": ("quality", Quality),
              "lidar": ("lidar", LidarSensorSpec), "radar": ("radar", RadarSensorSpec)}


@dataclass(frozen=True)
class RenderConfig:
    """A checked preset with its overrides applied. The component dicts hold the keys as the
    preset gave them (checked; defaults live in :mod:`fogsim.schema.presets`), so a dataset's
    ``render_run.json`` reads as its preset did; readers take the checked blocks with every
    default filled in (:attr:`quality_settings`, :attr:`label_settings`, :attr:`lighting_settings`,
    :func:`fogsim.render.fog_settings.fog_model`), never a default of their own."""

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
    sensor: dict = field(default_factory=dict)  # checked "sensor" object; {} = a perfect pinhole (fogsim.sensor)
    assets: dict = field(default_factory=dict)  # the asset library (resolve_assets); {} = procedural only
    lidar: dict = field(default_factory=dict)  # the checked LiDAR sensor block (bundled or inline); {} = none
    radar: dict = field(default_factory=dict)  # the checked radar sensor block (bundled or inline); {} = none

    # the blocks checked, every default filled in (from the schema): what readers use
    @cached_property
    def quality_settings(self) -> Quality:
        """``quality`` checked, defaults filled in (:func:`fogsim.render.quality.cycles_settings` reads it)."""
        return check(self.quality, Quality, self.source, prefix="quality")

    @cached_property
    def label_settings(self) -> Labels:
        """``labels`` checked, defaults filled in."""
        return check(self.labels, Labels, self.source, prefix="labels")

    @cached_property
    def lidar_sensor(self) -> LidarSensor | None:
        """The LiDAR on the ego vehicle (:class:`fogsim.lidar.sensors.LidarSensor`), None without one."""
        return LidarSensor.from_dict(self.lidar, self.source) if self.lidar else None

    @cached_property
    def radar_sensor(self) -> RadarSensor | None:
        """The radar on the ego vehicle (:class:`fogsim.radar.sensors.RadarSensor`), None without one."""
        return RadarSensor.from_dict(self.radar, self.source) if self.radar else None

    @cached_property
    def lighting_settings(self) -> Lighting:
        """``lighting`` checked, defaults filled in (day when the preset gives none)."""
        return check(self.lighting, Lighting, self.source, prefix="lighting")

    def to_dict(self) -> dict:
        d = {"name": self.name, "source": self.source, "style": self.style, "camera": self.camera,
             "resolution": list(self.resolution), "quality": self.quality,
             "levels": [lv.to_dict() for lv in self.levels], "fog_model": self.fog_model,
             "labels": self.labels, "exposure": self.exposure, "frames": self.frames, "seed": self.seed,
             "stereo_baseline_m": self.stereo_baseline, "train_fraction": self.train_fraction}
        if self.lighting:  # absent for day, so datasets rendered before lighting existed still resume
            d["lighting"] = self.lighting
        if self.sensor:  # absent without a sensor model, likewise
            d["sensor"] = self.sensor
        if self.assets:  # likewise absent without a library
            d["assets"] = self.assets
        if self.lidar:  # likewise absent without a LiDAR
            d["lidar"] = self.lidar
        if self.radar:  # and without a radar
            d["radar"] = self.radar
        return d


class Overrides(Closed):
    """The command-line overrides of a preset, by flag (the field aliases): what
    :func:`check_overrides` checks before the preset is read."""

    frames: int_in(1, MAX_FRAMES) | None = None
    seed: int_in(0) | None = None
    samples: int_in(1, MAX_SAMPLES) | None = None
    max_pixels: int_in(MIN_SIDE * MIN_SIDE) = MAX_PIXELS
    train_fraction: number_in(0, 1, lo_open=True, hi_open=True) | None = None
    fog: Literal[FOG_KINDS] | None = None
    fog_medium: Literal[FOG_MEDIA] | None = None
    fog_scale: number_in(0.1, 1) | None = None


def check_overrides(**flags) -> Overrides:
    """The overrides (``frames=…`` for ``--frames`` …) checked; a bad one is a ValueError naming its flag."""
    given = {k: v for k, v in flags.items() if v is not None}
    try:
        ov = check(given, Overrides)
    except ValueError as exc:
        key, _, rest = str(exc).partition(": ")
        raise ValueError(f"--{key.replace('_', '-')}: {rest}") from None
    for flag, value in (("--fog-medium", ov.fog_medium), ("--fog-scale", ov.fog_scale)):
        if value is not None and ov.fog not in (None, "volumetric"):
            raise ValueError(f"{flag} needs --fog volumetric")
    return ov


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
    return pixel_limit_problem(w, h, max_pixels, "render")


def _component(key: str, value, source: Path) -> dict:
    """The inline component as checked, or the bundled one of that name read and checked (its
    problems name the bundled file)."""
    folder, model = COMPONENTS[key]
    if isinstance(value, str):
        return load_json(presets.component_path(folder, value, source), model).given()
    return value.given()


def _levels(fog, source) -> list[FogLevel]:
    """The preset's ``fog``: a bundled fog preset's name or a list of β (1/m; "clear" = 0)."""
    if isinstance(fog, str):
        presets.component_path("fog", fog, source)  # an unknown name is the preset's problem
        return parse_levels(fog)
    return parse_levels(",".join("clear" if b == "clear" else repr(float(b)) for b in fog))


def load_render_preset(name_or_path: str | None = None, *, frames: int | None = None,
                       seed: int | None = None, resolution: str | None = None,
                       samples: int | None = None, levels: str | None = None,
                       stereo: bool | None = None, train_fraction: float | None = None,
                       max_pixels: int = MAX_PIXELS, fog: str | None = None,
                       fog_medium: str | None = None, fog_scale: float | None = None,
                       assets: str | None = None, lidar: str | None = None, radar: str | None = None) -> RenderConfig:
    """Read a dataset preset, check all of it and apply overrides; every problem of the
    preset names the preset file (and the key), every bad override its flag.

    ``fog`` (``--fog``): "koschmieder" | "volumetric", sets ``fog_model.kind``;
    ``fog_medium`` (``--fog-medium``): "full" | "hybrid" | "ea", sets
    ``fog_model.volumetric.medium`` (and implies ``--fog volumetric``); ``fog_scale``
    (``--fog-scale``): ``fog_model.volumetric.resolution_scale`` (implies ``--fog volumetric``); ``assets``
    (``--assets``): a folder with one sub-folder of models per class, replacing the preset's class
    entries; ``lidar`` (``--lidar``): a LiDAR on the ego vehicle, a bundled sensor's name or a sensor
    ``.json`` file, replacing the preset's ``lidar``; ``radar`` (``--radar``): likewise a radar
    (``presets/radar/``), replacing the preset's ``radar``."""
    # command-line overrides first: their errors are usage errors, not the preset's
    ov = check_overrides(frames=frames, seed=seed, samples=samples, max_pixels=max_pixels,
                         train_fraction=train_fraction, fog=fog, fog_medium=fog_medium,
                         fog_scale=fog_scale)
    res_override = parse_resolution(resolution) if resolution else None
    if res_override and (why := check_size(*res_override, ov.max_pixels)):
        raise ValueError(f"--resolution {why}")
    lv_override = parse_levels(levels) if levels is not None else None
    asset_dirs = assets_dir(assets) if assets is not None else None
    lidar_override = lidar_block(lidar) if lidar is not None else None
    radar_override = radar_block(radar) if radar is not None else None

    path = preset_path(name_or_path)
    if not path.is_file():
        raise InputError(path, "preset not found")
    cfg = _compose(load_json(path, DatasetPreset), path, ov, res_override, lv_override, stereo)
    cfg = replace(cfg, assets=resolve_assets(cfg.assets, path, asset_dirs, assets))
    cfg = replace(cfg, lidar=lidar_override) if lidar_override is not None else cfg
    cfg = replace(cfg, radar=radar_override) if radar_override is not None else cfg
    if cfg.lidar and (why := _unrenderable(cfg.lidar_sensor)):
        raise InputError(cfg.source, f"lidar: {why}")
    if cfg.lidar and fog_model(cfg).lidar.model == "stf2020":  # its n and g: the sensor's, or the calibration's
        from fogsim.lidar.stf2020 import constants

        try:
            constants(cfg.lidar_sensor.calibrated(fog_model(cfg).lidar.calibration))
        except ValueError as exc:
            raise InputError(cfg.source, f"fog_model.lidar: {exc}") from None
    return cfg


def _unrenderable(sensor: LidarSensor) -> str | None:
    """Why a render cannot sweep ``sensor`` (None when it can)."""
    if sensor.inclinations_deg is None:
        return (f"LiDAR {sensor.name!r} reads its beams from a dataset's calibration: a render needs a sensor with "
                "vertical_fov_deg or inclinations_deg (e.g. hdl64e, hdl32e)")
    return None


def lidar_block(spec: str) -> dict:
    """``--lidar``: a bundled sensor's name (``presets/lidar/``) or a sensor ``.json`` file, as the checked
    block a RenderConfig holds (a bad name is a ValueError naming the flag; a bad file an InputError naming it)."""
    if spec.endswith(".json") or Path(spec).is_file():
        block = load_json(spec, LidarSensorSpec).given()
    else:
        try:
            block = load_json(presets.component_path("lidar", spec, "--lidar"), LidarSensorSpec).given()
        except InputError as exc:
            raise ValueError(f"--lidar: {exc.problem}") from None
    if why := _unrenderable(LidarSensor.from_dict(block)):
        raise ValueError(f"--lidar {spec}: {why}")
    return block


def radar_block(spec: str) -> dict:
    """``--radar``: a bundled sensor's name (``presets/radar/``) or a sensor ``.json`` file, as the checked
    block a RenderConfig holds (a bad name is a ValueError naming the flag; a bad file an InputError naming it)."""
    if spec.endswith(".json") or Path(spec).is_file():
        return load_json(spec, RadarSensorSpec).given()
    try:
        return load_json(presets.component_path("radar", spec, "--radar"), RadarSensorSpec).given()
    except InputError as exc:
        raise ValueError(f"--radar: {exc.problem}") from None


def resolve_assets(given: dict, preset: Path, dirs: dict | None = None, dirs_source=None) -> dict:
    """The run's asset library from the preset's checked ``assets`` (paths relative to the preset's
    folder) and ``--assets`` (``dirs``: class → folder, replacing the preset's class entries):
    ``{"files": {class: [absolute paths]}, "mix": {class: share}, "units", "forward",
    "out_of_range"}``, or {} without any library. A class with no model file is an InputError."""
    classes = {k: v for k, v in given.items() if k in ASSET_CLASSES}
    if dirs is not None:
        classes = dict(dirs)
    if not classes:
        return {}
    source = dirs_source if dirs is not None else preset
    a = check({**{k: v for k, v in given.items() if k not in ASSET_CLASSES}, **classes}, Assets, source, "assets")
    files = library_files(classes, source, None if dirs is not None else preset.parent,
                          Path(dirs_source) if dirs is not None and dirs_source is not None else None)
    mix = {k: v for k, v in a.mix.given().items() if v is not None}
    return {"files": files, "mix": {c: float(mix.get(c, 1.0)) for c in files}, "units": a.units,
            "forward": a.forward, "out_of_range": a.out_of_range}


def _hdri_paths(lighting: dict, source: Path) -> dict:
    """``lighting`` with every HDRI path made absolute (relative: to the preset's folder); a
    missing file is the preset's problem. Blender world HDRI names stay names."""
    from fogsim.scene.library import inside
    from fogsim.scene.sky import hdri_problem
    from fogsim.schema.presets import WORLD_HDRIS

    spec = lighting.get("hdri")
    if spec is None:
        return lighting
    out = []
    for item in [spec] if isinstance(spec, str) else spec:
        if item not in WORLD_HDRIS:
            p = Path(item).expanduser()
            relative = not p.is_absolute()
            p = source.parent / p if relative else p
            if not p.is_file():
                raise InputError(source, f"lighting.hdri: no such file {str(p)!r}")
            if relative and not inside(p, source.parent):  # ../ or a link: a relative path stays in the folder
                raise InputError(source, f"lighting.hdri {item!r} lies outside the preset's folder {source.parent} "
                                         "(a relative path is confined to it; write an absolute path to use a file "
                                         "elsewhere)")
            if problem := hdri_problem(p):  # once per run, not per frame
                raise InputError(source, f"lighting.hdri {str(p)!r}: {problem}")
            item = str(p.resolve())
        out.append(item)
    return {**lighting, "hdri": out[0] if isinstance(spec, str) else out}


def _compose(d: DatasetPreset, path: Path, ov: Overrides, res_override, lv_override,
             stereo: bool | None) -> RenderConfig:
    """The checked preset ``d`` with the checked overrides, as a RenderConfig."""
    quality = _component("quality", d.quality, path)
    if ov.samples is not None:
        quality = {**quality, "samples": ov.samples}
    camera = _component("camera", d.camera, path)
    style = _component("style", d.style, path)
    res = res_override or tuple(d.resolution or (camera["width"], camera["height"]))
    if not res_override and (why := check_size(*res, ov.max_pixels)):
        raise InputError(path, f"resolution {why}")
    try:
        lv = lv_override or _levels(d.fog, path)
    except ValueError as exc:
        raise InputError(path, f"fog: {exc}") from None
    if any(x.key == "all" for x in lv):
        raise InputError(path, "fog: a fog level may not be keyed 'all' (the name of the mixed split)")
    # stereo: true = the camera's stereo_baseline_m, else Cityscapes'; {"baseline_m": b}; --stereo forces it
    spec = d.stereo.given() if isinstance(d.stereo, Closed) else d.stereo
    baseline = None
    if (bool(spec) if stereo is None else stereo):
        b = spec.get("baseline_m") if isinstance(spec, dict) else None
        baseline = float(b if b is not None else camera.get("stereo_baseline_m", CITYSCAPES_BASELINE_M))
    fog_model = fog_overrides(d.fog_model.given(), ov.fog, ov.fog_medium, ov.fog_scale)
    cfg = RenderConfig(
        name=d.name if d.name is not None else path.stem, source=str(path),
        style=style, camera=camera, resolution=(int(res[0]), int(res[1])), quality=quality, levels=tuple(lv),
        fog_model=fog_model, labels=d.labels.given(), lighting=_hdri_paths(check_lighting(d.lighting.given()), path),
        sensor=d.sensor.given() if d.sensor is not None else {},
        assets=d.assets.given(), lidar=_component("lidar", d.lidar, path) if d.lidar is not None else {},
        radar=_component("radar", d.radar, path) if d.radar is not None else {},
        exposure=d.exposure, frames=ov.frames if ov.frames is not None else d.frames,
        seed=ov.seed if ov.seed is not None else d.seed, stereo_baseline=baseline,
        train_fraction=ov.train_fraction if ov.train_fraction is not None else d.train_fraction)
    fog_settings(cfg)  # the fog_model with --fog / --fog-medium applied, checked again
    check_lens(cfg, path)
    return cfg


def check_lens(cfg: RenderConfig, source) -> None:
    """The sensor's distortion at the run's camera and resolution: values inside the schema's range
    that fold the image (:func:`fogsim.sensor.distortion_problem`) are refused naming the key."""
    from fogsim.scene.layout import camera_intrinsics
    from fogsim.sensor import distortion_problem

    coeffs = cfg.sensor.get("distortion")
    if coeffs and any(coeffs):
        problem = distortion_problem(camera_intrinsics(cfg.camera, cfg.resolution), coeffs)
        if problem:
            raise InputError(source, f"sensor.distortion {list(coeffs)}: {problem}")
