"""Renderer speed and memory: seconds per frame by stage, and RSS growth over many frames.

    fogsim bench render [--frames 100] [--preset default] [--baseline-frames 3]

Renders with the bpy module in this process (draft preset, 640×426 by default) and prints
the median seconds per frame for scene description, bpy build, Cycles render, ground truth,
fog and writing; the share of the frame spent outside Cycles; resident memory after frame
10 and after the last frame. The baseline, measured in the same run on the first frames'
scenes, is Blender's factory Cycles light-path and world settings at the same sample count,
so the ratio shows what fogsim's render settings buy. The same first scenes are rendered again
under the procedural sky, an HDRI (``city``) and an overcast sky, interleaved frame by frame, and
the Cycles seconds of each are printed with their ratio to the procedural sky (``--no-skies``
skips it). Targets (``docs/speed.md``): draft ≤ 6 s per
frame; outside Cycles ≤ 15 %; RSS growth frame 10 → 100 ≤ 100 MB.
"""
from __future__ import annotations

import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import bpy
import numpy as np

from fogsim.render.blender import build, cycles
from fogsim.render.blender.scratch import clear
from fogsim.render.frame import describe_frame, scene_meshes
from fogsim.render.job_options import RunOptions
from fogsim.render.preset import lidar_block, radar_block
from fogsim.runs import frame_seed

STAGES = ("scene", "bpy_build", "render", "ground_truth", "fog", "write")


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def _timed_render(config, index: int, quality: dict, factory: bool = False) -> float:
    """Cycles seconds of frame ``index``'s scene of ``config``, built in a scene of its own
    (configured with ``quality``; ``factory``: Blender's automatic world sampling), then removed."""
    desc = describe_frame(config, index)
    scene = bpy.data.scenes.new("bench")
    cycles.configure(scene, quality, frame_seed(config.seed, index))
    if factory:
        scene.cycles.use_adaptive_sampling = True
    built = build.build(desc, scene, scene_meshes(desc))
    if factory:
        scene.world.cycles.sampling_method = "AUTOMATIC"
    t0 = time.perf_counter()
    cycles.render(scene)
    seconds = time.perf_counter() - t0
    clear(built)
    bpy.data.scenes.remove(scene)
    return seconds


def factory_render_seconds(job, index: int) -> float:
    """Render frame ``index``'s scene with factory light paths and world sampling (baseline)."""
    q = job.config.quality_settings
    quality = {"samples": q.samples, "denoise": q.denoise,
               "bounces": {"total": 12, "diffuse": 4, "glossy": 4, "transmission": 12, "transparent": 8}}
    return _timed_render(job.config, index, quality, factory=True)


#: the skies ``fogsim bench render`` times against each other (the bundled presets' lighting)
SKIES = {"procedural": {}, "hdri": {"sky": "hdri", "hdri": "city"}, "overcast": {"overcast": True}}


def sky_render_seconds(job, index: int, lighting: dict) -> float:
    """Cycles seconds of frame ``index``'s scene under ``lighting`` (fogsim's render settings)."""
    from dataclasses import replace

    from fogsim.schema.presets import check_lighting

    config = replace(job.config, lighting=check_lighting(lighting))
    return _timed_render(config, index, config.quality)


def sky_costs(job, frames: int) -> dict[str, float]:
    """Median Cycles seconds per sky over the first ``frames`` scenes, skies interleaved per frame."""
    times = {name: [] for name in SKIES}
    for index in range(frames):
        for name, lighting in SKIES.items():
            times[name].append(sky_render_seconds(job, index, lighting))
    return {name: statistics.median(t) for name, t in times.items()}


def run(args) -> int:
    """``args``: frames, preset, resolution, baseline_frames, out (see ``fogsim bench render --help``)."""
    from fogsim.render.blender.job import RenderJob
    from fogsim.render.preset import load_render_preset

    out = args.out or tempfile.mkdtemp(prefix="fogsim_bench_")
    config = load_render_preset(args.preset, frames=args.frames, resolution=args.resolution)
    if getattr(args, "lidar", None):
        block = {k: v for k, v in lidar_block(args.lidar).items() if k != "horizontal_resolution_deg"}
        config = replace(config, lidar={**block, "steps_per_sweep": args.lidar_steps})
    if getattr(args, "radar", None):
        config = replace(config, radar=radar_block(args.radar))
    job = RenderJob(config, out, RunOptions(resume=False))
    times, rss, detections = [], [], []
    for i in range(args.frames):
        meta = job.step()
        times.append(meta["timings_s"])
        if "radar" in meta:
            detections.append(meta["radar"]["sweep"]["detections"])
        rss.append(rss_mb())
        wall = sum(v for k, v in meta["timings_s"].items() if not k.endswith("_cpu"))
        print(f"frame {i:4d}: {wall:5.2f} s  rss {rss[-1]:7.1f} MB", flush=True)
    base = [factory_render_seconds(job, i) for i in range(min(args.baseline_frames, args.frames))]
    skies = sky_costs(job, min(args.baseline_frames, args.frames)) if getattr(args, "skies", True) else None
    job.close()

    stages = STAGES + (("lidar",) if config.lidar else ()) + (("radar",) if config.radar else ())
    casters = lidar_casters(config, min(args.baseline_frames, args.frames)) if config.lidar else None
    med = {s: statistics.median(t[s] for t in times) for s in stages}
    total = statistics.median(sum(t[s] for s in stages) for t in times)
    ours = statistics.median(t["render"] for t in times[:len(base)])
    print(f"\nrender benchmark: preset {config.name}, {args.resolution}, quality {config.quality.get('name')}, "
          f"{config.quality_settings.samples} samples, {args.frames} frames (medians)")
    for s in stages:
        print(f"  {s:<14}{med[s]:8.3f} s  {100 * med[s] / total:5.1f} %")
    outside = total - med["render"]
    print(f"  {'frame':<14}{total:8.3f} s")
    print(f"  outside Cycles {outside:.3f} s = {100 * outside / total:.1f} % of the frame")
    print(f"  Cycles render vs factory light paths + world map (same scenes, {len(base)} frames): "
          f"{ours:.2f} s vs {statistics.median(base):.2f} s = {statistics.median(base) / ours:.2f}× faster")
    if skies:
        print(f"  Cycles render by sky (same scenes, {len(base)} frames, interleaved): "
              + ", ".join(f"{k} {v:.2f} s ({v / skies['procedural']:.2f}×)" for k, v in skies.items()))
    if casters:
        sensor = config.lidar_sensor
        in_render = statistics.median(t["lidar_cpu"] for t in times)
        print(f"  LiDAR {sensor.name}, {sensor.beams} beams × {sensor.steps_per_sweep} steps = "
              f"{casters['rays']:,} rays: its stage in the render {med['lidar']:.3f} s wall, {in_render:.3f} s CPU "
              f"per frame (sweep, 3D boxes, {len(config.levels)} fogged scans) = "
              f"{in_render / med['render']:.2f}× Cycles' render (CPU / wall)")
        print(f"  LiDAR stage on one core (sweep + labels: 3D boxes, points per object, {len(config.levels)} fogged "
              f"scans; {casters['frames']} frames, medians): {casters['stage_cpu']:.3f} s CPU "
              f"({casters['stage']:.3f} s wall) = {casters['stage_cpu'] / med['render']:.2f}× Cycles' frame "
              f"({med['render']:.2f} s)")
        print(f"  ray casting on one core ({casters['frames']} frames, {casters['faces']:,} triangles, medians): "
              f"Embree build + sweep {casters['embree']:.3f} s vs Blender's BVHTree in a Python loop "
              f"{casters['bvhtree']:.3f} s = {casters['bvhtree'] / casters['embree']:.1f}× faster")
    if config.radar:
        print(f"  radar {config.radar_sensor.name}: its stage {med['radar']:.3f} s per frame (rays, clusters, "
              f"{len(config.levels)} fogged levels; files in write) = {med['radar'] / med['render']:.2f}× Cycles' "
              f"render; {statistics.median(detections):.0f} detections per clear sweep (median)")
    at10 = rss[min(9, len(rss) - 1)]
    print(f"  RSS after frame 10: {at10:.0f} MB, after frame {len(rss)}: {rss[-1]:.0f} MB, "
          f"growth {rss[-1] - at10:+.0f} MB")
    checks = [("draft ≤ 6 s per frame", total <= 6.0), ("outside Cycles ≤ 15 %", outside / total <= 0.15),
              ("RSS growth 10 → last ≤ 100 MB", rss[-1] - at10 <= 100)]
    if casters:
        checks.append((f"LiDAR sweep ({casters['rays']:,} rays) ≤ 1 s on one core", casters["embree"] <= 1.0))
        checks.append((f"LiDAR stage ({casters['rays']:,} rays, labels included) ≤ 0.3 s CPU on one core",
                       casters["stage_cpu"] <= 0.3))
    for text, ok in checks:
        print(f"  [{'ok' if ok else 'MISSED'}] {text}")
    print(f"bench render: {total:.2f} s per frame, {100 * outside / total:.1f} % outside Cycles, Cycles "
          f"{statistics.median(base) / ours:.2f}× faster than factory light paths; "
          f"RSS growth {rss[-1] - at10:+.0f} MB; "
          + (f"HDRI {skies['hdri'] / skies['procedural']:.2f}×, overcast "
             f"{skies['overcast'] / skies['procedural']:.2f}× the procedural sky; " if skies else "")
          + f"{sum(ok for _, ok in checks)}/{len(checks)} targets met")  # the summary line (--quiet)
    return 0


def lidar_casters(config, frames: int) -> dict:
    """Median seconds per frame, pinned to one core, of the whole LiDAR stage (:func:`lidar_stage`: the sweep,
    3D boxes, points per object and every fogged scan; CPU seconds of this process — what one core spends,
    whatever else the machine runs — and wall seconds), and of the LiDAR sweep as fogsim casts it (Embree:
    build the frame's scene, cast every ray) against Blender's ``mathutils.bvhtree.BVHTree`` (build, then ``ray_cast``
    per ray in a Python loop: the option without a vectorised caster), over the first ``frames`` scenes."""
    import os

    from mathutils import Vector
    from mathutils.bvhtree import BVHTree

    from fogsim.render.frame import DescribedFrame
    from fogsim.render.lidar_frame import lidar_stage
    from fogsim.render.lidar_scan import Geometry, RayCaster, sweep, sweep_directions

    sensor = config.lidar_sensor
    cpus = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    if cpus:
        os.sched_setaffinity(0, {min(cpus)})
    embree, bvh, stage, stage_cpu, faces = [], [], [], [], 0
    try:
        for index in range(frames):
            frame = DescribedFrame.of(config, index)
            pose = np.asarray(frame.desc["lidar"]["lidar_to_world"])
            t0, c0 = time.perf_counter(), time.process_time()  # the whole stage, as a render runs it
            lidar_stage(config, frame.desc, frame.meshes, [], index)
            stage.append(time.perf_counter() - t0)
            stage_cpu.append(time.process_time() - c0)
            geometry = Geometry.of_frame(frame.desc, frame.meshes, within=(pose[:3, 3], sensor.reach_m))
            faces = len(geometry.faces)
            t0 = time.perf_counter()
            sweep(RayCaster(geometry), pose, sensor, "bench")
            t1 = time.perf_counter()
            tree = BVHTree.FromPolygons(geometry.vertices.tolist(), geometry.faces.tolist())
            d, _, _ = sweep_directions(sensor)
            origin = Vector(pose[:3, 3].tolist())
            for ray in (d @ pose[:3, :3].T).tolist():
                tree.ray_cast(origin, Vector(ray), sensor.max_range_m)
            embree.append(t1 - t0)
            bvh.append(time.perf_counter() - t1)
    finally:
        if cpus:
            os.sched_setaffinity(0, cpus)
    return {"embree": statistics.median(embree), "bvhtree": statistics.median(bvh), "frames": frames,
            "faces": faces, "rays": sensor.beams * sensor.steps_per_sweep, "stage": statistics.median(stage),
            "stage_cpu": statistics.median(stage_cpu)}


def _fog_variant(config, **volumetric):
    """``config`` with volumetric fog (``volumetric`` merged into fog_model.volumetric)."""
    from dataclasses import replace

    from fogsim.render.fog_settings import volumetric_settings

    spec = {**config.fog_model.get("volumetric", {}), **volumetric}
    cfg = replace(config, fog_model={**config.fog_model, "kind": "volumetric", "volumetric": spec})
    volumetric_settings(cfg)  # checked like a preset's
    return cfg


def run_fog(args) -> int:
    """``fogsim bench render-fog``: a volumetric frame against a Koschmieder frame, same scenes.

    ``args``: preset, resolution, frames, repeat, samples (clear render), fog_samples (fog
    renders; default the same), levels, fast_scale, out. After one untimed warm-up frame
    (Koschmieder), the variants are interleaved frame by frame: Koschmieder (clear render +
    post-process), volumetric "full" with OIDN (where this Blender has it), volumetric "hybrid"
    (w = 0.5, OIDN too), "hybrid-fast" (the same at ``resolution_scale`` = fast_scale, rebuilt
    at full size by :mod:`fogsim.render.fog_rebuild`) and "hybrid-seed2" (hybrid with another
    noise seed: the noise floor). Prints median seconds per frame, the fog renders' share,
    seconds per fog level, the ratios against the Koschmieder frame of the same run, and per fog
    level the RMS error (8-bit sRGB) of hybrid-fast against full-resolution hybrid beside the
    noise floor (hybrid-seed2 against hybrid).
    """
    from fogsim.render.blender.compat import has_denoiser
    from fogsim.render.blender.job import RenderJob
    from fogsim.render.preset import load_render_preset

    root = Path(args.out or tempfile.mkdtemp(prefix="fogsim_bench_fog_"))
    base = load_render_preset(args.preset, frames=args.frames, resolution=args.resolution, samples=args.samples,
                              levels=args.levels)
    fog_samples = args.fog_samples or base.quality_settings.samples
    variants = {"koschmieder": base,
                "full+oidn": _fog_variant(base, medium="full", denoise=True, samples=fog_samples),
                "hybrid": _fog_variant(base, medium="hybrid", denoise=True, samples=fog_samples),
                "hybrid-fast": _fog_variant(base, medium="hybrid", denoise=True, samples=fog_samples,
                                            resolution_scale=args.fast_scale),
                "hybrid-seed2": _fog_variant(base, medium="hybrid", denoise=True, samples=fog_samples,
                                             noise_seed=1)}
    jobs = {name: RenderJob(cfg, root / name, RunOptions(resume=False)) for name, cfg in variants.items()}
    n_fog = sum(lv.beta > 0 for lv in base.levels)
    times = {name: [] for name in variants}
    fog_times = {name: [] for name in variants}
    try:
        jobs["koschmieder"].todo = [0]  # untimed warm-up: the process's first frame pays one-time costs
        jobs["koschmieder"].step()
        for rep in range(args.repeat):
            for index in range(args.frames):
                for name, job in jobs.items():
                    job.todo = [index]
                    t = job.step()["timings_s"]
                    times[name].append(sum(t.values()))
                    fog_times[name].append(t.get("fog_render", 0.0))
                    print(f"repeat {rep} frame {index} {name:<12} {times[name][-1]:7.2f} s"
                          f" (fog renders {fog_times[name][-1]:.2f} s)", flush=True)
    finally:
        for i, job in enumerate(jobs.values()):  # the jobs share one scene: the last one removes it
            if i < len(jobs) - 1:
                job.scene = None
            job.close()
    k = statistics.median(times["koschmieder"])
    w, h = base.resolution
    print(f"\nfog render benchmark: preset {base.name}, {w}x{h}, clear {base.quality_settings.samples} spp "
          f"(quality {base.quality.get('name', 'inline')}), fog {fog_samples} spp, {n_fog} fog levels, "
          f"{args.frames} frames × {args.repeat} repeats (medians), OIDN {'yes' if has_denoiser() else 'no'}, "
          f"Blender {bpy.app.version_string}, device CPU")
    print(f"  {'variant':<12}{'frame s':>9}{'× Kosch.':>10}{'fog s/level':>13}{'1-level frame ×':>17}")
    ratios = {}
    for name in variants:
        frame = statistics.median(times[name])
        per_level = statistics.median(fog_times[name]) / n_fog if n_fog and name != "koschmieder" else 0.0
        one = (frame - per_level * (n_fog - 1)) / k if n_fog else frame / k
        ratios[name] = frame / k
        print(f"  {name:<12}{frame:9.2f}{frame / k:10.2f}{per_level:13.2f}{one:17.2f}")
    errors = fast_errors(root, base, args.frames)
    print(f"  error against full-resolution hybrid, 8-bit sRGB RMS (median over {args.frames} frames):")
    print(f"  {'level':<10}{'hybrid-fast':>12}{'noise floor':>13}{'ratio':>8}")
    for key, (fast, floor) in errors.items():
        print(f"  {key:<10}{fast:12.2f}{floor:13.2f}{fast / floor if floor else float('nan'):8.2f}")
    fast_rms = max((f for f, _ in errors.values()), default=float("nan"))
    ok = ratios["hybrid-fast"] <= 3.0
    print(f"  [{'ok' if ok else 'MISSED'}] hybrid-fast frame ≤ 3× the Koschmieder frame "
          f"({ratios['hybrid-fast']:.2f}×; full-resolution hybrid {ratios['hybrid']:.2f}×)")
    print(f"  (outputs in {root})")
    print(f"bench render-fog: Koschmieder {k:.2f} s per frame; volumetric full+oidn {ratios['full+oidn']:.2f}×, "
          f"hybrid {ratios['hybrid']:.2f}×, hybrid-fast (scale {args.fast_scale:g}) {ratios['hybrid-fast']:.2f}× "
          f"({'ok' if ok else 'MISSED'}: ≤ 3×), its worst-level RMS {fast_rms:.2f}/255")  # the summary line (--quiet)
    return 0


def fast_errors(root: Path, config, frames: int) -> dict:
    """Level key → (median RMS of hybrid-fast vs hybrid, median RMS of hybrid-seed2 vs hybrid),
    8-bit sRGB, over the frames of a :func:`run_fog` run in ``root``."""
    import numpy as np

    from fogsim.dataset.layout import DatasetLayout
    from fogsim.io.images import read_image
    from fogsim.render.frame import frame_name

    lay = {v: DatasetLayout(root / v) for v in ("hybrid", "hybrid-fast", "hybrid-seed2")}

    def rms(variant: str, key: str, name: str) -> float:
        a = read_image(lay[variant].image(key, name)).astype(np.float64)
        b = read_image(lay["hybrid"].image(key, name)).astype(np.float64)
        return float(np.sqrt(np.mean((a - b) ** 2)))

    out = {}
    for lv in config.levels:
        if lv.beta > 0:
            names = [frame_name(i) for i in range(frames)]
            out[lv.key] = (statistics.median(rms("hybrid-fast", lv.key, n) for n in names),
                           statistics.median(rms("hybrid-seed2", lv.key, n) for n in names))
    return out
