"""fogsim for Blender: build procedural street scenes and render labeled foggy datasets.

Panel: 3D Viewport ▸ Sidebar ▸ fogsim. "Build scene" puts frame N of the chosen preset in the
viewport; "Render dataset" renders the preset's frames with a progress bar (Esc or "Cancel"
stops after the current frame; a later run resumes).
"""
from __future__ import annotations

import sys
from pathlib import Path

bl_info = {
    "name": "fogsim",
    "author": "fogsim developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "3D Viewport > Sidebar > fogsim",
    "description": "Procedural street scenes rendered into labeled datasets at several fog densities",
    "category": "Render",
}

_LIB = Path(__file__).resolve().parent / "lib"  # the packaged add-on bundles fogsim + wheels here
if _LIB.is_dir() and str(_LIB) not in sys.path:
    sys.path.insert(0, str(_LIB))

import bpy  # noqa: E402
from bpy.props import BoolProperty, EnumProperty, IntProperty, PointerProperty, StringProperty  # noqa: E402

_state = {"built": None, "job": None, "timer": None, "cancel": False}
_PRESET_ITEMS: list = []  # Blender needs Python to keep dynamic enum items alive


def _preset_items(self, context):
    from fogsim.levels import presets_dir

    names = sorted(p.stem for p in presets_dir().glob("*.json"))
    items = [(n, n, f"presets/{n}.json") for n in names] or [("default", "default", "")]
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
    progress: IntProperty(name="Progress", default=0, min=0, max=100, subtype="PERCENTAGE")
    status: StringProperty(name="Status", default="")


def _config(s: FogsimSettings, frames: int | None = None):
    from fogsim.render_config import load_render_preset

    return load_render_preset(s.preset, frames=frames, seed=s.seed, resolution=s.resolution or None,
                              samples=s.samples or None)


class FOGSIM_OT_build_scene(bpy.types.Operator):
    """Build frame N of the preset in the current scene (replaces the last one built)"""

    bl_idname = "fogsim.build_scene"
    bl_label = "Build scene"
    bl_options = {"REGISTER"}  # no UNDO: an undo would leave _state["built"] pointing at freed data

    def execute(self, context):
        from fogsim.errors import FogsimError
        from fogsim.frames import describe_frame, scene_meshes

        from . import build

        s = context.scene.fogsim
        try:
            config = _config(s, frames=s.frame + 1)
        except (FogsimError, ValueError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        _clear_built()
        desc = describe_frame(config, s.frame)
        _state["built"] = build.build(desc, context.scene, scene_meshes(desc))
        n = sum(o["class"] not in ("road", "sidewalk", "curb", "lane_marking") for o in desc["objects"])
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
    from . import build

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

        from .pipeline import RenderJob

        s = context.scene.fogsim
        if _state["job"] is not None:
            self.report({"WARNING"}, "a render is already running")
            return {"CANCELLED"}
        try:
            job = RenderJob(_config(s, frames=s.frames), bpy.path.abspath(s.output), gpu=s.use_gpu)
        except (FogsimError, ValueError, OSError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        _state.update(job=job, cancel=False, total=max(1, len(job.todo)))
        if bpy.app.background or context.window is None:  # no event loop: run to the end
            try:
                while job.todo:
                    job.step()
            except Exception as exc:  # report, and leave the add-on ready for the next run
                self.report({"ERROR"}, f"{type(exc).__name__}: {exc}")
                _state["cancel"] = True
            return self._finish(context)
        context.window_manager.progress_begin(0, 100)
        _state["timer"] = context.window_manager.event_timer_add(0.1, window=context.window)
        context.window_manager.modal_handler_add(self)
        s.status = f"rendering {len(job.todo)} frames…"
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job, s = _state["job"], context.scene.fogsim
        if event.type == "ESC":
            _state["cancel"] = True
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if _state["cancel"] or not job.todo:
            return self._finish(context)
        try:
            meta = job.step()
        except Exception as exc:  # one failure ends the run cleanly; committed frames stay
            self.report({"ERROR"}, f"{type(exc).__name__}: {exc}")
            _state["cancel"] = True
            return self._finish(context)
        done = _state["total"] - len(job.todo)
        s.progress = int(100 * done / _state["total"])
        s.status = f"frame {meta['frame']} done ({done}/{_state['total']})"
        context.window_manager.progress_update(s.progress)
        return {"RUNNING_MODAL"}

    def _finish(self, context):
        job, wm = _state["job"], context.window_manager
        if _state["timer"] is not None:
            wm.event_timer_remove(_state["timer"])
            wm.progress_end()
        try:
            if job.layout.done_frames():
                job.finish()
        except Exception as exc:
            self.report({"ERROR"}, f"writing the dataset files failed: {exc}")
        finally:
            job.close()
        context.scene.fogsim.status = ("cancelled" if _state["cancel"] else "done") + f": {len(job.done)} frames"
        _state.update(job=None, timer=None)
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
    _state.update(job=None, timer=None, built=None)
    del bpy.types.Scene.fogsim
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
