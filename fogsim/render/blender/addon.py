"""The add-on's panel and operators (registered by ``blender_addon/__init__.py``).

Panel: 3D Viewport ▸ Sidebar ▸ fogsim. "Build scene" puts frame N of the chosen preset in the
viewport; "Render dataset" renders the preset's frames with a progress bar (Esc or "Cancel"
stops after the current frame; a later run resumes).
"""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty, PointerProperty, StringProperty

_state = {"built": None, "job": None, "loop": None, "timer": None, "cancel": False}
_PRESET_ITEMS: list = []  # Blender needs Python to keep dynamic enum items alive


def _preset_items(self, context):
    from fogsim import presets

    items = [(n, n, f"presets/{n}.json") for n in presets.names()] or [("default", "default", "")]
    if items != _PRESET_ITEMS:
        _PRESET_ITEMS[:] = items
    return _PRESET_ITEMS


class FogsimSettings(bpy.types.PropertyGroup):
    preset: EnumProperty(name="Preset", items=_preset_items, description="Dataset preset")
    seed: IntProperty(name="Seed", default=0, min=0, description="Dataset seed")
    frame: IntProperty(name="Frame", default=0, min=0, description="Frame to build in the viewport")
    frames: IntProperty(name="Frames", default=8, min=1, description="Frames to render")
    resolution: StringProperty(name="Resolution", default="", description="WxH override, e.g. 640x426")
    samples: IntProperty(name="Samples", default=0, min=0, description="Cycles samples override (0 = preset)")
    output: StringProperty(name="Output", default="//fogsim_dataset", subtype="DIR_PATH")
    use_gpu: BoolProperty(name="GPU", default=False, description="Render on the GPU when one exists")
    fog_model: EnumProperty(name="Fog", default="PRESET", items=[
        ("PRESET", "Preset's", "The preset's fog_model.kind (Koschmieder unless it says otherwise)"),
        ("koschmieder", "Koschmieder", "Post-process on the clear render (fast)"),
        ("volumetric", "Volumetric", "One Cycles render per fog level with a participating medium (slow)")])
    fog_medium: EnumProperty(name="Medium", default="PRESET", items=[
        ("PRESET", "Preset's", "The preset's fog_model.volumetric.medium (full unless it says otherwise)"),
        ("full", "Full", "Pure scattering, white, Henyey-Greenstein g"),
        ("hybrid", "Hybrid", "Half absorption + emission, half scattering: cheaper, lamps still glow"),
        ("ea", "Emission-absorption", "Camera-only emission-absorption: Koschmieder in linear light")])
    progress: IntProperty(name="Progress", default=0, min=0, max=100, subtype="PERCENTAGE")
    status: StringProperty(name="Status", default="")


def _config(s: FogsimSettings, frames: int | None = None):
    from fogsim.render.preset import load_render_preset

    volumetric = s.fog_model == "volumetric"
    return load_render_preset(s.preset, frames=frames, seed=s.seed, resolution=s.resolution or None,
                              samples=s.samples or None, fog=None if s.fog_model == "PRESET" else s.fog_model,
                              fog_medium=s.fog_medium if volumetric and s.fog_medium != "PRESET" else None)


class FOGSIM_OT_build_scene(bpy.types.Operator):
    """Build frame N of the preset in the current scene (replaces the last one built)"""

    bl_idname = "fogsim.build_scene"
    bl_label = "Build scene"
    bl_options = {"REGISTER"}  # no UNDO: an undo would leave _state["built"] pointing at freed data

    def execute(self, context):
        from fogsim.errors import FogsimError
        from fogsim.render.blender import build
        from fogsim.render.frame import describe_frame, scene_meshes
        from fogsim.scene.classes import STUFF

        s = context.scene.fogsim
        try:
            config = _config(s, frames=s.frame + 1)
        except (FogsimError, ValueError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        _clear_built()
        desc = describe_frame(config, s.frame)
        _state["built"] = build.build(desc, context.scene, scene_meshes(desc))
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
    from fogsim.render.blender import build

    if _state["built"] is not None:
        build.clear(_state["built"])
        _state["built"] = None


class FOGSIM_OT_render_dataset(bpy.types.Operator):
    """Render the preset's frames into the output folder (resumes; Esc cancels)"""

    bl_idname = "fogsim.render_dataset"
    bl_label = "Render dataset"

    def invoke(self, context, event):
        return self.execute(context)

    def execute(self, context):
        from fogsim.errors import FogsimError
        from fogsim.render.blender.job import RenderJob
        from fogsim.render.loop import FrameLoop

        s = context.scene.fogsim
        if _state["job"] is not None:
            self.report({"WARNING"}, "a render is already running")
            return {"CANCELLED"}
        try:
            job = RenderJob(_config(s, frames=s.frames), bpy.path.abspath(s.output), gpu=s.use_gpu)
        except (FogsimError, ValueError, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        loop = FrameLoop(job)
        _state.update(job=job, loop=loop, cancel=False)
        if bpy.app.background or context.window is None:  # no event loop: run to the end
            loop.run(lambda index, meta, error: self._report_failure(index, error))
            return self._finish(context)
        context.window_manager.progress_begin(0, 100)
        _state["timer"] = context.window_manager.event_timer_add(0.1, window=context.window)
        context.window_manager.modal_handler_add(self)
        s.status = f"rendering {loop.total} frames…"
        return {"RUNNING_MODAL"}

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


class FOGSIM_PT_panel(bpy.types.Panel):
    bl_label = "fogsim"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "fogsim"

    def draw(self, context):
        s, layout = context.scene.fogsim, self.layout
        layout.prop(s, "preset")
        row = layout.row(align=True)
        row.prop(s, "seed")
        row.prop(s, "frame")
        row = layout.row(align=True)
        row.operator("fogsim.build_scene", icon="SCENE_DATA")
        row.operator("fogsim.clear_scene", icon="TRASH")
        box = layout.box()
        box.prop(s, "frames")
        box.prop(s, "resolution")
        box.prop(s, "samples")
        box.prop(s, "use_gpu")
        box.prop(s, "fog_model")
        if s.fog_model == "volumetric":
            box.prop(s, "fog_medium")
        box.prop(s, "output")
        if _state["job"] is None:
            box.operator("fogsim.render_dataset", icon="RENDER_ANIMATION")
        else:
            box.prop(s, "progress", slider=True)
            box.operator("fogsim.cancel", icon="CANCEL")
        if s.status:
            layout.label(text=s.status)


CLASSES = (FogsimSettings, FOGSIM_OT_build_scene, FOGSIM_OT_clear_scene, FOGSIM_OT_render_dataset,
           FOGSIM_OT_cancel, FOGSIM_PT_panel)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.fogsim = PointerProperty(type=FogsimSettings)


def unregister():
    if _state["timer"] is not None and bpy.context.window_manager is not None:
        bpy.context.window_manager.event_timer_remove(_state["timer"])
    _state.update(job=None, loop=None, timer=None, built=None)
    del bpy.types.Scene.fogsim
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
