"""``fogsim render``: render a labeled foggy dataset of procedural street scenes.

    fogsim render --preset default --frames 200 --out OUT                   # bpy module (5.0)
    fogsim render --preset default --assets MODELS --out OUT                # with your own models
    blender -b -P scripts/render_batch.py -- --preset default --out OUT      # Blender binary (3.4+)

Each frame is rendered once (RGB, planar depth, object index) and fogged at every level of
the preset — by Koschmieder's law on the clear render (default), or with ``--fog volumetric``
by one more Cycles render per level with a participating medium around camera and scene
(labels, depth and masks still come from the clear render). A frame is committed atomically
(``meta/<frame>.json`` last); a restarted run skips committed frames, and ``--shard i/N``
renders frames i, i+N, … for a Slurm array or a Kubernetes indexed job (then
``fogsim render --out OUT --finalize-only`` once, after all shards: COCO, YAMLs and the contact
sheet over every frame, with the parameters render_run.json records). Needs bpy (the ``blender``
extra) or Blender itself; --finalize-only needs neither.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from fogsim.camera import CITYSCAPES_BASELINE_M
from fogsim.errors import EXIT_FAILED, EXIT_OK, EXIT_USAGE, MissingDependency, run_command
from fogsim.io.pixel_bound import MAX_PIXELS
from fogsim.schema.presets import TRAIN_FRACTION
from fogsim.schema.vocabulary import FOG_KINDS, FOG_MEDIA


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", help="bundled preset name (default, suburban, arterial, cityscapes-stereo, night) "
                                    "or a path to a preset JSON; default: default")
    p.add_argument("--out", required=True, help="dataset folder")
    p.add_argument("--frames", type=int, help="number of frames (overrides the preset)")
    p.add_argument("--seed", type=int, help="dataset seed (overrides the preset)")
    p.add_argument("--resolution", help="WxH, e.g. 640x426 (intrinsics scale with it)")
    p.add_argument("--max-pixels", type=int, default=MAX_PIXELS,
                   help=f"refuse a render of more pixels than this, width × height (default {MAX_PIXELS:,}, "
                        "about 8192×4883; Blender's own limit is 65536 px a side)")
    p.add_argument("--samples", type=int, help="Cycles samples (overrides the quality preset)")
    p.add_argument("--levels", help="fog levels: preset name or comma-separated β (overrides the preset)")
    p.add_argument("--fog", choices=FOG_KINDS,
                   help="fog model (overrides the preset's fog_model.kind): koschmieder = the post-process on the "
                        "clear render (default); volumetric = one Cycles render per fog level with a participating "
                        "medium (labels, depth and masks still come from the clear render)")
    p.add_argument("--fog-medium", choices=FOG_MEDIA,
                   help="volumetric medium (implies --fog volumetric): full = pure scattering (default), "
                        "hybrid = half absorption + emission (cheaper), ea = camera-only emission-absorption "
                        "(exactly Koschmieder in linear light; a check)")
    p.add_argument("--fog-scale", type=float,
                   help="cheap volumetric fog (implies --fog volumetric): render the fog levels at this fraction "
                        "of width and height (0.1-1, e.g. 0.5 = a quarter of the pixels) and rebuild them at full "
                        "size from the clear render")
    p.add_argument("--stereo", action="store_true",
                   help=f"also render the right camera (preset baseline, else the camera's, else "
                        f"{CITYSCAPES_BASELINE_M} m) "
                        "and write SGBM disparity in Cityscapes' layout under OUT/cityscapes/")
    p.add_argument("--assets", help="your own models: a folder with one sub-folder per class (car, van, truck, bus, "
                                    "pedestrian, cyclist, traffic_light, traffic_sign) of .glb/.gltf/.obj/.fbx/.blend "
                                    "files, imported once and sampled per frame (replaces the preset's assets "
                                    "classes; its mix, units, forward and out_of_range stay)")
    p.add_argument("--lidar", metavar="SENSOR",
                   help="also sweep a LiDAR in every frame and fog its scan per level: a bundled sensor (hdl64e, "
                        "hdl32e, hdl64-s3d) or a sensor .json (overrides the preset's lidar); writes lidar/<level>/, "
                        "per-point labels, 3D boxes in meta and COCO, and a KITTI tree per level (kitti/<level>/). "
                        "Scene mode: an object with the custom property fogsim_lidar is the sensor, else the "
                        "camera's pose plus KITTI's offset")
    p.add_argument("--radar", metavar="SENSOR",
                   help="also sweep a radar in every frame and fog its detections per level: a bundled sensor "
                        "(ars408-lr, srr-corner) or a sensor .json (overrides the preset's radar); writes "
                        "radar/<level>/<frame>.pcd (nuScenes radar) with per-detection labels, and the radar column "
                        "of the cross-sensor table. Scene mode: an object with the custom property fogsim_radar is "
                        "the sensor, else the camera's pose plus nuScenes' radar offset")
    p.add_argument("--train-fraction", type=float, help="share of frames in the train split (default: the "
                   f"preset's, else {TRAIN_FRACTION}; the paper's 8,100/4,800: 0.628); --finalize-only re-splits "
                   "without rendering")
    p.add_argument("--shard", help="i/N: render frames i, i+N, … (0-based), e.g. $SLURM_ARRAY_TASK_ID/N")
    p.add_argument("--no-resume", action="store_true", help="re-render committed frames")
    p.add_argument("--gpu", action="store_true", help="render on the GPU when one is available")
    p.add_argument("--finalize-only", action="store_true",
                   help="only write the dataset-wide files (COCO, splits, data YAMLs, dataset.json, contact sheet) "
                        "over the committed frames, once every shard has finished: the render's parameters are read "
                        "from OUT/render_run.json, so --out is all it needs (no Blender either); other flags given "
                        "must match the record (--train-fraction re-splits)")
    g = p.add_argument_group("scene mode (your own Blender scene; docs/own-scenes.md)")
    g.add_argument("--scene", help="render this .blend file's active scene instead of a preset ('current': the "
                                   "scene Blender has open, blender -b FILE.blend -P …); the file is never written")
    g.add_argument("--camera", help="camera object to render through (default: the scene's camera)")
    g.add_argument("--frame-range", help="START:END[:STEP], Blender frame numbers, END included "
                                         "(default: the scene's frame range)")
    g.add_argument("--class-map", help="JSON file (or inline JSON object) of object/collection name glob → class, "
                                       "e.g. '{\"Car*\": \"car\"}'; a fogsim_class custom property wins over it")
    p.add_argument("--quiet", action="store_true", help="print only errors and the summary line (no progress bar, "
                                                        "no frame log, none of Blender's own output)")


def add_parsers(sub) -> None:
    p = sub.add_parser("render", help="render a labeled foggy dataset of street scenes (needs Blender / bpy)",
                       description=__doc__)
    add_arguments(p)
    p.set_defaults(run=cmd_render)


def require_bpy() -> None:
    """bpy must be importable: the bpy module (``blender`` extra) or Blender's own Python.

    Only checks (``find_spec``): bpy itself is imported by ``fogsim.render.blender`` alone.
    """
    from importlib.util import find_spec

    if sys.modules.get("bpy") is None and find_spec("bpy") is None:
        raise MissingDependency("rendering needs Blender: pip install 'fogsim[blender]' (the bpy module, "
                                "Python 3.11), or run blender -b -P scripts/render_batch.py -- …")


def cmd_render(args) -> int:
    """Set up (every usage and setup error before anything is rendered), then loop over frames."""
    from fogsim.render.preset import load_render_preset
    from fogsim.runs import check_output, parse_shard

    if args.finalize_only:
        return _finalize_only(args)
    if args.scene:
        return _cmd_scene(args)
    if args.camera or args.frame_range or args.class_map:
        raise ValueError("--camera, --frame-range and --class-map need --scene")
    preset_file = args.preset if args.preset and Path(args.preset).is_file() else None
    check_output(args.out, {"--preset": preset_file, "--assets": args.assets})
    config = load_render_preset(args.preset, frames=args.frames, seed=args.seed, train_fraction=args.train_fraction,
                                resolution=args.resolution, samples=args.samples, levels=args.levels,
                                stereo=True if args.stereo else None, max_pixels=args.max_pixels,
                                fog=args.fog, fog_medium=args.fog_medium, fog_scale=args.fog_scale, assets=args.assets,
                                lidar=args.lidar, radar=args.radar)
    shard = parse_shard(args.shard)
    require_bpy()
    from fogsim.render.blender.job import RenderJob
    from fogsim.render.job_options import RunOptions

    job = RenderJob(config, args.out, RunOptions(shard, not args.no_resume, args.gpu, args.quiet))
    try:
        return _render(job, args, shard)
    finally:
        job.close()


def _cmd_scene(args) -> int:
    """Scene mode: the user's own Blender scene (:mod:`fogsim.render.blender.scene_mode`)."""
    from fogsim.render.job_options import RunOptions, SceneOptions
    from fogsim.render.scene_classes import load_class_map
    from fogsim.runs import check_output, parse_shard

    for flag, given in (("--preset", args.preset), ("--frames", args.frames), ("--stereo", args.stereo or None),
                        ("--train-fraction", args.train_fraction), ("--assets", args.assets)):
        if given is not None:
            raise ValueError(f"{flag} is not available with --scene (scene mode renders the scene's own objects: "
                             "--frame-range, --camera, --class-map, --levels, --samples, --resolution, --seed, "
                             "--fog, --fog-medium, --fog-scale, --lidar, --radar)")
    blend = None if args.scene == "current" else args.scene
    check_output(args.out, {"--scene": blend})
    options = SceneOptions(camera=args.camera, frame_range=args.frame_range, class_map=load_class_map(args.class_map),
                           levels=args.levels, samples=args.samples, resolution=args.resolution, seed=args.seed or 0,
                           max_pixels=args.max_pixels, fog=args.fog, fog_medium=args.fog_medium,
                           fog_scale=args.fog_scale, lidar=args.lidar,
                           radar=args.radar).check()  # a usage error before Blender
    shard = parse_shard(args.shard)
    require_bpy()
    from fogsim.render.blender.scene_mode import open_scene, scene_job

    scene = open_scene(args.scene, args.quiet)
    job = scene_job(scene, args.out, options, RunOptions(shard, not args.no_resume, args.gpu, args.quiet))
    if not args.quiet:
        print(job.summary)
        for note in job.notes:
            print(f"note: {note}")
    try:
        return _render(job, args, shard)
    finally:
        job.close()


def _render(job, args, shard) -> int:
    from fogsim.console import progress_bar
    from fogsim.render.loop import FrameLoop, frame_log
    from fogsim.runs import is_sharded

    loop = FrameLoop(job)
    t0 = time.perf_counter()
    with progress_bar(loop.total, "render", "frame", args.quiet) as bar:
        def on_frame(index, meta, error):
            if error is not None:
                bar.write(f"error: frame {index}: {error}")
            elif not args.quiet:  # the per-frame timing log (also kept in meta/<frame>.json)
                bar.write(frame_log(meta))
            bar.update(1)

        loop.run(on_frame)
    try:
        loop.finish(sharded=is_sharded(shard))
    except (OSError, ValueError) as exc:
        print(f"fogsim: error: writing the dataset files of {args.out} failed: {exc}", file=sys.stderr)
        return EXIT_FAILED
    note = _summary_warning(loop.summary, args.quiet)
    lines = [f"rendered {loop.done} frames ({job.skipped} already done, {len(loop.failed)} failed) "
             f"in {time.perf_counter() - t0:.1f} s → {args.out}"]
    if note and args.quiet:
        lines.append(f"warning: {note}")
    if is_sharded(shard):  # the dataset-wide files wait for one finalize after every shard
        lines.append(f"fogsim: shard {shard[0]}/{shard[1]} done; when every shard has finished, write the dataset "
                     f"files with: {finalize_command(args)}")
    print("; ".join(lines) if args.quiet else "\n".join(lines))  # --quiet: one summary line
    _visible(loop.summary, args.quiet)
    for index, error in loop.failed:
        print(f"  failed: frame {index}: {error}", file=sys.stderr)
    skipped = _skipped(loop.summary)
    return EXIT_FAILED if loop.failed or skipped else EXIT_OK


def finalize_command(args) -> str:
    """The finalize command of this run's output, for the entry the user ran (``fogsim render`` or the batch
    script under Blender); it needs nothing but ``--out``."""
    import shlex

    out = shlex.quote(str(args.out))
    entry = getattr(args, "entry", "fogsim render")
    if entry == "fogsim render":
        return f"fogsim render --out {out} --finalize-only"
    return (f"blender -b -P scripts/{entry} -- --out {out} --finalize-only "
            f"(or fogsim render --out {out} --finalize-only)")


def _summary_warning(summary: dict | None, quiet: bool) -> str | None:
    """The one-frame dataset's warning, printed unless ``quiet`` (then the summary line says it); returned."""
    from fogsim.dataset.writer import split_note

    note = split_note(summary) if summary is not None else None  # a one-frame dataset
    if note and not quiet:
        print(f"fogsim: warning: {note}", file=sys.stderr)
    return note


def _visible(summary: dict | None, quiet: bool) -> None:
    """Each level's visible boxes (the visible-only label sets, :mod:`fogsim.dataset.visible`), unless quiet."""
    from fogsim.dataset.visible import visible_line

    line = visible_line(summary) if summary is not None and not quiet else None
    if line:
        print(line)


def _skipped(summary: dict | None) -> list[str]:
    skipped = (summary or {}).get("skipped_frames", [])
    for line in skipped:
        print(f"  skipped: {line}", file=sys.stderr)
    return skipped


def _finalize_only(args) -> int:
    """``--finalize-only``: the dataset files over the committed frames, with the configuration
    ``render_run.json`` records (:mod:`fogsim.render.finalize`); flags given too must match it."""
    from dataclasses import replace

    from fogsim.dataset.layout import DatasetLayout
    from fogsim.render.finalize import RUN_FILE, check_flags, finalize_render, recorded_config
    from fogsim.render.preset import check_overrides
    from fogsim.runs import parse_shard

    shard = parse_shard(args.shard)
    check_overrides(frames=args.frames, train_fraction=args.train_fraction)  # a usage error first
    config, blender = recorded_config(args.out)
    flags = {"--preset": args.preset, "--seed": args.seed, "--resolution": args.resolution,
             "--samples": args.samples, "--levels": args.levels, "--fog": args.fog, "--fog-medium": args.fog_medium,
             "--fog-scale": args.fog_scale, "--stereo": args.stereo, "--assets": args.assets, "--lidar": args.lidar,
             "--radar": args.radar, "--scene": args.scene, "--camera": args.camera,
             "--frame-range": args.frame_range, "--class-map": args.class_map}
    check_flags(config, flags, Path(args.out) / RUN_FILE)
    if args.train_fraction is not None:  # a re-split: the one parameter finalize may change
        config = replace(config, train_fraction=args.train_fraction)
    layout = DatasetLayout(args.out)
    if not layout.done_frames():
        print(f"fogsim: error: {args.out}: no committed frames to finalize", file=sys.stderr)
        return EXIT_USAGE
    try:
        summary = finalize_render(layout, config, blender)
    except (OSError, ValueError) as exc:
        print(f"fogsim: error: writing the dataset files of {args.out} failed: {exc}", file=sys.stderr)
        return EXIT_FAILED
    note = _summary_warning(summary, args.quiet)
    skipped = _skipped(summary)
    frames = args.frames if args.frames is not None else summary["preset"]["frames"]
    print(finalize_line(summary, frames, shard) + f" → {args.out}" + (f"; warning: {note}" if note and args.quiet
                                                                      else ""))
    _visible(summary, args.quiet)
    return EXIT_FAILED if skipped else EXIT_OK


def finalize_line(summary: dict, frames: int, shard: tuple[int, int]) -> str:
    """What ``--finalize-only`` found: frames of the run's ``frames``, and the absent ones (with
    ``--shard i/N``: the shards they belong to, frame k being shard k mod N's)."""
    found = set(summary.get("frame_seeds", {}))
    absent = [k for k in range(frames) if f"{k:06d}" not in found]
    line = f"finalize: {summary['frames']} frames found of the run's {frames}"
    if absent:
        shown = ", ".join(str(k) for k in absent[:10]) + (" …" if len(absent) > 10 else "")
        line += f"; {len(absent)} absent (frames {shown})"
        if shard[1] > 1:
            line += f", from shards {', '.join(f'{i}/{shard[1]}' for i in sorted({k % shard[1] for k in absent}))}"
    return line


def main(argv: list[str] | None = None, prog: str = "fogsim render") -> int:
    """Entry of ``scripts/render_batch.py`` (``blender -b -P``): the same command, its own prog name."""
    from fogsim.cli.help import HelpFormatter
    from fogsim.io.paths import with_checked_paths

    p = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=HelpFormatter)
    add_arguments(p)
    p.set_defaults(entry=prog)
    interrupt_as_python()
    return run_command(with_checked_paths(cmd_render), p.parse_args(argv), prog="fogsim")


def interrupt_as_python() -> None:
    """Ctrl-C as KeyboardInterrupt in Blender's own Python too (``blender -b -P``). Blender embeds
    Python without its signal handlers and handles SIGINT itself: the first one only breaks the
    render in progress (the frame is lost and the run goes on), the second kills Blender (exit 2).
    With Python's handler, every front door stops alike: the current render completes, then exit
    130, resumable (:func:`fogsim.render.blender.cycles.interrupts_deferred`)."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) in (
            None, signal.SIG_DFL):
        signal.signal(signal.SIGINT, signal.default_int_handler)
