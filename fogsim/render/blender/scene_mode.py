"""Scene mode: any Blender scene becomes a labelled fog dataset.

    fogsim render --scene FILE.blend [--camera NAME] [--frame-range S:E[:STEP]] [--class-map JSON] --out OUT
    blender -b FILE.blend -P scripts/render_batch.py -- --scene current --out OUT

The add-on's *Source: current scene* calls :func:`scene_job` (``scene_job(bpy.context.scene, out,
…)``) and steps the job it returns with :class:`fogsim.render.loop.FrameLoop`, as it does a
:class:`~fogsim.render.blender.job.RenderJob`; :meth:`SceneJob.close` puts the scene back.

Per frame the user's scene is set to that frame and its evaluated depsgraph walked
(:mod:`fogsim.render.blender.realise`): every visible geometry *instance* (plain objects, linked
duplicates, collection instances, particle and geometry-nodes instances) becomes one realised mesh object — modifiers
applied, the world matrix of that instance, its materials and ray-visibility flags — in a render
scene, a copy of the user's scene (its render settings, world, view layer) whose own collection
holds only those objects, its lights and its camera. An object's pass index is its fogsim id, so
the mask, the boxes and the silhouettes (:mod:`fogsim.render.silhouette`, from the same realised
meshes) agree. The user's data is read only (the frame is restored on close); the ``.blend`` on
disk is never written.

Classes (:mod:`fogsim.render.scene_classes`): ``fogsim_class`` on an object, else the class map's
match of its name; else inherited from its parents, then from its collections. One labelled
object is the labelled ancestor with every unlabelled mesh below it (a labelled parent = the union
of its children); a collection instance is one object per instancer (its class may come from the
instanced collection); particle and geometry-nodes instances are one object each.
Hidden (``hide_render``, an excluded or render-disabled collection) objects are left out; holdout
and camera-invisible objects render as Blender renders them and are never labelled.
Blender's viewport evaluation is walked, made to see what a render sees (``render_visibility``:
objects hidden in viewports but not in renders shown, modifiers as in renders; put back after).
Limits: viewport levels of subdivision and viewport particle amounts apply; volumes, point clouds
and hair curves are not rendered; motion blur is turned off (the realised objects do not move
within a frame).
"""
from __future__ import annotations

import time
from collections import Counter
from pathlib import Path

import bpy
import numpy as np

from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.writer import finalize
from fogsim.deps import package_versions
from fogsim.errors import InputError
from fogsim.fileio import remove_stale_parts
from fogsim.fog.levels import parse_levels
from fogsim.render.blender.compat import has_denoiser, has_mie_phase, set_multilayer_exr
from fogsim.render.blender.cycles import render
from fogsim.render.blender.device import use_device
from fogsim.render.blender.job import RUN_FILE, RenderJob, dataset_parameters
from fogsim.render.blender.output import blender_output
from fogsim.render.blender.realise import SceneClasses, clear, realise, render_visibility
from fogsim.render.fog_settings import fog_overrides
from fogsim.render.frame import DescribedFrame, commit_frame, frame_name
from fogsim.render.leftovers import remove_render_tmp, render_tmp_dir
from fogsim.render.preset import RenderConfig, check_size, frame_volumetric, parse_resolution, volumetric_settings
from fogsim.render.scene_classes import PROPERTY, ClassMap
from fogsim.runs import FRAME_SEED_RULE, claim_output, frame_seed
from fogsim.scene.pose import blender_intrinsics, opencv_world_to_camera

RENDER_SCENE = "fogsim_scene_mode"


def open_blend(path: str | Path, quiet: bool = False):
    """Load ``path`` into this Blender session (read only: nothing is saved); its active scene."""
    p = Path(path)
    if not p.is_file():
        raise InputError(path, "no such .blend file")
    try:
        with blender_output(quiet):
            bpy.ops.wm.open_mainfile(filepath=str(p.resolve()), load_ui=False)
    except RuntimeError as exc:
        raise InputError(path, f"Blender cannot open it ({str(exc).strip()})") from None
    return bpy.context.scene


def open_scene(arg: str, quiet: bool = False):
    """``--scene``: "current" = the scene Blender has open (``blender -b FILE.blend -P …``), else a
    .blend path opened with :func:`open_blend`."""
    return bpy.context.scene if arg == "current" else open_blend(arg, quiet)


def parse_frame_range(text: str | None, scene) -> tuple[int, int, int]:
    """``--frame-range S:E[:STEP]`` (inclusive, as Blender's) or the scene's own range."""
    if not text:
        return scene.frame_start, scene.frame_end, max(1, scene.frame_step)
    try:
        parts = [int(v) for v in text.split(":")]
        start, end, step = (parts + [1])[:3] if len(parts) in (2, 3) else (None, None, None)
    except ValueError:
        start = None
    if start is None or step < 1 or end < start:
        raise ValueError(f"--frame-range must look like START:END or START:END:STEP with END ≥ START and "
                         f"STEP ≥ 1, got {text!r}")
    return start, end, step


def scene_camera(scene, name: str | None, source: str):
    """The camera object to render through: ``name`` or the scene's; refused when missing,
    orthographic or panoramic."""
    if name:
        cam = bpy.data.objects.get(name)
        if cam is None or cam.type != "CAMERA":
            raise InputError(source, f"no camera object named {name!r} (cameras: "
                                     f"{', '.join(o.name for o in bpy.data.objects if o.type == 'CAMERA') or 'none'})")
    else:
        cam = scene.camera
        if cam is None:
            raise InputError(source, f"scene {scene.name!r} has no active camera; pass --camera NAME")
    if cam.data.type != "PERSP":
        kind = {"ORTHO": "orthographic", "PANO": "panoramic"}.get(cam.data.type, cam.data.type)
        raise InputError(source, f"camera {cam.name!r} is {kind}; fogsim needs a perspective camera "
                                 "(depth, boxes and fog assume a pinhole)")
    return cam


def _render_scene(user_scene, resolution):
    """A copy of the user's scene (render settings, world, first view layer) with an empty collection."""
    copy = user_scene.copy()
    copy.name = RENDER_SCENE
    for child in list(copy.collection.children):
        copy.collection.children.unlink(child)
    for obj in list(copy.collection.objects):
        copy.collection.objects.unlink(obj)
    for layer in list(copy.view_layers)[1:]:
        copy.view_layers.remove(layer)
    copy.view_layers[0].name = "ViewLayer"  # the multilayer EXR's channel prefix (cycles.PASS_CHANNELS)
    if resolution:
        copy.render.resolution_x, copy.render.resolution_y = resolution
        copy.render.resolution_percentage = 100
    return copy


def configure_scene(scene, samples: int | None, seed: int, gpu: bool) -> tuple[dict, list[str]]:
    """The scene's own Cycles settings, with what fogsim needs (passes, EXR output, seed, device)
    and ``samples`` if given; returns what was used and the changes worth a message."""
    notes = []
    if scene.render.engine != "CYCLES":
        notes.append(f"render engine {scene.render.engine} switched to CYCLES")
        scene.render.engine = "CYCLES"
    device = use_device(scene, gpu)
    cy = scene.cycles
    if samples:
        cy.samples = int(samples)
    if cy.use_denoising and not has_denoiser():
        cy.use_denoising = False
        notes.append("denoising off: this Blender has no OpenImageDenoise")
    if scene.render.use_motion_blur:
        scene.render.use_motion_blur = False
        notes.append("motion blur off (scene mode renders each frame's realised objects)")
    cy.seed = int(seed) % 2**31
    cy.use_animated_seed = False
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    layer = scene.view_layers[0]
    layer.use_pass_combined = layer.use_pass_z = layer.use_pass_object_index = True
    set_multilayer_exr(scene.render.image_settings)
    return {**device, "engine": "CYCLES", "samples": cy.samples, "denoise": cy.use_denoising,
            "adaptive_threshold": cy.adaptive_threshold if cy.use_adaptive_sampling else None,
            "max_bounces": cy.max_bounces, "seed": cy.seed}, notes


def camera_record(scene, camera_obj) -> dict:
    """K (Blender's definition: focal, sensor size and fit, shift, pixel aspect, resolution) and
    the OpenCV pose of the evaluated camera at the scene's current frame."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    ev = camera_obj.evaluated_get(depsgraph)
    cam, r = ev.data, scene.render
    w = int(r.resolution_x * r.resolution_percentage / 100)
    h = int(r.resolution_y * r.resolution_percentage / 100)
    K = blender_intrinsics(cam.lens, cam.sensor_width, cam.sensor_height, cam.sensor_fit, cam.shift_x,
                           cam.shift_y, w, h, r.pixel_aspect_x, r.pixel_aspect_y)
    from fogsim.camera import Intrinsics

    return {"intrinsics": Intrinsics.from_dict(K).to_dict(),
            "world_to_camera": opencv_world_to_camera(np.array(ev.matrix_world)).tolist(),
            "blender": {"object": camera_obj.name, "lens_mm": cam.lens, "sensor_mm": [cam.sensor_width,
                        cam.sensor_height], "sensor_fit": cam.sensor_fit, "shift": [cam.shift_x, cam.shift_y],
                        "pixel_aspect": [r.pixel_aspect_x, r.pixel_aspect_y],
                        "clip_m": [cam.clip_start, cam.clip_end]}}


# ----------------------------------------------------------------------------- the job
class SceneJob(RenderJob):
    """The frames of one shard of a scene-mode dataset (the same ``todo`` / ``step`` / ``finish``
    / ``close`` as :class:`~fogsim.render.blender.job.RenderJob`, whose volumetric fog renders it
    shares). Build it with :func:`scene_job`."""

    def __init__(self, scene, out, *, source: str, camera: str | None = None, frame_range: str | None = None,
                 class_map: ClassMap = ClassMap(), levels: str | list | None = None, samples: int | None = None,
                 resolution: str | None = None, seed: int = 0, shard=(0, 1), resume: bool = True,
                 gpu: bool = False, quiet: bool = False, max_pixels: int | None = None,
                 fog: str | None = None, fog_medium: str | None = None, fog_model: dict | None = None):
        self.user_scene, self.quiet, self.gpu, self.samples = scene, quiet, gpu, samples
        self.frame_before = scene.frame_current
        self.render_scene = self.scene = None
        try:
            self._setup(out, source, camera, frame_range, class_map, levels, resolution, seed, shard, resume,
                        max_pixels, fog_overrides(dict(fog_model or {}), fog, fog_medium))
        except BaseException:  # a refusal leaves the user's scene as it was
            self.close()
            raise

    def _setup(self, out, source, camera, frame_range, class_map, levels, resolution, seed, shard, resume,
               max_pixels, fog_model) -> None:
        from fogsim.render.preset import MAX_PIXELS

        self.layout = DatasetLayout(out)
        self.camera = scene_camera(self.user_scene, camera, source)
        scene, samples = self.user_scene, self.samples
        start, end, step = parse_frame_range(frame_range, scene)
        self.frames = range(start, end + 1, step)  # Blender frame numbers, by dataset frame index
        res = parse_resolution(resolution) if resolution else None
        w = res[0] if res else int(scene.render.resolution_x * scene.render.resolution_percentage / 100)
        h = res[1] if res else int(scene.render.resolution_y * scene.render.resolution_percentage / 100)
        if why := check_size(w, h, max_pixels or MAX_PIXELS):
            raise InputError(source, f"resolution {why}")
        self.classes = SceneClasses(scene, class_map)
        self.config = RenderConfig(
            name="scene", source=source,
            style={"scene_mode": {"file": bpy.data.filepath or None, "scene": scene.name, "camera": self.camera.name,
                                  "frame_range": [self.frames.start, self.frames.stop - 1, self.frames.step],
                                  "class_map": class_map.to_dict()}},
            camera={"object": self.camera.name}, resolution=(w, h),
            quality={"samples": samples} if samples else {},  # {}: the scene's own Cycles settings
            levels=_levels(levels), fog_model=fog_model,
            frames=len(self.frames), seed=seed)
        self.fog = volumetric_settings(self.config)  # None: Koschmieder fog (post-process)
        if self.fog is not None and self.fog["samples"] is None:  # the scene's own samples, not a preset's
            self.fog = {**self.fog, "samples": samples or scene.cycles.samples}
        if self.fog is not None and self.fog["phase"] == "MIE" and not has_mie_phase():
            raise InputError(source, f"fog_model.volumetric.phase \"MIE\" needs Blender 4.3 or later "
                                     f"(this is {bpy.app.version_string}); use \"HG\" with g = 0.85")
        i, n = shard
        mine = [k for k in range(len(self.frames)) if k % n == i]
        self.summary = self._check(mine[0] if mine else 0, source)  # refusals before anything is written
        Path(out).mkdir(parents=True, exist_ok=True)
        claim_output(Path(out) / RUN_FILE, dataset_parameters(self.config),
                     {"blender": bpy.app.version_string, "config": self.config.to_dict()}, what="dataset")
        self.mine = {frame_name(k) for k in mine}
        remove_stale_parts(self.layout.root)
        remove_render_tmp(self.layout, self.mine)
        self.todo = [k for k in mine if not (resume and self.layout.frame_done(frame_name(k)))]
        self.skipped = len(mine) - len(self.todo)
        self.done: list[dict] = []
        self.render_scene = self.scene = _render_scene(scene, res)  # self.scene: RenderJob's fog renders
        self.notes = configure_scene(self.render_scene, samples, 0, self.gpu)[1]

    def _check(self, index: int, source: str) -> str:
        """Realise frame ``index`` once: a scene with no labelled visible object is refused; returns
        the per-class count of labelled objects and instances."""
        self.user_scene.frame_set(self.frames[index])
        probe = bpy.data.scenes.new("fogsim_probe")
        try:
            with render_visibility(self.user_scene):
                got = realise(self.user_scene, probe, self.classes, self.camera)
            clear(got)
        finally:
            bpy.data.scenes.remove(probe)
        if not got.labelled:
            raise InputError(source, f"no labelled object in scene {self.user_scene.name!r} at frame "
                                     f"{self.frames[index]}: set the custom property {PROPERTY} (e.g. \"car\") on "
                                     "objects or collections, or pass --class-map")
        counts = Counter((r["class"], r["kind"]) for r in got.labelled.values())
        per_class = ", ".join(f"{cls} {counts[cls, 'object']} objects + {counts[cls, 'instance']} instances"
                              for cls in sorted({c for c, _ in counts}))
        skipped = "".join(f", {n} {t.lower()} not rendered" for t, n in sorted(got.skipped.items()))
        return (f"scene {self.user_scene.name!r} frame {self.frames[index]}: labelled {per_class}; "
                f"{got.background} background instances{skipped}")

    def step(self) -> dict:
        """Render and commit the next frame; returns its meta record."""
        index = self.todo.pop(0)
        t0 = time.perf_counter()
        frame_no = self.frames[index]
        self.user_scene.frame_set(frame_no)
        self.render_scene.frame_current = frame_no  # the shared camera and light data animate with it
        info, _ = configure_scene(self.render_scene, self.samples, frame_seed(self.config.seed, index), self.gpu)
        with render_visibility(self.user_scene):
            got = realise(self.user_scene, self.render_scene, self.classes, self.camera)
        t1 = time.perf_counter()
        name = frame_name(index)
        objects = [{"id": oid, **rec} for oid, rec in got.labelled.items()]
        desc = {"seed": frame_seed(self.config.seed, index), "objects": objects,
                "source": {**self.config.style["scene_mode"], "blender_frame": frame_no},
                "background_instances": got.background}
        try:
            desc["camera"] = camera_record(self.render_scene, self.camera)
            passes = render(self.render_scene, render_tmp_dir(self.layout) / f"{name}.left.exr", self.quiet)
            t2 = time.perf_counter()
            if self.fog is not None:  # one Combined-only render per β > 0 with the fog layer, same seed
                fog = frame_volumetric(self.fog, desc)
                fog_linear, fog_cycles = self._fog_renders(got, fog, info["seed"],
                                                           render_tmp_dir(self.layout) / f"{name}.fog.exr")
        finally:
            clear(got)
        t3 = time.perf_counter()
        info["blender"] = bpy.app.version_string
        timings = {"scene": t1 - t0, "render": t2 - t1}
        fog_renders = None
        if self.fog is not None:
            timings["fog_render"] = t3 - t2
            fog_renders = self._fog_images(name, desc, passes, fog, fog_linear, fog_cycles)
        frame = DescribedFrame(index, desc, got.parts)
        meta = commit_frame(self.layout, self.config, frame, passes, fog_renders, timings=timings, render_info=info)
        self.done.append(meta)
        return meta

    def finish(self) -> None:
        """Write the dataset-level files (COCO, YAMLs, manifest, contact sheet) over all done frames."""
        frames = self.layout.done_frames()
        manifest = {"preset": self.config.to_dict(), "seed": self.config.seed,
                    "frame_seeds": {f: frame_seed(self.config.seed, int(f)) for f in frames},
                    "frame_seed_rule": FRAME_SEED_RULE, "blender": bpy.app.version_string,
                    "versions": package_versions()}
        finalize(self.layout, self.config.levels, manifest, self.config.train_fraction, seed=self.config.seed)

    def close(self) -> None:
        """Remove the render scene and temporary renders; the user's scene back at its frame."""
        if hasattr(self, "mine"):
            remove_render_tmp(self.layout, self.mine)
        if self.render_scene is not None and self.render_scene.name in bpy.data.scenes:
            bpy.data.scenes.remove(self.render_scene)
        self.render_scene = self.scene = None
        self.user_scene.frame_set(self.frame_before)


def _levels(levels) -> tuple:
    """``levels``: a ``--levels`` string (None: the paper's five) or FogLevel objects as they are."""
    if levels is None or isinstance(levels, str):
        return tuple(parse_levels(levels if levels is not None else "paper"))
    return tuple(levels)


def scene_job(scene, out, **options) -> SceneJob:
    """The add-on's *Source: current scene* (and the CLI's ``--scene``): a :class:`SceneJob` over
    ``scene`` writing the dataset to ``out``. ``options``: ``source`` (what error messages name;
    default the .blend path), ``camera``, ``frame_range`` ("S:E[:STEP]"), ``class_map``
    (:class:`~fogsim.render.scene_classes.ClassMap`), ``levels`` (a ``--levels`` string or a list of
    :class:`~fogsim.fog.levels.FogLevel`, e.g. from visibilities), ``samples``, ``resolution``
    ("WxH"), ``seed``, ``shard``, ``resume``, ``gpu``, ``quiet``, ``fog`` ("koschmieder" | "volumetric"),
    ``fog_medium``, ``fog_model`` (a preset's ``fog_model`` block). Every refusal (no labelled object,
    missing / orthographic / panoramic camera …) is an InputError raised before ``out`` is touched."""
    options.setdefault("source", bpy.data.filepath or f"scene {scene.name!r}")
    return SceneJob(scene, out, **options)
