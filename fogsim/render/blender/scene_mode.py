"""Scene mode: any Blender scene becomes a labelled fog dataset.

    fogsim render --scene FILE.blend [--camera NAME] [--frame-range S:E[:STEP]] [--class-map JSON] --out OUT
    blender -b FILE.blend -P scripts/render_batch.py -- --scene current --out OUT

The add-on's *Source: current scene* calls :func:`scene_job` (``scene_job(bpy.context.scene, out,
SceneOptions(…), RunOptions(…))``) and steps the job it returns with :class:`fogsim.render.loop.FrameLoop`, as
it does a :class:`~fogsim.render.blender.job.RenderJob`; :meth:`SceneJob.close` puts the scene back.

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

import math
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path

import bpy
import numpy as np

from fogsim.errors import InputError
from fogsim.fog.levels import parse_levels
from fogsim.render.blender.compat import has_denoiser, set_multilayer_exr
from fogsim.render.blender.cycles import render
from fogsim.render.blender.device import use_device
from fogsim.render.blender.job import RenderJob
from fogsim.render.blender.output import blender_output
from fogsim.render.blender.realise import SceneClasses, realise, render_visibility
from fogsim.render.blender.scratch import clear
from fogsim.render.fog_settings import fog_overrides, frame_volumetric
from fogsim.render.frame import DescribedFrame, commit_frame, frame_name
from fogsim.render.job_options import RunOptions, SceneOptions, check_frames, parse_frame_range
from fogsim.render.leftovers import remove_render_tmp, render_tmp_dir
from fogsim.render.lidar_rig import KITTI_CAMERA_OFFSET, LIDAR_PROPERTY, camera_offset_pose, object_pose
from fogsim.render.lidar_scan import Geometry
from fogsim.render.preset import RenderConfig, check_size, parse_resolution
from fogsim.render.radar_frame import RADAR_CAMERA_OFFSET, RADAR_PROPERTY
from fogsim.render.scene_classes import PROPERTY
from fogsim.runs import frame_seed
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


def frame_range(text: str | None, scene, source: str) -> tuple[int, int, int]:
    """``--frame-range S:E[:STEP]`` (inclusive, as Blender's; :func:`fogsim.render.job_options.parse_frame_range`)
    or the scene's own range, which is checked as the flag is (an InputError naming the .blend)."""
    if text:
        return parse_frame_range(text)
    start, end, step = scene.frame_start, scene.frame_end, max(1, scene.frame_step)
    try:
        check_frames(start, end, f"scene {scene.name!r}'s frame range")
    except ValueError as exc:
        raise InputError(source, str(exc)) from None
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


def check_libraries(source: str) -> None:
    """Refuse a scene that links from a library file that is missing (Blender leaves its objects out
    without an error: the refusal would otherwise be "no labelled object")."""
    for lib in bpy.data.libraries:
        path = Path(bpy.path.abspath(lib.filepath))
        if not path.is_file():
            raise InputError(source, f"links data from {lib.filepath!r}, which is missing ({path}): Blender "
                                     "leaves its objects out; restore the library or make the data local")


def lidar_object(scene, prop: str = LIDAR_PROPERTY):
    """The object of ``scene`` marked as the LiDAR (custom property ``fogsim_lidar``; ``prop``
    ``fogsim_radar``: the radar), or None; two are refused (one sensor of a kind per dataset)."""
    marked = [o for o in scene.objects if prop in o]
    if len(marked) > 1:
        raise InputError(f"scene {scene.name!r}", f"{len(marked)} objects carry {prop} "
                         f"({', '.join(o.name for o in marked)}): mark one")
    return marked[0] if marked else None


def render_size(scene, source: str) -> tuple[int, int]:
    """The scene's render size in pixels (resolution × percentage), refused (naming the .blend and the
    setting) when it makes no image."""
    r = scene.render
    w, h = int(r.resolution_x * r.resolution_percentage / 100), int(r.resolution_y * r.resolution_percentage / 100)
    if w < 1 or h < 1:
        raise InputError(source, f"scene {scene.name!r} renders {w}×{h} pixels (resolution {r.resolution_x}×"
                                 f"{r.resolution_y} at {r.resolution_percentage} %); set the resolution or pass "
                                 "--resolution WxH")
    return w, h


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


def camera_record(scene, camera_obj, size: tuple[int, int], source: str) -> dict:
    """K (Blender's definition: focal, sensor size and fit, shift, pixel aspect, at the render ``size``
    (w, h) in pixels) and the OpenCV pose of the evaluated camera at the scene's current frame; a camera that makes no
    image (a focal length, sensor or pixel aspect that is not a positive number, a pose that is not
    finite) is an InputError naming ``source``, the camera and the frame."""
    from fogsim.camera import Intrinsics

    depsgraph = bpy.context.evaluated_depsgraph_get()
    ev = camera_obj.evaluated_get(depsgraph)
    cam, r = ev.data, scene.render
    where = f"camera {camera_obj.name!r} at frame {scene.frame_current}"
    lens = {"focal length (mm)": cam.lens, "sensor width (mm)": cam.sensor_width,
            "sensor height (mm)": cam.sensor_height, "pixel aspect x": r.pixel_aspect_x,
            "pixel aspect y": r.pixel_aspect_y}
    bad = {k: v for k, v in lens.items() if not (math.isfinite(v) and v > 0)}
    if bad or not (math.isfinite(cam.shift_x) and math.isfinite(cam.shift_y)):
        raise InputError(source, f"{where}: unusable lens ({', '.join(f'{k} {v}' for k, v in bad.items()) or 'shift'})")
    matrix = np.array(ev.matrix_world)
    if not np.isfinite(matrix).all():
        raise InputError(source, f"{where}: its position or rotation is not finite (NaN or inf in its world matrix)")
    w, h = size
    K = blender_intrinsics(cam.lens, cam.sensor_width, cam.sensor_height, cam.sensor_fit, cam.shift_x,
                           cam.shift_y, w, h, r.pixel_aspect_x, r.pixel_aspect_y)
    try:
        K = Intrinsics.from_dict(K).to_dict()
    except (InputError, ValueError) as exc:
        raise InputError(source, f"{where}: {exc}") from None
    return {"intrinsics": K, "world_to_camera": opencv_world_to_camera(matrix).tolist(),
            "blender": {"object": camera_obj.name, "lens_mm": cam.lens, "sensor_mm": [cam.sensor_width,
                        cam.sensor_height], "sensor_fit": cam.sensor_fit, "shift": [cam.shift_x, cam.shift_y],
                        "pixel_aspect": [r.pixel_aspect_x, r.pixel_aspect_y],
                        "clip_m": [cam.clip_start, cam.clip_end]}}


# ----------------------------------------------------------------------------- the job
class SceneJob(RenderJob):
    """The frames of one shard of a scene-mode dataset: :class:`~fogsim.render.blender.job.RenderJob`'s
    set-up (:meth:`~fogsim.render.blender.job.RenderJob.claim`), ``todo`` / ``step`` / ``finish`` /
    ``close``, and its volumetric fog renders, over a user's scene. ``options``: what to render
    (:class:`~fogsim.render.job_options.SceneOptions`); ``run``: the shard, resume, GPU, quiet."""

    def __init__(self, scene, out, options: SceneOptions = SceneOptions(), run: RunOptions = RunOptions()):
        self.user_scene, self.options, self.run = scene, options, run
        self.gpu, self.quiet, self.samples = run.gpu, run.quiet, options.samples
        self.frame_before = scene.frame_current
        self.render_scene = self.scene = self.assets = None
        try:
            self._setup(out)
        except BaseException:  # a refusal leaves the user's scene as it was
            self.close()
            raise

    def _setup(self, out) -> None:
        from fogsim.io.pixel_bound import MAX_PIXELS

        o, scene = self.options, self.user_scene
        source = o.source or bpy.data.filepath or f"scene {scene.name!r}"
        check_libraries(source)
        self.camera = scene_camera(scene, o.camera, source)
        start, end, step = frame_range(o.frame_range, scene, source)
        self.frames = range(start, end + 1, step)  # Blender frame numbers, by dataset frame index
        res = parse_resolution(o.resolution) if o.resolution else None
        w, h = res if res else render_size(scene, source)
        if why := check_size(w, h, o.max_pixels or MAX_PIXELS):
            raise InputError(source, f"resolution {why}")
        self.classes = SceneClasses(scene, o.class_map)
        self.config = RenderConfig(
            name="scene", source=source,
            style={"scene_mode": {"file": bpy.data.filepath or None, "scene": scene.name, "camera": self.camera.name,
                                  "frame_range": [self.frames.start, self.frames.stop - 1, self.frames.step],
                                  "class_map": o.class_map.to_dict()}},
            camera={"object": self.camera.name}, resolution=(w, h),
            quality={"samples": o.samples} if o.samples else {},  # {}: the scene's own Cycles settings
            levels=_levels(o.levels),
            fog_model=fog_overrides(dict(o.fog_model or {}), o.fog, o.fog_medium, o.fog_scale),
            frames=len(self.frames), seed=o.seed, lidar=o.lidar_block(), radar=o.radar_block())
        self.lidar_object = lidar_object(scene) if self.config.lidar else None
        self.radar_object = lidar_object(scene, RADAR_PROPERTY) if self.config.radar else None
        self.claim(out, lambda first: setattr(self, "summary", self._check(first, source)))
        if self.fog is not None and self.fog["samples"] is None:  # the scene's own samples, not a preset's
            self.fog = {**self.fog, "samples": o.samples or scene.cycles.samples}
        self.render_scene = self.scene = _render_scene(scene, res)  # self.scene: RenderJob's fog renders
        self.notes = configure_scene(self.render_scene, o.samples, 0, self.gpu)[1]

    def _check(self, index: int, source: str) -> str:
        """Realise frame ``index`` once: a scene with no labelled visible object is refused; returns
        the per-class count of labelled objects and instances."""
        self.user_scene.frame_set(self.frames[index])
        camera_record(self.user_scene, self.camera, self.config.resolution, source)  # lens and pose make an image
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
            got = realise(self.user_scene, self.render_scene, self.classes, self.camera,
                          lidar=bool(self.config.lidar or self.config.radar))
        t1 = time.perf_counter()
        name = frame_name(index)
        objects = [{"id": oid, **rec} for oid, rec in got.labelled.items()]
        desc = {"seed": frame_seed(self.config.seed, index), "objects": objects,
                "source": {**self.config.style["scene_mode"], "blender_frame": frame_no},
                "background_instances": got.background}
        try:
            desc["camera"] = camera_record(self.render_scene, self.camera, self.config.resolution, self.config.source)
            if self.config.lidar:
                desc["lidar"] = self._lidar_pose(desc["camera"]["world_to_camera"])
            if self.config.radar:
                desc["radar"] = self._radar_pose(desc["camera"]["world_to_camera"])
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
        if self.config.lidar or self.config.radar:
            passes = replace(passes, geometry=Geometry.from_parts(got.lidar_parts))
        meta = commit_frame(self.layout, self.config, frame, passes, fog_renders, timings=timings, render_info=info)
        return meta

    def _lidar_pose(self, world_to_camera) -> dict:
        """``desc["lidar"]``: the marked object's pose at this frame, else the camera's plus KITTI's offset."""
        if self.lidar_object is not None:
            matrix = self.lidar_object.evaluated_get(bpy.context.evaluated_depsgraph_get()).matrix_world
            return {"sensor": self.config.lidar_sensor.name, "mount": f"object {self.lidar_object.name!r} "
                    f"({LIDAR_PROPERTY})", "lidar_to_world": object_pose(np.array(matrix)).tolist()}
        return {"sensor": self.config.lidar_sensor.name, "mount": f"the camera + {list(KITTI_CAMERA_OFFSET)} m "
                "(forward, left, up)", "lidar_to_world": camera_offset_pose(world_to_camera).tolist()}

    def _radar_pose(self, world_to_camera) -> dict:
        """``desc["radar"]``: the marked object's pose at this frame, else the camera's plus nuScenes' offset."""
        if self.radar_object is not None:
            matrix = self.radar_object.evaluated_get(bpy.context.evaluated_depsgraph_get()).matrix_world
            return {"sensor": self.config.radar_sensor.name, "mount": f"object {self.radar_object.name!r} "
                    f"({RADAR_PROPERTY})", "radar_to_world": object_pose(np.array(matrix)).tolist()}
        pose = camera_offset_pose(world_to_camera, RADAR_CAMERA_OFFSET)
        return {"sensor": self.config.radar_sensor.name, "mount": f"the camera + {list(RADAR_CAMERA_OFFSET)} m "
                "(forward, left, up)", "radar_to_world": pose.tolist()}

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


def scene_job(scene, out, options: SceneOptions = SceneOptions(), run: RunOptions = RunOptions()) -> SceneJob:
    """The add-on's *Source: current scene* (and the CLI's ``--scene``): a :class:`SceneJob` over
    ``scene`` writing the dataset to ``out`` (:class:`~fogsim.render.job_options.SceneOptions`: what,
    checked first; :class:`~fogsim.render.job_options.RunOptions`: how). Every refusal (no labelled
    object, a missing linked library, a missing / orthographic / panoramic camera, a camera or render
    size that makes no image …) is an InputError raised before ``out`` is touched."""
    return SceneJob(scene, out, options.check(), run)
