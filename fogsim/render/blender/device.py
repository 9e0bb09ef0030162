"""Which device Cycles renders on: ``--gpu`` picks OptiX, else CUDA (else HIP, oneAPI, Metal),
else the CPU, with a message saying why; the choice goes into every frame's meta.

The device query loads the GPU driver libraries (and prints Cycles' warnings about those it
cannot open), so it runs once per process, with Blender's output captured
(:mod:`fogsim.render.blender.output`), and its answer is reused for every scene. The record
:func:`use_device` returns is what ``meta/<frame>.json`` keeps under ``render``:
``device`` ("CPU", "OPTIX", "CUDA", …), ``gpu_devices`` (names), ``gpu_requested`` and, when a
GPU was asked for but none could be used, ``gpu_fallback`` (the reason).
"""
from __future__ import annotations

import sys
from functools import lru_cache

from fogsim.render.blender.compat import compute_devices, cycles_preferences
from fogsim.render.blender.output import blender_output

#: backends in order of preference (OptiX: RTX ray tracing; CUDA: every NVIDIA GPU)
GPU_BACKENDS = ("OPTIX", "CUDA", "HIP", "ONEAPI", "METAL")


@lru_cache(maxsize=None)
def find_gpu() -> tuple[str | None, tuple[str, ...], str]:
    """``(backend, device names, note)`` of the first backend with a device, else
    ``(None, (), why not)``. Leaves the Cycles preferences set to that backend, its devices on."""
    try:
        prefs = cycles_preferences()
    except (KeyError, AttributeError):
        return None, (), "the Cycles add-on is not enabled"
    seen = []
    with blender_output(quiet=True):  # Cycles' "CUEW initialization failed" …: the note says what matters
        for kind in GPU_BACKENDS:
            devices = compute_devices(prefs, kind)
            if devices is None:
                continue
            seen.append(kind)
            if devices:
                for d in prefs.devices:
                    d.use = d.type == kind
                return kind, tuple(d.name for d in devices), f"{kind}: {', '.join(d.name for d in devices)}"
        prefs.compute_device_type = "NONE"
    backends = f"backends in this Blender: {', '.join(seen)}" if seen else "this Blender has no GPU backend"
    return None, (), f"no OptiX or CUDA device found ({backends}; none has a device)"


def use_device(scene, want_gpu: bool) -> dict:
    """Set ``scene`` to render on the GPU when asked and one is found, else on the CPU; returns
    the record for the frame meta. A GPU asked for but not found is said once, on stderr."""
    scene.cycles.device = "CPU"
    if not want_gpu:
        return {"device": "CPU", "gpu_requested": False}
    kind, names, note = find_gpu()
    if kind is None:
        _warn_once(f"fogsim: --gpu: {note}; rendering on the CPU")
        return {"device": "CPU", "gpu_requested": True, "gpu_devices": [], "gpu_fallback": note}
    scene.cycles.device = "GPU"
    return {"device": kind, "gpu_requested": True, "gpu_devices": list(names)}


@lru_cache(maxsize=None)
def _warn_once(message: str) -> None:
    from tqdm import tqdm

    tqdm.write(message, file=sys.stderr)
