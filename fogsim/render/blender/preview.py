"""Render one frame for the add-on's *Preview fog* and hand it to Blender as an image.

The frame goes through the dataset path itself: a :class:`~fogsim.render.blender.job.RenderJob`
over that frame alone (shard N/N+1 of N+1 frames) with the levels clear and β, into a temporary
folder removed afterwards (:mod:`fogsim.render.preview` reads it back). The job builds the frame
in a scene of its own and removes it, so the user's scene is untouched.
"""
from __future__ import annotations

import tempfile
from dataclasses import replace
from typing import Callable

import bpy
import numpy as np

from fogsim.render.frame import frame_name
from fogsim.render.job_options import RunOptions
from fogsim.render.preset import RenderConfig
from fogsim.render.preview import FogPreview, preview_levels, read_preview

IMAGE_NAME = "fogsim preview"


def render_preview(config: RenderConfig, index: int, beta: float, gpu: bool = False, boxes: bool = True,
                   progress: Callable[[float], None] = lambda f: None) -> FogPreview:
    """Frame ``index`` of ``config`` as the dataset would hold it at ``beta`` (1/m), boxes drawn;
    ``progress`` is told 0…1 as it goes."""
    from fogsim.render.blender.job import RenderJob

    one = replace(config, levels=preview_levels(beta), frames=index + 1)
    with tempfile.TemporaryDirectory(prefix="fogsim_preview_") as tmp:
        job = RenderJob(one, tmp, RunOptions(shard=(index, index + 1), resume=False, gpu=gpu, quiet=True))
        progress(0.1)
        try:
            job.step()
        finally:
            job.close()
        progress(0.9)
        return read_preview(tmp, frame_name(index), beta, boxes)


def show_image(rgb: np.ndarray, name: str = IMAGE_NAME):
    """``rgb`` (H×W×3 uint8, top row first) as the Blender image ``name`` (created or resized)."""
    h, w = rgb.shape[:2]
    img = bpy.data.images.get(name)
    if img is None or tuple(img.size) != (w, h):
        if img is not None:
            bpy.data.images.remove(img)
        img = bpy.data.images.new(name, w, h, alpha=False)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[:, :, :3] = rgb[::-1] / np.float32(255)  # Blender's rows go bottom up
    img.pixels.foreach_set(rgba.ravel())
    img.update()
    return img


def image_pixels(img) -> np.ndarray:
    """A Blender image's pixels as H×W×3 uint8, top row first (the inverse of :func:`show_image`)."""
    w, h = img.size
    rgba = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(rgba)
    return np.rint(rgba.reshape(h, w, 4)[::-1, :, :3] * 255).astype(np.uint8)


def open_in_image_editor(context, img) -> bool:
    """Show ``img`` in an Image Editor: one already open in a window, else a new window turned
    into one. False when there is no window (background Blender) or none could be opened."""
    if bpy.app.background:
        return False
    wm = context.window_manager
    for window in wm.windows if wm is not None else ():
        for area in window.screen.areas:
            if area.type == "IMAGE_EDITOR":
                area.spaces.active.image = img
                return True
    if context.window is None:
        return False
    before = set(wm.windows[:])
    try:
        bpy.ops.wm.window_new()
    except RuntimeError:  # the operator's poll failed: no window to copy in this context
        return False
    new = [w for w in wm.windows if w not in before]
    if not new:
        return False
    area = new[0].screen.areas[0]
    area.type = "IMAGE_EDITOR"
    area.spaces.active.image = img
    return True
