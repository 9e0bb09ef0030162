"""Render one frame with Cycles: RGB (scene-linear), planar depth and object index, one pass each."""
from __future__ import annotations

import errno
import os
import shutil
import signal
import tempfile
import threading
from contextlib import contextmanager

import bpy
import numpy as np

from fogsim.camera import NO_HIT_DEPTH
from fogsim.errors import InputError
from fogsim.render.blender.compat import PASS_CHANNELS, has_denoiser, set_denoiser_speed, set_multilayer_exr
from fogsim.render.blender.device import use_device
from fogsim.render.blender.output import blender_output
from fogsim.render.exr_reader import read_exr
from fogsim.render.frame import FramePasses
from fogsim.render.quality import cycles_settings


def configure(scene, quality: dict, seed: int, gpu: bool = False) -> dict:
    """Cycles settings from a quality preset (:func:`fogsim.render.quality.cycles_settings`: every
    default from the schema); returns what was actually used (the device too:
    :func:`fogsim.render.blender.device.use_device`)."""
    scene.render.engine = "CYCLES"
    device = use_device(scene, gpu)
    cy = scene.cycles
    settings = cycles_settings(quality)
    speed = settings.pop("denoising_quality"), settings.pop("denoising_prefilter")
    settings["use_denoising"] = settings["use_denoising"] and has_denoiser()
    if not settings["use_adaptive_sampling"]:
        settings.pop("adaptive_threshold")
    for name, value in settings.items():
        setattr(cy, name, value)
    denoise = cy.use_denoising
    if denoise:
        set_denoiser_speed(cy, *speed)
    cy.seed = int(seed) % 2**31
    cy.use_animated_seed = False
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    scene.render.use_persistent_data = False
    scene.view_settings.view_transform = "Standard"
    layer = scene.view_layers[0]
    layer.use_pass_combined = True
    layer.use_pass_z = True
    layer.use_pass_object_index = True
    set_multilayer_exr(scene.render.image_settings)
    return {**device, "samples": cy.samples, "denoise": denoise,
            "adaptive_threshold": cy.adaptive_threshold if cy.use_adaptive_sampling else None,
            "max_bounces": cy.max_bounces, "seed": cy.seed}


def _pick(channels: dict, names: list):
    for name in names:
        if isinstance(name, tuple):
            if all(n in channels for n in name):
                return np.stack([channels[n] for n in name], axis=-1)
        elif name in channels:
            return channels[name]
    raise KeyError(f"render output lacks {names}; it has {sorted(channels)}")


def render(scene, exr_path: str | os.PathLike | None = None, quiet: bool = False) -> FramePasses:
    """Render ``scene`` to a temporary multilayer EXR and return its passes (the object pass
    index as the instance mask; no right view).

    ``exr_path``: where Cycles writes that file (removed once read). A render job gives a path
    in its dataset folder (:data:`fogsim.render.leftovers.TMP_DIR`), so a kill during Cycles
    leaves it where the resumed job removes it; without one (or when the path holds a '#',
    Blender's frame-number placeholder) it goes to the system temp folder. Blender's own output
    is captured (:func:`fogsim.render.blender.output.blender_output`; ``quiet``: errors only).
    """
    ch = _render_channels(scene, exr_path, quiet)
    depth = _pick(ch, PASS_CHANNELS["depth"]).astype(np.float32)
    depth[depth >= NO_HIT_DEPTH] = np.inf
    index = np.rint(_pick(ch, PASS_CHANNELS["index"])).astype(np.uint16)
    return FramePasses(_pick(ch, PASS_CHANNELS["rgb"]).astype(np.float32), depth, index)


def render_combined(scene, exr_path: str | os.PathLike | None = None, quiet: bool = False) -> np.ndarray:
    """Render only the Combined pass (H×W×3 float32, scene-linear): the caller has turned the Z and
    object-index passes off (a fog render's are not valid, ``docs/fog-physics.md``)."""
    return _pick(_render_channels(scene, exr_path, quiet), PASS_CHANNELS["rgb"]).astype(np.float32)


def _disk_full(scene, path: str) -> None:
    """Raise ENOSPC when the EXR Cycles wrote is unreadable because its disk is full: Blender
    reports a short write only in its log, so the file would otherwise read as a corrupt EXR of
    fogsim's own temp file. Full = less free space than the passes take uncompressed."""
    r = scene.render
    need = int(r.resolution_x * r.resolution_y * r.resolution_percentage / 100 * 5 * 4)  # RGB, Z, index: float32
    free = shutil.disk_usage(os.path.dirname(path)).free
    if free < need:
        raise OSError(errno.ENOSPC, f"No space left on device: Cycles could not write the whole render "
                                    f"({free:,} bytes free, a frame's passes take up to {need:,})", path)


@contextmanager
def interrupts_deferred():
    """Ctrl-C (SIGINT) during a call into Blender, raised as KeyboardInterrupt once the call returns.

    Cycles renders from its engine's Python callback, and Blender catches every exception of an
    engine callback — it prints the KeyboardInterrupt's traceback and goes on, so the run would
    render its remaining frames and exit 0. While the block runs SIGINT is only noted; after it
    (the current render completes: Blender has no API to stop it from Python) the interrupt is
    raised here, where every mode's frame loop sees it (exit 130, resumable). Outside the main
    thread, or when SIGINT is not Python's to handle (ignored, Blender's own), nothing changes."""
    previous = signal.getsignal(signal.SIGINT)
    if threading.current_thread() is not threading.main_thread() or not callable(previous):
        yield
        return
    noted = []
    signal.signal(signal.SIGINT, lambda signum, frame: noted.append(signum))
    try:
        yield
    except BaseException:
        if noted:
            raise KeyboardInterrupt from None
        raise
    finally:
        signal.signal(signal.SIGINT, previous)
    if noted:
        raise KeyboardInterrupt


def _render_channels(scene, exr_path, quiet: bool) -> dict:
    path = None if exr_path is None else os.path.abspath(exr_path)
    if path is None or "#" in path:  # Blender would put frame numbers in place of '#'
        fd, path = tempfile.mkstemp(prefix="fogsim_render_", suffix=".exr")
        os.close(fd)
    else:
        os.makedirs(os.path.dirname(path), exist_ok=True)
    try:
        scene.render.filepath = path
        scene.render.use_file_extension = False
        with blender_output(quiet), interrupts_deferred():
            bpy.ops.render.render(write_still=True, scene=scene.name)
        try:
            return read_exr(path)
        except InputError:
            _disk_full(scene, path)
            raise
    finally:
        if os.path.exists(path):
            os.unlink(path)
