"""``fogsim bench fog-physics``: how far is Koschmieder from Cycles' path-traced fog, on rendered frames.

Renders the same N frames three times with ``fogsim render`` (each in a process of its own,
resumable): twice with the volumetric fog (``--fog volumetric``, ``fog_model.volumetric``
``keep_linear: true`` and ``noise_seed`` 0 and 1, so the two fog renders of a frame differ
only in Cycles' sampling seed) and once clear (the default Koschmieder renderer). Then
:mod:`fogsim.fog.physics` compares, per β, the Koschmieder models (sRGB and linear blending,
standard and extended kernel) with the path-traced linear renders
(``linear/<level>/<frame>.exr``), and writes under ``OUT/report``: ``fog_physics.json``,
``fog_physics.md`` and ``panels_<frame>.png``. The table is printed with the render seconds
per frame of the fog runs against the clear run (the baseline measured in the same run).

Inputs taken from the clear run: planar depth → ray distance, instance mask, the clear image
(the β = 0 level; its linear render when the fog run kept one, else the 8-bit image decoded
to linear light — what the Koschmieder models blend anyway). The masks of the three runs
must be identical (labels come from the clear render in every fog model); the report says
whether they are.

    fogsim bench fog-physics [--frames 1] [--resolution 160x107] [--samples 16] [--out bench/fog-physics]
                             [--medium full|hybrid|ea] [--denoise]
    fogsim bench fog-physics --analyse-only --out DIR --pool DIR2 [--pool DIR3 …]   # frames pooled
                             [--scatter-params FILE]   # a fit-fog result instead of the shipped one

``--medium ea`` (the camera-only emission–absorption medium) is the zero-error control: linear
Koschmieder must match it to noise level in every bin.
"""
from __future__ import annotations

import copy
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np

from fogsim.bench.fog_physics_report import markdown, write_report
from fogsim.camera import Intrinsics, planar_to_ray
from fogsim.colour import srgb_to_linear
from fogsim.dataset.layout import DatasetLayout
from fogsim.dataset.reader import read_meta
from fogsim.errors import InputError
from fogsim.fog.physics import Comparison, default_models
from fogsim.io.atomic import atomic_write_bytes
from fogsim.io.depth_files import read_depth_file, read_uint16_map
from fogsim.io.documents import read_json, write_json
from fogsim.io.exr import read_exr_channels
from fogsim.io.images import read_image
from fogsim.presets import preset_path
from fogsim.schema.base import load_json
from fogsim.schema.documents import RenderRunFile

RUNS = {"clear": None, "volumetric_seed0": 0, "volumetric_seed1": 1}


def linear_path(layout: DatasetLayout, level: str, frame: str) -> Path:
    """``linear/<level>/<frame>.exr``: the fog run's linear render (``DatasetLayout.linear`` where it exists)."""
    method = getattr(layout, "linear", None)
    return method(level, frame) if method is not None else layout.root / "linear" / level / f"{frame}.exr"


def read_linear_rgb(path: Path) -> np.ndarray:
    """An RGB EXR (channels R, G, B, optionally with a layer prefix) → H×W×3 float32."""
    channels = read_exr_channels(path)
    pick = []
    for c in "RGB":
        name = next((n for n in channels if n == c or n.endswith("." + c)), None)
        if name is None:
            raise InputError(path, f"no {c} channel (found {', '.join(channels) or 'none'})")
        pick.append(channels[name].astype(np.float32))
    return np.stack(pick, axis=-1)


def fog_preset(base: str, noise_seed: int, path: Path, denoise: bool = False) -> Path:
    """Write the base preset with ``fog_model.volumetric`` set for a measurement: ``keep_linear``,
    ``noise_seed``, ``exposure = "none"`` (raw radiance: the comparison normalises itself) and
    ``denoise`` off by default (a denoiser's residual is not independent between seeds, and it
    biases; ``docs/fog-physics.md``)."""
    src = preset_path(base)
    if not src.is_file():
        raise InputError(src, "preset not found")
    d = copy.deepcopy(read_json(src))
    fm = d.setdefault("fog_model", {})
    vol = fm.get("volumetric") if isinstance(fm.get("volumetric"), dict) else {}
    fm["volumetric"] = {**vol, "keep_linear": True, "noise_seed": noise_seed, "exposure": "none",
                        "denoise": denoise}
    write_json(path, d)
    return path


def render_commands(out: Path, args) -> dict[str, list[str]]:
    """The ``fogsim render`` command of each run (``clear`` first)."""
    common = ["--frames", str(args.frames), "--resolution", args.resolution, "--samples", str(args.samples),
              "--seed", str(args.seed)]
    if args.levels:
        common += ["--levels", args.levels]
    if args.gpu:
        common.append("--gpu")
    if getattr(args, "quiet", False):
        common.append("--quiet")
    cmds = {}
    for name, noise_seed in RUNS.items():
        cmd = [sys.executable, "-m", "fogsim", "render", "--out", str(out / name)]
        if noise_seed is None:
            cmd += ["--preset", args.preset]
        else:
            preset = fog_preset(args.preset, noise_seed, out / "presets" / f"{name}.json",
                                getattr(args, "denoise", False))
            cmd += ["--preset", str(preset), "--fog", "volumetric"]
            if getattr(args, "medium", None):
                cmd += ["--fog-medium", args.medium]
        cmds[name] = cmd + common
    return cmds


def _levels(meta: dict) -> list[dict]:
    return list(meta.get("fog", {}).get("levels", []))


def committed_frames(out: Path) -> list[str]:
    """The frames committed in all three runs under ``out``; none is an InputError."""
    clear, fog0, fog1 = (DatasetLayout(out / name) for name in RUNS)
    frames = sorted(set(clear.done_frames()) & set(fog0.done_frames()) & set(fog1.done_frames()))
    if not frames:
        raise InputError(out, "no frame is committed in all three runs (clear, volumetric_seed0, volumetric_seed1)")
    return frames


def load_frame(out: Path, frame: str) -> dict:
    """One frame of the runs under ``out`` as :meth:`Comparison.add_frame` keyword arguments
    (``name``, ``clear_linear``, ``distance`` (ray), ``mask``, ``renders``, ``classes``, ``camera``,
    ``up``, ``night``), plus ``meta`` (the clear run's) and ``same_labels``."""
    from fogsim.fog.scatter_optics import up_from_world_to_camera

    clear, fog0, fog1 = (DatasetLayout(out / name) for name in RUNS)
    meta = read_meta(clear, frame)
    levels = _levels(meta)
    zero = next((lv["key"] for lv in levels if lv["beta"] == 0), None)
    if zero is None:
        raise InputError(clear.meta(frame), "the clear run has no β = 0 level (render it with one)")
    K = Intrinsics.from_dict(meta["camera"]["intrinsics"])
    depth = read_depth_file(clear.depth(frame))
    mask = read_uint16_map(clear.mask(frame))
    same = all(np.array_equal(read_uint16_map(other.mask(frame)), mask) for other in (fog0, fog1))
    keep = linear_path(fog0, zero, frame)
    if keep.is_file():
        clear_linear = read_linear_rgb(keep)
    else:
        clear_linear = srgb_to_linear(read_image(clear.image(zero, frame)).astype(np.float32) / 255.0)
    renders = {lv["beta"]: tuple(read_linear_rgb(linear_path(f, lv["key"], frame)) for f in (fog0, fog1))
               for lv in levels if lv["beta"] > 0}
    w2c = meta["camera"].get("world_to_camera")
    return {"name": frame, "clear_linear": clear_linear, "distance": planar_to_ray(depth, K), "mask": mask,
            "renders": renders, "classes": {int(r["id"]): r["class"] for r in meta["objects"]}, "camera": K,
            "up": up_from_world_to_camera(w2c) if w2c is not None else None,
            "night": meta.get("scene", {}).get("lighting", {}).get("time_of_day") == "night",
            "meta": meta, "same_labels": same}


def analyse(out: Path, frames: list[str] | None = None, comparison: Comparison | None = None,
            pool: list[Path] | tuple = ()) -> dict:
    """Compare the runs under ``out`` (clear, volumetric_seed0, volumetric_seed1) and write ``out/report``;
    ``pool``: more such folders whose frames are pooled with ``out``'s (frames named ``<folder>-<frame>``)."""
    comparison = comparison or Comparison(models=default_models())
    same_labels, timing = True, {name: [] for name in RUNS}
    for folder in (out, *pool):
        folder = Path(folder)
        layouts = [DatasetLayout(folder / name) for name in RUNS]
        names = frames if frames is not None and folder == out else committed_frames(folder)
        for frame in names:
            data = load_frame(folder, frame)
            data.pop("meta")
            same_labels &= data.pop("same_labels")
            if pool:
                data["name"] = f"{folder.name}-{frame}"
            comparison.add_frame(**data)
            for name, layout in zip(RUNS, layouts):
                t = read_meta(layout, frame).get("timings_s", {})  # the fog renders are timed apart ("fog_render")
                timing[name].append(float(t.get("render", float("nan"))) + float(t.get("fog_render", 0.0)))
    seconds = {name: statistics.median(v) for name, v in timing.items()}
    run_file = out / "clear" / "render_run.json"
    exposure = load_json(run_file, RenderRunFile).parameters.exposure if run_file.is_file() else 1.0
    result = write_report(comparison, out / "report")
    result["pooled_folders"] = [str(Path(f)) for f in (out, *pool)] if pool else []
    result["labels_identical"] = same_labels
    result["preset_exposure"] = exposure  # the clear image has it; the linear fog renders are compared as written
    result["render_seconds_per_frame"] = seconds
    result["fog_over_clear_render_time"] = (seconds["volumetric_seed0"] / seconds["clear"]
                                            if seconds["clear"] > 0 else None)
    write_json(out / "report" / "fog_physics.json", result)
    atomic_write_bytes(out / "report" / "fog_physics.md", (markdown(result) + footer(result)).encode())
    return result


def footer(result: dict) -> str:
    """Render time against the clear run, and whether the labels agree."""
    s, ratio = result["render_seconds_per_frame"], result["fog_over_clear_render_time"]
    lines = [""]
    if ratio:
        lines.append(f"Render seconds per frame (median): clear {s['clear']:.2f}, volumetric "
                     f"{s['volumetric_seed0']:.2f} (×{ratio:.1f} the clear render, same run).")
    lines.append(f"Instance masks identical across the three runs: {result['labels_identical']}.")
    if result.get("preset_exposure", 1.0) != 1.0:
        lines.append(f"Warning: the preset's exposure is {result['preset_exposure']:g}; the clear image includes it "
                     "and the raw comparison assumes the linear fog renders do too.")
    return "\n".join(lines) + "\n"


def run(args) -> int:
    """Render what is missing (unless ``--analyse-only``), analyse, print the table; 0 done."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if not args.analyse_only:
        for name, cmd in render_commands(out, args).items():
            print(f"fog-physics: rendering {name}: {' '.join(cmd[1:])}", flush=True)
            code = subprocess.run(cmd).returncode
            if code:
                print(f"fog-physics: the {name} render failed (exit {code}); --fog volumetric needs the "
                      "volumetric renderer", file=sys.stderr)
                return code
    pool = [Path(p) for p in getattr(args, "pool", None) or []]
    for folder in pool:
        if not folder.is_dir():
            raise InputError(folder, "not a fogsim bench fog-physics folder (--pool)")
    comparison = None
    if getattr(args, "scatter_params", None):
        from fogsim.fog.scatter import load_params

        comparison = Comparison(models=default_models(scatter=load_params(args.scatter_params)))
    result = analyse(out, comparison=comparison, pool=pool)
    print(markdown(result) + footer(result), end="")
    print(f"report: {out / 'report' / 'fog_physics.md'} (JSON, panels_<frame>.png beside it)")
    return 0
