"""Render a dataset frame by frame: describe → build → render → clear → commit.

:class:`RenderJob` renders one frame per :meth:`RenderJob.step`, so the batch script can
loop and the add-on's modal operator can step from a timer (progress bar, cancel).

Before the dataset folder is claimed (``render_run.json``) the first frame's scene is
described, so a preset the layout cannot use is a setup error, not a failure of every frame.
Cycles writes into ``OUT/.fogsim_tmp``; a starting job removes what a killed one left of its
own frames there and beside the outputs (:mod:`fogsim.render.leftovers`).
"""
from __future__ import annotations

import time
from contextlib import nullcontext
from dataclasses import replace
from pathlib import Path

import bpy
import numpy as np

from fogsim.dataset.layout import DatasetLayout
from fogsim.depth.stereo import right_world_to_camera
from fogsim.errors import InputError
from fogsim.io.parts import remove_stale_parts
from fogsim.render.blender import build as scene_build
from fogsim.render.blender import fog_volume
from fogsim.render.blender.compat import has_mie_phase
from fogsim.render.blender.cycles import configure, render, render_combined
from fogsim.render.blender.library import load_library
from fogsim.render.blender.motion import motion_blur
from fogsim.render.blender.scratch import clear
from fogsim.render.finalize import GROWABLE, RUN_FILE, dataset_parameters, finalize_render
from fogsim.render.fog_settings import frame_volumetric, volumetric_settings
from fogsim.render.frame import DescribedFrame, FogRenders, FramePasses, check_scene, commit_frame, frame_name
from fogsim.render.job_options import RunOptions
from fogsim.render.leftovers import remove_render_tmp, render_tmp_dir
from fogsim.render.preset import RenderConfig
from fogsim.runs import claim_output, frame_seed
from fogsim.scene.motion import frame_motion

SCENE_NAME = "fogsim"


def _legacy_parameters(old: dict) -> dict | None:
    """The parameters of a render_run.json written by fogsim 0.1 (which stored the whole config)."""
    if "config" not in old:
        return None
    params = {k: v for k, v in old["config"].items() if k not in GROWABLE}
    params.setdefault("stereo_baseline_m", None)  # datasets from before stereo existed
    return params


def refuse_mie(fog: dict | None, source: str) -> None:
    """The Mie phase function is Blender 4.3+: refused (naming the preset) on an older Blender."""
    if fog is not None and fog["phase"] == "MIE" and not has_mie_phase():
        raise InputError(source, f"fog_model.volumetric.phase \"MIE\" needs Blender 4.3 or later "
                                 f"(this is {bpy.app.version_string}); use \"HG\" with g = 0.85")


class RenderJob:
    """The frames of one shard still to render, and the means to render them: the procedural
    streets of a preset. :meth:`claim` is the set-up every job shares (scene mode's
    :class:`~fogsim.render.blender.scene_mode.SceneJob` too), :meth:`finish` the end.

    ``run``: the shard, resume, GPU (:mod:`fogsim.render.blender.device`) and quiet (Blender's own
    output shows errors only, :mod:`fogsim.render.blender.output`) — :class:`~fogsim.render.job_options.RunOptions`.
    """

    def __init__(self, config: RenderConfig, out: str | Path, run: RunOptions = RunOptions()):
        self.config, self.run, self.gpu, self.quiet = config, run, run.gpu, run.quiet
        # the user's models, imported once for the whole run (a refused one is a setup error, exit 2)
        self.assets = load_library(config.assets, run.quiet) if config.assets else None
        self.library = self.assets.library if self.assets else None
        # a preset the layout cannot use must not claim the folder (setup error, exit 2)
        self.claim(out, lambda first: check_scene(config, first, self.library))
        self.scene = bpy.data.scenes.get(SCENE_NAME) or bpy.data.scenes.new(SCENE_NAME)

    def claim(self, out: str | Path, check_first) -> None:
        """The set-up of every job, in this order, so that a refusal leaves ``out`` untouched: the
        volumetric fog's settings (the Mie phase refused on an old Blender), this shard's frames,
        ``check_first(index)`` on the first of them (whole-run problems: exit 2 before anything is
        written), then the claim of ``OUT/render_run.json``, the clean-up of a killed run's leftovers
        and the frames still to do (``todo``)."""
        config = self.config
        self.layout = DatasetLayout(out)
        self.fog = volumetric_settings(config)  # None: post-process fog (Koschmieder, scatter)
        refuse_mie(self.fog, config.source)
        mine = self.run.frames(config.frames)
        if len(mine):
            check_first(mine[0])
        Path(out).mkdir(parents=True, exist_ok=True)
        claim_output(Path(out) / RUN_FILE, dataset_parameters(config),
                     {"blender": bpy.app.version_string, "config": config.to_dict()},
                     what="dataset", legacy=_legacy_parameters)
        self.mine = {frame_name(k) for k in mine}
        remove_stale_parts(self.layout.root)  # a killed run's unfinished writes (dead writers only)
        remove_render_tmp(self.layout, self.mine)  # and its Cycles EXRs of this shard's frames
        self.todo = [k for k in mine if not (self.run.resume and self.layout.frame_done(frame_name(k)))]
        self.skipped = len(mine) - len(self.todo)

    def step(self) -> dict:
        """Render and commit the next frame; returns its meta record."""
        index = self.todo.pop(0)
        t0 = time.perf_counter()
        frame = DescribedFrame.of(self.config, index, self.library)
        desc = frame.desc
        t1 = time.perf_counter()
        info = configure(self.scene, self.config.quality, frame_seed(self.config.seed, index), self.gpu)
        built = scene_build.build(desc, self.scene, frame.meshes, self.assets)
        t2 = time.perf_counter()
        right = fog_linear = fog_cycles = None
        tmp = render_tmp_dir(self.layout)
        name = frame_name(index)
        motion = frame_motion(self.config.sensor.get("motion_blur"), desc, frame_seed(self.config.seed, index))
        blurred = (lambda: motion_blur(built, self.scene, motion)) if motion else nullcontext
        try:
            passes = render(self.scene, tmp / f"{name}.left.exr", self.quiet)
            if motion is not None:  # the image again with motion blur; labels, depth, masks stay sharp
                with blurred():
                    passes = replace(passes, rgb_linear=render_combined(self.scene, tmp / f"{name}.blur.exr",
                                                                        self.quiet))
                info["motion_blur"] = motion
            t_clear = time.perf_counter()
            if self.fog is not None:  # one Combined-only render per β > 0, fog layer in place, same seed
                fog = frame_volumetric(self.fog, desc)
                with blurred():
                    fog_linear, fog_cycles = self._fog_renders(built, fog, info["seed"], tmp / f"{name}.fog.exr")
            t_fog = time.perf_counter()
            if self.config.stereo_baseline:  # the right camera of a rectified pair, same scene
                w2c = right_world_to_camera(desc["camera"]["world_to_camera"], self.config.stereo_baseline)
                scene_build.set_camera_pose(self.scene, w2c)
                right = render(self.scene, tmp / f"{name}.right.exr", self.quiet).rgb_linear
        finally:
            clear(built)
        t3 = time.perf_counter()
        info["blender"] = bpy.app.version_string
        timings = {"scene": t1 - t0, "bpy_build": t2 - t1, "render": t3 - t2}
        fog_renders = None
        if self.fog is not None:
            timings = {"scene": t1 - t0, "bpy_build": t2 - t1, "render": (t_clear - t2) + (t3 - t_fog),
                       "fog_render": t_fog - t_clear}
            fog_renders = self._fog_images(name, desc, passes, fog, fog_linear, fog_cycles)
        meta = commit_frame(self.layout, self.config, frame, replace(passes, right_linear=right), fog_renders,
                            timings=timings, render_info=info)
        return meta

    def _fog_renders(self, built, fog: dict, seed: int, exr_path) -> tuple[dict, dict]:
        """Linear Combined renders of every level with β > 0 (level key → H×W×3), and the
        Cycles settings they had; the scene's settings are restored afterwards."""
        domain = fog_volume.build_domain(built, self.scene, fog)
        out = {}
        with fog_volume.fog_render_settings(self.scene, fog, self.config.quality, seed) as used:
            for lv in self.config.levels:
                if lv.beta > 0:
                    fog_volume.set_density(domain, lv.beta)
                    out[lv.key] = render_combined(self.scene, exr_path, self.quiet)
        return out, dict(used, phase=domain.phase)

    def _fog_images(self, name: str, desc: dict, passes: FramePasses, fog: dict, fog_linear: dict,
                    cycles_used: dict) -> FogRenders:
        """8-bit images per level (clear level = the clear render), linear EXRs if asked, meta["fog"]."""
        from fogsim.camera import Intrinsics, planar_to_ray
        from fogsim.colour import linear_to_srgb8
        from fogsim.fog.physics import far_luminance
        from fogsim.io.exr import write_rgb_exr
        from fogsim.render.fog_rebuild import RULE, rebuild
        from fogsim.render.volumetric import auto_exposure

        s, cfg = fog, self.config
        ray = planar_to_ray(passes.depth, Intrinsics.from_dict(desc["camera"]["intrinsics"]))
        foggy, factors, horizon, linear = {}, {}, {}, {}
        for lv in cfg.levels:
            if lv.beta == 0:
                foggy[lv.key] = linear_to_srgb8(passes.rgb_linear, cfg.exposure)
                img = passes.rgb_linear
            else:
                img = fog_linear[lv.key]
                if img.shape != passes.rgb_linear.shape:  # cheap fog: rendered at resolution_scale
                    img = rebuild(passes.rgb_linear, img, ray, lv.beta)
                factors[lv.key] = auto_exposure(passes.rgb_linear, img) if s["exposure"] == "auto" else 1.0
                horizon[lv.key] = far_luminance(img, ray, lv.beta)  # the horizon radiance
                foggy[lv.key] = linear_to_srgb8(img * np.float32(factors[lv.key]), cfg.exposure)
            if s["keep_linear"]:  # the renders before any exposure scale
                write_rgb_exr(self.layout.linear(lv.key, name), img)
                linear[lv.key] = self.layout.relative(self.layout.linear(lv.key, name))
        medium = {"full": ("g", "phase"), "hybrid": ("g", "phase", "scatter_fraction", "emission"),
                  "ea": ("emission",)}[s["medium"]]
        info = {"model": "volumetric", "medium": s["medium"], **{k: s[k] for k in medium},
                "layer_height_m": s["layer_height_m"], "extent_m": s["extent_m"], "domain": "box",
                "volume_bounces": cycles_used["volume_bounces"], "max_bounces": cycles_used["max_bounces"],
                "samples": cycles_used["samples"], "denoise": cycles_used["denoise"],
                "exposure": s["exposure"], "exposure_rule": "median luminance → the clear render's"
                if s["exposure"] == "auto" else None, "exposure_factor": factors,
                "horizon_radiance": horizon, "horizon_rule": "median linear luminance beyond ln(20)/β",
                "resolution_scale": s["resolution_scale"],
                "rebuild_rule": RULE if cycles_used["resolution_percentage"] < 100 else None,
                "seed": cycles_used["seed"], "noise_seed": s["noise_seed"], "cycles": cycles_used,
                "linear": linear or None, "clear_level": "the clear render (labels, depth, masks come from it)"}
        if "phase" in medium:  # what Blender was given (MIE: the droplet diameter replaces g)
            info["phase"] = cycles_used["phase"]
            if info["phase"] == "MIE":
                info["diameter_um"] = s["diameter_um"]
        return FogRenders(foggy, info)

    def finish(self) -> dict:
        """Write the dataset-level files over all done frames (:func:`fogsim.render.finalize.finalize_render`);
        returns ``dataset.json``'s content."""
        return finalize_render(self.layout, self.config, bpy.app.version_string)

    def close(self) -> None:
        """Remove the scene and this job's temporary renders (the folder too, once empty)."""
        remove_render_tmp(self.layout, self.mine)
        if self.assets is not None:
            self.assets.remove()
            self.assets = None
        if self.scene is not None and self.scene.name in bpy.data.scenes and len(bpy.data.scenes) > 1:
            bpy.data.scenes.remove(self.scene)
        self.scene = None
