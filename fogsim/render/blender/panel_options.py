"""What the add-on panel's settings mean: the RenderConfig of *Source: procedural preset* (its
overrides: levels, fog model, time of day, sky, HDRI, asset folder) and the scene job of *Source:
current scene*. ``s`` is the scene's ``fogsim`` settings (:class:`fogsim.render.blender.addon.FogsimSettings`);
every problem is a ValueError or InputError naming it, which the operators show in the panel.
"""
from __future__ import annotations

from pathlib import Path

import bpy

from fogsim.schema.presets import HDRI_SUFFIXES


def config(s, frames: int | None = None):
    """The panel's preset with its overrides, checked (a ValueError or InputError names the problem)."""
    from dataclasses import replace

    from fogsim.fog.levels import parse_levels
    from fogsim.render.preset import lidar_block, load_render_preset, radar_block

    volumetric = s.fog_model == "volumetric"
    cfg = load_render_preset(
        s.preset, frames=frames, seed=s.seed, resolution=s.resolution or None, samples=s.samples or None,
        levels=s.levels if s.levels_kind == "beta" else None,
        fog=None if s.fog_model == "PRESET" else s.fog_model,
        fog_medium=s.fog_medium if volumetric and s.fog_medium != "PRESET" else None,
        assets=bpy.path.abspath(s.assets) if s.assets.strip() else None)
    if s.levels_kind == "visibility":
        cfg = replace(cfg, levels=tuple(parse_levels(visibility=s.levels or "-")))
    if s.lidar not in ("PRESET", "NONE"):
        cfg = replace(cfg, lidar=lidar_block(s.lidar))
    elif s.lidar == "NONE":
        cfg = replace(cfg, lidar={})
    if s.radar not in ("PRESET", "NONE"):
        cfg = replace(cfg, radar=radar_block(s.radar))
    elif s.radar == "NONE":
        cfg = replace(cfg, radar={})
    light = lighting(s, cfg.lighting)
    if light is not None:
        cfg = replace(cfg, lighting=light)
    return cfg


def lighting(s, preset_lighting: dict) -> dict | None:
    """The checked ``lighting`` of the panel's *Time of day* and *Sky* (None: the preset's)."""
    from fogsim.schema.presets import check_lighting

    if s.sky == "PRESET":
        return None if s.time_of_day == "PRESET" else check_lighting({"time_of_day": s.time_of_day})
    night = s.time_of_day if s.time_of_day != "PRESET" else (preset_lighting or {}).get("time_of_day")
    if night == "night":
        raise ValueError(f"Sky {s.sky!r} is a day sky: set Time of day to Day (the night has its own sky and lights)")
    sky = {"sky": "hdri", "hdri": hdri(s)} if s.sky == "hdri" else {"overcast": True} if s.sky == "overcast" else {}
    return check_lighting({"time_of_day": "day", **sky})


def hdri(s) -> str:
    """The panel's HDRI: a Blender world HDRI name (its file checked) or an absolute file path."""
    from fogsim.errors import InputError
    from fogsim.render.blender.sky import blender_hdri

    if s.hdri != "FILE":
        if not blender_hdri(s.hdri).is_file():
            raise InputError(blender_hdri(s.hdri), f"HDRI {s.hdri!r}: this Blender does not ship it")
        return s.hdri
    if not s.hdri_file.strip():
        raise ValueError("HDRI file: choose an .exr or .hdr file")
    path = Path(bpy.path.abspath(s.hdri_file)).expanduser()
    if path.suffix.lower() not in HDRI_SUFFIXES:
        raise InputError(path, f"HDRI file: must be {' or '.join(HDRI_SUFFIXES)}")
    if not path.is_file():
        raise InputError(path, "HDRI file: no such file")
    return str(path.resolve())


def run_options(s):
    """How the panel's job runs (:class:`~fogsim.render.job_options.RunOptions`): resumed, GPU as
    asked, Blender's output quiet (the panel shows progress)."""
    from fogsim.render.job_options import RunOptions

    return RunOptions(gpu=s.use_gpu, quiet=True)


def scene_options(s):
    """*Source: current scene*'s :class:`~fogsim.render.job_options.SceneOptions` (the CLI's ``--scene``
    flags, from the panel)."""
    from fogsim.fog.levels import parse_levels
    from fogsim.render.job_options import SceneOptions
    from fogsim.render.scene_classes import load_class_map

    text = s.class_map.strip()
    class_map = load_class_map(text if text.startswith("{") or not text else bpy.path.abspath(text))
    levels = {"beta": s.levels, "visibility": None}.get(s.levels_kind)  # None: the paper's five
    if s.levels_kind == "visibility":
        levels = tuple(parse_levels(visibility=s.levels or "-"))  # FogLevel objects: their keys are vis<V>m
    volumetric = s.fog_model == "volumetric"
    return SceneOptions(camera=s.camera or None, frame_range=s.frame_range or None, class_map=class_map,
                        levels=levels, samples=s.samples or None, resolution=s.resolution or None, seed=s.seed,
                        fog=None if s.fog_model == "PRESET" else s.fog_model,
                        fog_medium=s.fog_medium if volumetric and s.fog_medium != "PRESET" else None,
                        lidar=s.lidar if s.lidar not in ("PRESET", "NONE") else None,
                        radar=s.radar if s.radar not in ("PRESET", "NONE") else None)


def scene_job(s, scene):
    """*Source: current scene*: a scene-mode job over ``scene`` with the panel's options (refusals
    are InputErrors raised before the output folder is touched)."""
    from fogsim.render.blender.scene_mode import scene_job as make_job

    return make_job(scene, bpy.path.abspath(s.output), scene_options(s), run_options(s))
