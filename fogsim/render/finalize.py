"""A render's dataset-wide files (COCO, split lists, data YAMLs, ``dataset.json``, contact sheet, the
sensors' tables and pictures) over its committed frames: at the end of a run, or by
``fogsim render --out OUT --finalize-only`` after every shard of an array job (or to re-split with
``--train-fraction``).

``--finalize-only`` reads the render's configuration back from ``OUT/render_run.json`` (its ``config``,
:class:`~fogsim.schema.documents.RenderRunConfig`), so ``--out`` is all it needs, whatever flags the
shards were given, and it runs without Blender. A flag given as well is checked against the record
(:func:`check_flags`): one that disagrees is refused naming the parameter and both values, so one
dataset is never finalized with another's configuration. No bpy here.
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.reader import frame_records
from fogsim.dataset.writer import finalize
from fogsim.deps import package_versions
from fogsim.errors import InputError
from fogsim.fog.levels import FogLevel, parse_levels
from fogsim.render.preset import RenderConfig
from fogsim.runs import FRAME_SEED_RULE, describe_difference, frame_seed
from fogsim.schema.base import load_json
from fogsim.schema.documents import RenderRunFile

__all__ = ["GROWABLE", "RUN_FILE", "check_flags", "dataset_parameters", "finalize_render", "recorded_config"]

#: the run file a render claims its folder with (:func:`fogsim.runs.claim_output`)
RUN_FILE = "render_run.json"

#: Preset keys that may change between runs into one dataset (more frames, another split).
GROWABLE = ("frames", "source", "train_fraction")


def dataset_parameters(config: RenderConfig) -> dict:
    """What must match for a run to add frames to an existing dataset (what ``render_run.json`` claims)."""
    return {k: v for k, v in config.to_dict().items() if k not in GROWABLE}


#: the keys of a configuration only a preset sets (no flag overrides them): what ``--preset`` is checked by
PRESET_KEYS = ("name", "style", "camera", "labels", "exposure", "lighting", "sensor")


def is_frame_name(name: str) -> bool:
    """A rendered frame's name: its index, six digits or more (:func:`fogsim.render.frame.frame_name`)."""
    return len(name) >= 6 and name.isdigit() and name == f"{int(name):06d}"


def recorded_config(out: str | Path) -> tuple[RenderConfig, str | None]:
    """The configuration ``OUT/render_run.json`` records, and the Blender version that claimed the folder.
    No run file: an InputError naming ``out`` ("not a dataset to finalize"); a malformed one names the file."""
    path = Path(out) / RUN_FILE
    if not path.is_file():
        raise InputError(out, f"no {RUN_FILE} here: not a dataset to finalize")
    run = load_json(path, RenderRunFile)
    c = run.config
    if c is None:
        raise InputError(path, "malformed render run file: lacks 'config' (the configuration the frames were "
                               "rendered with)")
    try:
        levels = tuple(FogLevel(lv.key, lv.name, lv.beta) for lv in c.levels)
    except ValueError as exc:
        raise InputError(path, f"malformed render run file: config.levels: {exc}") from None
    config = RenderConfig(
        name=c.name, source=c.source, style=c.style, camera=c.camera, resolution=(c.resolution[0], c.resolution[1]),
        quality=c.quality, levels=levels, fog_model=c.fog_model, labels=c.labels, exposure=c.exposure,
        frames=c.frames, seed=c.seed, stereo_baseline=c.stereo_baseline_m, train_fraction=c.train_fraction,
        lighting=c.lighting, sensor=c.sensor, assets=c.assets, lidar=c.lidar, radar=c.radar)
    return config, run.blender


def _scene_mode(config: RenderConfig) -> dict | None:
    """The ``scene_mode`` record of a scene-mode render's configuration (None: a preset's)."""
    return config.style.get("scene_mode") if isinstance(config.style.get("scene_mode"), dict) else None


def _with_flag(config: RenderConfig, flag: str, value) -> RenderConfig:
    """``config`` with one preset-mode flag applied, as the render would have applied it."""
    from fogsim.render.fog_settings import fog_overrides
    from fogsim.render.preset import lidar_block, load_render_preset, parse_resolution, radar_block, resolve_assets
    from fogsim.scene.library import assets_dir

    if flag == "--preset":
        loaded = load_render_preset(value)
        return replace(config, **{k: getattr(loaded, k) for k in PRESET_KEYS})
    if flag == "--seed":
        return replace(config, seed=value)
    if flag == "--resolution":
        return replace(config, resolution=parse_resolution(value))
    if flag == "--samples":
        return replace(config, quality={**config.quality, "samples": value})
    if flag == "--levels":
        return replace(config, levels=tuple(parse_levels(value)))
    if flag in ("--fog", "--fog-medium", "--fog-scale"):
        kind, medium, scale = (value if flag == f else None for f in ("--fog", "--fog-medium", "--fog-scale"))
        return replace(config, fog_model=fog_overrides(config.fog_model, kind, medium, scale))
    if flag == "--stereo":
        from fogsim.camera import CITYSCAPES_BASELINE_M

        baseline = config.camera.get("stereo_baseline_m", CITYSCAPES_BASELINE_M)
        return config if config.stereo_baseline is not None else replace(config, stereo_baseline=float(baseline))
    if flag == "--assets":
        library = resolve_assets({}, Path(config.source), assets_dir(value), value)
        return replace(config, assets={**config.assets, "files": library["files"]} if config.assets else library)
    if flag == "--lidar":
        return replace(config, lidar=lidar_block(value))
    if flag == "--radar":
        return replace(config, radar=radar_block(value))
    raise AssertionError(flag)


def _scene_flag(scene: dict, config: RenderConfig, flag: str, value) -> tuple[str, object, object]:
    """A scene-mode flag's parameter: ``(name, recorded value, the flag's value)``."""
    from fogsim.render.job_options import parse_frame_range
    from fogsim.render.scene_classes import load_class_map

    if flag == "--scene":  # "current": the file Blender has open, unknown here
        recorded = scene.get("file")
        given = recorded if value == "current" or recorded is None else str(Path(value).expanduser().resolve())
        return "style.scene_mode.file", recorded, given
    if flag == "--camera":
        return "camera.object", config.camera.get("object"), value
    if flag == "--frame-range":
        return "style.scene_mode.frame_range", scene.get("frame_range"), list(parse_frame_range(value))
    return "style.scene_mode.class_map", scene.get("class_map"), load_class_map(value).to_dict()


PRESET_FLAGS = ("--preset", "--seed", "--resolution", "--samples", "--levels", "--fog", "--fog-medium",
                "--fog-scale", "--stereo", "--assets", "--lidar", "--radar")
SCENE_FLAGS = ("--scene", "--camera", "--frame-range", "--class-map")


def _shown(config: RenderConfig) -> dict:
    """A configuration as a difference names it: the levels by their keys."""
    return {**config.to_dict(), "levels": [lv.key for lv in config.levels]}


def check_flags(config: RenderConfig, flags: dict, run_file: str | Path) -> None:
    """Every flag given with ``--finalize-only`` (``flags``: flag → value; None = not given) must say what
    the render recorded: the first that does not is an InputError naming ``run_file``, the flag, the
    parameter and both values. Flags the record decides nothing about (``--frames``, ``--train-fraction``,
    ``--shard``, ``--max-pixels``, ``--quiet``, ``--gpu``, ``--no-resume``) are not checked."""
    scene = _scene_mode(config)
    given = {f: v for f, v in flags.items() if v is not None and v is not False}
    for flag, value in given.items():
        shown = "" if value is True else f" {value}"
        if scene is None and flag in SCENE_FLAGS:
            raise InputError(run_file, f"{flag}{shown}: this dataset was rendered from the preset "
                                       f"{config.name!r}, not from a scene; --finalize-only reads every parameter "
                                       f"from {Path(run_file).name}: leave {flag} out")
        if scene is not None and flag == "--preset":
            raise InputError(run_file, f"--preset{shown}: this dataset was rendered from a scene (--scene "
                                       f"{scene.get('file') or scene.get('scene')}), not a preset; --finalize-only "
                                       f"reads every parameter from {Path(run_file).name}: leave --preset out")
        if flag in SCENE_FLAGS:
            name, old, new = _scene_flag(scene, config, flag, value)
            difference = describe_difference({name: old}, {name: new}, "recorded", f"with {flag}")
        elif flag in PRESET_FLAGS:
            other = _with_flag(config, flag, value)
            difference = (describe_difference(_shown(config), _shown(other), "recorded", f"with {flag}")
                          or describe_difference(config.to_dict(), other.to_dict(), "recorded", f"with {flag}"))
        else:
            continue
        if difference:
            raise InputError(run_file, f"{flag}{shown} disagrees with the render in this folder: {difference}; "
                                       f"--finalize-only reads every parameter from {Path(run_file).name}: "
                                       f"leave {flag} out")


def finalize_render(layout: DatasetLayout, config: RenderConfig, blender: str | None) -> dict:
    """Write the dataset-level files over every committed frame whose record passes the schema (the others are
    skipped and named in ``skipped_frames``); returns ``dataset.json``'s content. ``blender``: the version
    that rendered. ``preset.frames`` is never below the frames the dataset holds (a resume with fewer
    ``--frames`` does not shrink it)."""
    records = frame_records(layout)
    records.skipped += [f"{layout.meta(f)}: not a frame of a render (frame names are 6 digits)"
                        for f in records.frames if not is_frame_name(f)]
    keep = [n for n, f in enumerate(records.frames) if is_frame_name(f)]
    records.frames = [records.frames[n] for n in keep]
    records.metas = [records.metas[n] for n in keep]
    # keys sorted: a configuration read back from render_run.json (written sorted) gives the same bytes
    preset = json.loads(json.dumps(config.to_dict(), sort_keys=True))
    if records.frames:
        preset["frames"] = max(preset["frames"], max(int(f) for f in records.frames) + 1)
    manifest = {"preset": preset, "seed": config.seed,
                "frame_seeds": {f: frame_seed(config.seed, int(f)) for f in records.frames},
                "frame_seed_rule": FRAME_SEED_RULE, "blender": blender, "versions": package_versions()}
    return finalize(layout, config.levels, manifest, config.train_fraction, seed=config.seed, records=records)
