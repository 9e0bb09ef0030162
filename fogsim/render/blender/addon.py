"""The add-on's panel and operators (registered by ``blender_addon/__init__.py``).

Panel: 3D Viewport ▸ Sidebar ▸ fogsim. *Source*: a procedural preset or the current scene.
"Build scene" puts frame N of the chosen preset in the viewport; "Render dataset" renders the
preset's frames (or the open scene's frame range through scene mode,
:func:`fogsim.render.blender.scene_mode.scene_job`) with a progress bar (Esc or "Cancel" stops
after the current frame; a later run resumes). The panel overrides the preset's fog levels (β or
visibility list), fog model and medium, time of day, sky (procedural, HDRI, overcast) and asset
folder (``--assets``); "Preview fog" renders frame N at one β and shows it, boxes drawn, in an
Image Editor; "Assign" sets ``fogsim_class`` on the selected objects. Every operator reports its
errors in the panel (status line and Blender's report), never as a traceback.
"""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from fogsim.render.blender.panel_options import config as _config
from fogsim.render.blender.panel_options import run_options
from fogsim.render.blender.panel_options import scene_job as _scene_job
from fogsim.render.scene_classes import PROPERTY
from fogsim.scene.classes import LABELLED
from fogsim.schema.presets import SKIES, WORLD_HDRIS
from fogsim.schema.vocabulary import FOG_KINDS, FOG_MEDIA

_state = {"built": None, "job": None, "loop": None, "timer": None, "cancel": False, "preview": None}
#: the panel's words for the vocabulary's (a word without its label fails at import: the enums are the vocabulary)
FOG_LABELS = {"koschmieder": ("Koschmieder", "Post-process on the clear render (fast)"),
              "scatter": ("Scatter", "Post-process with forward scattering, elevation airlight and glow (fast)"),
              "volumetric": ("Volumetric", "One Cycles render per fog level with a participating medium (slow)")}
MEDIUM_LABELS = {"full": ("Full", "Pure scattering, white, Henyey-Greenstein g"),
                 "hybrid": ("Hybrid", "Half absorption + emission, half scattering: cheaper, lamps still glow"),
                 "ea": ("Emission-absorption", "Camera-only emission-absorption: Koschmieder in linear light")}
SKY_LABELS = {"procedural": ("Procedural", "Blender's physical sky texture and a sun lamp"),
              "hdri": ("HDRI", "A world HDRI (Blender's own or your .exr/.hdr), turned at random per frame; "
                               "no sun lamp"),
              "overcast": ("Overcast", "CIE standard overcast sky, no sun: soft shadows")}


def _lidar_items() -> list:
    """The LiDAR choice: the preset's, none, or a bundled sensor a render can sweep (its beams are known)."""
    from fogsim.lidar.sensors import LidarSensor, sensor_names

    sensors = [n for n in sensor_names() if LidarSensor.preset(n).inclinations_deg is not None]
    return ([("PRESET", "Preset's", "The preset's lidar (none unless it names one)"),
             ("NONE", "None", "No LiDAR")]
            + [(n, n, LidarSensor.preset(n).description[:120]) for n in sensors])


def _radar_items() -> list:
    """The radar choice: the preset's, none, or a bundled sensor."""
    from fogsim.radar.sensors import RadarSensor, radar_sensor_names

    return ([("PRESET", "Preset's", "The preset's radar (none unless it names one)"), ("NONE", "None", "No radar")]
            + [(n, n, RadarSensor.preset(n).description[:120]) for n in radar_sensor_names()])


def _enum(words, labels: dict, preset: str) -> list:
    """An EnumProperty's items: "Preset's" first, then one per word of the vocabulary."""
    return [("PRESET", "Preset's", preset)] + [(w, *labels[w]) for w in words]
_PRESET_ITEMS: list = []  # Blender needs Python to keep dynamic enum items alive


def _preset_items(self, context):
    from fogsim import presets

    items = [(n, n, f"presets/{n}.json") for n in presets.names()] or [("default", "default", "")]
    if items != _PRESET_ITEMS:
        _PRESET_ITEMS[:] = items
    return _PRESET_ITEMS


class FogsimSettings(bpy.types.PropertyGroup):
    source: EnumProperty(name="Source", default="PRESET", items=[
        ("PRESET", "Procedural preset", "Streets built from the preset (fogsim render --preset)"),
        ("SCENE", "Current scene", "The open scene through scene mode (fogsim render --scene): objects "
                                   "labelled by fogsim_class or the class map; the scene is left as it was")])
    camera: StringProperty(name="Camera", default="", description="Camera object to render through "
                                                                  "(empty = the scene's camera)")
    frame_range: StringProperty(name="Frame range", default="", description="START:END[:STEP], inclusive "
                                                                           "(empty = the scene's own range)")
    class_map: StringProperty(name="Class map", default="", subtype="FILE_PATH",
                              description="JSON file (or inline JSON) mapping object-name patterns to classes")
    sky: EnumProperty(name="Sky", default="PRESET", items=_enum(
        SKIES + ("overcast",), SKY_LABELS, "The preset's lighting (procedural unless it says HDRI or overcast)"))
    hdri: EnumProperty(name="HDRI", default="city", items=[(n, n.capitalize(), f"Blender's world HDRI {n!r}")
                                                          for n in WORLD_HDRIS]
                       + [("FILE", "File…", "Your own .exr or .hdr file")])
    hdri_file: StringProperty(name="HDRI file", default="", subtype="FILE_PATH", description="An .exr or .hdr file")
    assets: StringProperty(name="Assets", default="", subtype="DIR_PATH",
                           description="Your own models: a folder with one sub-folder per class (car, pedestrian …); "
                                       "empty = the preset's")
    preset: EnumProperty(name="Preset", items=_preset_items, description="Dataset preset")
    seed: IntProperty(name="Seed", default=0, min=0, description="Dataset seed")
    frame: IntProperty(name="Frame", default=0, min=0, description="Frame to build in the viewport")
    frames: IntProperty(name="Frames", default=8, min=1, description="Frames to render")
    resolution: StringProperty(name="Resolution", default="", description="WxH override, e.g. 640x426")
    samples: IntProperty(name="Samples", default=0, min=0, description="Cycles samples override (0 = preset)")
    output: StringProperty(name="Output", default="//fogsim_dataset", subtype="DIR_PATH")
    use_gpu: BoolProperty(name="GPU", default=False, description="Render on the GPU when one exists")
    fog_model: EnumProperty(name="Fog", default="PRESET", items=_enum(
        FOG_KINDS, FOG_LABELS, "The preset's fog_model.kind (Koschmieder unless it says otherwise)"))
    fog_medium: EnumProperty(name="Medium", default="PRESET", items=_enum(
        FOG_MEDIA, MEDIUM_LABELS, "The preset's fog_model.volumetric.medium (full unless it says otherwise)"))
    lidar: EnumProperty(name="LiDAR", default="PRESET", items=_lidar_items(),
                        description="A LiDAR swept in every frame, its scan fogged with each level's β")
    radar: EnumProperty(name="Radar", default="PRESET", items=_radar_items(),
                        description="A radar swept in every frame, its detections fogged with each level's β")
    levels_kind: EnumProperty(name="Levels", default="PRESET", items=[
        ("PRESET", "Preset's", "The preset's fog levels (the paper's five unless it says otherwise)"),
        ("beta", "β list", "Comma-separated extinction coefficients β in 1/m (\"clear\" or 0 = no fog)"),
        ("visibility", "Visibility list", "Comma-separated visibilities in metres (V = ln 20 / β)")])
    levels: StringProperty(name="Values", default="clear,0.03,0.06",
                           description="β in 1/m or visibilities in metres, comma-separated")
    time_of_day: EnumProperty(name="Time of day", default="PRESET", items=[
        ("PRESET", "Preset's", "The preset's lighting (day unless it says night)"),
        ("day", "Day", "Procedural sky and sun"),
        ("night", "Night", "Street lamps, vehicle lights, lit windows, no sun (the night preset's lights; "
                           "its airlight 50 comes only with the night preset)")])
    preview_beta: FloatProperty(name="Preview β", default=0.06, min=0.0, max=1000.0, precision=3, step=1,
                                description="Fog density of the preview, 1/m (visibility ln 20 / β)")
    preview_boxes: BoolProperty(name="Boxes", default=True, description="Draw the kept objects' boxes")
    assign_class: EnumProperty(name="Class", default=LABELLED[0], description="Class for the selected objects",
                               items=[(c, c, f"fogsim_class = \"{c}\"") for c in LABELLED]
                               + [("NONE", "(background)", "Remove fogsim_class: the object becomes background")])
    progress: IntProperty(name="Progress", default=0, min=0, max=100, subtype="PERCENTAGE")
    status: StringProperty(name="Status", default="")


def _fail(op, s, message: str):
    """Report ``message`` in Blender's report and the panel's status line; the operator's result."""
    op.report({"ERROR"}, message)
    s.status = f"error: {message}"
    return {"CANCELLED"}


def _problem(exc: Exception) -> str:
    """One line for the user: fogsim's and the checks' own messages as they are, others with their type."""
    from fogsim.errors import FogsimError

    if isinstance(exc, (FogsimError, ValueError, OSError)):
        return str(exc)
    return f"{type(exc).__name__}: {exc}"


class FOGSIM_OT_build_scene(bpy.types.Operator):
    """Build frame N of the preset in the current scene (replaces the last one built)"""

    bl_idname = "fogsim.build_scene"
    bl_label = "Build scene"
    bl_options = {"REGISTER"}  # no UNDO: an undo would leave _state["built"] pointing at freed data

    def execute(self, context):
        from fogsim.render.blender import build
        from fogsim.render.frame import describe_frame, scene_meshes
        from fogsim.scene.classes import STUFF

        s = context.scene.fogsim
        try:
            config = _config(s, frames=s.frame + 1)
            _clear_built()
            desc = describe_frame(config, s.frame)
            _state["built"] = build.build(desc, context.scene, scene_meshes(desc))
        except Exception as exc:
            return _fail(self, s, _problem(exc))
        n = sum(o["class"] not in STUFF for o in desc["objects"])
        s.status = f"frame {s.frame}: {n} objects, style {desc['style']}"
        return {"FINISHED"}


class FOGSIM_OT_clear_scene(bpy.types.Operator):
    """Remove what "Build scene" created"""

    bl_idname = "fogsim.clear_scene"
    bl_label = "Clear"

    def execute(self, context):
        _clear_built()
        context.scene.fogsim.status = "cleared"
        return {"FINISHED"}


def _clear_built():
    from fogsim.render.blender.scratch import clear

    if _state["built"] is not None:
        clear(_state["built"])
        _state["built"] = None


class FOGSIM_OT_render_dataset(bpy.types.Operator):
    """Render the preset's frames, or the current scene's frame range, into the output folder (resumes; Esc cancels)"""

    bl_idname = "fogsim.render_dataset"
    bl_label = "Render dataset"

    def invoke(self, context, event):
        return self.execute(context)

    def execute(self, context):
        from fogsim.render.blender.job import RenderJob
        from fogsim.render.loop import FrameLoop

        s = context.scene.fogsim
        if _state["job"] is not None:
            self.report({"WARNING"}, "a render is already running")
            return {"CANCELLED"}
        try:
            if s.source == "SCENE":
                if _state["built"] is not None:  # its procedural street would be labelled as the user's
                    return _fail(self, s, "the scene holds a street built by fogsim (Build scene): "
                                          "press Clear scene first, then render the current scene")
                job = _scene_job(s, context.scene)
            else:
                job = RenderJob(_config(s, frames=s.frames), bpy.path.abspath(s.output), run_options(s))
        except Exception as exc:
            return _fail(self, s, _problem(exc))
        for note in getattr(job, "notes", ()):
            self.report({"INFO"}, note)
        loop = FrameLoop(job)
        _state.update(job=job, loop=loop, cancel=False)
        if bpy.app.background or context.window is None:  # no event loop: run to the end
            try:
                loop.run(lambda index, meta, error: self._report_failure(index, error))
            except KeyboardInterrupt:
                self._interrupted(context)
            return self._finish(context)
        context.window_manager.progress_begin(0, 100)
        _state["timer"] = context.window_manager.event_timer_add(0.1, window=context.window)
        context.window_manager.modal_handler_add(self)
        s.status = f"rendering {loop.total} frames…" + (f" ({job.summary})" if s.source == "SCENE" else "")
        return {"RUNNING_MODAL"}

    def _interrupted(self, context):
        """Ctrl-C stops the batch as it stops ``fogsim render``: the committed frames stay (a rerun
        resumes), one line, exit 130. An operator cannot raise it on: Blender catches every
        exception of an operator, prints it and goes on — the script that called it would too — so
        the job is closed and the process ends here (SystemExit ends Blender and the bpy module)."""
        import sys

        from fogsim.errors import EXIT_INTERRUPTED

        job, loop = _state["job"], _state["loop"]
        job.close()
        context.scene.fogsim.status = f"interrupted: {loop.done} frames (the output folder resumes)"
        _state.update(job=None, loop=None, timer=None)
        print("fogsim: error: interrupted", file=sys.stderr)
        sys.stderr.flush()
        raise SystemExit(EXIT_INTERRUPTED)

    def _report_failure(self, index, error):
        if error is not None:  # the frame loop's policy: report it and go on with the next frame
            self.report({"ERROR"}, f"frame {index}: {error}")

    def modal(self, context, event):
        loop, s = _state["loop"], context.scene.fogsim
        if event.type == "ESC":
            _state["cancel"] = True
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if _state["cancel"] or not loop.remaining:
            return self._finish(context)
        index, meta, error = loop.step()
        self._report_failure(index, error)
        done = loop.total - loop.remaining
        s.progress = int(100 * done / max(1, loop.total))
        s.status = f"frame {index} {'failed' if error else 'done'} ({done}/{loop.total})"
        context.window_manager.progress_update(s.progress)
        return {"RUNNING_MODAL"}

    def _finish(self, context):
        job, loop, wm = _state["job"], _state["loop"], context.window_manager
        if _state["timer"] is not None:
            wm.event_timer_remove(_state["timer"])
            wm.progress_end()
        try:
            loop.finish(sharded=False)
        except Exception as exc:
            self.report({"ERROR"}, f"writing the dataset files failed: {exc}")
        finally:
            job.close()
        failed = f", {len(loop.failed)} failed" if loop.failed else ""
        context.scene.fogsim.status = ("cancelled" if _state["cancel"] else "done") + f": {loop.done} frames{failed}"
        _state.update(job=None, loop=None, timer=None)
        return {"CANCELLED"} if _state["cancel"] else {"FINISHED"}


class FOGSIM_OT_cancel(bpy.types.Operator):
    """Stop the running render after the current frame"""

    bl_idname = "fogsim.cancel"
    bl_label = "Cancel"

    def execute(self, context):
        _state["cancel"] = True
        return {"FINISHED"}


class FOGSIM_OT_preview_fog(bpy.types.Operator):
    """Render frame N of the preset and show it fogged at the preview β, boxes drawn, in an Image Editor"""

    bl_idname = "fogsim.preview_fog"
    bl_label = "Preview fog"

    def execute(self, context):
        from fogsim.render.blender.preview import open_in_image_editor, render_preview, show_image

        s, wm = context.scene.fogsim, context.window_manager
        if _state["job"] is not None:
            return _fail(self, s, "a render is running: preview after it (or cancel it)")
        wm.progress_begin(0, 100)
        try:
            config = _config(s, frames=s.frame + 1)
            preview = render_preview(config, s.frame, s.preview_beta, gpu=s.use_gpu, boxes=s.preview_boxes,
                                     progress=lambda f: wm.progress_update(int(100 * f)))
            img = show_image(preview.image)
        except Exception as exc:
            return _fail(self, s, _problem(exc))
        finally:
            wm.progress_end()
        _state["preview"] = preview
        shown = open_in_image_editor(context, img)
        s.status = f"frame {s.frame}: {preview.caption}" + ("" if shown else f" (image \"{img.name}\")")
        return {"FINISHED"}


class FOGSIM_OT_assign_class(bpy.types.Operator):
    """Set the fogsim_class custom property of the selected objects (what scene mode labels them as)"""

    bl_idname = "fogsim.assign_class"
    bl_label = "Assign"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        s = context.scene.fogsim
        objects = list(context.selected_objects or ())
        if not objects:
            return _fail(self, s, "no object selected: select the objects to label first")
        for obj in objects:
            if s.assign_class == "NONE":
                obj.pop(PROPERTY, None)
            else:
                obj[PROPERTY] = s.assign_class
        what = "background" if s.assign_class == "NONE" else s.assign_class
        s.status = f"{len(objects)} object{'s' * (len(objects) != 1)} → {what}"
        return {"FINISHED"}


class FOGSIM_PT_panel(bpy.types.Panel):
    bl_label = "fogsim"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "fogsim"

    def draw(self, context):
        s, layout = context.scene.fogsim, self.layout
        layout.row().prop(s, "source", expand=True)
        scene_source = s.source == "SCENE"
        if scene_source:
            box = layout.box()
            box.label(text="Current scene", icon="SCENE_DATA")
            box.prop_search(s, "camera", context.scene, "objects", icon="CAMERA_DATA")
            box.prop(s, "frame_range")
            box.prop(s, "class_map")
        else:
            layout.prop(s, "preset")
            row = layout.row(align=True)
            row.prop(s, "seed")
            row.prop(s, "frame")
            row = layout.row(align=True)
            row.operator("fogsim.build_scene", icon="SCENE_DATA")
            row.operator("fogsim.clear_scene", icon="TRASH")
            box = layout.box()
            box.label(text="Light and models", icon="LIGHT_SUN")
            box.prop(s, "time_of_day")
            box.prop(s, "sky")
            if s.sky == "hdri":
                box.prop(s, "hdri")
                if s.hdri == "FILE":
                    box.prop(s, "hdri_file")
            box.prop(s, "assets")

        box = layout.box()
        box.label(text="Fog", icon="MOD_FLUIDSIM")
        box.prop(s, "levels_kind")
        if s.levels_kind != "PRESET":
            box.prop(s, "levels")
        box.prop(s, "fog_model")
        if s.fog_model == "volumetric":
            box.prop(s, "fog_medium")
        box.prop(s, "lidar")
        box.prop(s, "radar")
        if not scene_source:
            row = box.row(align=True)
            row.prop(s, "preview_beta", text="Preview β")
            row.prop(s, "preview_boxes", toggle=True, icon="SELECT_SET", icon_only=True)
            box.operator("fogsim.preview_fog", icon="IMAGE_DATA")

        box = layout.box()
        box.label(text="Label selected objects", icon="OBJECT_DATA")
        row = box.row(align=True)
        row.prop(s, "assign_class", text="")
        row.operator("fogsim.assign_class")

        box = layout.box()
        box.label(text="Dataset", icon="RENDER_ANIMATION")
        if scene_source:
            box.prop(s, "seed")
        else:
            box.prop(s, "frames")
        box.prop(s, "resolution")
        box.prop(s, "samples")
        box.prop(s, "use_gpu")
        box.prop(s, "output")
        if _state["job"] is None:
            box.operator("fogsim.render_dataset", icon="RENDER_ANIMATION")
        else:
            box.prop(s, "progress", slider=True)
            box.operator("fogsim.cancel", icon="CANCEL")
        if s.status:
            layout.label(text=s.status, icon="ERROR" if s.status.startswith("error:") else "INFO")


CLASSES = (FogsimSettings, FOGSIM_OT_build_scene, FOGSIM_OT_clear_scene, FOGSIM_OT_render_dataset,
           FOGSIM_OT_cancel, FOGSIM_OT_preview_fog, FOGSIM_OT_assign_class, FOGSIM_PT_panel)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.fogsim = PointerProperty(type=FogsimSettings)


def unregister():
    if _state["timer"] is not None and bpy.context.window_manager is not None:
        bpy.context.window_manager.event_timer_remove(_state["timer"])
    _state.update(job=None, loop=None, timer=None, built=None, preview=None)
    del bpy.types.Scene.fogsim
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
